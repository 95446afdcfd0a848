"""The C heap of a solver process: keep what MUMPS frees for its next factorization.

IPOPT factorises its KKT matrix with MUMPS at least once per iteration, and MUMPS allocates its
workspace anew each time (IPOPT asks for ten times MUMPS's own estimate, ``mumps_mem_percent``
1000: 35 MB on the paper track's 40-interval limit lap). glibc's malloc serves a request above
its mmap threshold (at most 32 MB) with fresh pages from the kernel and returns them on free, so
every factorization faulted its workspace in again: measured on the paper track's cold limit lap
(182 iterations), 373 000 page faults and 1.25 s of system time, with the first touch of each
page (a memset) in the user time as well. With mmap off and the heap kept, the same solve took
32 000 page faults and 0.22 s of system time, the same lap to the last bit (the allocator only
chooses addresses; benchmarks/RESULTS-codesign.md, "The fastest frame's CPU").

:func:`keep_heap` is process-wide (the allocator is), so it is the command line's to call: the
process is casadrone's. A library user may call it for a solver-heavy process of their own.
"""

from __future__ import annotations

import sys

#: mallopt parameters (glibc's malloc.h)
M_TRIM_THRESHOLD = -1
M_MMAP_MAX = -4
#: Free memory at the top of the heap is returned to the kernel beyond this (bytes): above the
#: workspace of any limit lap measured, below mallopt's int range.
TRIM_THRESHOLD = 1 << 30


def keep_heap() -> bool:
    """Serve every allocation from the heap (no mmap) and keep up to :data:`TRIM_THRESHOLD` of
    freed memory for the next request. True when glibc's ``mallopt`` took both settings; False
    elsewhere (another C library or platform: nothing changes)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    return bool(mallopt(M_MMAP_MAX, 0)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
