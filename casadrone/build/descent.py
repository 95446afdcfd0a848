"""A ranked dominant race moved to the co-design's optimum by the race's own gradient: a
projected secant (quasi-Newton) descent over the geometry box, one warm-started race per step,
instead of a co-design of the combination.

Why: a dominant race (:mod:`casadrone.build.dominance`) is nearly but not exactly the
co-design's optimum; where its gradient dT/dθ is not first-order optimal over the box
(:func:`casadrone.build.dominance.stationary`), the build used to co-design the combination
from that frame: one co-design NLP (θ and the whole lap, a cold IPOPT of ~200 iterations) and a
race of its frame, 60–120 s of CPU on the paper track. Measured on build-small's winner
(DA4022 + 1750 KV + 6S at the short-arm corner, paper track), the race's gradient in λa is
-0.333 ms/mm, and central differences of the lap re-solved at the race's voltage ±0.1 and
±0.25 mm around it give -0.324 and -0.315 ms/mm (tests/integration/
test_build_descent_race.py): the envelope gradient means what it says there, and the lap is
a smooth function of θ at the millimetre scale. A race warm-started from its
neighbour's lap costs ~20 s; two gradients along a step give the curvature; so:

1. the gradient per box width, each key that sits at a bound and whose slope points out of the
   box held there (a projected gradient p; :func:`projected`);
2. the first step moves :data:`STEP` of the box width along -p; every later one the secant's
   Newton length |p|/h along -p, h the curvature of the race between the best frame and the
   last one raced (their gradients' difference along their difference), at most
   :data:`GROW` times the last move; without a positive curvature the last move doubled
   (after a faster race) or halved (after a slower one); each frame clipped into the box;
3. each step is a race of that frame warm-started from the best one's, under its current
   limits (a derated race's: :func:`casadrone.build.solve.current_derate`), its first pass
   flown at the voltage of the best race's last pass (:func:`casadrone.build.solve.race_dominant`,
   ``soc``): one pass where the step's race ends within the race's tolerance of that charge,
   and two races that differ by θ alone (flown first at the best race's *end* charge, within
   the same tolerance of it, build-small's winner's 0.5 mm step, 0.005 % faster at one
   voltage, came out slower: the voltage moves a race as much as the step). The faster
   feasible race is kept;
4. it stops where the best frame is stationary, where the secant predicts less than
   :data:`GAIN_RTOL` of the race left to gain (|p|²/2h: a tenth of the build's ranking
   tolerance, below the ~0.05 % by which local optima of one race differ), or after
   :data:`MAX_RACES` races. Only the last leaves the combination unsettled (co-designed from
   the best frame, :func:`casadrone.build.search.confirmed`).

The race kept is a race of a valid frame of the box flown within the pack's limits: whatever
the steps do, the ranking's time is achievable, and never slower than the dominant race.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from casadrone.build.solve import BuildResult

#: The first step, as a fraction of the box's width along the descent direction (0.5 mm over
#: build-small's 50 mm arms: the forward difference there matches the envelope gradient).
STEP = 0.01
#: Most races of one descent (after the dominant race).
MAX_RACES = 3
#: A descent stops where the secant predicts less than this fraction of the race left to gain.
GAIN_RTOL = 1e-4
#: Longest step, as a multiple of the last move.
GROW = 4.0


@dataclass(frozen=True)
class Step:
    """The next frame of a descent (box coordinates, 0 to 1 per key) and the gain (s) the
    secant predicts there (inf before a curvature is known)."""

    x: np.ndarray
    predicted_gain_s: float


def scaled(r: BuildResult, keys: tuple[str, ...], lower: np.ndarray, upper: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray]:
    """(θ in box coordinates, dT/dθ in s per box width; NaN where a key has no value)."""
    width = upper - lower
    x = (np.array([r.theta.get(k, math.nan) for k in keys]) - lower) / width
    g = np.array([r.race_gradient.get(k, math.nan) for k in keys]) * width
    return x, g


def projected(x: np.ndarray, g: np.ndarray) -> np.ndarray:
    """The gradient with each key that sits at a bound and whose slope points out of the box
    set to zero (a descent cannot move it)."""
    from casadrone.codesign.certificate import AT_BOUND  # casadi: lazy

    blocked = ((x <= AT_BOUND) & (g > 0)) | ((x >= 1 - AT_BOUND) & (g < 0))
    return np.where(blocked, 0.0, g)


def next_step(x: np.ndarray, g: np.ndarray, other: tuple[np.ndarray, np.ndarray] | None,
              accepted: bool) -> Step:
    """The next frame from the best one (``x``, gradient ``g``, both scaled) after ``other``
    (the last frame raced before it and its gradient, None before a step), ``accepted``
    whether that last race was kept (module docstring, item 2)."""
    p = projected(x, g)
    size = float(np.linalg.norm(p))
    if size == 0:  # nothing moves into the box: a stationary frame
        return Step(x, 0.0)
    d = -p / size
    alpha, gain = STEP, math.inf
    if other is not None:
        dx = other[0] - x
        move = float(np.linalg.norm(dx))
        h = float((other[1] - g) @ dx) / move**2 if np.all(np.isfinite(other[1])) else math.nan
        if h > 0:
            alpha, gain = min(size / h, GROW * move), size**2 / (2 * h)
        else:
            alpha = 2 * move if accepted else move / 2
    return Step(np.clip(x + alpha * d, 0.0, 1.0), gain)


def descend(r: BuildResult, keys: tuple[str, ...], lower: np.ndarray, upper: np.ndarray,
            race_at: Callable[[dict[str, float], BuildResult], BuildResult],
            settled: Callable[[BuildResult], bool]) -> tuple[BuildResult, bool]:
    """(the fastest race of the descent from ``r``, a dominant race with its gradient, whether
    it settled: stationary or nothing left to gain); ``race_at(θ, best)`` races frame θ from
    the best race so far, ``settled(best)`` says whether a race is stationary. The result's
    CPU is every race's, its ``geometry_by`` "descent" where a step was kept."""
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    best, other, accepted, cpu, races = r, None, False, r.cpu_s, 0
    while not settled(best):
        x, g = scaled(best, keys, lower, upper)
        if not np.all(np.isfinite(g) & np.isfinite(x)) or races >= MAX_RACES:
            return _done(r, best, cpu, races, False)
        step = next_step(x, g, other, accepted)
        if step.predicted_gain_s < GAIN_RTOL * best.race_s or np.allclose(step.x, x):
            return _done(r, best, cpu, races, True)
        theta = {k: float(v) for k, v in zip(keys, lower + step.x * (upper - lower),
                                             strict=True)}
        got = race_at(theta, best)
        cpu, races = cpu + got.cpu_s, races + 1
        if not got.theta:  # the frame was refused before any solve: no step to learn from
            return _done(r, best, cpu, races, False)
        accepted = got.feasible and got.race_s < best.race_s
        other = (x, g) if accepted else scaled(got, keys, lower, upper)
        best = got if accepted else best
    return _done(r, best, cpu, races, True)


def _done(r: BuildResult, best: BuildResult, cpu: float, races: int, settled: bool
          ) -> tuple[BuildResult, bool]:
    how = "descent" if best is not r else r.geometry_by
    n = f"{races} race{'s' * (races != 1)}"
    note = "" if not races else (
        f"descended from the dominant frame in {n}, "
        f"{(r.race_s - best.race_s) / r.race_s:.4%} faster" if best is not r else
        f"no faster frame in {n} of descent: the dominant frame's race is kept")
    return replace(best, geometry_by=how, cpu_s=cpu,
                   reason="; ".join(s for s in (best.reason, note) if s)), settled
