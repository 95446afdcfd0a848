"""ev-MOGA's ε-box archive A held as plain numpy arrays, updated by the rules of
``docs/concepts/evmoga.md#insertion``.

The archive keeps its members as row-aligned arrays (``rows``: ``"X"``, ``"F"``, ``"G"``, ... of
one length; ``F`` holds the minimised objectives) and their box indices ``box`` on the current
grid (``grid_min``, ``grid_max``, ``eps``). Children are offered one at a time (:meth:`offer`),
exactly as the sequential rules of ``docs/concepts/evmoga.md`` say, and each step is vectorised
over the archive: its cost is O(|A| m) numpy work, never a Python loop over the members. A
generation's children are offered together (:meth:`offer_many`): each run of them inside the grid,
which none of them can move, is settled by one vectorised re-insertion (below) instead of one
insert each, with the same result.

When a child moves the grid, the rules (docs/concepts/evmoga.md#generation) rebuild A by
re-inserting its members one at a time on the new grid. :meth:`fill` gives the same result in one
vectorised pass, from this characterisation of inserting items 1…n in order into an empty archive
on a fixed grid (proved in its docstring):

- the boxes that survive are exactly the boxes of the items that no other item's box dominates;
- they appear in the order of their first item;
- each holds the winner of the same-box contest (case 3) folded over its items in order.

Members whose box the new grid leaves unchanged cannot dominate or meet each other (they did not
on the old grid), so a rebuild only compares pairs with a changed member, as bitsets (64 members
per machine word). Boxes are stored one row per objective, and also packed one int64 per member
(:func:`box_packing`, a guard bit above each objective's field) so that :meth:`BoxArchive.insert`
tests "member box <= child box" (and ">=") against the whole archive with one subtraction instead
of m comparisons.

A property test (``tests/unit/test_boxarchive.py``) checks every step, and every batch of
:meth:`offer_many`, against the sequential implementation this module replaced, on random streams
of 2 to 6 objectives.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

__all__ = [
    "BoxArchive",
    "box_dominates",
    "box_index",
    "box_packing",
    "pack_box",
    "pack_boxes",
    "pareto_dominates",
    "pareto_dominates_rows",
]

def pareto_dominates(f: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Whether ``f`` Pareto-dominates each row of ``F`` (minimisation)."""
    F = np.atleast_2d(F)
    return np.asarray((f <= F).all(axis=1) & (f < F).any(axis=1))


