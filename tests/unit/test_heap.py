"""casadrone.heap: the command line's malloc settings keep freed workspace for the next request.

Oracle: the kernel's count of minor page faults (getrusage) while a 48 MB buffer, above glibc's
largest mmap threshold as MUMPS's workspace is, is allocated with malloc, written and freed ten
times: fresh pages every time by default, the same heap pages after keep_heap.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

PROBE = """
import ctypes, resource, sys
libc = ctypes.CDLL(None)
libc.malloc.restype = ctypes.c_void_p
libc.malloc.argtypes = [ctypes.c_size_t]
libc.free.argtypes = [ctypes.c_void_p]
libc.memset.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t]
if sys.argv[1] == "keep":
    from casadrone.heap import keep_heap
    assert keep_heap()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(10):  # as a Fortran ALLOCATE of MUMPS's workspace: malloc, written, freed
    buf = libc.malloc(48_000_000)
    libc.memset(buf, 1, 48_000_000)
    libc.free(buf)
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt")
def test_keep_heap_reuses_freed_workspace():
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    faults = {}
    for mode in ("default", "keep"):
        out = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True,
                             text=True, check=True)
        faults[mode] = int(out.stdout.split()[-1])
    pages = 10 * 48_000_000 // os.sysconf("SC_PAGE_SIZE")
    assert faults["default"] > 0.5 * pages  # fresh pages each time: the cost removed
    assert faults["keep"] < 0.2 * pages  # the first allocation's pages only
