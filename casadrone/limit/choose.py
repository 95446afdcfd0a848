"""Choosing the limit lap among its starts: the re-simulation check of every converged start,
the best verified one, how far the verified starts agree, and why none passed
(docs/concepts/limit-lap.md, "Robustness").

Verification: a converged start counts only if its commands, flown by CVODES, pass every target
within ``options.max_miss_m``. An optimum can exploit the discretisation (seen: a warm start from
a distant frame "converged" to 3.58 s, below the 3.74 s point-mass reference, at 54 m/s with a
23 m re-simulation miss); such a start is reported, never chosen.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from casadrone.limit.check import resimulation_miss
from casadrone.limit.result import Certainty, LimitLapOptions, StartResult
from casadrone.limit.starts import Problem, StartSolve, trajectory

#: Verified starts within this relative distance of the best count as the same optimum.
CERTAIN_REL = 1e-3


def resimulation_misses(pb: Problem, solves: Sequence[StartSolve],
                        known: Mapping[str, float] | None = None) -> dict[str, float]:
    """Re-simulation miss (m) of every converged start, by name (none when the options do not
    re-simulate); ``known`` misses are kept, not flown again."""
    misses = dict(known or {})
    if not pb.options.resimulate:
        return misses
    for name, sol in solves:
        if sol.success and name not in misses:
            misses[name] = resimulation_miss(pb.frame, trajectory(pb.full, sol.point.w,
                                                                  pb.layout),
                                             pb.targets.vector, pb.targets.kinds,
                                             legs=pb.options.resimulation == "legs")
    return misses


def verified(solves: Sequence[StartSolve], misses: Mapping[str, float],
             options: LimitLapOptions) -> list[StartSolve]:
    """The converged starts that pass the re-simulation check (all converged ones without it)."""
    return [(n, s) for n, s in solves
            if s.success and (not options.resimulate or misses[n] <= options.max_miss_m)]


def best(good: Sequence[StartSolve]) -> StartSolve:
    """The fastest verified start."""
    return min(good, key=lambda ns: ns[1].objective)


def start_results(solves: Sequence[StartSolve], misses: Mapping[str, float]
                  ) -> tuple[StartResult, ...]:
    """What each start gave."""
    return tuple(StartResult(n, s.success, s.return_status, s.objective, s.iterations,
                             s.wall_time_s, misses.get(n, math.nan), s.solver,
                             s.fatrop[0] if s.fatrop else "")
                 for n, s in solves)


def certainty(good: Sequence[StartSolve], grid_laps: Sequence[float] = ()
              ) -> tuple[Certainty, float]:
    """("agreed" | "single" | "spread", spread in s) of the verified starts' lap times and the
    laps on other grids (``grid_laps``, those the coarse-grid and fine-grid starts solved):
    "agreed" only when every one lands within CERTAIN_REL of the best. The same optimum on
    another grid moves by less than that (SY250, paper track: 0.01 % from 40 to 60 intervals,
    0.06 % from 30 to 60), so a grid that disagrees by more found another local optimum."""
    times = np.array([s.objective for _, s in good] + list(grid_laps))
    if len(times) < 2:
        return "single", math.nan
    spread = float(times.max() - times.min())
    return ("agreed" if spread <= CERTAIN_REL * times.min() else "spread"), spread


def failure(solves: Sequence[StartSolve], misses: Mapping[str, float],
            options: LimitLapOptions) -> tuple[str, tuple[StartResult, ...]]:
    """Why no start gave a verified lap, and what each start gave."""
    starts = start_results(solves, misses)
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
