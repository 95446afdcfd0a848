"""The vectorised ε-box archive (casadrone.optimise.boxarchive) equals the sequential one.

Oracle: ``SequentialArchive`` below is the archive code ev-MOGA used before the archive was
vectorised (``casadrone/optimise/evmoga.py`` at git 683f05d: ``_archive``, ``_insert``,
``_centre_distance``), kept verbatim on pymoo ``Population`` objects, with a thin adapter to the
``BoxArchive`` interface; its box index is computed here (:func:`reference_box_index`), not
imported from the code under test.
Random streams of children (2 to 6 objectives, coarse grids, exact ties,
duplicates, grid moves, children dominating the whole archive, constant objectives) are offered to
both; after every child the members (all row arrays, bit for bit, in order), their boxes and the
grid must be identical. Whole ev-MOGA runs with either archive must give the same archive too.
"""

from __future__ import annotations

import numpy as np
import pytest
from pymoo.core.individual import Individual
from pymoo.core.population import Population
from pymoo.problems import get_problem
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

from casadrone.optimise.boxarchive import (
    BoxArchive,
    _stable_argsort,
    box_dominates,
    box_index,
    box_packing,
    dominated_boxes,
    pack_box,
    pack_boxes,
    pareto_dominates,
    pareto_dominates_rows,
)
from casadrone.optimise.evmoga import ROW_KEYS, EvMOGA, constrained_dominates

KEYS = ("X", "F", "G", "H", "CV")


# ---------------------------------------------------------------------------------------------
# the oracle: the sequential archive of git 683f05d, verbatim, plus an adapter
# ---------------------------------------------------------------------------------------------


