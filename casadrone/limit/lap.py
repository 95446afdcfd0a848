"""The limit lap: the minimum-time flight of an airframe through a track
(docs/concepts/limit-lap.md).

``limit_lap(airframe, track, options) -> LimitLap`` (``design_limit_lap(config, ...)`` for the
airframe of a config, with dT/dθ over its decision variables). The NLP
(:mod:`casadrone.limit.nlp`) is built once per track layout on the one symbolic model; the
airframe enters only as the parameter p.
Legs are the track's route segments (start → climb point → waypoints, or start → gates); a leg
ends inside the waypoint's acceptance ball or through the gate's opening. Start: hover at the
first route point (rotors at hover thrust, at rest, the track's start yaw), as the closed-loop
lap starts, or ``options.start_state``. Attitude limit: |φ|, |θ| ≤ the track's ``max_tilt_deg``
(the closed loop's failure test). The lap ends at the last waypoint, at any speed (the track's
``end``: or at rest, at a velocity, or periodic: in the state it started from, that start state
optimised, :func:`casadrone.limit.nlp._periodic_rows`).

Robustness:

- starts: ``closed-loop`` (casadrone's own closed-loop lap of the frame, sampled onto the grid: a
  dynamically consistent but slow guess) and ``point-mass`` (the lower-bound solution lifted to
  the full state: fast but not consistent); for each of ``seeds.warm_starts`` (neighbouring
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
- grid refinement: when starts converge but none passes the re-simulation check (a grid too
  coarse for the lap: the propeller model's ~20 ms rotor lag on long legs, where the legs share
  one number of intervals), the fastest converged lap is resampled onto ``REFINE_FACTOR`` times
  the intervals and solved there (``refined-N``), at most ``options.refinements`` times
  (:func:`refined`).
- every failure (no convergence, unflyable frame, unreachable target) is a result with status
  ``failed`` and a reason; :func:`limit_lap` does not raise for a bad airframe.

Determinism: IPOPT with MUMPS is deterministic for the same inputs, and the starts depend only on
the airframe, the track and ``options`` (including ``warm_start``), never on what was solved
before in the process. An optimisation warm-starts every candidate from the *same* per-study
reference solution (see :mod:`casadrone.evaluate`), so a candidate's value does not depend on the
worker or the order of evaluation.

The steps, each a module of pure functions: :mod:`~casadrone.limit.problem` (track → targets,
refusals, start state, bounds), :mod:`~casadrone.limit.starts` (the prepared problem and one
solve per start), :mod:`~casadrone.limit.choose` (re-simulation check, best start, certainty,
failure reason), then here the result's assembly and its sensitivities.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from casadrone.airframe import Airframe, build_airframe
from casadrone.config.airframe import AirframeConfig
from casadrone.config.limitlap import COMMAND_GRID_ROUNDS, MAX_INTERVALS
from casadrone.config.track import TrackConfig
from casadrone.limit import events, parallel
from casadrone.limit.check import bang_bang_fraction, theta_sensitivities
from casadrone.limit.choose import (
    CERTAIN_REL,
    best,
    certainty,
    failure,
    resimulation_misses,
    start_results,
    verified,
)
from casadrone.limit.guesses import (
    closed_loop_lap,
    guess_from_lap,
    guess_from_trajectory,
    lifted_guess,
    point_mass_guess,
    straight_guess,
)
from casadrone.limit.lagless import is_lagless, lagless_thrust_states
from casadrone.limit.nlp import NlpPoint
from casadrone.limit.pointmass import (
    POINT_MASS_PARAMS,
    REFERENCE_SPEEDS_MPS,
    point_mass_p,
    point_mass_reference,
)
from casadrone.limit.problem import (
    Targets,
    bounds,
    check_inputs,
    frame_clearance_m,
    row_bounds,
    start_state,
    track_targets,
)
from casadrone.limit.result import (
    DEFAULT_INTERVALS,
    Attitude,
    Certainty,
    LapSeeds,
    LimitLap,
    LimitLapOptions,
    Solver,
    Start,
    StartResult,
    TiltLimit,
    euler_states,
    model_states,
    node_times,
)
from casadrone.limit.sensitivity import sensitivity_table
from casadrone.limit.starts import (
    COARSE_SHARE,
    RELAXED_RADIUS_M,
    Problem,
    StartSolve,
    coarse_intervals,
    cold_solves,
    fallback_solve,
    fine_intervals,
    inner_options,
    prepare,
    run_starts,
)
from casadrone.model import param_names
from casadrone.pool import Pool
from casadrone.progress import counting
from casadrone.propulsion import max_static_thrust, propulsion_model

#: The limit lap's names, wherever their step lives (``from casadrone.limit.lap import ...``).
__all__ = [
    "BANG_BANG_TOL", "CERTAIN_REL", "COARSE_SHARE", "COMMAND_GRID_ROUNDS", "DEFAULT_INTERVALS",
    "MAX_INTERVALS", "POINT_MASS_PARAMS", "REFERENCE_SPEEDS_MPS", "RELAXED_RADIUS_M",
    "Attitude", "Certainty", "LapSeeds", "LimitLap", "LimitLapOptions", "Solver", "Start",
    "StartResult", "Targets", "TiltLimit", "bounds", "check_inputs", "closed_loop_lap",
    "design_limit_lap", "euler_states", "frame_clearance_m", "guess_from_lap",
    "guess_from_trajectory", "lifted_guess", "limit_lap",
    "model_states", "node_times", "param_sensitivity", "point_mass_guess", "point_mass_p",
    "point_mass_reference", "refusal", "row_bounds", "start_state", "straight_guess",
    "track_targets",
]

BANG_BANG_TOL = 0.02  # a command within this of 0 or 1 counts as saturated


#: The propeller diameter (m) whose radius a bare :class:`Airframe`'s gate clearance adds (the
#: paper's 5-inch propeller, AirframeConfig's default; :func:`frame_clearance_m`).
BARE_PROP_DIAMETER_M = 0.127


def limit_lap(airframe: Airframe, track: TrackConfig,
              options: LimitLapOptions = LimitLapOptions(),
              seeds: LapSeeds = LapSeeds(), pool: Pool | None = None) -> LimitLap:
    """The minimum-time lap of ``airframe`` on ``track``; never raises for a bad airframe.

    The result carries ``cpu_time_s`` beside ``wall_time_s``: what the whole call cost this
    process and the ``pool``'s workers (every start, check and grid round; a compiler the first
    solve runs is another process). ``seeds``: what the starts may use beside the cold starts
    (earlier laps as warm starts, the frame's closed-loop lap if flown, the controller that
    flies it). With a ``pool`` of more than one worker the independent cold starts, then each
    grid round's solves, run side by side on it (:mod:`casadrone.limit.parallel`); the lap is
    the same. :func:`design_limit_lap` flies the airframe of a config and adds dT/dθ.
    """
    if not isinstance(airframe, Airframe):
        raise TypeError(f"limit_lap takes an Airframe, not {type(airframe).__name__} "
                        "(design_limit_lap takes an AirframeConfig)")
    return _timed(airframe, None, track, options, seeds, pool)


def design_limit_lap(config: AirframeConfig, track: TrackConfig,
                     options: LimitLapOptions = LimitLapOptions(),
                     seeds: LapSeeds = LapSeeds(), frame: Airframe | None = None,
                     pool: Pool | None = None) -> LimitLap:
    """The limit lap of the airframe ``config`` builds (``frame``, where built already), as
    :func:`limit_lap`, with what only the config knows: ``sensitivities`` over its
    decision-variable keys (chain θ → p through the same build as the evaluation; with
    ``options.sensitivities``) and the gate clearance of its own propeller diameter."""
    return _timed(frame if frame is not None else build_airframe(config), config, track,
                  options, seeds, pool)


def round_lap(frame: Airframe, cfg: AirframeConfig | None, track: TrackConfig,
              options: LimitLapOptions, seeds: LapSeeds) -> LimitLap:
    """The limit lap of ``frame`` (and its config, where given) in one process: a grid round's
    lap on another grid, here or in a pool's worker (:mod:`casadrone.limit.parallel`)."""
    return _timed(frame, cfg, track, options, seeds)


