"""The limit lap's progress events (:mod:`casadrone.progress`): what each step says while the
lap is solved, composed here so the steps (:mod:`~casadrone.limit.lap`,
:mod:`~casadrone.limit.starts`) only call one function each."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from casadrone.limit.nlp import NlpSolution
from casadrone.limit.result import LimitLapOptions
from casadrone.progress import active, emit, nested


def solve_text(sol: NlpSolution) -> str:
    """What one solve reached: its lap (or how it failed) and iterations."""
    lap = f"lap {sol.objective:.4f} s" if sol.success and math.isfinite(sol.objective) else \
        f"no lap ({sol.return_status})"
    return f"{lap}, {sol.iterations} iterations"


def begun(options: LimitLapOptions, warm_starts: int = 0) -> None:
    """The lap's set-up, before its NLP is built (the first use of a model compiles it), with
    ``warm_starts`` earlier laps to start from."""
    if active():
        starts = ", ".join(options.starts) or "none"
        warm = f" and {warm_starts} warm start(s)" if warm_starts else ""
        fallback = (f" (where they give no lap: {', '.join(options.fallback_starts)})"
                    if options.fallback_starts else "")
        emit("stage", f"limit lap on {options.intervals} intervals per leg ({options.solver}): "
             f"starts {starts}{warm}{fallback}, grid rounds up to {options.grid_rounds}")


@contextmanager
def start(name: str, intervals: int) -> Iterator[Callable[[NlpSolution], None]]:
    """Around one start: the block runs nested (a start's own lap on another grid is an inner
    call) and gets ``done(solution)``, which emits the start's lap, iterations and CPU."""
    c0 = time.process_time()
    got: list[NlpSolution] = []
    with nested():
        yield got.append
    for sol in got:  # at the caller's depth, not the nested block's
        reported(name, intervals, sol, time.process_time() - c0)


def reported(name: str, intervals: int, sol: NlpSolution, cpu_s: float) -> None:
    """Start ``name`` solved (here, or in a worker process that took ``cpu_s``:
    :mod:`casadrone.limit.parallel` reports its tasks in the parent as they return)."""
    emit("start", f"start {name} on {intervals} intervals: {solve_text(sol)}, {cpu_s:.1f} s "
         "CPU", lap_s=sol.objective, iterations=sol.iterations, cpu_s=cpu_s)


def solved(intervals: int, solve: Callable[[], tuple[str, NlpSolution] | None]
           ) -> tuple[str, NlpSolution] | None:
    """``solve()`` (a named solve, or None when it could not run), nested, reported under its
    own name when it ran (the fallback start: ``reference-SY250``)."""
    c0 = time.process_time()
    with nested():
        out = solve()
    if out is not None:
        reported(out[0], intervals, out[1], time.process_time() - c0)
    return out


def verified(n_verified: int, n_converged: int, n_solves: int) -> None:
    """After the re-simulation check of the starts solved so far."""
    emit("stage", f"re-simulation check: {n_verified} of {n_converged} converged start(s) "
         f"verified ({n_solves} solved)", verified=n_verified)


def round_done(r: int, before_s: float, after_s: float, solves: int, cpu_s: float) -> None:
    """After grid-continuation round ``r``: the best verified lap before and after it."""
    gain = 100 * (before_s - after_s) / before_s if math.isfinite(before_s) else math.nan
    emit("round", f"grid round {r}: {solves} solve(s), best lap {after_s:.4f} s (was "
         f"{before_s:.4f} s, {gain:.3f} % better), {cpu_s:.1f} s CPU", round=r, lap_s=after_s,
         cpu_s=cpu_s)


def refining(intervals: int) -> None:
    """No start passed the re-simulation check: the lap is solved again on a finer grid."""
    emit("stage", f"no start passed the re-simulation check: solving again on {intervals} "
         "intervals per leg")