def reference_box_index(F: np.ndarray, f_min: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """The ε-box of each row of ``F``, element by element from the definition of
    docs/concepts/evmoga.md#boxes, ``ceil((f - min) / ε)`` (0 where ε = 0), the ratio rounded to
    6 decimals first (floating noise must not move a point across a box edge). Written here, not
    imported: the oracle must not share the code it checks."""
    F = np.atleast_2d(np.asarray(F, float))
    width = np.asarray(eps, float)
    boxes = np.ceil(np.round((F - f_min) / np.where(width > 0.0, width, 1.0), 6))
    return np.where(width > 0.0, boxes, 0.0).astype(np.int64)


def box_dominates_rows(B: np.ndarray, b: np.ndarray) -> np.ndarray:
    B = np.atleast_2d(B)
    return (B <= b).all(axis=1) & (B != b).any(axis=1)


class SequentialArchive:
    """The archive rules of docs/concepts/evmoga.md, one member at a time (the code before
    vectorisation)."""

    def __init__(self, n_div, widths) -> None:
        self.n_div = np.asarray(n_div, dtype=np.int64)
        self.widths = dict(widths)
        m = len(self.n_div)
        self.archive_pop = Population.empty()
        self.archive_F = np.empty((0, m))
        self.archive_box = np.empty((0, m), dtype=np.int64)
        self.grid_min = self.grid_max = self.eps = None
        self.counts = dict.fromkeys(
            ("rebuild", "rebuild_same_box", "rebuild_rejected", "rebuild_deleted", "dominates_all",
             "same_box_replaced", "same_box_kept", "deleted"), 0)
        self._rebuilding = False

    # -- adapter ---------------------------------------------------------------------------

    def __len__(self) -> int:
        return len(self.archive_pop)

    @property
    def rows(self) -> dict[str, np.ndarray]:
        n = len(self.archive_pop)
        return {k: np.asarray(self.archive_pop.get(k), dtype=float).reshape(n, self.widths[k])
                for k in self.widths}

    @property
    def F(self) -> np.ndarray:
        return self.archive_F

    @property
    def box(self) -> np.ndarray:
        return self.archive_box

    def set_grid(self, f_min, f_max) -> None:
        self._set_grid(f_min, f_max)

    @staticmethod
    def individual(row) -> Individual:
        return Individual(**{k: np.array(v, float) for k, v in row.items()})

    def offer(self, row) -> None:
        self._archive(self.individual(row), np.array(row["F"], float))

    def fill(self, rows) -> None:
        for i in range(len(rows["F"])):
            row = {k: v[i] for k, v in rows.items()}
            self._insert(self.individual(row), np.array(row["F"], float))

    # -- verbatim (self.archive_pop etc. as in EvMOGA; counters added) ----------------------

    def _set_grid(self, f_min: np.ndarray, f_max: np.ndarray) -> None:
        self.grid_min = np.array(f_min, dtype=float)
        self.grid_max = np.array(f_max, dtype=float)
        self.eps = (self.grid_max - self.grid_min) / self.n_div

    def _set_archive(self, pop: Population, F: np.ndarray, box: np.ndarray) -> None:
        self.archive_pop, self.archive_F, self.archive_box = pop, F, box

    def _archive(self, ind: Individual, f: np.ndarray) -> None:
        m = len(f)
        if len(self.archive_pop) == 0 and self.grid_min is None:
            self._set_grid(f, f)
            self._set_archive(
                Population.create(ind), f[None, :].copy(), np.zeros((1, m), dtype=np.int64)
            )
            return
        a = int(np.sum(f >= self.grid_max))
        b = int(np.sum(f <= self.grid_min))
        if a == 0 and b == 0:
            self._insert(ind, f)
        elif a == m and b == 0:
            return
        elif a == 0 and b == m:
            self.counts["dominates_all"] += 1
            eps = self.eps
            self._set_grid(f, f)
            self.eps = eps
            self._set_archive(
                Population.create(ind), f[None, :].copy(),
                reference_box_index(f, self.grid_min, self.eps),
            )
        else:
            if np.any(pareto_dominates_rows(self.archive_F, f)):
                return
            self.counts["rebuild"] += 1
            keep = ~pareto_dominates(f, self.archive_F)
            pop, F = self.archive_pop[keep], self.archive_F[keep]
            both = np.vstack([F, f])
            self._set_grid(both.min(axis=0), both.max(axis=0))
            self._set_archive(Population.empty(), np.empty((0, m)), np.empty((0, m), np.int64))
            self._rebuilding = True
            for k in range(len(pop)):
                self._insert(pop[k], F[k])
            self._rebuilding = False
            self._insert(ind, f)

    def _insert(self, ind: Individual, f: np.ndarray) -> bool:
        b = reference_box_index(f, self.grid_min, self.eps)[0]
        B = self.archive_box
        if len(B) and np.any(box_dominates_rows(B, b)):
            self.counts["rebuild_rejected"] += self._rebuilding
            return False  # case 1: x's box is dominated
        same = np.flatnonzero((B == b).all(axis=1)) if len(B) else np.empty(0, dtype=int)
        if len(same):  # case 3 (the invariant leaves nothing for case 2 to delete)
            self.counts["rebuild_same_box"] += self._rebuilding
            k = int(same[0])
            f_k = self.archive_F[k]
            if pareto_dominates(f, f_k)[0]:
                replace = True
            elif pareto_dominates(f_k, f)[0] or np.array_equal(f, f_k):
                replace = False
            else:
                replace = self._centre_distance(f, b) < self._centre_distance(f_k, b)
            if replace:
                self.archive_pop[k] = ind
                self.archive_F[k] = f
            self.counts["same_box_replaced" if replace else "same_box_kept"] += 1
            return replace
        keep = ~box_dominates(b, B) if len(B) else np.ones(0, dtype=bool)  # case 2
        self.counts["rebuild_deleted" if self._rebuilding else "deleted"] += int((~keep).sum())
        self._set_archive(  # case 4
            Population.merge(self.archive_pop[keep], Population.create(ind)),
            np.vstack([self.archive_F[keep], f]),
            np.vstack([B[keep], b]),
        )
        return True

    def _centre_distance(self, f: np.ndarray, b: np.ndarray) -> float:
        centre = self.grid_min + (b - 0.5) * self.eps
        positive = self.eps > 0.0
        d = np.where(positive, (f - centre) / np.where(positive, self.eps, 1.0), 0.0)
        return float(np.linalg.norm(d))


# ---------------------------------------------------------------------------------------------
# random streams
# ---------------------------------------------------------------------------------------------


def random_front(rng: np.random.Generator, n: int, m: int) -> np.ndarray:
    """Points near a curved front (many mutually non-dominated), some of them quantised."""
    d = np.abs(rng.normal(size=(n, m)))
    p = rng.choice([0.5, 1.0, 2.0])
    F = d / np.linalg.norm(d, ord=p, axis=1, keepdims=True)
    F *= 1.0 + 0.2 * rng.random((n, 1)) * rng.choice([0.0, 1.0])
    return F


def child_stream(rng: np.random.Generator, n: int, m: int) -> np.ndarray:
    """Children: front points, coarse-quantised points (exact ties and box edges), duplicates,
    near-duplicates, points far outside the grid, points stretching the grid (rebuilds that merge
    boxes), points below everything, and constant objectives."""
    F = random_front(rng, n, m)
    kind = rng.choice(8, size=n, p=[0.35, 0.1, 0.04, 0.03, 0.07, 0.01, 0.25, 0.15])
    quant = rng.choice([0.05, 0.1, 0.25])
    F[kind == 1] = np.round(F[kind == 1] / quant) * quant
    F[kind == 2] *= rng.uniform(0.3, 1.8, size=(int((kind == 2).sum()), 1))  # grid moves
    F[kind == 3] = rng.uniform(-0.5, 1.5, size=(int((kind == 3).sum()), m))
    dup = np.flatnonzero(kind == 4)
    dup = dup[dup > 0]
    F[dup] = F[rng.integers(0, dup)]  # an earlier child again
    low = np.flatnonzero(kind == 5)
    F[low] = F[low] - rng.uniform(0.0, 1.5, size=(len(low), 1))  # may dominate all
    near = np.flatnonzero(kind == 6)
    near = near[near > 0]
    F[near] = F[rng.integers(0, near)] + rng.normal(0.0, 0.03, size=(len(near), m))
    for i in np.flatnonzero(kind == 7):  # stretch all objectives but one up, that one down
        k = rng.integers(m)
        F[i] *= rng.uniform(2.0, 30.0)
        F[i, k] /= rng.uniform(3.0, 20.0)
    if rng.random() < 0.15:
        F[:, rng.integers(m)] = 0.5  # a constant objective: eps_j = 0
    return F


def rows_of(F: np.ndarray, rng: np.random.Generator, n_var: int = 3) -> dict[str, np.ndarray]:
    n = len(F)
    return {"X": np.column_stack([np.arange(n, dtype=float), rng.random((n, n_var - 1))]),
            "F": F, "G": -rng.random((n, 1)), "H": np.empty((n, 0)), "CV": np.zeros((n, 1))}


WIDTHS = {"X": 3, "F": None, "G": 1, "H": 0, "CV": 1}


def archive_pair(rng: np.random.Generator, most_div: int) -> tuple[int, BoxArchive,
                                                                   SequentialArchive]:
    """2 to 6 objectives, divisions per objective or one for all; both archives, empty."""
    m = int(rng.integers(2, 7))
    n_div = (rng.integers(2, 14, size=m) if rng.random() < 0.5
             else np.full(m, rng.integers(2, most_div)))
    widths = {**WIDTHS, "F": m}
    return m, BoxArchive(n_div, widths), SequentialArchive(n_div, widths)


def fill_from(P: np.ndarray, rng: np.random.Generator, *archives) -> None:
    """Start like ev-MOGA: P's non-dominated front on its own grid."""
    nd = np.sort(NonDominatedSorting().do(P, only_non_dominated_front=True))
    rows = {k: v[nd] for k, v in rows_of(P, rng).items()}
    for a in archives:
        a.set_grid(rows["F"].min(axis=0), rows["F"].max(axis=0))
        a.fill(rows)


def assert_same(fast: BoxArchive, slow: SequentialArchive, where: str) -> None:
    assert len(fast) == len(slow), where
    for k in KEYS:
        np.testing.assert_array_equal(fast.rows[k], slow.rows[k], err_msg=f"{where}: {k}")
    np.testing.assert_array_equal(fast.box, slow.box, err_msg=f"{where}: box")
    for name in ("grid_min", "grid_max", "eps"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name),
                                      err_msg=f"{where}: {name}")


