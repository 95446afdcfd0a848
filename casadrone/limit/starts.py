"""The starts of the limit lap: the problem prepared once (NLP, parameters, bounds), then one
solve per start (docs/concepts/limit-lap.md, "Robustness").

Each cold start is one entry of :data:`COLD_STARTS` (``LimitLapOptions.starts`` chooses among
them, solved in the registry's order); warm starts come from ``LapSeeds.warm_starts``; the
fallback start is the limit lap of a shipped reference frame. A start that needs a limit lap of
its own (the coarse grid, the fallback reference) gets the solver as ``lap_of``, so this module
does not import :mod:`casadrone.limit.lap`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from casadrone.airframe import Airframe, build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.io import ConfigError
from casadrone.config.limitlap import MAX_INTERVALS
from casadrone.config.track import TrackConfig
from casadrone.limit import events
from casadrone.limit.gates import TARGET_SIZE
from casadrone.limit.guesses import (
    closed_loop_lap,
    guess_from_lap,
    guess_from_trajectory,
    lifted_guess,
    point_mass_guess,
    straight_guess,
)
from casadrone.limit.lagless import is_lagless, with_guess_lag, without_lag
from casadrone.limit.library import shipped_laps, usable
from casadrone.limit.nlp import (
    ATTITUDE_MODELS,
    Layout,
    Nlp,
    NlpPoint,
    NlpSolution,
    build_nlp,
    exponential_rotor,
    point_mass_ocp_model,
    solve,
)
from casadrone.limit.pointmass import point_mass_from, point_mass_reference
from casadrone.limit.problem import (
    Targets,
    bounds,
    frame_clearance_m,
    row_bounds,
    start_state,
    track_targets,
)
from casadrone.limit.result import (
    LapSeeds,
    LimitLap,
    LimitLapOptions,
    Start,
    model_states,
    node_times,
)
from casadrone.propulsion import hover_rotors, propulsion_model

#: Share of the intervals of the coarse grid of the "coarse-grid" start (40 -> 30).
COARSE_SHARE = 0.75
#: Share of the intervals of the fine grid of the "fine-grid" start (40 -> 60).
FINE_SHARE = 1.5
#: Smallest ball radius (m) of the first solve of the "relaxed-tolerance" start.
RELAXED_RADIUS_M = 1.0

#: A named solve: the start's name and what IPOPT gave from it.
StartSolve = tuple[str, NlpSolution]
#: The limit lap itself (:func:`casadrone.limit.lap.limit_lap`), for starts that need one.
LapOf = Callable[[Airframe, TrackConfig, LimitLapOptions, LapSeeds], LimitLap]


@dataclass(frozen=True)
class Problem:
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
    seeds: LapSeeds = LapSeeds()  # warm starts, a flown lap, the closed-loop start's controller

    def solve(self, w0: np.ndarray, warm: NlpPoint | None = None) -> NlpSolution:
        if warm is None:
            w0 = periodic_guess(self.full, w0)
        return solve(self.full, w0, self.P, *self.box, warm=warm, lbg=self.rows[0],
                     ubg=self.rows[1], solver=self.options.solver)

    @cached_property
    def point_mass(self) -> Nlp:  # only when a point-mass start or the reference needs it
        return build_nlp(point_mass_ocp_model(self.frame.propulsion),
                         replace(self.layout, tilt_cone=False, max_advance_ratio=None,
                                 max_pack_current_a=None, max_motor_current_a=None),
                         self.options.tol, self.options.max_iter)

    @cached_property
    def reference(self) -> NlpSolution | None:
        return point_mass_reference(self.point_mass, self.frame, self.track, self.options,
                                    self.targets, self.x0_euler)

    def lap_reference(self, w: np.ndarray) -> NlpSolution | None:
        """The point-mass reference a lap reports: the relaxation solved from the lap ``w``'s
        own path (:func:`~casadrone.limit.pointmass.point_mass_from`), or the straight-line
        starts' reference (:attr:`reference`) where a start already solved it and it is
        lower; None when neither converged."""
        from_lap = point_mass_from(self.point_mass,
                                   point_mass_guess(self.full, self.point_mass, w, self.frame),
                                   self.frame, self.track, self.options, self.targets,
                                   self.x0_euler)
        found = [s for s in (from_lap, self.__dict__.get("reference")) if s is not None]
        return min(found, key=lambda s: s.objective) if found else None

    @cached_property
    def lifted(self) -> np.ndarray | None:
        """The point-mass reference lifted to the full model (None without a reference)."""
        if self.reference is None:
            return None
        return lifted_guess(self.full, self.point_mass, self.reference.point.w, self.frame,
                            self.x0)


def periodic_guess(nlp: Nlp, w0: np.ndarray) -> np.ndarray:
    """A guess for a periodic layout: its start node replaced by its own end node (the guesses
    start from the track's given start state, at rest, while the periodic lap's start is its
    end; where the start position is pinned, :meth:`Problem.solve`'s box clips it back);
    unchanged for any other layout."""
    if not nlp.layout.periodic:
        return w0
    nx, M = nlp.model.nx, nlp.layout.n_intervals
    per = 1 + nlp.model.nu + nx * (nlp.layout.n_coll + 1)  # a block of w: S, u, z, x_i
    w = np.array(w0, float)
    w[per - nx:per] = w[M * per:]  # both in the NLP's units (Nlp.pack)
    return w


def prepare(frame: Airframe, track: TrackConfig, options: LimitLapOptions,
            clearance_m: float, seeds: LapSeeds = LapSeeds()) -> Problem:
    """The problem of ``frame`` on ``track``: the NLP of its layout (built once per process),
    P = [p, x0, targets], the box and the row bounds; ``seeds``: what its starts may use."""
    targets = track_targets(track, options, clearance_m)
    assert options.intervals is not None  # limit_lap resolved it (DEFAULT_INTERVALS)
    layout = Layout(targets.kinds, options.intervals, options.degree, options.method,
                    options.substeps, end_at_rest=track.end in ("rest", "velocity"),
                    tilt_cone=options.tilt_limit == "cone", periodic=track.end == "periodic",
                    max_advance_ratio=frame.max_advance_ratio,  # None: the model has none
                    max_pack_current_a=frame.max_pack_current_a,
                    max_motor_current_a=frame.max_motor_current_a)
    model = ATTITUDE_MODELS[options.attitude](frame.propulsion)
    if is_lagless(frame):  # thrust.time_constant_s: 0, the lag-off idealisation
        model = without_lag(model)
    elif options.rotor_step == "exponential":  # a lagless model has no rotor lag to integrate
        model = exponential_rotor(model)
    full = build_nlp(model, layout, options.tol, options.max_iter)
    x0_euler = start_state(frame, track, options)
    x0 = model_states(options.attitude, x0_euler)[0]
    return Problem(frame, track, options, targets, layout, full, x0_euler, x0,
                   np.concatenate([frame.p, x0, targets.vector]),
                   bounds(full, frame, track, options, point_mass=False),
                   row_bounds(full, track, options), seeds)


def trajectory(nlp: Nlp, w: np.ndarray, layout: Layout) -> LimitLap:
    """A decision vector as a (not yet checked) LimitLap: enough to re-simulate it."""
    T, X, U = nlp.unpack(w)
    return LimitLap(status="completed", reason="", t=node_times(T, layout.intervals), x=X, u=U,
                    layout=layout, attitude=nlp.model.attitude)


# --------------------------------------------------------------------------------------------
# Cold starts
# --------------------------------------------------------------------------------------------


def closed_loop_start(pb: Problem, lap_of: LapOf) -> NlpSolution | None:
    """From the frame's closed-loop lap sampled onto the grid (straight lines when it does not
    fly the track)."""
    seeds, full, x0 = pb.seeds, pb.full, pb.x0
    guess = None
    traj = seeds.guess_trajectory or closed_loop_lap(with_guess_lag(pb.frame), pb.track,
                                                     seeds.controller)
    if traj is not None:
        guess = guess_from_trajectory(full, traj, x0)
    if guess is None:
        guess = straight_guess(full, pb.targets.route, x0, hover_command=None if
                               propulsion_model(pb.frame.propulsion).command_linear else float(
                                   np.mean(hover_rotors(pb.frame, pb.frame.hover_thrusts())[1])))
    return pb.solve(guess)


def coarse_intervals(n: int) -> int:
    """Intervals per leg of the coarse-grid start's grid for a grid of ``n``."""
    return max(2, round(COARSE_SHARE * n))


