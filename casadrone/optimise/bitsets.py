"""Componentwise comparison of every point with every query, as bitsets (64 points a word).

``points_below(Q, P)`` answers, for each row ``q`` of ``Q``, which rows ``p`` of ``P`` satisfy
``p <= q`` in every column: per column, the points sorted by that column and, for each prefix of
that order, the set of its points (one row of words); a query's answer is the AND over the
columns of the prefix of points at or below it (found by binary search). That is
O(|Q| · m · |P| / 64) word operations after an O(m |P| log |P|) setup, against O(|Q| · |P| · m)
comparisons done pairwise, and exact: it makes the same ``<=`` comparisons, only shared.

Used for the hypervolume estimate's samples (:mod:`casadrone.optimise.hypervolume`) and for
ev-MOGA's child-over-P dominance (:mod:`casadrone.optimise.evmoga`). Values must not be NaN.
"""

from __future__ import annotations

import numpy as np

__all__ = ["points_below", "unpack"]

#: Queries answered per block (bounds the temporary words to BLOCK · |P| / 8 bytes).
BLOCK = 1024


def points_below(Q: np.ndarray, P: np.ndarray) -> np.ndarray:
    """For each row of ``Q``: the rows of ``P`` that are ``<=`` it in every column, as a bitset
    (``uint64`` words, bit ``k % 64`` of word ``k // 64`` for row ``k``), shape
    ``(len(Q), ceil(len(P) / 64))``."""
    Q, P = np.asarray(Q, float), np.asarray(P, float)
    n, words = len(P), -(-len(P) // 64)
    out = np.zeros((len(Q), words), dtype=np.uint64)
    if n == 0 or len(Q) == 0:
        return out
    bits = np.left_shift(np.uint64(1), (np.arange(n) & 63).astype(np.uint64))
    tables, values = [], []
    for j in range(P.shape[1]):
        order = np.argsort(P[:, j], kind="stable")
        table = np.zeros((n + 1, words), dtype=np.uint64)  # row r: the r lowest in column j
        table[np.arange(1, n + 1), order >> 6] = bits[order]
        tables.append(np.bitwise_or.accumulate(table, axis=0))
        values.append(P[order, j])
    for lo in range(0, len(Q), BLOCK):
        block = Q[lo:lo + BLOCK]
        acc = tables[0][np.searchsorted(values[0], block[:, 0], side="right")]
        for j in range(1, len(tables)):
            acc &= tables[j][np.searchsorted(values[j], block[:, j], side="right")]
        out[lo:lo + BLOCK] = acc
    return out


def unpack(bitsets: np.ndarray, n: int) -> np.ndarray:
    """Bitsets of :func:`points_below` as a boolean matrix ``(len(bitsets), n)``."""
    as_bytes = np.ascontiguousarray(bitsets).astype("<u8", copy=False).view(np.uint8)
    return np.unpackbits(as_bytes, axis=1, bitorder="little")[:, :n].astype(bool)