@pytest.mark.parametrize("seeds", [
    range(0, 50),
    pytest.param(range(50, 1000), marks=pytest.mark.slow),
])
def test_random_streams_equal_the_sequential_archive(seeds):
    totals: dict[str, int] = {}
    n_children = 0
    for seed in seeds:
        rng = np.random.default_rng(seed)
        m, fast, slow = archive_pair(rng, 30)
        if rng.random() < 0.7:
            fill_from(child_stream(rng, int(rng.integers(1, 60)), m), rng, fast, slow)
            assert_same(fast, slow, f"seed {seed}, initial fill")
        F = child_stream(rng, int(rng.integers(50, 250)), m)
        rows = rows_of(F, rng)
        for i in range(len(F)):
            row = {k: v[i] for k, v in rows.items()}
            fast.offer(row)
            slow.offer(row)
            assert_same(fast, slow, f"seed {seed}, m {m}, child {i}")
        n_children += len(F)
        for k, v in slow.counts.items():
            totals[k] = totals.get(k, 0) + v
    # the streams exercised every rule, rebuilds with collisions included
    assert n_children > 5_000
    assert all(v >= 8 for k, v in totals.items() if k != "rebuild_same_box"), str(totals)
    assert totals["rebuild_same_box"] >= 1, str(totals)


