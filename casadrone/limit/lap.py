"""The limit lap: the minimum-time flight of an airframe through a track
(docs/concepts/limit-lap.md).

``limit_lap(airframe, track, options) -> LimitLap``. The NLP (:mod:`casadrone.limit.nlp`) is built
once per track layout on the one symbolic model; the airframe enters only as the parameter p.
Legs are the track's route segments (start → climb point → waypoints, or start → gates); a leg
ends inside the waypoint's acceptance ball or through the gate's opening. Start: hover at the
first route point (rotors at hover thrust, at rest, the track's start yaw), as the closed-loop
lap starts, or ``options.start_state``. Attitude limit: |φ|, |θ| ≤ the track's ``max_tilt_deg``
(the closed loop's failure test). The lap ends at the last waypoint, at any speed.

Robustness:

- starts: ``closed-loop`` (casadrone's own closed-loop lap of the frame, sampled onto the grid: a
  dynamically consistent but slow guess) and ``point-mass`` (the lower-bound solution lifted to
  the full state: fast but not consistent); for each of ``options.warm_starts`` (neighbouring
  LimitLaps on the same layout) also ``warm-i``, a primal-dual IPOPT warm start, or
  ``resampled-i`` for a LimitLap of the same legs on another grid (grid refinement follows the
  same local optimum). The best converged start that passes the re-simulation check wins; a
  single start can miss the best local optimum by a few per cent.
- fallback: when none of those gives a verified optimum, ``reference-<name>``, a primal-dual warm
  start from the limit lap of the shipped airframe ``options.fallback_reference`` (SY250) on the
  same track and options, solved once per process. The NLP is the same for every frame (the
  airframe is only its parameter p), so a verified optimum of a paper frame is a consistent
  start for any other. Measured: one of 50 random Table 1 frames (40 intervals) got no
  converged start (closed-loop: restoration failed; point-mass: iteration limit; the same on
  20-, 25- and 30-interval grids, so a coarse-grid start does not help); from SY250's optimum it
  converged in 88 iterations (3 s).
- every failure (no convergence, unflyable frame, unreachable target) is a result with status
  ``failed`` and a reason; :func:`limit_lap` does not raise for a bad airframe.

Determinism: IPOPT with MUMPS is deterministic for the same inputs, and the starts depend only on
the airframe, the track and ``options`` (including ``warm_start``), never on what was solved
before in the process. An optimisation warm-starts every candidate from the *same* per-study
reference solution (see :mod:`casadrone.evaluate`), so a candidate's value does not depend on the
worker or the order of evaluation.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Literal

import numpy as np

from casadrone.airframe import Airframe
from casadrone.config.airframe import AirframeConfig
from casadrone.config.controller import ControllerConfig
from casadrone.config.track import TrackConfig
from casadrone.guidance import segment_headings
from casadrone.limit.gates import (
    MAX_EDGES,
    TargetKind,
    gate_frame,
    polygon_edges,
    target_vector,
)
from casadrone.limit.nlp import (
    ATTITUDE_MODELS,
    Layout,
    Nlp,
    NlpPoint,
    NlpSolution,
    build_nlp,
    point_mass_ocp_model,
    solve,
)
from casadrone.model import NX, rotation_matrix
from casadrone.propulsion import (
    equal_rotor_guess,
    hover_rotors,
    max_static_thrust,
    rotor_state_bounds,
    rotor_thrust_bound,
    static_thrusts,
)
from casadrone.results import Status

Start = Literal["closed-loop", "point-mass", "coarse-grid", "relaxed-tolerance"]
#: The attitude models of the limit lap, and the ways it limits the tilt.
Attitude = Literal["euler", "quaternion"]
TiltLimit = Literal["axes", "cone", "none"]
BANG_BANG_TOL = 0.02  # a command within this of 0 or 1 counts as saturated
#: Share of the intervals of the coarse grid of the "coarse-grid" start (40 -> 30).
COARSE_SHARE = 0.75
#: Smallest ball radius (m) of the first solve of the "relaxed-tolerance" start.
RELAXED_RADIUS_M = 1.0
#: Verified starts within this relative distance of the best count as the same optimum.
CERTAIN_REL = 1e-3
#: Constant speeds (m/s) of the straight-line starts of the point-mass reference (best of them).
REFERENCE_SPEEDS_MPS = (5.0, 10.0, 20.0)

#: The target kind of each gate shape (a ball is a waypoint without a gate).
KIND_OF_SHAPE: dict[str, TargetKind] = {"rectangle": "gate", "circle": "circle",
                                        "polygon": "polygon"}
#: How far the verified starts agree (:func:`_certainty`).
Certainty = Literal["agreed", "single", "spread"]


def euler_states(attitude: str, X: np.ndarray) -> np.ndarray:
    """Model states (rows) as 16 Euler-model states."""
    if attitude == "quaternion":
        from casadrone.limit.attitude import quat_states_to_euler

        return quat_states_to_euler(X)
    return np.asarray(X, float)


def model_states(attitude: str, X: np.ndarray) -> np.ndarray:
    """16 Euler-model states (rows) as the model's states."""
    if attitude == "quaternion":
        from casadrone.limit.attitude import euler_states_to_quat

        return euler_states_to_quat(X)
    return np.atleast_2d(np.asarray(X, float))
