"""The run's hypervolume, as the console shows it per generation and the report plots it.

Of the non-dominated set of every feasible evaluation so far (objectives minimised, maximised ones
negated), in one normalised space fixed for the whole run: [0, 1] per objective between the ideal
and nadir points of the non-dominated feasible set of the first generation that has a feasible
evaluation, reference point 1.1 per objective. The set only gains points and the space never
moves, so the value never falls (an elitist run's per-generation front, normalised on its own
bounds, can: 0.567 → 0.459). A pymoo test problem keeps its raw objectives (the space is the unit
box), so its value compares with the problem's known optimum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
        return float(HV(ref_point=np.full(len(self.ideal), 1.1))((np.asarray(F) - self.ideal)
                                                                / span))


@dataclass(frozen=True)
class HypervolumeState:
    """The non-dominated feasible set so far and the fixed space (None before any feasible
    evaluation); :func:`advance` gives the next state and the value to show."""

    archive: np.ndarray
    space: HypervolumeSpace | None = None


def advance(state: HypervolumeState | None, F_feasible: np.ndarray,
            raw: bool = False) -> tuple[HypervolumeState, float]:
    """Add one generation's feasible (minimised) objective vectors; the new state and the
    hypervolume of the set so far in the fixed space."""
    F_feasible = np.asarray(F_feasible, float)
    if state is None:
        state = HypervolumeState(np.empty((0, F_feasible.shape[1])))
    if len(F_feasible) == 0:
        return state, (state.space.hypervolume(state.archive) if state.space else 0.0)
    space = state.space or HypervolumeSpace.of(F_feasible, raw)
    archive = non_dominated(np.vstack([state.archive, F_feasible]))
    return HypervolumeState(archive, space), space.hypervolume(archive)