def _timed(frame: Airframe, cfg: AirframeConfig | None, track: TrackConfig,
           options: LimitLapOptions, seeds: LapSeeds, pool: Pool | None = None) -> LimitLap:
    cpu, worker_cpu = time.process_time(), pool.worker_cpu_s() if pool is not None else 0.0
    if pool is None:
        lap = _limit_lap(frame, cfg, track, options, seeds)
    else:
        with counting(pool.worker_cpu_s):  # the progress lines' CPU counts the workers
            lap = _limit_lap(frame, cfg, track, options, seeds, pool)
        worker_cpu = pool.worker_cpu_s() - worker_cpu
    return replace(lap, cpu_time_s=time.process_time() - cpu + worker_cpu,
                   workers=pool.workers if pool is not None else 1)


def _limit_lap(frame: Airframe, cfg: AirframeConfig | None, track: TrackConfig,
               options: LimitLapOptions, seeds: LapSeeds, pool: Pool | None = None
               ) -> LimitLap:
    start = time.perf_counter()
    if options.intervals is None:
        options = replace(options, intervals=DEFAULT_INTERVALS.get(frame.propulsion, 40))
    clearance_m = frame_clearance_m(frame, cfg.prop_diameter_mm / 1000 if cfg is not None
                                    else BARE_PROP_DIAMETER_M)
    why = refusal(frame, track, options, clearance_m, seeds)
    if why:
        return _failed(why, start)
    events.begun(options, len(seeds.warm_starts))
    pb = prepare(frame, track, options, clearance_m, seeds)
    grid_laps: dict[int, float] = {}  # the laps the grid-continuation starts solved on theirs

    def on_grid(lap: LimitLap) -> LimitLap:
        if lap.completed and lap.layout is not None:
            n = lap.layout.intervals
            grid_laps[n] = min(grid_laps.get(n, math.inf), lap.lap_time_s)
        return lap

    def lap_on_grid(f: Airframe, trk: TrackConfig, opts: LimitLapOptions, s: LapSeeds
                    ) -> LimitLap:
        return on_grid(limit_lap(f, trk, opts, s))

    def again(opts: LimitLapOptions, warm: LimitLap) -> LimitLap:
        """This airframe (and config) and track, from ``warm``, with other options."""
        return round_lap(frame, cfg, track, opts, replace(seeds, warm_starts=(warm,)))

    sd = parallel.side(pool, frame, cfg, seeds, pb, clearance_m, grid_laps, limit_lap, round_lap)
    known: dict[str, float] = {}  # misses the workers re-simulated
    solves = run_starts(pb, lap_on_grid) if sd is None else parallel.run_starts(sd, pb, known)
    misses = resimulation_misses(pb, solves, known)
    good = verified(solves, misses, options)
    if not good and options.fallback_starts:  # the fast path's cold starts
        solves += cold_solves(replace(pb, options=replace(
            options, starts=options.fallback_starts, fallback_starts=())), lap_on_grid)
        misses = resimulation_misses(pb, solves, misses)
        good = verified(solves, misses, options)
    events.verified(len(good), sum(s.success for _, s in solves), len(solves))
    if solves and not good and (fallback := events.solved(
            pb.layout.intervals, lambda: fallback_solve(pb, limit_lap))) is not None:
        solves.append(fallback)
        misses = resimulation_misses(pb, solves, misses)
        good = verified(solves, misses, options)
    if not good and (fine := refined(again, options, pb, solves, misses)) is not None:
        return replace(fine, starts=start_results(solves, misses) + fine.starts,
                       wall_time_s=time.perf_counter() - start)
    if not good:
        reason, starts = failure(solves, misses, options)
        return _failed(reason, start, starts=starts, layout=pb.layout)
    if options.grid_rounds:
        misses = grid_rounds(lambda opts, warm: on_grid(again(opts, warm)), options, pb,
                             solves, misses, sd)
        good = verified(solves, misses, options)
    result = assemble_lap(pb, good, solves, misses, grid_laps)
    if options.sensitivities and cfg is not None:
        result = with_theta_sensitivities(result, cfg, pb, good)
    return replace(result, wall_time_s=time.perf_counter() - start)


