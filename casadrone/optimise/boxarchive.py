"""ev-MOGA's ε-box archive A held as plain numpy arrays, updated by the rules of ``EVMOGA.md``.

The archive keeps its members as row-aligned arrays (``rows``: ``"X"``, ``"F"``, ``"G"``, ... of
one length; ``F`` holds the minimised objectives) and their box indices ``box`` on the current
grid (``grid_min``, ``grid_max``, ``eps``). Children are offered one at a time (:meth:`offer`),
exactly as the sequential rules of ``EVMOGA.md`` say, and each step is vectorised over the
archive: its cost is O(|A| m) numpy work, never a Python loop over the members.

When a child moves the grid, EVMOGA.md rebuilds A by re-inserting its members one at a time on the
new grid. :meth:`fill` gives the same result in one vectorised pass, from this characterisation of
inserting items 1…n in order into an empty archive on a fixed grid (proved in its docstring):

- the boxes that survive are exactly the boxes of the items that no other item's box dominates;
- they appear in the order of their first item;
- each holds the winner of the same-box contest (case 3) folded over its items in order.

A property test (``tests/unit/test_boxarchive.py``) checks every step against the sequential
implementation this module replaced, on random streams of 2 to 6 objectives.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = [
    "BoxArchive",
    "box_dominates",
    "box_index",
    "pareto_dominates",
    "pareto_dominates_rows",
]

#: Candidate pairs checked per vectorised block in :func:`_dominated_boxes` (bounds the memory).
_PAIR_BLOCK = 1 << 20


def pareto_dominates(f: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Whether ``f`` Pareto-dominates each row of ``F`` (minimisation)."""
    F = np.atleast_2d(F)
    return (f <= F).all(axis=1) & (f < F).any(axis=1)