def fine_intervals(n: int) -> int:
    """Intervals per leg of the fine-grid start's grid for a grid of ``n`` (at most
    MAX_INTERVALS)."""
    return min(MAX_INTERVALS, round(FINE_SHARE * n))


def inner_options(options: LimitLapOptions, **changes) -> LimitLapOptions:
    """``options`` for a lap solved inside another (a grid-continuation start's own grid, a grid
    round): no point-mass reference, sensitivities, fallback (reference or starts), refinement
    or grid rounds of its own (the outer lap checks what it brings back), with ``changes``."""
    return replace(options, point_mass_reference=False, sensitivities=False,
                   fallback_reference=None, fallback_starts=(), refinements=0, grid_rounds=0,
                   **changes)


def coarse_grid_start(pb: Problem, lap_of: LapOf) -> NlpSolution | None:
    """Grid continuation: the closed-loop start on COARSE_SHARE of the intervals, its optimum
    resampled onto this grid (None when the coarse lap fails)."""
    return _grid_continuation(pb, lap_of, coarse_intervals(pb.layout.intervals), "closed-loop")


def fine_grid_start(pb: Problem, lap_of: LapOf) -> NlpSolution | None:
    """Grid continuation from a finer grid: the point-mass start solved on FINE_SHARE of the
    intervals (at most MAX_INTERVALS), its optimum resampled onto this grid (None when the fine
    lap fails). The point-mass start lands in different local optima on different grids (SY250,
    paper track: 3.942 s on 40 intervals, 3.889 s on 60), and the fine grid's, resampled, led
    to the best optimum known on the 40-interval grid for SY250 and HS210
    (benchmarks/RESULTS-limitlap-issue19.md)."""
    return _grid_continuation(pb, lap_of, fine_intervals(pb.layout.intervals), "point-mass")


