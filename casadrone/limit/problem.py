"""The limit-lap problem posed from a track: its targets, the checks that it can be posed, the
start state and the bounds (docs/concepts/limit-lap.md). Pure functions of the airframe, the
track and the options."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from casadrone.airframe import PARAM_NAMES, Airframe
from casadrone.config.limitlap import (
    MAX_GRID_ROUNDS,
    MAX_INTERVALS,
    MAX_SUBSTEPS,
    ROTOR_STEPS,
    SOLVERS,
)
from casadrone.config.track import TrackConfig, unreachable_target
from casadrone.guidance import segment_headings
from casadrone.limit.gates import MAX_EDGES, TargetKind, gate_frame, target_vector
from casadrone.limit.nlp import Nlp
from casadrone.limit.result import (
    DEFAULT_INTERVALS,
    MAX_TOTAL_INTERVALS,
    LimitLapOptions,
    model_states,
)
from casadrone.model import NX
from casadrone.propulsion import hover_rotors, rotor_state_bounds, rotor_thrust_bound
from casadrone.targets import kind_of_shape


@dataclass(frozen=True)
class Targets:
    """The legs of a track as the NLP sees them."""

    kinds: tuple[TargetKind, ...]
    vector: np.ndarray  # the ``targets`` part of P
    first_timed: int  # leg that ends at the first waypoint
    lap_ends: tuple[int, ...] = ()  # leg that ends each lap
    route: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # start, climb, targets


def _lap_items(track: TrackConfig) -> list[int]:
    """Waypoint index of each timed target over ``track.laps`` laps. A lap that ends where it
    began (last waypoint = first, as a gate track closing through its first gate) is not flown
    through that point twice: the next lap starts at the second waypoint."""
    n = len(track.waypoints_m)
    closes = n > 1 and np.allclose(track.waypoints_m[0], track.waypoints_m[-1])
    items = list(range(n))
    for _ in range(track.laps - 1):
        items += list(range(1 if closes else 0, n))
    return items


def frame_clearance_m(airframe: Airframe, prop_diameter_m: float = 0.127) -> float:
    """The frame's own size as a gate clearance (m): the farthest rotor centre from the centre
    of mass in the rotor plane plus a propeller's radius (the default 127 mm is the paper's
    5-inch propeller, AirframeConfig's default)."""
    at = PARAM_NAMES.index("r1x")
    r = np.asarray(airframe.p[at:at + 12]).reshape(4, 3)[:, 0:2]
    return float(np.linalg.norm(r, axis=1).max()) + prop_diameter_m / 2


def track_targets(track: TrackConfig, options: LimitLapOptions,
                  clearance_m: float | None = None) -> Targets:
    """Ball or gate per route leg (the climb point is always a ball), over every lap. Gates
    shrink by ``options.gate_clearance_m``, or by ``clearance_m`` (the frame's size) when the
    option is None."""
    first = track.first_timed_segment
    items = _lap_items(track)
    route = np.vstack([track.route[:first + 1], np.asarray(track.waypoints_m, float)[items]])
    n_legs = len(route) - 1
    acc = track.acceptance_radius_m if options.ball_radius_m is None else options.ball_radius_m
    tol = acc if track.tolerance_m is None or options.ball_radius_m is not None \
        else track.tolerance_m
    radii = np.full(n_legs, acc)
    radii[first:] = np.broadcast_to(np.asarray(tol, float), (len(track.waypoints_m),))[items]
    kinds: list[TargetKind] = ["ball"] * n_legs
    heads = segment_headings(route, math.radians(track.start_yaw_deg))
    frames = np.array([gate_frame(0.0, 0.0, h) for h in heads])
    hw, hh = np.zeros(n_legs), np.zeros(n_legs)
    edges = np.tile([0.0, 0.0, 1.0], (n_legs, MAX_EDGES, 1))
    clear = options.gate_clearance_m if options.gate_clearance_m is not None else clearance_m
    clear = 0.0 if clear is None else clear
    for k, j in enumerate(items):
        if track.gates:
            gate, leg = track.gates[j], first + k
            kind = kind_of_shape(gate.shape)  # its packing: casadrone.targets
            packed = kind.pack(gate, clear)
            kinds[leg] = kind.name
            frames[leg] = gate_frame(*gate.rpy_rad)
            hw[leg], hh[leg] = packed.half_width_m, packed.half_height_m
            if packed.edges is not None:
                edges[leg] = packed.edges
    n_wp = len(track.waypoints_m)
    ends = [first + i for i in range(len(items)) if items[i] == n_wp - 1]
    return Targets(tuple(kinds), target_vector(route[1:], tuple(kinds), heads, hw, hh, radii,
                                               frames, edges), first, tuple(ends), route)


#: Shortest leg duration (s) of the limit lap's box (:func:`bounds`): a leg of zero time would
#: make its RK4 steps zero and its dynamics rows empty.
MIN_LEG_S = 1e-3
#: How far below the start (or the ground, whichever is lower) the limit lap's floor lies when
#: the track gives no ``floor_m`` (m).
DEFAULT_FLOOR_GAP_M = 0.1