def grid_rounds(lap_on_grid: Callable[[LimitLapOptions, LimitLap], LimitLap],
                options: LimitLapOptions,
                pb: Problem, solves: list[StartSolve], misses: dict[str, float],
                sd: parallel.Side | None = None) -> dict[str, float]:
    """Grid continuation, at most ``options.grid_rounds`` rounds; returns the re-simulation
    misses with the new solves' (appended to ``solves``). A round's solves are independent: with
    ``sd`` they run side by side (:func:`casadrone.limit.parallel.round_solves`).

    A round resamples a verified lap onto the coarse- and fine-grid starts' grids
    (:func:`~casadrone.limit.starts.coarse_intervals`, :func:`~casadrone.limit.starts.
    fine_intervals`) and solves it there (``lap_on_grid``: the same airframe and track with
    other options, from a warm start, so those laps count in the result's
    ``grid_laps_s`` and certainty), then resamples each of those laps back onto this grid and
    solves it here, re-simulated and verified like any other start. The first round does this
    from **every** verified start (``grid-N-round-1-START``), later rounds from the best lap so
    far (``grid-N-round-r``); it stops after a round that improves the best lap by less than
    CERTAIN_REL. A local optimum on one grid is often not one on another (the point-mass
    start: SY250 3.942 s on 40 intervals, 3.889 s on 60), so the path through another grid
    leaves a worse optimum, and which start's path leads to the best one is not known in
    advance: from the chosen lap alone the rounds left NSY200 at 3.7423 s and SY220 at
    3.8164 s, from every start they reach 3.7249 s and 3.8046 s, the best laps known for them
    (benchmarks/RESULTS-limitlap-issue19.md, "Grid rounds as the command's default")."""
    n = pb.layout.intervals
    grids = sorted({coarse_intervals(n), fine_intervals(n)} - {n})
    def cpu() -> float:  # this process's and the pool's workers'
        return time.process_time() + (sd.pool.worker_cpu_s() if sd is not None else 0.0)

    for r in range(1, options.grid_rounds + 1):
        cpu0, count = cpu(), len(solves)
        good = verified(solves, misses, options)
        before = best(good)[1].objective
        sources = _distinct(good) if r == 1 else [best(good)]
        jobs = [(f"grid-{g}-" + (f"round-{r}-{name}" if r == 1 else f"round-{r}"),
                 assemble_lap(pb, [(name, sol)], solves, misses, reference=False), g)
                for name, sol in sources for g in grids]
        if sd is not None:
            solves += parallel.round_solves(sd, pb, jobs, misses)
        for tag, here, g in jobs if sd is None else ():
            with events.start(tag, n) as done:
                other = lap_on_grid(inner_options(options, intervals=g, starts=()), here)
                if other.completed:
                    solves.append((tag, pb.solve(guess_from_lap(pb.full, other, pb.x0))))
                    done(solves[-1][1])
        misses = resimulation_misses(pb, solves, misses)
        after = best(verified(solves, misses, options))[1].objective
        events.round_done(r, before, after, len(solves) - count, cpu() - cpu0)
        if after > (1 - CERTAIN_REL) * before:
            break
    return misses