#: Most intervals per leg. Grid refinement moved SY250's lap by 0.02 % from 40 to 80 intervals
#: (LimitLapOptions.intervals), so 400 is ten times finer than any measured need; the NLP's
#: memory grows in proportion (20 000 intervals reached 5.8 GB and failed to allocate), so 400
#: stays near 0.1 GB.
MAX_INTERVALS = 400


@dataclass(frozen=True)
class LimitLapOptions:
    """Numerical and modelling settings of the limit lap (identical for every candidate)."""

    # Intervals per leg. Grid refinement on SY250, from the coarse optimum resampled: 30 -> 60
    # changed the lap by 0.13 %, 40 -> 80 by 0.02 % (the acceptance is < 0.1 %); 40 with 2 RK4
    # steps per interval instead of 3 changed by up to 0.16 %.
    intervals: int = 40
    method: Literal["shooting", "collocation"] = "shooting"  # see casadrone.limit.nlp
    substeps: int = 3  # RK4 steps per interval (shooting)
    degree: int = 3  # Radau collocation points per interval (collocation)
    # "coarse-grid": grid continuation, the closed-loop start solved on COARSE_SHARE of the
    # intervals and its optimum resampled onto this grid (a coarse grid smooths the problem);
    # "relaxed-tolerance": tolerance homotopy from the point-mass start (balls of at least
    # RELAXED_RADIUS_M first, then the track's tolerances from that point).
    # Measured (benchmarks/RESULTS-limitlap-issue19.md): on the gate track the coarse-grid start
    # is 0.34 % faster than the other two; on the paper track it adds nothing (+0.03 %).
    starts: tuple[Start, ...] = ("closed-loop", "point-mass", "coarse-grid")
    warm_starts: tuple[LimitLap, ...] = ()  # neighbouring solutions (same legs; any grid)
    guess_trajectory: object | None = None  # the frame's closed-loop lap, if already flown
    ball_radius_m: float | None = None  # None: the track's acceptance radius
    # Kept from the gate's frame on each side (m); None: the frame's own size (the farthest
    # rotor plus a propeller radius, frame_clearance_m).
    gate_clearance_m: float | None = None
    max_tilt_deg: float | None = None  # None: the track's max_tilt_deg
    # Attitude of the full model: "euler" (ZYX angles, singular at 90 deg of pitch) or
    # "quaternion" (no singularity: split-S, loops, inverted flight; casadrone.limit.attitude).
    attitude: Attitude = "euler"
    # Tilt limit at max_tilt_deg: "axes" |phi|, |theta| each (the closed loop's failure test;
    # Euler only; together they allow up to 88 deg of total tilt at 80), "cone" on the total
    # tilt (angle between body z and world z, at every node), or "none".
    tilt_limit: TiltLimit = "axes"
    start_state: tuple[float, ...] | None = None  # 16 values; None: hover at the start
    controller: ControllerConfig | None = None  # closed-loop guess; None: default controller
    tol: float = 1e-6  # IPOPT: laps agree with tol 1e-8's to ~1e-6 s in 5-20 % fewer iterations
    max_iter: int = 1000
    # The point-mass reference (not a bound: the best of REFERENCE_SPEEDS_MPS local optima of
    # the point-mass relaxation), solved once per (mass, thrust, drag, track) and cached.
    point_mass_reference: bool = True
    resimulate: bool = True  # re-simulate every converged start; choose among those that pass
    # Largest re-simulation miss (m) of a chosen start. Honest optima miss by 0.003-0.09 m (the
    # open-loop drift of a 4 s lap at up to 55 m/s); optima that exploit the discretisation
    # (RK4 near the Euler-angle singularity at 80 deg tilt) missed by 0.2-60 m.
    max_miss_m: float = 0.15
    sensitivities: bool = True
    # Shipped airframe whose limit lap (same track and options) starts a frame whose own starts
    # all fail (module docstring, "fallback"); None: no fallback.
    fallback_reference: str | None = "SY250"


@dataclass(frozen=True)
class StartResult:
    """What one start of the solver gave."""

    start: str
    success: bool
    return_status: str
    lap_time_s: float
    iterations: int
    wall_time_s: float
    resimulation_miss_m: float = math.nan  # NaN: not converged or not re-simulated