def _grid_continuation(pb: Problem, lap_of: LapOf, intervals: int, start: Start
                       ) -> NlpSolution | None:
    """The lap from cold start ``start`` on ``intervals`` per leg, its optimum resampled onto
    this grid and solved here (None when that lap fails)."""
    other = lap_of(pb.frame, pb.track, inner_options(pb.options, intervals=intervals,
                                                     starts=(start,)),
                   replace(pb.seeds, warm_starts=()))
    if not other.completed:
        return None
    return pb.solve(guess_from_lap(pb.full, other, pb.x0))


def point_mass_start(pb: Problem, lap_of: LapOf) -> NlpSolution | None:
    """From the point-mass reference lifted to the full model (None without a reference)."""
    return None if pb.lifted is None else pb.solve(pb.lifted)


def relaxed_tolerance_start(pb: Problem, lap_of: LapOf) -> NlpSolution | None:
    """Tolerance homotopy from the lifted point mass (straight lines without one)."""
    w0 = pb.lifted if pb.lifted is not None else straight_guess(pb.full, pb.targets.route, pb.x0)
    return relaxed_then_tight(pb, w0)


#: The cold starts, in the order they are solved; ``LimitLapOptions.starts`` names those to run.
COLD_STARTS: dict[Start, Callable[[Problem, LapOf], NlpSolution | None]] = {
    "closed-loop": closed_loop_start,
    "coarse-grid": coarse_grid_start,
    "fine-grid": fine_grid_start,
    "point-mass": point_mass_start,
    "relaxed-tolerance": relaxed_tolerance_start,
}