def _distinct(good: list[StartSolve]) -> list[StartSolve]:
    """The verified starts, fastest first, without those that found the same lap as a faster
    one (within 1e-9 relative: a start that converged to another's optimum)."""
    out: list[StartSolve] = []
    for name, sol in sorted(good, key=lambda ns: ns[1].objective):
        if not any(abs(sol.objective - s.objective) <= 1e-9 * s.objective for _, s in out):
            out.append((name, sol))
    return out


#: Intervals per leg of a grid refinement, as a multiple of the grid that missed; the limit
#: lap's and co-design's (casadrone.codesign.design): SY250-components-propeller's fastest frame
#: missed its re-simulation on 80 intervals and passed on 120, 2.2 cm.
REFINE_FACTOR = 1.5


def refined_intervals(n: int) -> int:
    """Intervals per leg of the grid that refines one of ``n`` (at most MAX_INTERVALS)."""
    return min(MAX_INTERVALS, math.ceil(REFINE_FACTOR * n))


def refined(again: Callable[[LimitLapOptions, LimitLap], LimitLap], options: LimitLapOptions,
            pb: Problem, solves: list[StartSolve], misses: dict[str, float]
            ) -> LimitLap | None:
    """The limit lap on a finer grid when starts converged but none passes the re-simulation
    check: the fastest converged lap resampled onto ``REFINE_FACTOR`` × the intervals (at most
    MAX_INTERVALS) is that grid's only start, and that call may refine once less. None when
    nothing converged, no refinement is left, the grid cannot grow, or the finer grid gives no
    verified lap either. The lap's chosen start is named ``refined-N`` (N intervals per leg);
    ``again`` flies the same airframe and track with other options from a warm start."""
    converged = [(n, s) for n, s in solves if s.success]
    n = pb.layout.intervals
    fine = refined_intervals(n)
    if not converged or options.refinements <= 0 or fine <= n:
        return None
    _, sol = best(converged)
    events.refining(fine)
    T, X, U = pb.full.unpack(sol.point.w)
    coarse = LimitLap(status="failed", reason="re-simulation missed: a start only",
                      leg_times_s=T, t=node_times(T, n), x=X, u=U,
                      attitude=pb.full.model.attitude, layout=pb.layout, solution=sol.point)
    lap = again(replace(options, intervals=fine, starts=(), fallback_reference=None,
                        fallback_starts=(), refinements=options.refinements - 1), coarse)
    if not lap.completed:
        return None
    name = f"refined-{fine}"
    return replace(lap, start=name if lap.start == "resampled-1" else lap.start,
                   starts=tuple(replace(r, start=name) if r.start == "resampled-1" else r
                                for r in lap.starts))