@dataclass(frozen=True)
class LimitLap:
    """The limit lap of one airframe on one track.

    ``t`` holds the node times (M + 1), ``x`` the node states (M + 1, the model's states: 16 for
    the Euler model, 17 for the quaternion model; :attr:`x_euler` gives 16 with Euler angles),
    ``u`` the ESC commands held on each interval (M, 4). ``certainty`` says whether the verified
    starts agree: "agreed" (two or more, all within CERTAIN_REL of the best), "single" (one
    verified start), "spread" (farther apart: a better optimum may exist). Agreement is no
    proof: the best known SY250 optimum (3.8951 s) is reached by none of the default starts.
    ``sensitivities`` maps decision-variable keys to dT/dθ in
    seconds per unit of the key (only when the airframe config was given); ``param_sensitivity``
    is dT/dp over the model parameters (PARAM_NAMES order), s per SI unit.
    """

    status: Status  # completed: a verified optimum (casadrone.results' one word for success)
    reason: str
    lap_time_s: float = math.nan
    split_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # at each waypoint
    leg_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # every route leg
    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    x: np.ndarray = field(default_factory=lambda: np.zeros((0, NX)))
    u: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    iterations: int = 0
    wall_time_s: float = 0.0
    bang_bang_fraction: float = math.nan
    point_mass_reference_s: float = math.nan  # best local optimum found, not a bound
    lap_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # time of each lap
    spread_s: float = math.nan  # slowest minus fastest verified start (NaN: only one)
    certainty: Certainty = "single"
    attitude: str = "euler"
    resimulation_miss_m: float = math.nan
    param_sensitivity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sensitivities: dict[str, float] = field(default_factory=dict)
    start: str = ""
    starts: tuple[StartResult, ...] = ()
    layout: Layout | None = None
    solution: NlpPoint | None = None  # primal-dual point, for warm starts

    @property
    def completed(self) -> bool:
        return self.status == "completed"

    @property
    def optimal(self) -> bool:
        """The same as :attr:`completed` (the limit lap's earlier word for it)."""
        return self.completed

    @property
    def x_euler(self) -> np.ndarray:
        """Node states with ZYX Euler angles (16 columns), whatever the model's attitude."""
        return euler_states(self.attitude, self.x)

    @property
    def speed(self) -> np.ndarray:
        """Speed at the nodes (m/s)."""
        return np.linalg.norm(self.x[:, 3:6], axis=1)

    @property
    def waypoint_index(self) -> np.ndarray:
        """Route leg (0-based) each interval belongs to."""
        n = self.layout.intervals if self.layout else 1
        return np.arange(len(self.u)) // n


# --------------------------------------------------------------------------------------------
# Track → targets
# --------------------------------------------------------------------------------------------


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
    from casadrone.airframe import PARAM_NAMES

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
            kinds[leg] = KIND_OF_SHAPE[gate.shape]
            frames[leg] = gate_frame(*gate.rpy_rad)
            hw[leg] = gate.width_m / 2 - clear
            hh[leg] = gate.height_m / 2 - clear
            if gate.vertices_m is not None:
                edges[leg] = polygon_edges(np.asarray(gate.vertices_m), clear)
    n_wp = len(track.waypoints_m)
    ends = [first + i for i in range(len(items)) if items[i] == n_wp - 1]
    return Targets(tuple(kinds), target_vector(route[1:], tuple(kinds), heads, hw, hh, radii,
                                               frames, edges), first, tuple(ends), route)


def check_inputs(track: TrackConfig, options: LimitLapOptions,
                 clearance_m: float | None = None) -> str:
    """Why the problem cannot be posed (empty string when it can)."""
    if not 2 <= options.intervals <= MAX_INTERVALS or not 1 <= options.degree <= 9 \
            or not 1 <= options.substeps <= 20:
        return (f"intervals must be 2…{MAX_INTERVALS}, degree 1…9 and substeps 1…20 (got "
                f"{options.intervals}, {options.degree}, {options.substeps})")
    if options.start_state is not None and len(options.start_state) != NX:
        return f"start_state needs {NX} values, got {len(options.start_state)}"
    if options.attitude == "quaternion" and options.tilt_limit == "axes":
        return ("tilt_limit 'axes' bounds Euler angles: with the quaternion attitude use 'cone' "
                "or 'none'")
    clear = options.gate_clearance_m if options.gate_clearance_m is not None else clearance_m
    for j, gate in enumerate(track.gates or []):
        if clear is None:
            break
        inner = min(gate.width_m, gate.height_m) / 2
        if gate.vertices_m is not None:  # the largest circle inside the polygon's edges
            inner = float(np.min(polygon_edges(np.asarray(gate.vertices_m), 0.0)[
                :len(gate.vertices_m), 2]))
        if inner <= clear:
            return (f"gate {j + 1}: opening {gate.width_m:g} x {gate.height_m:g} m is not wider "
                    f"than twice the clearance {clear:.3g} m")
    if options.ball_radius_m is not None and options.ball_radius_m < 0:
        return "ball_radius_m must not be negative"
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


def row_bounds(nlp: Nlp, track: TrackConfig, options: LimitLapOptions
               ) -> tuple[np.ndarray, np.ndarray]:
    """(lbg, ubg): the tilt cone at the track's tilt limit, the end velocity."""
    tilt = math.radians(track.max_tilt_deg if options.max_tilt_deg is None
                        else options.max_tilt_deg)
    return nlp.row_bounds(math.cos(tilt), track.end_velocity_mps if track.end == "velocity"
                          else None)


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
    t_lo, t_hi = np.full(L, 1e-3), np.full(L, track.time_limit_s * track.laps)
    if track.floor_m is not None:
        floor = track.floor_m
    else:
        floor = min(track.start_position_m[2], 0.0) - 0.1 if options.start_state is None \
            else -np.inf
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
        xl[0], xu[0] = x0, x0  # also an equality on the parameter; the bound helps IPOPT
    d = nlp.layout.n_coll
    return (nlp.pack(t_lo, xl, ul, np.repeat(zl[1:, None, :], d, axis=1)),
            nlp.pack(t_hi, xu, uu, np.repeat(zu[1:, None, :], d, axis=1)))


