"""The limit lap's independent solves side by side (docs/concepts/limit-lap.md, "Every core"):
the cold starts, then each grid round's solves, as tasks of a :class:`casadrone.pool.Pool`
(spawned processes on this machine, or a Dask cluster).

A task carries what :func:`~casadrone.limit.starts.prepare` takes (the frame, track, resolved
options, clearance and seeds), prepares the same problem in its worker (the NLP is built once per
process; its compiled blocks are loaded from the cache the parent filled when it prepared its
own, :func:`warm_cache`), solves, and re-simulates what converged. The parent takes the results
in the serial order, so the solves, misses and grid laps are those of the serial call and the
lap chosen from them is the same whatever the pool (IPOPT with MUMPS is deterministic for the
same inputs; tests/integration/test_limitlap_parallel.py).

The serial path (:func:`casadrone.limit.starts.run_starts`, :func:`casadrone.limit.lap.
grid_rounds` without a pool) is unchanged; the task functions here call the same steps.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

from casadrone.airframe import Airframe
from casadrone.config.airframe import AirframeConfig
from casadrone.config.track import TrackConfig
from casadrone.limit import events
from casadrone.limit.choose import resimulation_misses
from casadrone.limit.guesses import guess_from_lap
from casadrone.limit.nlp import NlpSolution
from casadrone.limit.result import LapSeeds, LimitLap, LimitLapOptions
from casadrone.limit.starts import (
    COLD_STARTS,
    LapOf,
    Problem,
    StartSolve,
    inner_options,
    library_solves,
    not_run,
    prepare,
    warm_solves,
)
from casadrone.pool import Pool

#: The cold starts that solve the point-mass relaxation (its NLP compiled on first use).
#: The limit lap of a frame and its config (None: a bare frame), from seeds: a grid round's.
RoundOf = Callable[[Airframe, AirframeConfig | None, TrackConfig, LimitLapOptions, LapSeeds],
                   LimitLap]

POINT_MASS_STARTS = frozenset({"point-mass", "fine-grid", "relaxed-tolerance"})


@dataclass(frozen=True)
class Setting:
    """What a worker needs to prepare the parent's problem (:func:`prepare`'s arguments) and to
    solve a lap on another grid as the parent would: ``config``, the airframe's config where the
    parent was given one (its propeller sets the inner laps' clearance); ``lap_of``, the limit
    lap of a frame (:func:`casadrone.limit.lap.limit_lap`, what the cold starts solve inner laps
    with), and ``round_of``, that of the frame and its config (the grid rounds'); both pickled
    by reference."""

    frame: Airframe
    config: AirframeConfig | None
    track: TrackConfig
    options: LimitLapOptions
    clearance_m: float
    seeds: LapSeeds
    lap_of: LapOf
    round_of: RoundOf


@dataclass(frozen=True)
class Solved:
    """What a task gave: the named solve (None: a grid round whose other-grid lap failed), its
    re-simulation miss (NaN: not converged or not checked), the laps it solved on other grids
    (intervals per leg → s), and the task's CPU time (s) in its worker."""

    name: str
    solution: NlpSolution | None
    miss_m: float = math.nan
    grid_laps: dict[int, float] = field(default_factory=dict)
    cpu_s: float = 0.0
    #: the point-mass reference of the parent's problem where the task solved it (one entry)
    reference: tuple[NlpSolution | None, ...] = ()


@dataclass(frozen=True)
class Side:
    """A limit lap's solves side by side: the pool, what its tasks prepare, and the laps on
    other grids they brought back (intervals per leg → best lap, s; filled as tasks return)."""

    pool: Pool
    setting: Setting
    grid_laps: dict[int, float]


def side(pool: Pool | None, frame: Airframe, config: AirframeConfig | None, seeds: LapSeeds,
         pb: Problem, clearance_m: float, grid_laps: dict[int, float], lap_of: LapOf,
         round_of: RoundOf) -> Side | None:
    """The :class:`Side` of the parent's prepared problem ``pb`` on ``pool`` (``lap_of``,
    ``round_of``: :class:`Setting`'s); None (serial) without a pool or with one of a single
    worker."""
    if pool is None or pool.workers <= 1:
        return None
    return Side(pool, Setting(frame, config, pb.track, pb.options, clearance_m, seeds, lap_of,
                              round_of), grid_laps)


def warm_cache(pb: Problem) -> None:
    """Build in the parent what more than one task would otherwise compile at once on a cold
    cache (the point-mass NLP): the compile cache has no lock (casadrone.codegen installs
    atomically), so two workers would each compile the same block."""
    if POINT_MASS_STARTS & set(pb.options.starts) or pb.options.point_mass_reference:
        _ = pb.point_mass


class _Recorder:
    """``lap_of`` that keeps the best lap it solved on each grid (the serial call's
    ``lap_on_grid``)."""

    def __init__(self, lap_of: Callable[..., LimitLap]):
        self.lap_of, self.laps = lap_of, dict[int, float]()

    def __call__(self, *args: object) -> LimitLap:
        lap = self.lap_of(*args)
        if lap.completed and lap.layout is not None:
            n = lap.layout.intervals
            self.laps[n] = min(self.laps.get(n, math.inf), lap.lap_time_s)
        return lap


def _checked(s: Setting, pb: Problem, name: str, sol: NlpSolution | None,
             laps: dict[int, float], cpu0: float) -> Solved:
    """A task's :class:`Solved`, its converged solve re-simulated here."""
    import time

    miss = math.nan
    if sol is not None and sol.success:
        miss = resimulation_misses(pb, [(name, sol)]).get(name, math.nan)
    return Solved(name, sol, miss, dict(laps), time.process_time() - cpu0)


def cold_start_task(s: Setting, name: str) -> Solved:
    """Cold start ``name`` of the parent's problem, solved in this worker."""
    import time

    cpu0 = time.process_time()
    pb = prepare(s.frame, s.track, s.options, s.clearance_m, s.seeds)
    lap_of = _Recorder(s.lap_of)
    sol = COLD_STARTS[name](pb, lap_of)  # type: ignore[index]
    done = _checked(s, pb, name, sol if sol is not None else not_run(pb, name), lap_of.laps,
                    cpu0)
    return replace(done, reference=(pb.__dict__["reference"],)) \
        if "reference" in pb.__dict__ else done


def grid_round_task(s: Setting, name: str, here: LimitLap, intervals: int) -> Solved:
    """One grid-round solve: ``here`` solved on ``intervals`` per leg (a lap of its own), that
    lap resampled onto the parent's grid and solved there (no solution when that lap failed;
    :func:`casadrone.limit.lap.grid_rounds`)."""
    import time

    cpu0 = time.process_time()
    lap_of = _Recorder(s.round_of)
    other = lap_of(s.frame, s.config, s.track, inner_options(
        s.options, intervals=intervals, starts=()), replace(s.seeds, warm_starts=(here,)))
    if not other.completed:
        return Solved(name, None, cpu_s=time.process_time() - cpu0)
    pb = prepare(s.frame, s.track, s.options, s.clearance_m, s.seeds)
    return _checked(s, pb, name, pb.solve(guess_from_lap(pb.full, other, pb.x0)), lap_of.laps,
                    cpu0)


#: Cold starts by their CPU, most first, so that the longest runs from the beginning and the
#: others fill the second worker: SY250 on the paper track, 40 intervals (the progress lines of
#: ``casadrone limit-lap SY250 --certify`` in one process, 2026-12-07, at load average ~11):
#: fine-grid 44 s, point-mass 21 s, closed-loop 9.3 s, coarse-grid 9.0 s; on two processes the
#: cold starts then took as long as the fine-grid start alone (38 s of 73). Only the order the
#: tasks are handed out in: the results are taken in the serial order.
COST_RANK: dict[str, int] = {"fine-grid": 0, "point-mass": 1, "relaxed-tolerance": 1,
                             "closed-loop": 2, "coarse-grid": 3}


def in_order(pool: Pool, task: Callable[..., Solved], rows: list[tuple],
             rank: Callable[[tuple], float], meanwhile: Callable[[], None] = lambda: None
             ) -> list[Solved]:
    """``task`` over ``rows`` on ``pool``, handed out by ``rank`` (smallest first), returned in
    the rows' order; ``meanwhile`` runs here once the tasks are handed out."""
    order = sorted(range(len(rows)), key=lambda i: rank(rows[i]))
    results = pool.map(task, [rows[i] for i in order])
    meanwhile()
    out: list[Solved | None] = [None] * len(rows)
    for i, done in zip(order, results, strict=True):
        out[i] = done
    return [d for d in out if d is not None]


def _gathered(sd: Side, done_tasks: list[Solved], intervals: int, misses: dict[str, float]
              ) -> list[StartSolve]:
    """In the serial order: report each solve, keep its miss and its other grids' laps, and
    return the named solves."""
    solves: list[StartSolve] = []
    for done in done_tasks:
        for n, lap in done.grid_laps.items():
            sd.grid_laps[n] = min(sd.grid_laps.get(n, math.inf), lap)
        if done.solution is None:
            continue
        events.reported(done.name, intervals, done.solution, done.cpu_s)
        if math.isfinite(done.miss_m):
            misses[done.name] = done.miss_m
        solves.append((done.name, done.solution))
    return solves


def run_starts(sd: Side, pb: Problem, misses: dict[str, float]) -> list[StartSolve]:
    """:func:`casadrone.limit.starts.run_starts` with the cold starts on the pool (their misses
    into ``misses``); the warm starts here."""
    warm_cache(pb)
    names = [n for n in COLD_STARTS if n in pb.options.starts]
    done = in_order(sd.pool, cold_start_task, [(sd.setting, n) for n in names],
                    lambda row: COST_RANK.get(row[1], len(COST_RANK)),
                    lambda: _reference_here(pb, names))
    for task in done:
        if task.reference and "reference" not in pb.__dict__:
            adopt_reference(pb, task.reference[0])
    return library_solves(pb) + _gathered(sd, done, pb.layout.intervals, misses) + warm_solves(pb)


def _reference_here(pb: Problem, names: Sequence[str]) -> None:
    """While the workers solve: the point-mass reference the result reports, unless the
    point-mass start's worker brings it back."""
    if pb.options.point_mass_reference and "point-mass" not in names:
        _ = pb.reference


def adopt_reference(pb: Problem, reference: NlpSolution | None) -> None:
    """Give ``pb`` the point-mass reference a worker solved for the same problem (the same
    inputs give the same solve), so that this process does not solve it again: the value of
    :attr:`Problem.reference`'s cache (a ``cached_property`` keeps it in the instance's
    ``__dict__``, which a frozen dataclass allows)."""
    pb.__dict__["reference"] = reference


def round_solves(sd: Side, pb: Problem, jobs: list[tuple[str, LimitLap, int]],
                 misses: dict[str, float]) -> list[StartSolve]:
    """One grid round's solves (name, lap to start from, other grid) on the pool, in order;
    those whose other-grid lap failed are left out, as in the serial round."""
    done = in_order(sd.pool, grid_round_task, [(sd.setting, *job) for job in jobs],
                    lambda row: -row[3])  # the finer grid's lap first: it costs more
    return _gathered(sd, done, pb.layout.intervals, misses)