def refusal(frame: Airframe, track: TrackConfig, options: LimitLapOptions,
            clearance_m: float, seeds: LapSeeds = LapSeeds()) -> str:
    """Why the limit lap of ``frame`` cannot be posed or flown (empty string when it can): the
    inputs (:func:`check_inputs`), a frame that cannot hover, no start to solve from."""
    why = check_inputs(track, options, clearance_m)
    if why:
        return why
    weight, full_thrust = frame.mass * frame.gravity, 4 * max_static_thrust(frame)
    if weight >= full_thrust:
        return (f"cannot hover: weight {weight:.2f} N is not below the full thrust "
                f"{full_thrust:.2f} N")
    if not options.starts and not any(w.solution is not None for w in seeds.warm_starts):
        return "no start: give starts or warm_starts"
    return ""


def _failed(reason: str, start: float, **kw) -> LimitLap:
    return LimitLap(status="failed", reason=reason, wall_time_s=time.perf_counter() - start, **kw)


def param_sensitivity(pb: Problem, point: NlpPoint) -> np.ndarray:
    """dT/dp (the airframe's parameter order, s per SI unit) at a solution: minus the parameter
    multipliers, plus, for the thrust gain K, the active bounds set from K (each rotor's thrust
    ≤ K): bounds are numbers, not parameters of the NLP, so the parameter multipliers miss them.
    Measured on SY250 (a 30 m straight and a 2.5 m curve, 20 intervals per leg), where the
    thrust saturates: without the bound term dT/dK was 3.4 % short of central differences of
    warm re-solves, with it they agree to 1e-5 (tests/integration/test_limitlap_optimality.py)."""
    out = -point.lam_p[:len(pb.frame.p)].copy()
    names = param_names(pb.frame.propulsion)
    # rotor states that are thrusts: their bounds are [0, K] (propulsion.rotor_state_bounds),
    # linear in K, so their slope is one difference (a propeller's rotor-speed bound has no K)
    if propulsion_model(pb.frame.propulsion).thrust_is_state and "K" in names:
        lo0, hi0 = pb.box
        lo1, hi1 = bounds(pb.full, replace(pb.frame, thrust_gain=pb.frame.thrust_gain + 1.0),
                          pb.track, pb.options, point_mass=False)
        with np.errstate(invalid="ignore"):  # inf - inf where unbounded: no bound moves
            slope = np.nan_to_num(np.where(point.lam_x > 0, hi1 - hi0, lo1 - lo0), nan=0.0)
        out[names.index("K")] -= float(point.lam_x @ slope)
    return out


def start_sensitivity(pb: Problem, point: NlpPoint) -> np.ndarray:
    """dT/dx_start (the model's states, s per SI unit) at a solution. The start state enters
    the NLP twice: as a row on the parameter x_start, and as equal bounds on the first node
    wherever the track fixes it (:func:`casadrone.limit.problem.bounds`: the bound helps
    IPOPT). The two constraints coincide, and IPOPT may put the whole multiplier on either:
    on the short test track from rest it puts it on the bounds, where the parameter multipliers
    give 0 and dT/dθ missed the start's hover rotor speeds (the envelope gradient in λa was a
    quarter of the forward difference of re-solved laps). So both: minus the parameter
    multipliers, minus each fixed bound's multiplier times the bound's slope in x_start (the
    NLP's units: 1 over the state's scale)."""
    nlp, nx, lay = pb.full, pb.full.model.nx, pb.full.layout
    out = -point.lam_p[len(pb.frame.p):len(pb.frame.p) + nx].copy()
    lo, hi = pb.box
    X = np.zeros((lay.n_intervals + 1, nx))
    X[0] = 1.0  # the first node's states, in their order: the bounds' slopes in x_start
    e = nlp.pack(np.zeros(lay.n_legs), X, np.zeros((lay.n_intervals, nlp.model.nu)),
                 np.zeros((lay.n_intervals, lay.n_coll, nx)) if lay.n_coll else None)
    at = np.flatnonzero(e)
    out -= np.where(lo[at] == hi[at], point.lam_x[at] * e[at], 0.0)
    return out