# --------------------------------------------------------------------------------------------
# Initial guesses
# --------------------------------------------------------------------------------------------


def closed_loop_lap(airframe: Airframe, track: TrackConfig,
                    controller: ControllerConfig | None = None):
    """casadrone's closed-loop lap of this frame (a :class:`Trajectory`), or None if the frame
    cannot be trimmed or controlled."""
    from casadrone.config.airframe import load_airframe
    from casadrone.config.controller import load_controller
    from casadrone.control import design_for
    from casadrone.simulate import simulate
    from casadrone.trim import trim

    ctrl = controller or load_controller(None)
    tp = trim(airframe, "hover", 0.0, solver="newton")
    if not tp.success or np.any(tp.u0 > 1.0):
        return None
    ref = ctrl.reference_airframe
    reference = None
    if ref is not None:
        from casadrone.airframe import build_airframe

        reference = build_airframe(load_airframe(ref))
    design = design_for(airframe, ctrl, reference, tp, certificate=False)
    if not design.stable:
        return None
    return simulate(airframe, design, track)


def _sample(t_nodes, t, values, hold: bool):
    if hold:
        idx = np.clip(np.searchsorted(t, t_nodes, side="right") - 1, 0, len(t) - 1)
        return values[idx]
    return np.column_stack([np.interp(t_nodes, t, values[:, i]) for i in range(values.shape[1])])


def guess_from_trajectory(nlp: Nlp, traj, x0: np.ndarray) -> np.ndarray | None:
    """Decision vector sampled from a completed closed-loop lap (leg ends where the guidance
    switched segment); None when the lap did not reach the end (or the NLP has more legs than
    the closed loop flew: a multi-lap course)."""
    L, N = nlp.layout.n_legs, nlp.layout.intervals
    switches = []
    for k in range(L):
        hit = np.flatnonzero(traj.segment > k)
        if not hit.size:
            return None
        switches.append(traj.t[hit[0]])
    ends = np.maximum.accumulate(np.maximum(switches, 1e-2 * np.arange(1, L + 1)))
    T = np.diff(np.concatenate([[0.0], ends]))
    t_nodes = np.concatenate([[0.0]] + [s + np.linspace(0, d, N + 1)[1:] for s, d in
                                        zip(ends - T, T, strict=True)])
    X = model_states(nlp.model.attitude, _sample(t_nodes, traj.t, traj.x, hold=False))
    X[0] = x0
    U = _sample(t_nodes[:-1], traj.t, traj.u, hold=True)
    return nlp.pack(T, X, U)


def guess_from_lap(nlp: Nlp, lap: LimitLap, x0: np.ndarray) -> np.ndarray:
    """Decision vector of a limit lap solved on another grid of the same legs (grid
    refinement) or with the other attitude model: same leg durations, states interpolated at
    the new nodes, commands held."""
    T = lap.leg_times_s
    t_nodes = node_times(T, nlp.layout.intervals)
    x = lap.x
    if lap.attitude != nlp.model.attitude:  # a lap of the other attitude model, converted
        x = model_states(nlp.model.attitude, lap.x_euler)
    X = _sample(t_nodes, lap.t, x, hold=False)
    X[0] = x0
    U = _sample(t_nodes[:-1], lap.t[:-1], lap.u, hold=True)
    return nlp.pack(T, X, U)


def straight_guess(nlp: Nlp, route: np.ndarray, x0: np.ndarray, speed: float = 5.0,
                   weight_n: float = 0.0, hover_command: float | None = None) -> np.ndarray:
    """Constant ``speed`` (m/s) along the route in the start's attitude: the guess when no
    closed loop flies, and the point-mass reference's starts (commands ``hover_command``;
    default the paper model's rotor thrust over K)."""
    L, N = nlp.layout.n_legs, nlp.layout.intervals
    T = np.maximum(np.linalg.norm(np.diff(route, axis=0), axis=1) / speed, 0.1)
    X = np.repeat(x0[None, :], L * N + 1, axis=0)
    for k in range(L):
        s = np.linspace(0, 1, N + 1)[1:, None]
        X[k * N + 1:(k + 1) * N + 1, 0:3] = route[k] + s * (route[k + 1] - route[k])
    rotor = nlp.model.rotor
    if rotor is None:  # the point mass: level, total thrust the weight
        U = np.zeros((L * N, nlp.model.nu))
        U[:, 3] = weight_n
        return nlp.pack(T, X, U)
    U = np.full((L * N, nlp.model.nu), float(np.mean(x0[rotor])) / 9.0519
                if hover_command is None else hover_command)
    return nlp.pack(T, X, np.clip(U, 0, 1))


