"""Chunking of a generation for the process and Dask backends."""

import numpy as np
import pytest

from casadrone.optimise.backends import guided_chunks, guided_sizes


@pytest.mark.parametrize("rows", [0, 1, 3, 8, 17, 850, 1700])
@pytest.mark.parametrize("workers", [1, 2, 3, 16, 64])
def test_guided_chunks_cover_rows_in_order(rows, workers):
    X = np.arange(rows * 2, dtype=float).reshape(rows, 2)
    parts = guided_chunks(X, workers)
    assert all(len(p) >= 1 for p in parts)
    np.testing.assert_array_equal(np.vstack([X[:0], *parts]), X)
    sizes = guided_sizes(rows, workers)
    assert [len(p) for p in parts] == sizes
    # non-increasing (but the remainder at the end), the first chunk one worker's share
    assert all(a >= b for a, b in zip(sizes[:-2], sizes[1:-1], strict=True))
    if sizes:
        assert sizes[0] <= max(2, -(-rows // workers))


def test_guided_chunks_per_worker_stay_few_and_tail_small():
    """850 rows on 16 workers: a handful of chunks per worker, the last ones a few rows."""
    sizes = guided_sizes(850, 16)
    assert len(sizes) <= 5 * 16
    assert max(sizes[-16:]) <= 2
    assert sizes[0] == 54
