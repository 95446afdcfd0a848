"""Componentwise comparison as bitsets (casadrone.optimise.bitsets) equals the pairwise one."""

from __future__ import annotations

import numpy as np

from casadrone.optimise.bitsets import BLOCK, points_below, unpack


def brute(Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    if len(Q) == 0 or len(P) == 0:
        return np.zeros((len(Q), len(P)), dtype=bool)
    return (P[None, :, :] <= Q[:, None, :]).all(axis=2)


def test_points_below_equals_pairwise_comparison():
    """Ties (coarse values, queries equal to points, -0.0 against 0.0, infinities), 1 to 6
    columns, point counts around word edges and query counts beyond one block."""
    rng = np.random.default_rng(0)
    sizes = [(0, 5), (5, 0), (1, 1), (3, 63), (3, 64), (3, 65), (BLOCK + 7, 129)]
    for t in range(150):
        m = int(rng.integers(1, 7))
        nq, n = sizes[t] if t < len(sizes) else (int(rng.integers(0, 400)),
                                                int(rng.integers(0, 300)))
        P = rng.normal(size=(n, m))
        Q = rng.normal(size=(nq, m))
        if t % 3 == 0:
            P, Q = np.round(P), np.round(Q)  # many exact ties; round gives -0.0 and 0.0
        if t % 7 == 0 and n and nq:
            P[rng.integers(n)] = np.inf
            Q[rng.integers(nq)] = -np.inf
        k = min(n, nq) // 2
        Q[:k] = P[:k]
        bits = points_below(Q, P)
        assert bits.shape == (nq, -(-n // 64)) and bits.dtype == np.uint64
        got = unpack(bits, n)
        np.testing.assert_array_equal(got, brute(Q, P), err_msg=str((t, m, nq, n)))
        assert got[np.arange(k), np.arange(k)].all()  # a point is below itself


def test_unpack_reads_bit_k_of_word_k_over_64():
    words = np.zeros((2, 2), dtype=np.uint64)
    words[0, 0] = np.uint64(1) << np.uint64(3)
    words[1, 1] = np.uint64(1) << np.uint64(63)
    out = unpack(words, 128)
    assert out.shape == (2, 128)
    assert list(np.flatnonzero(out[0])) == [3] and list(np.flatnonzero(out[1])) == [127]
    assert unpack(words, 100).shape == (2, 100)