def theta_sensitivities_at(cfg: AirframeConfig, pb: Problem, point: NlpPoint
                           ) -> dict[str, float]:
    """dT/dθ (s per unit of each decision-variable key) at the optimum ``point``: dT/dp and
    dT/dx0 (:func:`start_sensitivity`) chained through θ → p and θ → start state (the same
    build as the evaluation)."""
    options = pb.options
    dT_dx0 = start_sensitivity(pb, point)
    return theta_sensitivities(
        cfg, param_sensitivity(pb, point), dT_dx0,
        lambda f: model_states(options.attitude, start_state(f, pb.track, options))[0])


def with_theta_sensitivities(result: LimitLap, cfg: AirframeConfig, pb: Problem,
                             good: list[StartSolve] | None = None) -> LimitLap:
    """``result`` with dT/dθ over the config's decision-variable keys at its optimum, and the
    table of those slopes against the other verified optima's in ``good`` (one per distinct
    lap: :func:`_distinct`; casadrone.limit.sensitivity)."""
    if result.solution is None:
        return result
    chosen = theta_sensitivities_at(cfg, pb, result.solution)
    distinct = [sol for name, sol in _distinct(good or []) if name != result.start]
    others = [theta_sensitivities_at(cfg, pb, sol.point) for sol in distinct]
    gaps = [sol.objective - result.lap_time_s for sol in distinct]
    return replace(result, sensitivities=chosen,
                   sensitivity_table=sensitivity_table(chosen, others, gaps,
                                                       CERTAIN_REL * result.lap_time_s))


def assemble_lap(pb: Problem, good: list[StartSolve], solves: list[StartSolve],
                 misses: dict[str, float], grid_laps: dict[int, float] | None = None,
                 reference: bool = True) -> LimitLap:
    """The LimitLap of the best verified start; ``grid_laps`` (intervals per leg → lap) are the
    other grids' laps of the grid-continuation starts, part of its certainty. ``reference``:
    solve its point-mass reference (with the options' ``point_mass_reference``; not for the
    laps a grid round starts from, which report none)."""
    name, chosen = best(good)
    T, X, U = pb.full.unpack(chosen.point.w)
    if is_lagless(pb.frame):  # the rotor states the lag-free model flies: T = K δ
        X = lagless_thrust_states(X, U, pb.full.model.rotor, pb.frame.thrust_gain)
    ends = np.cumsum(T)
    lap_ends = ends[list(pb.targets.lap_ends)]
    agreement, spread = certainty(good, tuple((grid_laps or {}).values()))
    ref = pb.lap_reference(chosen.point.w) if reference and pb.options.point_mass_reference \
        else None
    return LimitLap(
        status="completed", reason="", lap_time_s=float(np.sum(T)),
        split_times_s=ends[pb.targets.first_timed:], leg_times_s=T,
        t=node_times(T, pb.layout.intervals), x=X, u=U, iterations=chosen.iterations,
        bang_bang_fraction=bang_bang_fraction(U, BANG_BANG_TOL),
        point_mass_reference_s=ref.objective if ref is not None else math.nan,
        lap_times_s=np.diff(np.concatenate([[0.0], lap_ends])), spread_s=spread,
        certainty=agreement, attitude=pb.full.model.attitude,
        start_state=euler_states(pb.full.model.attitude, X[:1])[0],
        grid_laps_s=dict(sorted((grid_laps or {}).items())),
        resimulation_miss_m=misses.get(name, math.nan),
        param_sensitivity=param_sensitivity(pb, chosen.point), start=name,
        starts=start_results(solves, misses), layout=pb.layout, solution=chosen.point,
        propulsion=pb.frame.propulsion, params=np.asarray(pb.frame.p, float),
    )