def point_mass_guess(full: Nlp, pm: Nlp, w_full: np.ndarray, airframe: Airframe | None = None
                     ) -> np.ndarray:
    """The point-mass decision vector of a full-model one: same durations, positions, world
    velocities; attitude and total thrust (of the rotor states at rest) as the controls."""
    T, X, U = full.unpack(w_full)
    X = euler_states(full.model.attitude, X)
    Xp = np.zeros((len(X), 6))
    Xp[:, 0:3] = X[:, 0:3]
    for i, x in enumerate(X):
        Xp[i, 3:6] = np.asarray(rotation_matrix(*x[9:12])).reshape(3, 3) @ x[3:6]
    rotor = X[:-1, 12:16] if airframe is None else static_thrusts(airframe, X[:-1, 12:16])
    Up = np.column_stack([X[:-1, 9:12], rotor.sum(axis=1)])
    return pm.pack(T, Xp, Up)


def lifted_guess(full: Nlp, pm: Nlp, w_pm: np.ndarray, airframe: Airframe, x0: np.ndarray
                 ) -> np.ndarray:
    """A full-model decision vector from a point-mass solution: attitude from its controls,
    body velocity rotated into it, each rotor a quarter of the thrust, no body rates."""
    T, Xp, Up = pm.unpack(w_pm)
    X = np.zeros((len(Xp), NX))
    att = np.vstack([Up, Up[-1:]])
    X[:, 0:3] = Xp[:, 0:3]
    X[:, 9:12] = att[:, 0:3]
    X[:, 12:16], U = equal_rotor_guess(airframe, att[:, 3] / 4)
    for i in range(len(X)):
        R = np.asarray(rotation_matrix(*att[i, 0:3])).reshape(3, 3)
        X[i, 3:6] = R.T @ Xp[i, 3:6]
    X = model_states(full.model.attitude, X)
    X[0] = x0
    U = np.clip(U[:-1], 0, 1)
    return full.pack(T, X, U)


# --------------------------------------------------------------------------------------------
# The point-mass reference: once per (mass, thrust, drag, track)
# --------------------------------------------------------------------------------------------

#: Entries of p the point-mass model reads (casadrone.limit.nlp.point_mass_ocp_model).
POINT_MASS_PARAMS = ("mass", "g", "rho", "CdA_x", "CdA_y", "CdA_z")
_POINT_MASS: dict[bytes, NlpSolution | None] = {}


def point_mass_p(airframe: Airframe) -> np.ndarray:
    """p with every entry the point mass does not read set to zero, so the point-mass problem,
    and its cache key, depend on mass, gravity, drag and density only (thrust is its bound)."""
    from casadrone.model import param_names
    from casadrone.propulsion import PROPELLER_PARAM_NAMES

    names = np.array(param_names(airframe.propulsion))
    # the propeller's data set the point mass's thrust bound: they stay in the key
    keep = np.isin(names, POINT_MASS_PARAMS + PROPELLER_PARAM_NAMES)
    return np.where(keep, airframe.p, 0.0)


def point_mass_reference(pm: Nlp, airframe: Airframe, track: TrackConfig,
                         options: LimitLapOptions, targets: Targets, x0: np.ndarray
                         ) -> NlpSolution | None:
    """The best converged point-mass solve over straight-line starts at REFERENCE_SPEEDS_MPS,
    cached per (mass, gravity, drag, thrust, track targets, start, bounds): never per frame.

    Not a lower bound: the point-mass problem is a relaxation of the limit lap (every flight of
    the full model is one of the point mass), so its *global* optimum bounds the lap from below,
    but IPOPT finds local optima, and the best of a few starts is only the best found.
    """
    R = np.asarray(rotation_matrix(*x0[9:12])).reshape(3, 3)
    x0_pm = np.concatenate([x0[0:3], R @ x0[3:6]])
    P = np.concatenate([point_mass_p(airframe), x0_pm, targets.vector])
    lbx, ubx = bounds(pm, airframe, track, options, point_mass=True)
    lbg, ubg = row_bounds(pm, track, options)
    key = b"".join(np.ascontiguousarray(a, float).tobytes() for a in (P, lbx, ubx, lbg, ubg)) \
        + repr((pm.layout, options.tol, options.max_iter)).encode()
    if key not in _POINT_MASS:
        x0_guess = np.concatenate([x0_pm[0:3], np.zeros(3)])
        sols = [solve(pm, straight_guess(pm, targets.route, x0_guess, v,
                                     airframe.mass * airframe.gravity), P, lbx, ubx,
                      lbg=lbg, ubg=ubg) for v in REFERENCE_SPEEDS_MPS]
        good = [s for s in sols if s.success]
        _POINT_MASS[key] = min(good, key=lambda s: s.objective) if good else None
    return _POINT_MASS[key]


# --------------------------------------------------------------------------------------------
# Solve
# --------------------------------------------------------------------------------------------


def node_times(T: np.ndarray, intervals: int) -> np.ndarray:
    """Node times (s) of leg durations ``T`` with ``intervals`` uniform intervals per leg."""
    ends = np.cumsum(T)
    return np.concatenate([[0.0]] + [e - d + np.linspace(0, d, intervals + 1)[1:]
                                     for e, d in zip(ends, T, strict=True)])