def test_grid_stretches_that_merge_boxes_equal_the_sequential_archive():
    """A populated archive, then children that widen the grid by 1.2-3x: members that held
    neighbouring boxes share one after the rebuild (the case-3 contest inside a rebuild)."""
    merged = 0
    for seed in range(12):
        rng = np.random.default_rng(1000 + seed)
        m = int(rng.integers(2, 5))
        widths = {**WIDTHS, "F": m}
        n_div = np.full(m, int(rng.integers(10, 40)))
        fast, slow = BoxArchive(n_div, widths), SequentialArchive(n_div, widths)
        F = random_front(rng, 300, m)
        # above the grid in all objectives but one, below it in that one: every ε grows
        stretch = F.max(axis=0) * rng.uniform(1.1, 2.5, size=(6, m))
        stretch[np.arange(6), rng.integers(0, m, size=6)] = -rng.uniform(0.1, 1.5, size=6)
        F = np.vstack([F, stretch, random_front(rng, 60, m)])
        rows = rows_of(F, rng)
        for i in range(len(F)):
            row = {k: v[i] for k, v in rows.items()}
            fast.offer(row)
            slow.offer(row)
            assert_same(fast, slow, f"seed {seed}, child {i}")
        merged += slow.counts["rebuild_same_box"]
    assert merged >= 50


def test_fill_equals_sequential_inserts_on_large_fronts():
    """The vectorised rebuild on fronts of thousands of points (blocks of candidate pairs)."""
    contests = 0
    for seed, (n, m, div) in enumerate([(3000, 5, 200), (2000, 3, 40), (1500, 6, 15),
                                        (1000, 2, 50), (800, 4, 1)]):
        rng = np.random.default_rng(100 + seed)
        F = random_front(rng, n, m)
        if seed == 2:
            F = np.round(F, 2)  # many exact ties
        nd = np.sort(NonDominatedSorting().do(F, only_non_dominated_front=True))
        rows = {k: v[nd] for k, v in rows_of(F, rng).items()}
        widths = {**WIDTHS, "F": m}
        fast, slow = BoxArchive(np.full(m, div), widths), SequentialArchive(np.full(m, div), widths)
        for a in (fast, slow):
            a.set_grid(rows["F"].min(axis=0), rows["F"].max(axis=0) * 1.3)
            a.fill(rows)
        assert 0 < len(fast) < len(nd)
        assert_same(fast, slow, f"n {n} m {m}")
        contests += slow.counts["same_box_replaced"] + slow.counts["same_box_kept"]
    assert contests > 300  # many boxes held several points: the case-3 fold ran


@pytest.mark.parametrize("seeds", [
    range(0, 60),
    pytest.param(range(60, 600), marks=pytest.mark.slow),
])
def test_offer_many_equals_offering_each_child_in_turn(seeds):
    """Offering a generation's children at once (runs inside the grid inserted by one
    vectorised rebuild, runs as short as one child) ends, after each batch, with the archive
    the sequential oracle reaches offering them one by one: rows bit for bit, order, boxes and
    grid. Batches start from a filled archive or an empty one, and mix grid moves, children
    dominating everything, duplicates, ties, constant objectives and large fronts."""
    calls: list[int] = []
    for seed in seeds:
        rng = np.random.default_rng(5000 + seed)
        m, fast, slow = archive_pair(rng, 60)
        fast.BATCH = int(rng.choice([1, 2, 5, 24]))
        fast._insert_batch = lambda rows, a=fast: (calls.append(len(rows["F"])),
                                                   BoxArchive._insert_batch(a, rows))
        if rng.random() < 0.7:
            fill_from(random_front(rng, int(rng.integers(1, 300)), m), rng, fast, slow)
        for batch in range(int(rng.integers(1, 5))):
            if rng.random() < 0.5:
                F = child_stream(rng, int(rng.integers(1, 200)), m)
            else:  # mostly inside the grid: long runs
                F = random_front(rng, int(rng.integers(1, 400)), m) * rng.uniform(0.95, 1.1)
            rows = rows_of(F, rng)
            fast.offer_many(rows)
            for i in range(len(F)):
                slow.offer({k: v[i] for k, v in rows.items()})
            assert_same(fast, slow, f"seed {seed}, m {m}, batch {batch}")
    assert sum(calls) > 20 * len(seeds)  # most children went through the vectorised path