def relaxed_then_tight(pb: Problem, w0: np.ndarray) -> NlpSolution:
    """Tolerance homotopy: solve with every ball at least RELAXED_RADIUS_M, then from that
    primal-dual point with the track's tolerances (the same NLP: radii are parameters)."""
    P = pb.P.copy()
    at = len(pb.frame.p) + pb.full.model.nx + 14  # the first target's ball radius
    radii = P[at::TARGET_SIZE]
    P[at::TARGET_SIZE] = np.maximum(radii, RELAXED_RADIUS_M)
    loose = solve(pb.full, w0, P, *pb.box, lbg=pb.rows[0], ubg=pb.rows[1],
                  solver=pb.options.solver)
    if not loose.success:
        return loose
    tight = pb.solve(loose.point.w, warm=loose.point)
    return replace(tight, iterations=loose.iterations + tight.iterations,
                   wall_time_s=loose.wall_time_s + tight.wall_time_s)


def library_solves(pb: Problem) -> list[StartSolve]:
    """With the ``library`` start: one solve from each shipped lap of this track and
    propulsion kind (:mod:`casadrone.limit.library`), ``library-<airframe>``: primal-dual on
    the same layout, resampled on another grid; a failed ``library`` solve saying why when
    none is shipped for this track."""
    if "library" not in pb.options.starts:
        return []
    solves: list[StartSolve] = []
    for s in shipped_laps(pb.track, pb.frame.propulsion):
        how = usable(s, pb.layout, pb.full.model.attitude)
        if how is None:
            continue
        with events.start(f"library-{s.name}", pb.layout.intervals) as done:
            point = s.lap.solution  # a shipped lap always has its primal-dual point
            sol = pb.solve(point.w, warm=point) if how == "warm" and point is not None else \
                pb.solve(guess_from_lap(pb.full, s.lap, pb.x0))
            done(sol)
        solves.append((f"library-{s.name}", sol))
    if not solves:  # a line for it too, saying why it did not run
        with events.start("library", pb.layout.intervals) as done:
            solves.append(("library", not_run(pb, "library")))
            done(solves[-1][1])
    return solves


def warm_solves(pb: Problem) -> list[StartSolve]:
    """One solve per usable warm start: ``warm-i`` (primal-dual, same layout and attitude) or
    ``resampled-i`` (same legs and method, another grid or attitude)."""
    solves: list[StartSolve] = []
    for i, ws in enumerate(pb.seeds.warm_starts):
        if ws.solution is None or ws.layout is None:
            continue
        if ws.layout == pb.layout and ws.attitude == pb.full.model.attitude:
            solves.append((f"warm-{i + 1}", pb.solve(ws.solution.w, warm=ws.solution)))
        elif ws.layout.kinds == pb.layout.kinds and ws.layout.method == pb.layout.method:
            solves.append((f"resampled-{i + 1}", pb.solve(guess_from_lap(pb.full, ws, pb.x0))))
    return solves


#: Why a cold start that needs a lap of its own had no guess (its function returned None).
NOT_RUN: dict[str, str] = {
    "coarse-grid": "not run: the coarse grid's own lap failed",
    "fine-grid": "not run: the fine grid's own lap failed",
    "point-mass": "not run: no point-mass reference converged",
    "library": "not run: no lap of this track and propulsion kind is shipped",
}


def not_run(pb: Problem, name: str) -> NlpSolution:
    """A failed solve standing for cold start ``name`` when it had no guess, so that the result's
    starts list every start asked for and why each failed (such a start was left out, and a lap
    that asked for the point-mass start alone said only "no start ran")."""
    n, m = len(pb.box[0]), len(pb.rows[0])
    return NlpSolution(False, NOT_RUN.get(name, "not run: no guess"), float("nan"),
                       NlpPoint(np.zeros(n), np.zeros(n), np.zeros(m), np.zeros(len(pb.P))),
                       0, 0.0, pb.options.solver)