def _trajectory(nlp: Nlp, w: np.ndarray, layout: Layout) -> LimitLap:
    """A decision vector as a (not yet checked) LimitLap: enough to re-simulate it."""
    T, X, U = nlp.unpack(w)
    return LimitLap(status="completed", reason="", t=node_times(T, layout.intervals), x=X, u=U,
                    layout=layout, attitude=nlp.model.attitude)


_REFERENCE_LAPS: dict[tuple, LimitLap] = {}


def reference_lap(name: str, track: TrackConfig, options: LimitLapOptions) -> LimitLap:
    """The limit lap of the shipped airframe ``name`` on ``track`` with ``options`` (its own
    cold starts only, no point-mass reference or sensitivities), solved once per process and
    cached: deterministic, so a cache hit is the same result as a new solve."""
    from casadrone.config.airframe import load_airframe

    ref_options = replace(options, warm_starts=(), guess_trajectory=None,
                          point_mass_reference=False, sensitivities=False,
                          fallback_reference=None, starts=LimitLapOptions.starts)
    key = (name, track.model_dump_json(), repr(ref_options))
    if key not in _REFERENCE_LAPS:
        _REFERENCE_LAPS[key] = limit_lap(load_airframe(name), track, ref_options)
    return _REFERENCE_LAPS[key]


def _fallback_name(name: str | None, propulsion: str) -> str | None:
    """The shipped reference whose limit lap may start a frame with propulsion kind
    ``propulsion``: ``name`` itself with the paper model, ``name-propeller`` (SY250-propeller)
    with the propeller model, None when that airframe is not shipped or has another kind (its
    rotor states would mean something else)."""
    if name is None or propulsion == "paper":
        return name
    from casadrone.config.airframe import load_airframe
    from casadrone.config.io import ConfigError

    try:
        ref = load_airframe(f"{name}-{propulsion}")
    except ConfigError:
        return None
    return f"{name}-{propulsion}" if ref.propulsion.model == propulsion else None


def _failed(reason: str, start: float, **kw) -> LimitLap:
    return LimitLap(status="failed", reason=reason, wall_time_s=time.perf_counter() - start, **kw)


@dataclass(frozen=True)
class _Problem:
    """One limit-lap problem, prepared: the frame, its NLP, parameters and bounds."""

    frame: Airframe
    track: TrackConfig
    options: LimitLapOptions
    targets: Targets
    layout: Layout
    full: Nlp
    x0_euler: np.ndarray
    x0: np.ndarray  # in the model's states
    P: np.ndarray
    box: tuple[np.ndarray, np.ndarray]
    rows: tuple[np.ndarray, np.ndarray]

    def solve(self, w0: np.ndarray, warm: NlpPoint | None = None) -> NlpSolution:
        return solve(self.full, w0, self.P, *self.box, warm=warm, lbg=self.rows[0],
                     ubg=self.rows[1])

    @cached_property
    def point_mass(self) -> Nlp:  # only when a point-mass start or the reference needs it
        return build_nlp(point_mass_ocp_model(self.frame.propulsion),
                         replace(self.layout, tilt_cone=False),
                         self.options.tol, self.options.max_iter)

    @cached_property
    def reference(self) -> NlpSolution | None:
        return point_mass_reference(self.point_mass, self.frame, self.track, self.options,
                                    self.targets, self.x0_euler)


def _prepare(frame: Airframe, track: TrackConfig, options: LimitLapOptions,
             clearance_m: float) -> _Problem:
    targets = track_targets(track, options, clearance_m)
    layout = Layout(targets.kinds, options.intervals, options.degree, options.method,
                    options.substeps, end_at_rest=track.end != "free",
                    tilt_cone=options.tilt_limit == "cone")
    full = build_nlp(ATTITUDE_MODELS[options.attitude](frame.propulsion), layout, options.tol,
                     options.max_iter)
    x0_euler = start_state(frame, track, options)
    x0 = model_states(options.attitude, x0_euler)[0]
    return _Problem(frame, track, options, targets, layout, full, x0_euler, x0,
                    np.concatenate([frame.p, x0, targets.vector]),
                    bounds(full, frame, track, options, point_mass=False),
                    row_bounds(full, track, options))