def test_box_index_equals_the_reference_on_edges_noise_and_zero_widths():
    """Rows on box edges (exact multiples of ε, ± noise below the rounding), inside boxes and at
    the minimum, with some objectives of zero width: the package's box index (vectorised) equals
    the element-by-element reference."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        m = int(rng.integers(2, 7))
        f_min, eps = rng.normal(size=m), rng.uniform(0.01, 2.0, m) * (rng.random(m) < 0.8)
        k = rng.integers(0, 30, size=(50, m))
        F = f_min + eps * (k + rng.choice([0.0, 0.5, 1e-12, -1e-12, 1e-3], size=(50, m)))
        np.testing.assert_array_equal(box_index(F, f_min, eps),
                                      reference_box_index(F, f_min, eps))


def test_dominated_boxes_against_brute_force():
    for seed in range(150):
        rng = np.random.default_rng(seed)
        m = int(rng.integers(2, 7))
        F = random_front(rng, int(rng.integers(2, 400)), m)
        nd = NonDominatedSorting().do(F, only_non_dominated_front=True)
        eps = (F.max(axis=0) - F.min(axis=0)) / rng.integers(1, 25)
        U = np.unique(reference_box_index(F[nd], F.min(axis=0), eps), axis=0)
        brute = np.array([np.any(box_dominates_rows(np.delete(U, i, axis=0), u))
                          for i, u in enumerate(U)])
        np.testing.assert_array_equal(dominated_boxes(U.T, np.ones(len(U), bool)), brute)
        # columns known not to dominate each other need not be compared among themselves
        changed = brute | (rng.random(len(U)) < 0.3)
        np.testing.assert_array_equal(dominated_boxes(U.T, changed), brute)


def test_packed_boxes_compare_like_their_entries():
    """One subtraction on packed boxes (box_packing) decides ``B <= b`` componentwise, for
    entries anywhere in their fields (0 and the largest value included); what does not fit is
    refused."""
    rng = np.random.default_rng(7)
    for _ in range(300):
        m = int(rng.integers(2, 8))
        n_div = rng.integers(1, 2 ** rng.integers(1, 9, size=m) + 1)
        packing = box_packing(n_div)
        assert packing is not None
        top = np.array([1 << w for w in packing[1]])  # entries 0 .. top - 1 fit
        assert np.all(top > n_div)
        B = rng.integers(0, top, size=(200, m))
        B[rng.random(B.shape) < 0.2] = 0
        edge = rng.random(B.shape) < 0.2
        B[edge] = np.broadcast_to(top - 1, B.shape)[edge]
        b = B[rng.integers(len(B))].copy()
        keys, key, guard = pack_boxes(B.T, packing), pack_box(b, packing), packing[2]
        np.testing.assert_array_equal((((key | guard) - keys) & guard) == guard,
                                      (B <= b).all(axis=1))
        np.testing.assert_array_equal((((keys | guard) - key) & guard) == guard,
                                      (B >= b).all(axis=1))
        bad = b.copy()
        bad[rng.integers(m)] = rng.choice([-1, top.max()]) if rng.random() < 0.5 else -1
        if (bad < 0).any() or (bad >= top).any():
            assert pack_box(bad, packing) is None
            assert pack_boxes(np.vstack([B, bad]).T, packing) is None
    assert box_packing(np.full(7, 255)) is not None  # 7 x (8 + 1) = 63 bits
    assert box_packing(np.full(7, 256)) is None


def test_stable_argsort_is_numpys_stable_argsort():
    """The 16-bit radix path gives numpy's stable int64 permutation (many ties), and values that
    do not fit 16 bits take the plain path."""
    rng = np.random.default_rng(11)
    for _ in range(200):
        high = int(rng.choice([3, 200, 2**16, 2**16 + 5, 2**40]))
        a = rng.integers(-2 if rng.random() < 0.2 else 0, high, size=int(rng.integers(0, 3000)))
        np.testing.assert_array_equal(_stable_argsort(a), np.argsort(a, kind="stable"))


@pytest.mark.parametrize("n_div", [None, 2**20])
def test_archive_without_packed_boxes_is_the_same(n_div):
    """The archive that compares packed boxes and one that cannot pack them (boxes too wide for
    63 bits, or packing switched off) take the same steps on random streams."""
    total_used = 0
    for seed in range(15):
        rng = np.random.default_rng(300 + seed)
        m = int(rng.integers(2, 7))
        divisions = np.full(m, n_div if n_div else int(rng.integers(2, 30)))
        widths = {**WIDTHS, "F": m}
        packed, plain = BoxArchive(divisions, widths), BoxArchive(divisions, widths)
        plain._packing = None
        F = child_stream(rng, int(rng.integers(50, 250)), m)
        rows = rows_of(F, rng)
        used = 0  # children offered while packed boxes were in use
        for i in range(len(F)):
            row = {k: v[i] for k, v in rows.items()}
            used += packed._packed is not None
            packed.offer(row)
            plain.offer(row)
            assert len(packed) == len(plain)
            for k in KEYS:
                assert packed.rows[k].tobytes() == plain.rows[k].tobytes(), (seed, i, k)
            np.testing.assert_array_equal(packed.box, plain.box)
        assert plain._packed is None
        fits = n_div is None or m <= 2  # 2**20 needs 21 + 1 bits per objective
        assert (packed._packing is not None) == fits
        assert fits or used == 0
        total_used += used
    if n_div is None:
        assert total_used > 500


# ---------------------------------------------------------------------------------------------
# whole runs: ev-MOGA on either archive
# ---------------------------------------------------------------------------------------------


class SequentialEvMOGA(EvMOGA):
    """ev-MOGA with the sequential archive and the P update of git 683f05d."""

    def _setup(self, problem, **kwargs) -> None:
        super()._setup(problem, **kwargs)
        self.box_archive = SequentialArchive(self.n_div, self._widths())

    def _advance(self, infills=None, **kwargs) -> None:
        from casadrone.optimise.evmoga import _violation

        F, cv = _violation(infills)
        rows = self._rows_of_children(infills)
        for i in range(len(infills)):
            if cv[i] <= 0.0:
                self.box_archive.offer({k: v[i] for k, v in rows.items()})
        n = len(self.pop_F)
        for i in range(len(infills)):
            start = int(self.random_state.integers(n))
            order = (start + np.arange(n)) % n
            hit = np.flatnonzero(
                constrained_dominates(F[i], cv[i], self.pop_F[order], self.pop_cv[order])
            )
            if len(hit):
                j = order[hit[0]]
                for key in ROW_KEYS:  # P's objectives and violation follow its rows
                    self.pop_rows[key][j] = rows[key][i]


@pytest.mark.parametrize(("name", "kwargs", "n_div", "generations", "n_ind_ga"), [
    ("zdt1", {"n_var": 4}, 10, 150, 16),
    ("zdt2", {"n_var": 3}, [7, 13], 150, 16),
    ("dtlz2", {"n_var": 6, "n_obj": 4}, 6, 60, 16),
    # generations of many children: runs inside the grid go through offer_many's batches
    ("zdt1", {"n_var": 4}, 60, 25, 200),
    ("dtlz2", {"n_var": 6, "n_obj": 3}, 25, 12, 300),
])
def test_runs_equal_the_sequential_archive(name, kwargs, n_div, generations, n_ind_ga,
                                           monkeypatch):
    problem = get_problem(name, **kwargs)
    batches: list[int] = []
    insert_batch = BoxArchive._insert_batch
    monkeypatch.setattr(BoxArchive, "_insert_batch",
                        lambda self, rows: (batches.append(1), insert_batch(self, rows))[1])
    results = []
    for cls in (EvMOGA, SequentialEvMOGA):
        alg = cls(n_ind_p=40, n_ind_ga=n_ind_ga, n_div=n_div, generations=generations)
        alg.setup(problem, seed=4)
        while alg.has_next():
            alg.next()
        results.append(alg)
    fast, slow = results
    assert slow.box_archive.counts["rebuild"] > 0
    assert (len(batches) > 10) == (n_ind_ga > BoxArchive.BATCH)
    assert_same(fast.box_archive, slow.box_archive, name)
    np.testing.assert_array_equal(fast.box_archive.rows["id"], slow.box_archive.rows["id"])
    np.testing.assert_array_equal(fast.pop.get("X"), slow.pop.get("X"))
    res = fast.result()
    np.testing.assert_array_equal(res.X, slow.box_archive.rows["X"])
    np.testing.assert_array_equal(res.F, slow.box_archive.F)


def resumes_to_the_uninterrupted_end(problem, settings: dict, seed: int, stop: int,
                                     old_format, check_loaded) -> None:
    """Run ev-MOGA ``stop`` generations, pickle it, rewrite the pickled state into an older
    revision's checkpoint format (``old_format(state, alg)``), load that (checked by
    ``check_loaded(loaded, alg)``) and run it to the end: the result (X, F in order) and P equal
    the uninterrupted run's."""
    import pickle

    full = EvMOGA(**settings)
    full.setup(problem, seed=seed)
    while full.has_next():
        full.next()
    alg = EvMOGA(**settings)
    alg.setup(problem, seed=seed)
    for _ in range(stop):
        alg.next()
    state = pickle.loads(pickle.dumps(alg)).__dict__.copy()
    old_format(state, alg)
    resumed = EvMOGA.__new__(EvMOGA)
    resumed.__setstate__(pickle.loads(pickle.dumps(state)))
    check_loaded(resumed, alg)
    while resumed.has_next():
        resumed.next()
    res, ref = resumed.result(), full.result()
    np.testing.assert_array_equal(res.X, ref.X)
    np.testing.assert_array_equal(res.F, ref.F)
    np.testing.assert_array_equal(resumed.pop.get("X"), full.pop.get("X"))