def default_floor_m(track: TrackConfig) -> float:
    """The floor (m) of a track without ``floor_m``: 0.1 m below the start or the ground."""
    return min(track.start_position_m[2], 0.0) - DEFAULT_FLOOR_GAP_M


def check_inputs(track: TrackConfig, options: LimitLapOptions,
                 clearance_m: float | None = None) -> str:
    """Why the problem cannot be posed (empty string when it can)."""
    if (options.intervals is not None and not 2 <= options.intervals <= MAX_INTERVALS) \
            or not 1 <= options.degree <= 9 \
            or not 1 <= options.substeps <= MAX_SUBSTEPS:
        return (f"intervals must be 2…{MAX_INTERVALS}, degree 1…9 and substeps "
                f"1…{MAX_SUBSTEPS} (got {options.intervals}, {options.degree}, "
                f"{options.substeps})")
    # intervals None: the propulsion kind decides (limit_lap resolves it before calling this);
    # the fewest of the kinds' defaults here, so that no posable problem is refused early
    per_leg = options.intervals or min(DEFAULT_INTERVALS.values())
    legs = len(track.waypoints_m) * track.laps + (track.climb_to_m is not None)
    if legs * per_leg > MAX_TOTAL_INTERVALS:
        return (f"waypoints_m: {legs} legs ({len(track.waypoints_m)} targets x {track.laps} "
                f"laps) at {per_leg} intervals each make {legs * per_leg} intervals, more than "
                f"the {MAX_TOTAL_INTERVALS} a limit lap takes (memory grows with them); use "
                f"fewer laps or targets, or fewer intervals per leg")
    if options.rotor_step not in ROTOR_STEPS:
        return f"rotor_step must be one of {', '.join(ROTOR_STEPS)} (got {options.rotor_step!r})"
    if not 0 <= options.grid_rounds <= MAX_GRID_ROUNDS:
        return f"grid_rounds must be 0…{MAX_GRID_ROUNDS} (got {options.grid_rounds})"
    if options.start_state is not None and len(options.start_state) != NX:
        return f"start_state needs {NX} values, got {len(options.start_state)}"
    if options.resimulation not in ("lap", "legs"):
        return f"resimulation must be 'lap' or 'legs' (got {options.resimulation!r})"
    if options.solver not in SOLVERS:
        return f"solver must be one of {', '.join(SOLVERS)} (got {options.solver!r})"
    if options.solver == "fatrop" and track.end == "periodic":
        return ("solver 'fatrop' needs stages coupled only to their neighbours: end 'periodic' "
                "ties the last node to the first (use solver 'ipopt')")
    if options.solver == "fatrop" and options.method != "shooting":
        return "solver 'fatrop' needs method 'shooting' (collocation has no stage order here)"
    if options.attitude == "quaternion" and options.tilt_limit == "axes":
        return ("tilt_limit 'axes' bounds Euler angles: with the quaternion attitude use 'cone' "
                "or 'none'")
    clear = options.gate_clearance_m if options.gate_clearance_m is not None else clearance_m
    for j, gate in enumerate(track.gates or []):
        if clear is None:
            break
        inner = kind_of_shape(gate.shape).inner_m(gate)  # its largest inscribed radius
        if inner <= clear and gate.vertices_m is not None:
            return (f"gate {j + 1}: the polygon's largest circle about its centre (radius "
                    f"{inner:.3g} m) is not wider than the clearance {clear:.3g} m")
        if inner <= clear:
            return (f"gate {j + 1}: opening {gate.width_m:g} x {gate.height_m:g} m is not wider "
                    f"than twice the clearance {clear:.3g} m")
    if options.ball_radius_m is not None and options.ball_radius_m < 0:
        return "ball_radius_m must not be negative"
    return _track_limits_problem(track, options)


def _track_limits_problem(track: TrackConfig, options: LimitLapOptions) -> str:
    """Why the box of :func:`bounds` cannot hold the track (empty when it can). Reading the
    track refuses what its own keys rule out; these two come from the limit lap's own limits,
    and without them IPOPT reported "Ill-posed problem" or infeasibility as a failed lap (exit
    0) instead of naming the key: a time limit below the shortest leg duration, and a target
    wholly below the floor that applies when the track gives no ``floor_m``."""
    if track.time_limit_s * track.laps < MIN_LEG_S:
        return (f"time_limit_s: {track.time_limit_s:g} s x {track.laps} lap(s) is below the "
                f"shortest leg duration of the limit lap ({MIN_LEG_S:g} s)")
    if track.floor_m is None and options.start_state is None:
        return unreachable_target(track, default_floor_m(track), None,
                                  floor_note=": no floor_m given, "
                                  f"{DEFAULT_FLOOR_GAP_M:g} m below the start or the ground; "
                                  "set floor_m to fly lower")
    return ""


