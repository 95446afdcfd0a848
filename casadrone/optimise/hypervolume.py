"""The run's hypervolume, as the console shows it per generation and the report plots it.

Of the non-dominated set of every feasible evaluation so far (objectives minimised, maximised ones
negated), in one normalised space fixed for the whole run: [0, 1] per objective between the ideal
and nadir points of the non-dominated feasible set of the first generation that has a feasible
evaluation, reference point 1.1 per objective. The set only gains points and the space never
moves, so the value never falls (an elitist run's per-generation front, normalised on its own
bounds, can: 0.567 → 0.459). A pymoo test problem keeps its raw objectives (the space is the unit
box), so its value compares with the problem's known optimum.

Its cost stays bounded as the set grows (a paper-scale run has tens of thousands of
non-dominated evaluations in five objectives, whose exact hypervolume takes minutes):

- up to three objectives it is exact, every generation (O(n log n) on the non-dominated set,
  which is kept sorted and updated with each generation's own front, :func:`front_union`);
- from four objectives it is estimated from :data:`HV_SAMPLES` fixed uniform points of the box
  [0, 1.1]^m of the fixed space: the fraction of them that some evaluation dominates, times the
  box volume. It is kept incrementally, as the set of samples dominated so far: each generation
  tests only its own new points against the samples not yet dominated (O(samples · new points),
  no growing set to keep), so the estimate is computed every generation and, the samples being
  fixed, cannot fall either. Its standard error is at most 0.5/√samples of the box volume
  (0.55 % for 8 192 samples); regions better than the first generation's ideal (below 0) are not
  counted.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np

from casadrone.optimise.bitsets import points_below, unpack

#: Objectives up to which the hypervolume is exact.
EXACT_MAX_OBJECTIVES = 3
#: Fixed sample points of the estimate used from four objectives on.
HV_SAMPLES = 8192
#: Upper corner of the sampled box in the normalised space (the reference point).
REFERENCE = 1.1


def non_dominated(F: np.ndarray) -> np.ndarray:
    """The non-dominated rows of ``F`` (minimised), duplicates removed."""
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    F = np.unique(np.asarray(F, float), axis=0)
    return F[NonDominatedSorting().do(F, only_non_dominated_front=True)] if len(F) > 1 else F


def _row_keys(F: np.ndarray) -> np.ndarray:
    """The rows of ``F`` as one structured value each, ordered as :func:`numpy.unique` orders
    rows (objective by objective)."""
    F = np.ascontiguousarray(F, dtype=float)
    return F.view([(f"f{j}", F.dtype) for j in range(F.shape[1])]).ravel()


def front_union(front: np.ndarray, F: np.ndarray) -> np.ndarray:
    """``non_dominated(vstack([front, F]))`` for a ``front`` that :func:`non_dominated` made
    (rows sorted, distinct, mutually non-dominated), without sorting and filtering the whole
    union again: the new points' own front is filtered against the old one and the old one
    against it (both as bitsets over the new points,
    :func:`~casadrone.optimise.bitsets.points_below`), and the new survivors are inserted where
    the sort puts them. Equal to the recomputation bit for bit (rows compared as numbers, so a
    -0.0 and a 0.0 count as equal, as there)."""
    F = np.asarray(F, float)
    if len(F) == 0:
        return front
    new = non_dominated(F)
    if len(front) == 0:
        return new
    below = points_below(front, new)  # per old point: the new points <= it
    hit = np.flatnonzero(below.any(axis=1))
    gone = np.zeros(len(front), dtype=bool)
    if len(hit):  # dominated when one of them is not equal to it
        i, k = np.nonzero(unpack(below[hit], len(new)))
        gone[hit[i[(new[k] < front[hit[i]]).any(axis=1)]]] = True
    covered = unpack(np.bitwise_or.reduce(points_below(-front, -new), axis=0)[None, :],
                     len(new))[0]  # new points some old point is <= (equal included)
    kept, added = front[~gone], new[~covered]
    if len(added) == 0:
        return kept
    return np.insert(kept, np.searchsorted(_row_keys(kept), _row_keys(added)), added, axis=0)


@cache
def samples(n_obj: int, n_samples: int = HV_SAMPLES) -> np.ndarray:
    """The fixed uniform sample points of [0, REFERENCE]^m (seed 0; read-only)."""
    S = np.random.default_rng(0).random((n_samples, n_obj)) * REFERENCE
    S.setflags(write=False)
    return S


def dominated_by(Z: np.ndarray, S: np.ndarray) -> np.ndarray:
    """Which rows of ``S`` some row of ``Z`` weakly dominates (minimised): as bitsets over
    ``Z`` (:func:`casadrone.optimise.bitsets.points_below`), O(|S| · m · |Z| / 64) word
    operations."""
    return np.asarray(points_below(S, Z).any(axis=1))


@dataclass(frozen=True)
class HypervolumeSpace:
    """The fixed normalisation: F ↦ (F − ideal) / (nadir − ideal), reference point 1.1."""

    ideal: np.ndarray
    nadir: np.ndarray

    @classmethod
    def of(cls, F_first: np.ndarray, raw: bool = False) -> HypervolumeSpace:
        """The space fixed by the first feasible generation's objectives (or the unit box)."""
        m = np.asarray(F_first).shape[1]
        if raw:
            return cls(np.zeros(m), np.ones(m))
        nd = non_dominated(F_first)
        return cls(nd.min(axis=0), nd.max(axis=0))

    def normalise(self, F: np.ndarray) -> np.ndarray:
        """``F`` (minimised) in this space."""
        span = np.where(self.nadir > self.ideal, self.nadir - self.ideal, 1.0)
        return (np.asarray(F, float) - self.ideal) / span

    def hypervolume(self, F: np.ndarray) -> float:
        """Hypervolume of the (minimised) points ``F`` in this space: exact up to three
        objectives, else the fixed-sample estimate (the same value the run shows)."""
        from pymoo.indicators.hv import HV

        m = len(self.ideal)
        if len(F) == 0:
            return 0.0
        if m > EXACT_MAX_OBJECTIVES:
            return float(REFERENCE ** m * dominated_by(self.normalise(F), samples(m)).mean())
        return float(HV(ref_point=np.full(m, REFERENCE))(self.normalise(F)))