def test_checkpoint_of_the_sequential_archive_resumes_to_the_same_end():
    """A checkpoint pickled by the sequential ev-MOGA (archive_pop, archive_F, archive_box, grid
    and opt attributes; P a Population) is converted on loading and ends like the uninterrupted
    run."""
    def sequential(state, alg):
        for key in ("box_archive", "_n_seen", "_opt", "_opt_rows", "pop_rows"):
            del state[key]
        state.update(pop=alg.pop, pop_F=alg.pop_F.copy(), pop_cv=alg.pop_cv,
                     archive_pop=alg.archive_pop, archive_F=alg.archive_F.copy(),
                     archive_box=alg.archive_box.copy(), grid_min=alg.grid_min.copy(),
                     grid_max=alg.grid_max.copy(), eps=alg.eps.copy(), opt=alg.opt)

    def same_archive_size(loaded, alg):
        assert len(loaded.box_archive) == len(alg.box_archive) > 1

    resumes_to_the_uninterrupted_end(get_problem("zdt1", n_var=4),
                                     dict(n_ind_p=40, n_ind_ga=8, n_div=30, generations=80), 2,
                                     30, sequential, same_archive_size)


def test_checkpoint_of_p_as_rows_under_pop_resumes_to_the_same_end():
    """A checkpoint of git 6094a45 and before (P's rows under ``pop``, its objectives and
    violation as ``pop_F`` and ``pop_cv``, the archive's Individual cache ``_individuals``)
    loads into P's rows and ends like the uninterrupted run, on a constrained problem: a
    paper-scale run interrupted before this revision resumes after it."""
    def rows_under_pop(state, alg):
        state.update(pop=state.pop("pop_rows"), pop_F=alg.pop_F.copy(), pop_cv=alg.pop_cv,
                     _individuals={})

    def p_in_rows(loaded, alg):
        assert not {"_individuals", "pop", "pop_F", "pop_cv"} & loaded.__dict__.keys()
        assert loaded.pop_rows["X"].tobytes() == alg.pop_rows["X"].tobytes()

    resumes_to_the_uninterrupted_end(
        get_problem("bnh"), dict(n_ind_p=30, n_ind_ga=10, n_div=20, generations=40), 3, 15,
        rows_under_pop, p_in_rows)