def pareto_dominates_rows(F: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Whether each row of ``F`` Pareto-dominates ``f`` (minimisation)."""
    F = np.atleast_2d(F)
    return (F <= f).all(axis=1) & (F < f).any(axis=1)


def box_index(F: np.ndarray, f_min: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """ε-box indices ``ceil((f - min) / ε)`` per objective (0 where ε = 0), rows of ``F``.

    The ratio is rounded to 1e-6 before the ceiling so that floating noise does not move a point
    across a box edge. Elementwise, so a row gets the same box alone or inside a matrix.
    """
    F = np.atleast_2d(F)
    positive = eps > 0.0
    ratio = np.where(positive, (F - f_min) / np.where(positive, eps, 1.0), 0.0)
    return np.ceil(np.round(ratio, 6)).astype(np.int64)


def box_dominates(b: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Whether box ``b`` dominates each row of ``B`` (``b <= B`` componentwise, ``b != B``)."""
    B = np.atleast_2d(B)
    return (b <= B).all(axis=1) & (b != B).any(axis=1)


def centre_distance(f: np.ndarray, b: np.ndarray, f_min: np.ndarray, eps: np.ndarray) -> float:
    """Distance from ``f`` to the centre ``min + (b - 0.5) ε`` of box ``b``, in units of ε (0
    where ε = 0)."""
    centre = f_min + (b - 0.5) * eps
    positive = eps > 0.0
    d = np.where(positive, (f - centre) / np.where(positive, eps, 1.0), 0.0)
    return float(np.linalg.norm(d))


def challenger_wins(f: np.ndarray, f_k: np.ndarray, b: np.ndarray, f_min: np.ndarray,
                    eps: np.ndarray) -> bool:
    """EVMOGA.md case 3: whether ``f`` replaces the member ``f_k`` of its own box ``b``.

    It does if it Pareto-dominates the member; it does not if the member dominates it or they are
    equal; otherwise the one closer to the box centre (in ε units) stays, the member on a tie.
    """
    if pareto_dominates(f, f_k)[0]:
        return True
    if pareto_dominates(f_k, f)[0] or np.array_equal(f, f_k):
        return False
    return centre_distance(f, b, f_min, eps) < centre_distance(f_k, b, f_min, eps)


def _dominated_boxes(U: np.ndarray) -> np.ndarray:
    """Which rows of ``U`` (distinct boxes of mutually Pareto non-dominated points) another row
    box-dominates.

    If the box of ``a`` dominates the box of ``b`` although neither point dominates the other,
    some objective has ``f_a,j > f_b,j`` and, box indices being monotone in ``f``, the two boxes
    share coordinate ``j``. So only pairs that share a coordinate are compared: per objective,
    within each run of equal coordinates sorted by coordinate sum (a dominating box has the smaller
    sum), in blocks of at most ``_PAIR_BLOCK`` pairs.
    """
    n, m = U.shape
    dominated = np.zeros(n, dtype=bool)
    if n < 2:
        return dominated
    total = U.sum(axis=1)
    positions = np.arange(n)
    for j in range(m):
        order = np.lexsort((total, U[:, j]))
        col = U[order, j]
        starts = np.flatnonzero(np.r_[True, col[1:] != col[:-1]])
        group_start = np.repeat(starts, np.diff(np.r_[starts, n]))
        count = positions - group_start  # earlier members of the run: the possible dominators
        count[dominated[order]] = 0  # already known to be dominated
        if not count.any():
            continue
        U_sorted = U[order]
        ends = np.cumsum(count)
        lo = 0
        while lo < n:
            hi = int(np.searchsorted(ends, ends[lo] - count[lo] + _PAIR_BLOCK, side="right"))
            hi = max(hi, lo + 1)
            c = count[lo:hi]
            n_pairs = int(c.sum())
            if n_pairs:
                p = np.repeat(positions[lo:hi], c)
                offset = np.repeat(np.cumsum(c) - c, c)
                q = group_start[p] + (np.arange(n_pairs) - offset)
                hit = (U_sorted[q] <= U_sorted[p]).all(axis=1)
                dominated[order[p[hit]]] = True
            lo = hi
    return dominated


class BoxArchive:
    """The ε-Pareto set A of ev-MOGA on a grid of ``n_div`` boxes per objective.

    Args:
        n_div: Boxes per objective (one int per objective).
        widths: Number of columns of each row array (must include ``"F"``, the minimised
            objectives), e.g. ``{"X": n_var, "F": n_obj, "G": n_ieq, "H": n_eq, "CV": 1}``.

    Attributes (read them, do not edit them):
        rows: Row-aligned member arrays, in archive order (the order ev-MOGA draws parents from).
        box: Box indices of the members on the current grid.
        grid_min, grid_max, eps: The grid (``None`` until the first member).
    """

    def __init__(self, n_div: np.ndarray, widths: Mapping[str, int]) -> None:
        if "F" not in widths:
            raise ValueError("the archive's rows need an 'F' array")
        self.n_div = np.asarray(n_div, dtype=np.int64)
        self.rows: dict[str, np.ndarray] = {k: np.empty((0, int(w))) for k, w in widths.items()}
        self.box = np.empty((0, len(self.n_div)), dtype=np.int64)
        self.grid_min: np.ndarray | None = None
        self.grid_max: np.ndarray | None = None
        self.eps: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.box)

    @property
    def F(self) -> np.ndarray:
        """Objectives of the members (minimised)."""
        return self.rows["F"]

    # ---- grid and rows ------------------------------------------------------------------------

    def set_grid(self, f_min: np.ndarray, f_max: np.ndarray) -> None:
        """Grid from the extremes: ``ε = (max - min) / n_div``."""
        self.grid_min = np.array(f_min, dtype=float)
        self.grid_max = np.array(f_max, dtype=float)
        self.eps = (self.grid_max - self.grid_min) / self.n_div

    def _take(self, index: np.ndarray) -> None:
        """Keep the members ``index`` (a boolean mask or positions, in the new order)."""
        self.rows = {k: v[index] for k, v in self.rows.items()}
        self.box = self.box[index]

    def _row(self, row: Mapping[str, np.ndarray], key: str) -> np.ndarray:
        """One member's values of row array ``key`` as a (1, width) float array."""
        return np.asarray(row[key], dtype=float).reshape(1, self.rows[key].shape[1])

    def _append(self, row: Mapping[str, np.ndarray], b: np.ndarray) -> None:
        self.rows = {k: np.concatenate([v, self._row(row, k)]) for k, v in self.rows.items()}
        self.box = np.concatenate([self.box, b[None, :]])

    def _only(self, row: Mapping[str, np.ndarray], b: np.ndarray) -> None:
        self.rows = {k: self._row(row, k) for k in self.rows}
        self.box = b[None, :].astype(np.int64)

    # ---- EVMOGA.md rules ----------------------------------------------------------------------

    def offer(self, row: Mapping[str, np.ndarray]) -> None:
        """Offer one feasible child (``row[k]``: its values of each row array), recomputing the
        grid when it moves the extremes (EVMOGA.md "archive each child in turn")."""
        f = np.asarray(row["F"], dtype=float).ravel()
        m = len(f)
        if len(self) == 0 and self.grid_min is None:
            self.set_grid(f, f)
            self._only(row, np.zeros(m, dtype=np.int64))
            return
        a = int(np.sum(f >= self.grid_max))
        b = int(np.sum(f <= self.grid_min))
        if a == 0 and b == 0:
            self.insert(row)
        elif a == m and b == 0:
            return
        elif a == 0 and b == m:  # dominates the whole archive: A = {child}, min = max = f
            eps = self.eps
            self.set_grid(f, f)
            self.eps = eps
            self._only(row, box_index(f, self.grid_min, self.eps)[0])
        else:
            F = self.F
            if np.any(pareto_dominates_rows(F, f)):
                return
            self._take(~pareto_dominates(f, F))
            both = np.vstack([self.F, f])
            self.set_grid(both.min(axis=0), both.max(axis=0))
            self._rebuild()
            self.insert(row)

    def insert(self, row: Mapping[str, np.ndarray]) -> bool:
        """Insert with the current grid (EVMOGA.md cases 1-4); return whether the child entered."""
        f = np.asarray(row["F"], dtype=float).ravel()
        b = box_index(f, self.grid_min, self.eps)[0]
        B = self.box
        if len(B) == 0:
            self._append(row, b)
            return True
        equal = (B == b).all(axis=1)
        if np.any((B <= b).all(axis=1) & ~equal):
            return False  # case 1: the child's box is dominated
        same = np.flatnonzero(equal)
        if len(same):  # case 3 (the invariant leaves nothing for case 2 to delete)
            k = int(same[0])
            if not challenger_wins(f, self.F[k], b, self.grid_min, self.eps):
                return False
            for key, v in self.rows.items():
                v[k] = self._row(row, key)[0]
            return True
        gone = (b <= B).all(axis=1)  # case 2 (B == b is excluded above)
        if gone.any():
            self._take(~gone)
        self._append(row, b)  # case 4
        return True

    def fill(self, rows: Mapping[str, np.ndarray]) -> None:
        """Insert the rows (2-D arrays), in order, into the empty archive on the current grid.

        Equal to calling :meth:`insert` on each row in turn, given that the rows are mutually Pareto
        non-dominated (P's non-dominated front, or A itself). Proof of the characterisation in the
        module docstring: each insert leaves every processed item's box weakly dominated by a member
        box and keeps the members' boxes mutually non-dominated, so the final boxes are the minimal
        item boxes; a minimal box is never rejected (case 1) nor deleted (case 2), so it enters with
        its first item, keeps its place, and only case 3 changes its member.
        """
        if len(self):
            raise ValueError("fill needs an empty archive")
        self.rows = {k: np.array(rows[k], dtype=float) for k in self.rows}
        self._rebuild()

    def _rebuild(self) -> None:
        """Re-insert the members, in order, into an empty archive on the current grid (vectorised
        equivalent of EVMOGA.md's re-insertion loop, see :meth:`fill`)."""
        F = self.F
        B = box_index(F, self.grid_min, self.eps) if len(F) else self.box
        self.box = B
        if len(F) < 2:
            return
        boxes, first, group = np.unique(B, axis=0, return_index=True, return_inverse=True)
        group = group.ravel()
        keep = np.flatnonzero(~_dominated_boxes(boxes))
        keep = keep[np.argsort(first[keep], kind="stable")]  # order of first appearance
        winner = first[keep]
        sizes = np.bincount(group, minlength=len(boxes))
        crowded = np.flatnonzero(sizes[keep] > 1)
        if len(crowded):  # fold case 3 over each crowded box's items, in order
            members = np.argsort(group, kind="stable")  # items grouped by box, in order
            bounds = np.r_[0, np.cumsum(sizes)]
            for i in crowded:
                g = keep[i]
                queue = members[bounds[g]:bounds[g + 1]]
                k = queue[0]
                for c in queue[1:]:
                    if challenger_wins(F[c], F[k], boxes[g], self.grid_min, self.eps):
                        k = c
                winner[i] = k
        if len(winner) < len(F) or np.any(winner != np.arange(len(F))):
            self._take(winner)