def start_state(airframe: Airframe, track: TrackConfig, options: LimitLapOptions) -> np.ndarray:
    """The state the limit lap starts from, as 16 Euler-model states: level at the track's start
    yaw, rotors at hover thrust, at rest or at the track's ``start.velocity_mps`` (world), unless
    ``options.start_state`` gives it."""
    if options.start_state is not None:
        return np.asarray(options.start_state, float)
    x = np.zeros(NX)
    x[0:3] = track.start_position_m
    psi = math.radians(track.start_yaw_deg)
    x[11] = psi
    c, s = math.cos(psi), math.sin(psi)
    vw = np.asarray(track.start.velocity_mps, float)
    x[3:6] = [c * vw[0] + s * vw[1], -s * vw[0] + c * vw[1], vw[2]]  # Rz(ψ)ᵀ v
    x[12:16] = hover_rotors(airframe, airframe.hover_thrusts())[0]
    return x


def closes(track: TrackConfig) -> bool:
    """Whether the track's start is its finish (no climb point, the start position on the last
    waypoint to 1 mm): a periodic lap then repeats its position too, and starts anywhere in the
    last target (pinned to the waypoint itself, its one lap boundary would have less room than
    the lap boundaries inside a multi-lap flight, which lie anywhere in that target: measured
    on SY250, paper rectangle at 20 m, 20 intervals per leg, 1 m balls: two periodic laps
    0.71 % below twice the pinned one)."""
    return track.climb_to_m is None and bool(np.allclose(
        track.start_position_m, track.waypoints_m[-1], rtol=0.0, atol=1e-3))


def row_bounds(nlp: Nlp, track: TrackConfig, options: LimitLapOptions
               ) -> tuple[np.ndarray, np.ndarray]:
    """(lbg, ubg): the tilt cone at the track's tilt limit, the end velocity, the periodic
    lap's rows (position among them where the track :func:`closes`)."""
    tilt = math.radians(track.max_tilt_deg if options.max_tilt_deg is None
                        else options.max_tilt_deg)
    return nlp.row_bounds(math.cos(tilt), track.end_velocity_mps if track.end == "velocity"
                          else None, periodic_position=closes(track))


def bounds(nlp: Nlp, airframe: Airframe, track: TrackConfig, options: LimitLapOptions,
           point_mass: bool) -> tuple[np.ndarray, np.ndarray]:
    """Box on the decision vector: leg durations, floor and ceiling, tilt (axes), body rates,
    rotor states and commands, the start state. The point mass keeps only what it has
    (durations, altitude, its attitude controls within ±tilt per axis, which contains the
    cone, and total thrust ≤ 4K): every flight of the full model stays one of the point mass."""
    model = nlp.model
    L, M = nlp.layout.n_legs, nlp.layout.n_intervals
    tilt = math.radians(track.max_tilt_deg if options.max_tilt_deg is None
                        else options.max_tilt_deg)
    t_lo, t_hi = np.full(L, MIN_LEG_S), np.full(L, track.time_limit_s * track.laps)
    if track.floor_m is not None:
        floor = track.floor_m
    else:
        floor = default_floor_m(track) if options.start_state is None else -np.inf
    nx, nu = model.nx, model.nu
    xl, xu = np.full((M + 1, nx), -np.inf), np.full((M + 1, nx), np.inf)
    ul, uu = np.full((M, nu), -np.inf), np.full((M, nu), np.inf)
    xl[:, 2] = floor
    if track.ceiling_m is not None:
        xu[:, 2] = track.ceiling_m
    zl, zu = xl, xu  # collocation states: the same box, the start state not fixed
    if point_mass:
        if options.tilt_limit != "none":
            ul[:, 0:2], uu[:, 0:2] = -tilt, tilt
        ul[:, 3], uu[:, 3] = 0.0, 4 * rotor_thrust_bound(airframe)
    else:
        if options.tilt_limit == "axes":
            xl[:, 9:11], xu[:, 9:11] = -tilt, tilt
        xl[:, model.rotor], xu[:, model.rotor] = rotor_state_bounds(airframe)
        rate = track.max_body_rate_rad_s
        if rate is not None and model.rates is not None:
            lim = np.array([rate.roll_pitch, rate.roll_pitch, rate.yaw])
            xl[:, model.rates], xu[:, model.rates] = -lim, lim
        ul[:], uu[:] = 0.0, 1.0
        x0 = model_states(model.attitude, start_state(airframe, track, options))[0]
        zl, zu = xl.copy(), xu.copy()
        # also an equality on the parameter; the bound helps IPOPT. Periodic: the start state
        # is a decision variable (Nlp.row_bounds), but for its position where the track does
        # not close
        fixed = slice(None) if not nlp.layout.periodic else \
            slice(0, 0) if closes(track) else slice(0, 3)
        xl[0, fixed], xu[0, fixed] = x0[fixed], x0[fixed]
    d = nlp.layout.n_coll
    return (nlp.pack(t_lo, xl, ul, np.repeat(zl[1:, None, :], d, axis=1)),
            nlp.pack(t_hi, xu, uu, np.repeat(zu[1:, None, :], d, axis=1)))