def _run_starts(pb: _Problem) -> list[tuple[str, NlpSolution]]:
    """Solve from each of the options' starts and warm starts."""
    options, full, x0 = pb.options, pb.full, pb.x0
    solves: list[tuple[str, NlpSolution]] = []
    if "closed-loop" in options.starts:
        guess = None
        traj = options.guess_trajectory or closed_loop_lap(pb.frame, pb.track,
                                                           options.controller)
        if traj is not None:
            guess = guess_from_trajectory(full, traj, x0)
        if guess is None:
            guess = straight_guess(full, pb.targets.route, x0, hover_command=None if
                                   pb.frame.propulsion == "paper" else float(np.mean(
                                       hover_rotors(pb.frame, pb.frame.hover_thrusts())[1])))
        solves.append(("closed-loop", pb.solve(guess)))
    if "coarse-grid" in options.starts:
        coarse = limit_lap(pb.frame, pb.track, replace(
            options, intervals=max(2, round(COARSE_SHARE * options.intervals)),
            starts=("closed-loop",), warm_starts=(), point_mass_reference=False,
            sensitivities=False, fallback_reference=None))
        if coarse.completed:
            solves.append(("coarse-grid", pb.solve(guess_from_lap(full, coarse, x0))))
    lifted = None
    if pb.reference is not None and {"point-mass", "relaxed-tolerance"} & set(options.starts):
        lifted = lifted_guess(full, pb.point_mass, pb.reference.point.w, pb.frame, x0)
    if "point-mass" in options.starts and lifted is not None:
        solves.append(("point-mass", pb.solve(lifted)))
    if "relaxed-tolerance" in options.starts:
        w0 = lifted if lifted is not None else straight_guess(full, pb.targets.route, x0)
        solves.append(("relaxed-tolerance", _relaxed_then_tight(pb, w0)))
    for i, ws in enumerate(options.warm_starts):
        if ws.solution is None or ws.layout is None:
            continue
        if ws.layout == pb.layout and ws.attitude == full.model.attitude:
            solves.append((f"warm-{i + 1}", pb.solve(ws.solution.w, warm=ws.solution)))
        elif ws.layout.kinds == pb.layout.kinds and ws.layout.method == pb.layout.method:
            solves.append((f"resampled-{i + 1}", pb.solve(guess_from_lap(full, ws, x0))))
    return solves


def _relaxed_then_tight(pb: _Problem, w0: np.ndarray) -> NlpSolution:
    """Tolerance homotopy: solve with every ball at least RELAXED_RADIUS_M, then from that
    primal-dual point with the track's tolerances (the same NLP: radii are parameters)."""
    from casadrone.limit.gates import TARGET_SIZE

    P = pb.P.copy()
    at = len(pb.frame.p) + pb.full.model.nx + 14  # the first target's ball radius
    radii = P[at::TARGET_SIZE]
    P[at::TARGET_SIZE] = np.maximum(radii, RELAXED_RADIUS_M)
    loose = solve(pb.full, w0, P, *pb.box, lbg=pb.rows[0], ubg=pb.rows[1])
    if not loose.success:
        return loose
    tight = pb.solve(loose.point.w, warm=loose.point)
    return replace(tight, iterations=loose.iterations + tight.iterations,
                   wall_time_s=loose.wall_time_s + tight.wall_time_s)


def _failure(solves, misses: dict[str, float], options: LimitLapOptions
             ) -> tuple[str, tuple[StartResult, ...]]:
    """Why no start gave a verified lap, and what each start gave."""
    starts = _start_results(solves, misses)
    detail = "; ".join(f"{r.start}: {r.return_status}" + (
        f", re-simulation miss {r.resimulation_miss_m:.3g} m"
        if np.isfinite(r.resimulation_miss_m) else "") for r in starts) or "no start ran"
    reason = f"no start converged ({detail})"
    if starts and all("Infeasible" in r.return_status for r in starts):
        reason = f"infeasible: a target cannot be reached within the limits ({detail})"
    elif any(r.success for r in starts):
        reason = (f"no converged start passes the re-simulation check (miss ≤ "
                  f"{options.max_miss_m:g} m): {detail}")
    return reason, starts


def _start_results(solves, misses) -> tuple[StartResult, ...]:
    return tuple(StartResult(n, s.success, s.return_status, s.objective, s.iterations,
                             s.wall_time_s, misses.get(n, math.nan)) for n, s in solves)


def _certainty(good: list[tuple[str, NlpSolution]]) -> tuple[Certainty, float]:
    """("agreed" | "single" | "spread", spread in s) of the verified starts' lap times:
    "agreed" only when every verified start lands within CERTAIN_REL of the best."""
    times = np.array([s.objective for _, s in good])
    if len(times) < 2:
        return "single", math.nan
    spread = float(times.max() - times.min())
    return ("agreed" if spread <= CERTAIN_REL * times.min() else "spread"), spread