def cold_solves(pb: Problem, lap_of: LapOf) -> list[StartSolve]:
    """One solve from each of the options' cold starts (registry order); a start without a
    guess is a failed solve saying why (:func:`not_run`)."""
    solves: list[StartSolve] = []
    for name, start in COLD_STARTS.items():
        if name in pb.options.starts:
            with events.start(name, pb.layout.intervals) as done:  # progress, its lap and CPU
                sol = start(pb, lap_of)
                sol = sol if sol is not None else not_run(pb, name)
                done(sol)
            solves.append((name, sol))
    return solves


def run_starts(pb: Problem, lap_of: LapOf) -> list[StartSolve]:
    """Solve from the shipped laps (the ``library`` start), the options' cold starts, then the
    warm starts."""
    return library_solves(pb) + cold_solves(pb, lap_of) + warm_solves(pb)


# --------------------------------------------------------------------------------------------
# The fallback start
# --------------------------------------------------------------------------------------------

_REFERENCE_LAPS: dict[tuple, LimitLap] = {}


def reference_lap(name: str, track: TrackConfig, options: LimitLapOptions,
                  lap_of: LapOf, seeds: LapSeeds = LapSeeds()) -> LimitLap:
    """The limit lap of the shipped airframe ``name`` on ``track`` with ``options`` (its own
    cold starts only, no point-mass reference or sensitivities; of ``seeds`` only the
    controller), solved once per process and cached: deterministic, so a cache hit is the same
    result as a new solve. Its gates keep the reference's own clearance (its config's
    propeller; ``options.gate_clearance_m`` where set)."""
    ref_options = replace(options, point_mass_reference=False, sensitivities=False,
                          fallback_reference=None, starts=LimitLapOptions.starts,
                          grid_rounds=0)
    ref_seeds = LapSeeds(controller=seeds.controller)
    key = (name, track.model_dump_json(), repr(ref_options), repr(ref_seeds))
    if key not in _REFERENCE_LAPS:
        cfg = load_airframe(name)
        frame = build_airframe(cfg)
        clearance_m = ref_options.gate_clearance_m
        if clearance_m is None:
            clearance_m = frame_clearance_m(frame, cfg.prop_diameter_mm / 1000)
        _REFERENCE_LAPS[key] = lap_of(frame, track,
                                      replace(ref_options, gate_clearance_m=clearance_m),
                                      ref_seeds)
    return _REFERENCE_LAPS[key]


def fallback_name(name: str | None, propulsion: str) -> str | None:
    """The shipped reference whose limit lap may start a frame with propulsion kind
    ``propulsion``: ``name`` itself with the paper model, ``name-propeller`` (SY250-propeller)
    with the propeller model, None when that airframe is not shipped or has another kind (its
    rotor states would mean something else)."""
    suffix = propulsion_model(propulsion).suffix
    if name is None or not suffix:
        return name

    try:
        ref = load_airframe(f"{name}-{propulsion}")
    except ConfigError:
        return None
    return f"{name}-{propulsion}" if ref.propulsion.model == propulsion else None


def fallback_solve(pb: Problem, lap_of: LapOf) -> StartSolve | None:
    """``reference-<name>``: a primal-dual warm start from the shipped reference frame's limit
    lap on the same track and options (None when there is none or its layout differs)."""
    name = fallback_name(pb.options.fallback_reference, pb.frame.propulsion)
    if name is None:
        return None
    ref = reference_lap(name, pb.track, pb.options, lap_of, pb.seeds)
    if ref.solution is None or ref.layout != pb.layout:
        return None
    return f"reference-{name}", pb.solve(ref.solution.w, warm=ref.solution)
