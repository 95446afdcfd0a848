"""The vectorised "update P with each child" of ev-MOGA equals the per-child rule of
docs/concepts/evmoga.md.

Oracle: ``per_child_update`` below, the per-child loop ``EvMOGA._advance`` ran before (git
8c4e08e): each child draws a random start, scans P (as edited by the earlier children) circularly
for the first member it dominates feasibility-first (``constrained_dominates``) and replaces it.
On random streams of 2 to 6 objectives with ties, duplicates, infeasible members and children
(equal and infinite violations, NaN objectives of failed evaluations), the vectorised
``replacements`` must leave P bit for bit the same and the random generator in the same state.
"""

from __future__ import annotations

import numpy as np
import pytest

from casadrone.optimise.evmoga import (
    constrained_dominance_matrix,
    constrained_dominates,
    replacements,
)


def per_child_update(pop_F, pop_cv, pop_id, F, cv, ids, random_state) -> None:
    """The per-child P update of git 8c4e08e (edits ``pop_F``, ``pop_cv``, ``pop_id``)."""
    n = len(pop_F)
    for i in range(len(F)):
        start = int(random_state.integers(n))
        hit = np.flatnonzero(constrained_dominates(F[i], cv[i], pop_F, pop_cv))
        if len(hit):
            later = hit[hit >= start]
            j = int(later[0] if len(later) else hit[0])
            pop_id[j] = ids[i]
            pop_F[j], pop_cv[j] = F[i], cv[i]


def random_solutions(rng: np.random.Generator, n: int, m: int, levels: int, pool=None):
    """``n`` solutions with objectives on ``levels`` values per objective (ties), a share of them
    infeasible (violations on few values, some infinite with NaN objectives), and some copied from
    ``pool`` (duplicates)."""
    F = rng.integers(0, levels, size=(n, m)).astype(float) + rng.choice([0.0, 0.5], size=(n, 1))
    cv = np.where(rng.random(n) < rng.random(), rng.integers(1, 4, size=n) * 0.25, 0.0)
    failed = rng.random(n) < 0.1
    cv[failed] = np.inf
    F[failed] = np.where(rng.random((failed.sum(), m)) < 0.5, np.nan, F[failed])
    if pool is not None and len(pool[0]):
        copy = np.flatnonzero(rng.random(n) < 0.2)
        src = rng.integers(len(pool[0]), size=len(copy))
        F[copy], cv[copy] = pool[0][src], pool[1][src]
    return F, cv


@pytest.mark.parametrize("seed", range(12))
def test_vectorised_update_equals_the_per_child_rule(seed):
    rng = np.random.default_rng(seed)
    changed = 0
    for _ in range(40):
        m = int(rng.integers(2, 7))
        n, c = int(rng.integers(1, 70)), 2 * int(rng.integers(1, 40))
        levels = int(rng.integers(2, 6))
        pop_F, pop_cv = random_solutions(rng, n, m, levels)
        F, cv = random_solutions(rng, c, m, levels, pool=(pop_F, pop_cv))
        # children also copy earlier children: a child may meet an equal one in a slot
        dup = np.flatnonzero(rng.random(c) < 0.15)
        dup = dup[dup > 0]
        src = rng.integers(0, dup) if len(dup) else dup
        F[dup], cv[dup] = F[src], cv[src]
        stream = int(rng.integers(2**32))

        ref_F, ref_cv, ref_id = pop_F.copy(), pop_cv.copy(), -1 - np.arange(n)
        ref_rs = np.random.default_rng(stream)
        per_child_update(ref_F, ref_cv, ref_id, F, cv, np.arange(c), ref_rs)

        new_rs = np.random.default_rng(stream)
        taken = replacements(pop_F, pop_cv, F, cv, new_rs)
        new_F, new_cv, new_id = pop_F.copy(), pop_cv.copy(), -1 - np.arange(n)
        for j, i in taken.items():
            new_F[j], new_cv[j], new_id[j] = F[i], cv[i], i

        np.testing.assert_array_equal(new_id, ref_id)
        assert new_F.tobytes() == ref_F.tobytes()
        assert new_cv.tobytes() == ref_cv.tobytes()
        assert new_rs.bit_generator.state == ref_rs.bit_generator.state
        assert new_rs.random() == ref_rs.random()
        changed += len(taken)
    assert changed > 0  # the streams do replace members


@pytest.mark.parametrize("seed", range(4))
def test_dominance_matrix_equals_the_row_rule(seed):
    rng = np.random.default_rng(100 + seed)
    for m in range(2, 7):
        A_F, A_cv = random_solutions(rng, 30, m, 3)
        B_F, B_cv = random_solutions(rng, 25, m, 3, pool=(A_F, A_cv))
        D = constrained_dominance_matrix(A_F, A_cv, B_F, B_cv)
        rows = np.array([constrained_dominates(f, v, B_F, B_cv)
                         for f, v in zip(A_F, A_cv, strict=True)])
        np.testing.assert_array_equal(D, rows)
        assert D.any() and not D.all()


def test_dominance_matrix_equals_the_row_rule_on_large_sets():
    """Hundreds of columns (several 64-bit words), ties, duplicates, infeasible columns with NaN
    objectives, and feasible non-finite objectives (the pairwise path)."""
    rng = np.random.default_rng(7)
    for t in range(30):
        m = int(rng.integers(2, 7))
        A_F, A_cv = random_solutions(rng, int(rng.integers(1, 300)), m, int(rng.integers(2, 9)))
        B_F, B_cv = random_solutions(rng, int(rng.integers(1, 400)), m, int(rng.integers(2, 9)),
                                     pool=(A_F, A_cv))
        if t % 5 == 0:  # a feasible row or column with an infinite objective
            A_F[0, 0], A_cv[0] = -np.inf, 0.0
            B_F[-1, -1], B_cv[-1] = np.inf, 0.0
        D = constrained_dominance_matrix(A_F, A_cv, B_F, B_cv)
        rows = np.array([constrained_dominates(f, v, B_F, B_cv)
                         for f, v in zip(A_F, A_cv, strict=True)])
        np.testing.assert_array_equal(D, rows, err_msg=str(t))