def limit_lap(airframe: Airframe | AirframeConfig, track: TrackConfig,
              options: LimitLapOptions = LimitLapOptions()) -> LimitLap:
    """The minimum-time lap of ``airframe`` on ``track``; never raises for a bad airframe.

    Given an :class:`AirframeConfig`, the result also carries ``sensitivities`` over its
    decision-variable keys (chain θ → p through the same build as the evaluation).
    """
    from casadrone.airframe import build_airframe
    from casadrone.limit.check import resimulation_miss, theta_sensitivities

    start = time.perf_counter()
    cfg = airframe if isinstance(airframe, AirframeConfig) else None
    frame: Airframe = build_airframe(airframe) if isinstance(airframe, AirframeConfig) else airframe
    prop_diameter_m = cfg.prop_diameter_mm / 1000 if cfg is not None else 0.127
    why = check_inputs(track, options, frame_clearance_m(frame, prop_diameter_m))
    if why:
        return _failed(why, start)
    weight, full_thrust = frame.mass * frame.gravity, 4 * max_static_thrust(frame)
    if weight >= full_thrust:
        return _failed(f"cannot hover: weight {weight:.2f} N is not below the full thrust "
                       f"{full_thrust:.2f} N", start)
    pb = _prepare(frame, track, options, frame_clearance_m(frame, prop_diameter_m))
    if not options.starts and not any(w.solution is not None for w in options.warm_starts):
        return _failed("no start: give starts or warm_starts", start)
    solves = _run_starts(pb)
    # Verification: a converged start counts only if its commands, flown by CVODES, pass every
    # target within options.max_miss_m. An optimum can exploit the discretisation (seen: a warm
    # start from a distant frame "converged" to 3.58 s, below the 3.74 s point-mass reference,
    # at 54 m/s with a 23 m re-simulation miss); such a start is reported, never chosen.
    misses: dict[str, float] = {}

    def verified(n: str, s: NlpSolution) -> bool:
        if s.success and options.resimulate and n not in misses:
            misses[n] = resimulation_miss(frame, _trajectory(pb.full, s.point.w, pb.layout),
                                          pb.targets.vector, pb.targets.kinds)
        return s.success and (not options.resimulate or misses[n] <= options.max_miss_m)

    fallback = _fallback_name(options.fallback_reference, frame.propulsion)
    if solves and fallback and not any(verified(n, s) for n, s in solves):
        ref = reference_lap(fallback, track, options)
        if ref.solution is not None and ref.layout == pb.layout:
            solves.append((f"reference-{fallback}", pb.solve(ref.solution.w, warm=ref.solution)))
    good = [(n, s) for n, s in solves if verified(n, s)]
    if not good:
        reason, starts = _failure(solves, misses, options)
        return _failed(reason, start, starts=starts, layout=pb.layout)
    result = _assemble_lap(pb, good, solves, misses)
    if options.sensitivities and cfg is not None and result.solution is not None:
        dT_dx0 = -result.solution.lam_p[len(frame.p):len(frame.p) + pb.full.model.nx]
        result = replace(result, sensitivities=theta_sensitivities(
            cfg, result.param_sensitivity, dT_dx0,
            lambda f: model_states(options.attitude, start_state(f, track, options))[0]))
    return replace(result, wall_time_s=time.perf_counter() - start)


def param_sensitivity(pb: _Problem, point: NlpPoint) -> np.ndarray:
    """dT/dp (the airframe's parameter order, s per SI unit) at a solution: minus the parameter
    multipliers, plus, for the thrust gain K, the active bounds set from K (each rotor's thrust
    ≤ K): bounds are numbers, not parameters of the NLP, so the parameter multipliers miss them.
    Measured on SY250 (a 30 m straight and a 2.5 m curve, 20 intervals per leg), where the
    thrust saturates: without the bound term dT/dK was 3.4 % short of central differences of
    warm re-solves, with it they agree to 1e-5 (tests/integration/test_limitlap_optimality.py)."""
    from casadrone.model import param_names

    out = -point.lam_p[:len(pb.frame.p)].copy()
    names = param_names(pb.frame.propulsion)
    # paper propulsion: the rotor-state bounds are [0, K] (propulsion.rotor_state_bounds), linear
    # in K, so their slope is one difference (a propeller's rotor-speed bound has no K)
    if pb.frame.propulsion == "paper" and "K" in names:
        lo0, hi0 = pb.box
        lo1, hi1 = bounds(pb.full, replace(pb.frame, thrust_gain=pb.frame.thrust_gain + 1.0),
                          pb.track, pb.options, point_mass=False)
        with np.errstate(invalid="ignore"):  # inf - inf where unbounded: no bound moves
            slope = np.nan_to_num(np.where(point.lam_x > 0, hi1 - hi0, lo1 - lo0), nan=0.0)
        out[names.index("K")] -= float(point.lam_x @ slope)
    return out


def _assemble_lap(pb: _Problem, good, solves, misses) -> LimitLap:
    """The LimitLap of the best verified start."""
    from casadrone.limit.check import bang_bang_fraction

    name, best = min(good, key=lambda ns: ns[1].objective)
    T, X, U = pb.full.unpack(best.point.w)
    ends = np.cumsum(T)
    lap_ends = ends[list(pb.targets.lap_ends)]
    certainty, spread = _certainty(good)
    ref = pb.reference if pb.options.point_mass_reference else None
    return LimitLap(
        status="completed", reason="", lap_time_s=float(np.sum(T)),
        split_times_s=ends[pb.targets.first_timed:], leg_times_s=T,
        t=node_times(T, pb.layout.intervals), x=X, u=U, iterations=best.iterations,
        bang_bang_fraction=bang_bang_fraction(U, BANG_BANG_TOL),
        point_mass_reference_s=ref.objective if ref is not None else math.nan,
        lap_times_s=np.diff(np.concatenate([[0.0], lap_ends])), spread_s=spread,
        certainty=certainty, attitude=pb.full.model.attitude,
        resimulation_miss_m=misses.get(name, math.nan),
        param_sensitivity=param_sensitivity(pb, best.point), start=name,
        starts=_start_results(solves, misses), layout=pb.layout, solution=best.point,
    )