@dataclass(frozen=True)
class HypervolumeState:
    """What the run keeps between generations: the fixed space (None before any feasible
    evaluation) and, up to three objectives, the non-dominated set so far, from four, which fixed
    samples the evaluations so far dominate. :func:`advance` gives the next state and value."""

    archive: np.ndarray
    space: HypervolumeSpace | None = None
    hit: np.ndarray | None = None

    def value(self) -> float:
        """The hypervolume of the set so far (0 before any feasible evaluation)."""
        if self.space is None:
            return 0.0
        if self.hit is not None:
            return float(REFERENCE ** len(self.space.ideal) * self.hit.mean())
        return self.space.hypervolume(self.archive)


def advance(state: HypervolumeState | None, F_feasible: np.ndarray,
            raw: bool = False) -> tuple[HypervolumeState, float]:
    """Add one generation's feasible (minimised) objective vectors; the new state and the
    hypervolume of the set so far in the fixed space."""
    F_feasible = np.asarray(F_feasible, float)
    m = F_feasible.shape[1]
    if state is None:
        state = HypervolumeState(np.empty((0, m)))
    if len(F_feasible) == 0:
        return state, state.value()
    space = state.space or HypervolumeSpace.of(F_feasible, raw)
    if m > EXACT_MAX_OBJECTIVES:
        hit = np.zeros(HV_SAMPLES, dtype=bool) if state.hit is None else state.hit.copy()
        open_ = ~hit
        hit[open_] = dominated_by(space.normalise(F_feasible), samples(m)[open_])
        new = HypervolumeState(state.archive, space, hit)
    else:
        new = HypervolumeState(front_union(state.archive, F_feasible), space)
    return new, new.value()