def pareto_dominates_rows(F: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Whether each row of ``F`` Pareto-dominates ``f`` (minimisation)."""
    F = np.atleast_2d(F)
    return np.asarray((F <= f).all(axis=1) & (F < f).any(axis=1))


def box_index(F: np.ndarray, f_min: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """ε-box indices ``ceil((f - min) / ε)`` per objective (0 where ε = 0), rows of ``F``.

    The ratio is rounded to 1e-6 before the ceiling so that floating noise does not move a point
    across a box edge. Elementwise, so a row gets the same box alone or inside a matrix.
    """
    F = np.atleast_2d(F)
    positive = eps > 0.0
    ratio = (F - f_min) / np.where(positive, eps, 1.0)
    if not positive.all():
        ratio = np.where(positive, ratio, 0.0)
    ratio = ratio.round(6)
    return np.ceil(ratio, out=ratio).astype(np.int64)


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
    """Insertion case 3 (docs/concepts/evmoga.md#insertion): whether ``f`` replaces the member
    ``f_k`` of its own box ``b``.

    It does if it Pareto-dominates the member; it does not if the member dominates it or they are
    equal; otherwise the one closer to the box centre (in ε units) stays, the member on a tie.
    """
    if pareto_dominates(f, f_k)[0]:
        return True
    if pareto_dominates(f_k, f)[0] or np.array_equal(f, f_k):
        return False
    return centre_distance(f, b, f_min, eps) < centre_distance(f_k, b, f_min, eps)


def _all_le(Bt: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``B[i] <= b`` componentwise for each column ``i`` of ``Bt`` (one row per objective)."""
    out = Bt[0] <= b[0]
    for j in range(1, len(b)):
        out &= Bt[j] <= b[j]
    return out


def box_packing(n_div: np.ndarray) -> tuple[list[int], list[int], int] | None:
    """Bit layout that packs a box (entries ``0 <= b_j < 2**w_j``, ``w_j`` the bit length of
    ``n_div_j``, so up to ``n_div_j`` fits) into one int64: field ``j`` at bit ``shift_j`` with a
    guard bit above it. Returns ``(shifts, widths, guard mask)``, or ``None`` beyond 63 bits.

    For packed ``k``, ``K``: ``((k | guard) - K) & guard == guard`` exactly when ``K <= k``
    componentwise (each field computes ``2**w_j + k_j - K_j``, which keeps its guard bit iff
    ``k_j >= K_j`` and never borrows from the next field): one comparison for m objectives.
    """
    shifts, widths, at = [], [], 0
    for d in np.asarray(n_div).tolist():
        widths.append(int(d).bit_length())
        shifts.append(at)
        at += widths[-1] + 1
    if at > 63:
        return None
    return shifts, widths, sum(1 << (s + w) for s, w in zip(shifts, widths, strict=True))


def pack_boxes(Bt: np.ndarray, packing: tuple[list[int], list[int], int]) -> np.ndarray | None:
    """The boxes (columns of ``Bt``, one row per objective) packed by :func:`box_packing`, or
    ``None`` if an entry does not fit its field."""
    shifts, widths, _ = packing
    keys = np.zeros(Bt.shape[1], dtype=np.int64)
    for j, (s, w) in enumerate(zip(shifts, widths, strict=True)):
        if Bt.shape[1] and (Bt[j].min() < 0 or Bt[j].max() >= 1 << w):
            return None
        keys |= Bt[j] << s
    return keys


def pack_box(b: np.ndarray, packing: tuple[list[int], list[int], int]) -> int | None:
    """One box packed by :func:`box_packing` (a Python int), or ``None`` if it does not fit."""
    key = 0
    for v, s, w in zip(b.tolist(), packing[0], packing[1], strict=True):
        if not 0 <= v < 1 << w:
            return None
        key |= v << s
    return key


def _stable_argsort(a: np.ndarray) -> np.ndarray:
    """``np.argsort(a, kind="stable")`` of a 1-D integer array; sorted as uint16 (numpy's radix
    sort, ~10x faster than int64) when every value fits: a stable sort's permutation depends only
    on the order of the values, so it is the same."""
    if len(a) and a.min() >= 0 and a.max() < 1 << 16:
        a = a.astype(np.uint16)
    return np.argsort(a, kind="stable")


def _any_below(U: np.ndarray, targets: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """For each target column of ``U`` (distinct boxes, one row per objective): whether another
    source column is ``<=`` it componentwise, i.e. dominates it.

    Per objective, a table holds as bitsets (64 sources per word) the sources at or below each
    value; a target's dominators are the AND of its m table rows, less itself. Sources are ranked
    by coordinate sum (a dominator has the smaller sum), so a block of targets only reads the words
    of the sources with a sum below its largest. O(targets · sources · m / 64) word operations.
    """
    total = U.sum(axis=0)
    asked = targets
    sources = sources[_stable_argsort(total[sources])]
    targets = targets[_stable_argsort(total[targets])]
    ns = len(sources)
    k = np.arange(ns)
    bits = np.left_shift(np.uint64(1), (k & 63).astype(np.uint64))
    tables, rows = [], []
    for j in range(U.shape[0]):
        v, t = U[j, sources], U[j, targets]
        if v.min() >= 0 and v.max() < 4 * ns + 64:  # box indices: index the table directly
            size, row = int(max(v.max(), t.max())) + 1, t
        else:  # large or negative values: by rank
            values, v = np.unique(v, return_inverse=True)
            size, row = len(values), np.searchsorted(values, t, side="right") - 1
        table = np.zeros((size + 1, -(-ns // 64)), dtype=np.uint64)  # last row: no source
        np.bitwise_or.at(table, (v.ravel(), k >> 6), bits)
        table = np.bitwise_or.accumulate(table, axis=0)
        table[-1] = 0
        tables.append(table)
        rows.append(np.where(row < 0, size, row))
    where = np.full(U.shape[1], -1)
    where[sources] = k
    own = where[targets]
    word, bit = own >> 6, bits[np.maximum(own, 0)]
    below = np.searchsorted(total[sources], total[targets], side="left")  # sources with less sum
    out = np.zeros(U.shape[1], dtype=bool)
    for lo in range(0, len(targets), 256):
        sl = slice(lo, lo + 256)
        n_words = -(-int(below[sl].max()) // 64)
        if n_words == 0:
            continue
        acc = tables[0][:, :n_words][rows[0][sl]]
        for table, row in zip(tables[1:], rows[1:], strict=True):
            acc &= table[:, :n_words][row[sl]]
        mine = np.flatnonzero((own[sl] >= 0) & (word[sl] < n_words))
        acc[mine, word[sl][mine]] &= ~bit[sl][mine]
        out[targets[sl]] = acc.any(axis=1)
    return out[asked]


def dominated_boxes(U: np.ndarray, changed: np.ndarray) -> np.ndarray:
    """Which columns of ``U`` (distinct boxes, one row per objective) another column dominates,
    given that the columns not ``changed`` do not dominate each other.

    The changed columns are tested against all; the others only against the changed columns
    found undominated: following dominators down from an unchanged column ends (the order is
    strict and finite) at an undominated column that dominates it too, and that one cannot be
    unchanged."""
    dominated = np.zeros(U.shape[1], dtype=bool)
    moved, still = np.flatnonzero(changed), np.flatnonzero(~changed)
    if 2 * len(moved) > U.shape[1]:  # one pass over all pairs is cheaper than two
        everyone = np.arange(U.shape[1])
        return _any_below(U, everyone, everyone)
    if len(moved):
        dominated[moved] = _any_below(U, moved, np.arange(U.shape[1]))
        minimal = moved[~dominated[moved]]
        if len(still) and len(minimal):  # a dominated column has a minimal moved dominator
            dominated[still] = _any_below(U, still, minimal)
    return dominated


def _box_keys(Bt: np.ndarray) -> np.ndarray:
    """One integer per box (columns of ``Bt``), equal exactly for equal boxes."""
    radix = Bt.max(axis=1) + 1
    if Bt.min() >= 0 and float(np.prod(radix.astype(float))) < 2.0**62:
        keys = np.zeros(Bt.shape[1], dtype=np.int64)
        for j in range(Bt.shape[0]):
            keys = keys * radix[j] + Bt[j]
        return keys
    return np.unique(Bt.T, axis=0, return_inverse=True)[1].ravel()


class BoxArchive:
    """The ε-Pareto set A of ev-MOGA on a grid of ``n_div`` boxes per objective.

    Args:
        n_div: Boxes per objective (one int per objective).
        widths: Number of columns of each row array (must include ``"F"``, the minimised
            objectives), e.g. ``{"X": n_var, "F": n_obj, "G": n_ieq, "H": n_eq, "CV": 1}``.

    Read (never edit) ``rows`` (row-aligned member arrays, in archive order: the order ev-MOGA
    draws parents from), ``F``, ``box`` (box indices on the current grid) and the grid
    ``grid_min``, ``grid_max``, ``eps`` (``None`` until the first member). Storage grows by
    doubling, so appending a member is O(1) amortised.
    """

    def __init__(self, n_div: np.ndarray, widths: Mapping[str, int]) -> None:
        if "F" not in widths:
            raise ValueError("the archive's rows need an 'F' array")
        self.n_div = np.asarray(n_div, dtype=np.int64)
        self._n = 0
        self._rows: dict[str, np.ndarray] = {k: np.empty((0, int(w))) for k, w in widths.items()}
        self._box = np.empty((len(self.n_div), 0), dtype=np.int64)  # one row per objective
        self._packing = box_packing(self.n_div)
        self._packed: np.ndarray | None = None  # boxes packed (box_packing), None: not built
        self.grid_min: np.ndarray | None = None
        self.grid_max: np.ndarray | None = None
        self.eps: np.ndarray | None = None

    def __len__(self) -> int:
        return self._n

    @property
    def rows(self) -> dict[str, np.ndarray]:
        """The members' row arrays (views)."""
        return {k: v[:self._n] for k, v in self._rows.items()}

    @property
    def F(self) -> np.ndarray:
        """Objectives of the members (minimised)."""
        return self._rows["F"][:self._n]

    @property
    def box(self) -> np.ndarray:
        """Box indices of the members, one row per member."""
        return self._box[:, :self._n].T

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_rows"] = {k: v.copy() for k, v in self.rows.items()}
        state["_box"] = self._box[:, :self._n].copy()
        state["_packed"] = None
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self._packing = box_packing(self.n_div)  # absent from checkpoints before it existed
        self._packed = None

    # ---- grid and storage ---------------------------------------------------------------------

    def set_grid(self, f_min: np.ndarray, f_max: np.ndarray) -> None:
        """Grid from the extremes: ``ε = (max - min) / n_div``."""
        self.grid_min = np.array(f_min, dtype=float)
        self.grid_max = np.array(f_max, dtype=float)
        self.eps = (self.grid_max - self.grid_min) / self.n_div

    def _grid(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``grid_min``, ``grid_max`` and ``eps``, which :meth:`set_grid` sets before any member
        is inserted."""
        if self.grid_min is None or self.grid_max is None or self.eps is None:
            raise RuntimeError("the archive's grid is not set")
        return self.grid_min, self.grid_max, self.eps

    def _box_columns(self, F: np.ndarray) -> np.ndarray:
        """:func:`box_index` of the rows of ``F``, one row per objective (same arithmetic)."""
        f_min, _, eps = self._grid()
        out = np.zeros((F.shape[1], len(F)), dtype=np.int64)
        for j in range(F.shape[1]):
            if eps[j] > 0.0:
                out[j] = np.ceil(np.round((F[:, j] - f_min[j]) / eps[j], 6))
        return out

    def _set(self, rows: Mapping[str, np.ndarray], box_columns: np.ndarray) -> None:
        self._rows = {k: np.asarray(rows[k], dtype=float) for k in self._rows}
        self._box = np.ascontiguousarray(box_columns, dtype=np.int64)
        self._n = self._box.shape[1]
        self._packed = None

    def _take(self, index: np.ndarray, box_columns: np.ndarray | None = None) -> None:
        """Keep the members ``index`` (mask or positions, in the new order); their boxes are
        ``box_columns[:, index]`` when given, else the stored ones."""
        B = self._box[:, :self._n] if box_columns is None else box_columns
        index = np.flatnonzero(index) if index.dtype == bool else index
        n = len(index)
        cap = n + max(16, n // 4)  # room to append without copying again
        rows = {}
        for k, v in self.rows.items():
            rows[k] = np.empty((cap, v.shape[1]))
            np.take(v, index, axis=0, out=rows[k][:n])
        box = np.empty((B.shape[0], cap), dtype=np.int64)
        np.take(B, index, axis=1, out=box[:, :n])
        self._rows, self._box, self._n = rows, box, n
        self._packed = None

    def _row(self, row: Mapping[str, np.ndarray], key: str) -> np.ndarray:
        """One member's values of row array ``key`` as a (width,) float array."""
        return np.asarray(row[key], dtype=float).reshape(self._rows[key].shape[1])

    def _append(self, row: Mapping[str, np.ndarray], b: np.ndarray) -> None:
        n = self._n
        if n == self._box.shape[1]:  # grow by doubling
            cap = max(16, 2 * n)
            self._rows = {k: np.concatenate([v[:n], np.empty((cap - n, v.shape[1]))])
                          for k, v in self._rows.items()}
            self._box = np.concatenate([self._box[:, :n],
                                        np.empty((len(b), cap - n), dtype=np.int64)], axis=1)
        for k, v in self._rows.items():
            v[n] = self._row(row, k)
        self._box[:, n] = b
        if self._packed is not None and self._packing is not None:
            key = pack_box(b, self._packing)
            if key is None or len(self._packed) <= n:  # does not fit, or storage grew
                self._packed = None
            else:
                self._packed[n] = key
        self._n = n + 1

    def _packed_boxes(self) -> np.ndarray | None:
        """The members' boxes packed (:func:`box_packing`), or ``None`` if they do not fit."""
        if self._packed is None and self._packing is not None:
            keys = pack_boxes(self._box[:, :self._n], self._packing)
            if keys is not None:  # as long as the box storage: room to append
                self._packed = np.empty(self._box.shape[1], dtype=np.int64)
                self._packed[:self._n] = keys
        return None if self._packed is None else self._packed[:self._n]

    def _only(self, row: Mapping[str, np.ndarray], b: np.ndarray) -> None:
        self._set({k: self._row(row, k)[None, :].copy() for k in self._rows}, b[:, None])

    # ---- ev-MOGA's rules (docs/concepts/evmoga.md) -------------------------------------------

    def offer(self, row: Mapping[str, np.ndarray]) -> None:
        """Offer one feasible child (``row[k]``: its values of each row array), recomputing the
        grid when it moves the extremes ("archive each child in turn",
        docs/concepts/evmoga.md#generation)."""
        f = np.asarray(row["F"], dtype=float).ravel()
        m = len(f)
        if self._n == 0 and self.grid_min is None:
            self.set_grid(f, f)
            self._only(row, np.zeros(m, dtype=np.int64))
            return
        a = int(np.count_nonzero(f >= self.grid_max))
        b = int(np.count_nonzero(f <= self.grid_min))
        if a == 0 and b == 0:
            self.insert(row)
        elif a == m and b == 0:
            return
        elif a == 0 and b == m:  # dominates the whole archive: A = {child}, min = max = f
            eps = self.eps
            self.set_grid(f, f)
            self.eps = eps
            f_min, _, eps = self._grid()
            self._only(row, box_index(f, f_min, eps)[0])
        else:
            F = self.F
            lower, higher = F[:, 0] < f[0], F[:, 0] > f[0]  # column by column: no axis-1 reduce
            for j in range(1, m):
                lower |= F[:, j] < f[j]
                higher |= F[:, j] > f[j]
            if np.any(lower & ~higher):  # a member dominates the child
                return
            gone = higher & ~lower  # members the child dominates
            if gone.any():
                self._take(~gone)
            both = np.vstack([self.F, f])
            self.set_grid(both.min(axis=0), both.max(axis=0))
            self._rebuild(changed_only=True)
            self.insert(row)

    def offer_many(self, rows: Mapping[str, np.ndarray]) -> None:
        """Offer feasible children (``rows[k]``: 2-D arrays, one row per child) in order: the
        same archive as :meth:`offer` on each in turn.

        Children strictly inside the grid (``min < f < max`` in every objective) do not move it,
        and inserting a run of them on a fixed grid is the re-insertion :meth:`_rebuild` makes
        (the module docstring's characterisation holds for any items in any order: cases 1, 2
        and 4 depend on boxes only, so the surviving boxes are the minimal boxes of the members
        and the children, in the order of their first item, each holding the case-3 fold over
        its items in order). So each run of at least :attr:`BATCH` such children is appended
        and settled by one vectorised rebuild in which only the children's boxes are new; the
        others are offered one at a time.
        """
        F = np.asarray(rows["F"], dtype=float)
        n, i = len(F), 0
        while i < n:
            if self.grid_min is None or self._n == 0:
                self.offer({k: v[i] for k, v in rows.items()})
                i += 1
                continue
            rest = F[i:]
            f_min, f_max, _ = self._grid()
            inside = np.ones(len(rest), dtype=bool)
            for j in range(rest.shape[1]):
                inside &= (rest[:, j] < f_max[j]) & (rest[:, j] > f_min[j])
            end = i + (int(inside.argmin()) if not inside.all() else len(rest))
            if end - i >= self.BATCH:
                self._insert_batch({k: v[i:end] for k, v in rows.items()})
            else:
                for c in range(i, end):
                    self.insert({k: v[c] for k, v in rows.items()})
            if end < n:  # a child on or outside the grid's edge: the sequential rules
                self.offer({k: v[end] for k, v in rows.items()})
            i = end + 1

    #: Shortest run of children inside the grid that :meth:`offer_many` inserts in one pass.
    BATCH = 24

    def _insert_batch(self, rows: Mapping[str, np.ndarray]) -> None:
        """Insert children (2-D rows) in order on the current grid, which none of them moves:
        appended with an impossible box (-1), so the rebuild compares only pairs with a child."""
        k, n = len(rows["F"]), self._n
        need = n + k
        if need > self._box.shape[1]:
            cap = max(16, 2 * need)
            self._rows = {key: np.concatenate([v[:n], np.empty((cap - n, v.shape[1]))])
                          for key, v in self._rows.items()}
            self._box = np.concatenate([self._box[:, :n],
                                        np.empty((self._box.shape[0], cap - n), np.int64)],
                                       axis=1)
        for key, v in self._rows.items():
            v[n:need] = np.asarray(rows[key], dtype=float).reshape(k, v.shape[1])
        self._box[:, n:need] = -1
        self._n = need
        self._packed = None
        self._rebuild(changed_only=True)

    def insert(self, row: Mapping[str, np.ndarray]) -> bool:
        """Insert with the current grid (insertion cases 1-4, docs/concepts/evmoga.md#insertion);
        return whether the child entered."""
        f = np.asarray(row["F"], dtype=float).ravel()
        f_min, _, eps = self._grid()
        b = box_index(f, f_min, eps)[0]
        if self._n == 0:
            self._append(row, b)
            return True
        Bt = self._box[:, :self._n]
        packed, packing = self._packed_boxes(), self._packing
        packed_b = None if packed is None or packing is None else pack_box(b, packing)
        if packed_b is None:
            below = np.flatnonzero(_all_le(Bt, b))  # members whose box is <= the child's
        else:  # the same test on packed boxes (box_packing)
            assert packed is not None and packing is not None
            guard = packing[2]
            below = np.flatnonzero((((packed_b | guard) - packed) & guard) == guard)
        if len(below):
            if not (Bt[:, below] == b[:, None]).all():
                return False  # case 1: the child's box is dominated
            # case 3: the one member of the child's box (nothing for case 2 to delete)
            k = int(below[0])
            if not challenger_wins(f, self.F[k], b, f_min, eps):
                return False
            for key, v in self._rows.items():
                v[k] = self._row(row, key)
            return True
        if packed_b is None:  # case 2 (equal boxes are excluded above)
            gone = Bt[0] >= b[0]
            for j in range(1, len(b)):
                gone &= Bt[j] >= b[j]
        else:
            assert packed is not None
            gone = (((packed | guard) - packed_b) & guard) == guard
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
        if self._n:
            raise ValueError("fill needs an empty archive")
        F = np.asarray(rows["F"], dtype=float)
        self._set({k: np.array(rows[k], dtype=float) for k in self._rows},
                  np.zeros((F.shape[1], len(F)), dtype=np.int64))
        self._rebuild(changed_only=False)

    def _rebuild(self, changed_only: bool) -> None:
        """Re-insert the members, in order, into an empty archive on the current grid (vectorised
        equivalent of the re-insertion loop of docs/concepts/evmoga.md#generation, see
        :meth:`fill`). With ``changed_only`` the stored boxes are the members' boxes on the
        previous grid, where they were distinct and mutually non-dominated: only pairs with a
        member whose box changed are compared."""
        n, F = self._n, self.F
        old = self._box[:, :n]
        new = self._box_columns(F)
        changed = (new != old).any(axis=0) if changed_only else np.ones(n, dtype=bool)
        if n < 2 or not changed.any():
            self._box, self._packed = new, None
            return
        keys, first, group = np.unique(_box_keys(new), return_index=True, return_inverse=True)
        group = group.ravel()
        changed_box = np.zeros(len(keys), dtype=bool)
        changed_box[group[changed]] = True
        keep = np.flatnonzero(~dominated_boxes(new[:, first], changed_box))
        keep = keep[_stable_argsort(first[keep])]  # order of first appearance
        winner = first[keep]
        sizes = np.bincount(group, minlength=len(keys))
        crowded = np.flatnonzero(sizes[keep] > 1)
        if len(crowded):  # fold case 3 over each crowded box's items, in order
            f_min, _, eps = self._grid()
            members = _stable_argsort(group)  # items grouped by box, in order
            bounds = np.r_[0, np.cumsum(sizes)]
            for i in crowded:
                g = keep[i]
                queue = members[bounds[g]:bounds[g + 1]]
                k = queue[0]
                for c in queue[1:]:
                    if challenger_wins(F[c], F[k], new[:, c], f_min, eps):
                        k = c
                winner[i] = k
        if len(winner) == n and np.array_equal(winner, np.arange(n)):
            self._box, self._packed = new, None
        else:
            self._take(winner, new)
