"""The run's hypervolume, as the console shows it per generation and the report plots it.

Of the non-dominated set of every feasible evaluation so far (objectives minimised, maximised ones
negated), in one normalised space fixed for the whole run: [0, 1] per objective between the ideal
and nadir points of the non-dominated feasible set of the first generation that has a feasible
evaluation, reference point 1.1 per objective. The set only gains points and the space never
moves, so the value never falls (an elitist run's per-generation front, normalised on its own
bounds, can: 0.567 → 0.459). A pymoo test problem keeps its raw objectives (the space is the unit
box), so its value compares with the problem's known optimum.

Its cost is bounded as the set grows (issue "paper scale"): with up to three objectives it is exact
every generation (O(n log n)); with four or more the new points are only buffered, and the set is
merged and measured every :data:`HV_EVERY` generations and at the last (the others log NULL and the
console shows "-"). Exact up to five objectives; from six, estimated from :data:`HV_SAMPLES` fixed
uniform points of the box [0, 1.1]^m of the fixed space (the fraction dominated times the box
volume): the same points every time, so the estimate cannot fall either.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: With four or more objectives the hypervolume is computed every this many generations (and at the
#: last one); in between the new points are buffered.
HV_EVERY = 10
#: Fixed sample points of the Monte Carlo estimate used from six objectives on.
HV_SAMPLES = 4096


def due(n_obj: int, generation: int, last: bool) -> bool:
    """Whether the hypervolume is computed after ``generation`` (see the module docstring)."""
    return n_obj <= 3 or last or generation % HV_EVERY == 0


def dominated_fraction(F: np.ndarray, lo: np.ndarray, ref: np.ndarray,
                       n_samples: int = HV_SAMPLES) -> float:
    """Fraction of ``n_samples`` fixed uniform points of the box [lo, ref] that some row of ``F``
    (minimised) weakly dominates; O(samples · points · objectives), in blocks of 256 points."""
    S = lo + np.random.default_rng(0).random((n_samples, len(ref))) * (ref - lo)
    hit = np.zeros(n_samples, dtype=bool)
    for k in range(0, len(F), 256):
        hit |= (F[None, k:k + 256, :] <= S[:, None, :]).all(axis=2).any(axis=1)
    return float(hit.mean())


def non_dominated(F: np.ndarray) -> np.ndarray:
    """The non-dominated rows of ``F`` (minimised), duplicates removed."""
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    F = np.unique(np.asarray(F, float), axis=0)
    return F[NonDominatedSorting().do(F, only_non_dominated_front=True)] if len(F) > 1 else F


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

    def hypervolume(self, F: np.ndarray) -> float:
        """Hypervolume of the (minimised) points ``F`` in this space."""
        from pymoo.indicators.hv import HV

        if len(F) == 0:
            return 0.0
        span = np.where(self.nadir > self.ideal, self.nadir - self.ideal, 1.0)
        Z, ref = (np.asarray(F) - self.ideal) / span, np.full(len(self.ideal), 1.1)
        if len(ref) >= 6:  # exact: ~2 min for 5 000 points in 6 objectives
            return float(np.prod(ref) * dominated_fraction(Z, np.zeros_like(ref), ref))
        return float(HV(ref_point=ref)(Z))


@dataclass(frozen=True)
class HypervolumeState:
    """The non-dominated feasible set so far, the points not merged into it yet, and the fixed
    space (None before any feasible evaluation); :func:`advance` gives the next state and the
    value to show."""

    archive: np.ndarray
    space: HypervolumeSpace | None = None
    pending: np.ndarray | None = None


def advance(state: HypervolumeState | None, F_feasible: np.ndarray, raw: bool = False,
            compute: bool = True) -> tuple[HypervolumeState, float | None]:
    """Add one generation's feasible (minimised) objective vectors; the new state and the
    hypervolume of the set so far in the fixed space (None when ``compute`` is false: the points
    are buffered until the next generation that computes it)."""
    F_feasible = np.asarray(F_feasible, float)
    if state is None:
        state = HypervolumeState(np.empty((0, F_feasible.shape[1])))
    pending = state.pending if state.pending is not None else np.empty((0, F_feasible.shape[1]))
    if len(F_feasible):
        pending = np.vstack([pending, F_feasible])
    space = state.space or (HypervolumeSpace.of(F_feasible, raw) if len(F_feasible) else None)
    if not compute:
        return HypervolumeState(state.archive, space, pending), None
    if len(pending) == 0:
        return state, (state.space.hypervolume(state.archive) if state.space else 0.0)
    archive = non_dominated(np.vstack([state.archive, pending]))
    return HypervolumeState(archive, space), space.hypervolume(archive)
