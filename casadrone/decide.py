"""Decision making on a Pareto front (paper Table 6, Appendix C): utopian, compromise, extreme.

All three work in a normalised objective space: maximised objectives are negated (so every
objective is minimised), then each objective is scaled to [0, 1] over the front
(``(f - min) / (max - min)``; an objective constant over the front maps to 0). In that space the
utopian point is the origin and the front's mean point is ``MP_j = mean_i f_ij`` (paper Table 6).
Distances are Euclidean and dimensionless. Ties go to the lowest row index.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["METHODS", "Decision", "decide", "normalise"]

METHODS: tuple[str, ...] = ("utopian", "compromise", "extreme")


@dataclass(frozen=True)
class Decision:
    """One chosen design on the front.

    Attributes:
        method: ``"utopian"``, ``"compromise"`` or ``"extreme"``.
        index: Row of the chosen design in the front ``F``.
        distance: Distance (normalised objective space, dimensionless) from the chosen design to
            the method's target: the utopian point (``utopian`` and ``extreme``) or the front's
            mean point (``compromise``).
    """

    method: str
    index: int
    distance: float


def normalise(F: np.ndarray, senses: Sequence[str]) -> np.ndarray:
    """Front in the normalised minimisation space: max objectives negated, each scaled to [0, 1]."""
    sign = np.array([-1.0 if s == "max" else 1.0 for s in senses])
    G = np.asarray(F, dtype=float) * sign
    lo, span = G.min(axis=0), np.ptp(G, axis=0)
    return np.where(span > 0.0, (G - lo) / np.where(span > 0.0, span, 1.0), 0.0)


def decide(
    F: np.ndarray,
    senses: Sequence[str] | Mapping[str, str],
    method: str,
    objective: int | str | None = None,
) -> Decision:
    """Choose one design of the front ``F`` (rows: designs, columns: objectives, in their units).

    Args:
        F: Pareto front, shape ``(n_designs, n_objectives)``, objectives in their own sense.
        senses: ``"min"`` or ``"max"`` per column; a mapping ``{name: sense}`` (in column order)
            also names the columns for ``objective``.
        method: ``"utopian"`` (closest to the utopian point), ``"compromise"`` (closest to the
            front's mean point) or ``"extreme"`` (best on ``objective``; ties broken by the
            distance to the utopian point).
        objective: For ``extreme``: the column index, or its name when ``senses`` is a mapping.

    Raises:
        ValueError: empty or non-finite front, mismatched senses, unknown method or objective.
    """
    names = list(senses) if isinstance(senses, Mapping) else None
    sense_list = list(senses.values()) if isinstance(senses, Mapping) else list(senses)
    F = np.asarray(F, dtype=float)
    if F.ndim != 2 or F.shape[0] == 0:
        raise ValueError(f"the front is empty (shape {F.shape}): no feasible design to decide on")
    if F.shape[1] != len(sense_list):
        raise ValueError(f"F has {F.shape[1]} objectives but {len(sense_list)} senses were given")
    bad = [s for s in sense_list if s not in ("min", "max")]
    if bad:
        raise ValueError(f"senses must be 'min' or 'max', got {bad}")
    if not np.all(np.isfinite(F)):
        raise ValueError("the front contains non-finite objective values")
    if method not in METHODS:
        raise ValueError(f"unknown decision method {method!r}; known: {', '.join(METHODS)}")

    N = normalise(F, sense_list)
    to_utopian = np.linalg.norm(N, axis=1)
    if method == "utopian":
        i = int(np.argmin(to_utopian))
        return Decision(method, i, float(to_utopian[i]))
    if method == "compromise":
        to_mean = np.linalg.norm(N - N.mean(axis=0), axis=1)
        i = int(np.argmin(to_mean))
        return Decision(method, i, float(to_mean[i]))

    j = _column(objective, names, F.shape[1])
    column = -F[:, j] if sense_list[j] == "max" else F[:, j]
    best = np.flatnonzero(column == column.min())
    i = int(best[np.argmin(to_utopian[best])])
    return Decision(method, i, float(to_utopian[i]))


def _column(objective: int | str | None, names: list[str] | None, n_obj: int) -> int:
    """Column index of ``objective`` (an index, or a name when the senses are named)."""
    if objective is None:
        raise ValueError("method 'extreme' needs an objective (column index or name)")
    if isinstance(objective, str):
        if names is None or objective not in names:
            known = ", ".join(names) if names else "none (senses is not a mapping)"
            raise ValueError(f"unknown objective {objective!r}; named objectives: {known}")
        return names.index(objective)
    if isinstance(objective, bool) or not isinstance(objective, int | np.integer):
        raise ValueError(f"objective must be a column index or a name, got {objective!r}")
    if not 0 <= objective < n_obj:
        raise ValueError(f"objective index {objective} out of range for {n_obj} objectives")
    return int(objective)
