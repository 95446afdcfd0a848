"""Worker processes that end with their coordinator, whatever kills it.

A pool worker whose coordinator is killed (SIGKILL, SIGTERM from ``timeout`` or a batch
scheduler, an out-of-memory kill) would otherwise live on, holding its memory, until its next
task fails. :func:`worker_init` is the pool's initialiser: on Linux it asks the kernel to kill the
worker when its parent dies (``prctl(PR_SET_PDEATHSIG, SIGKILL)``), and on every platform a daemon
thread polls the parent pid and ends the worker when it changes (re-parented: the coordinator is
gone). Workers ignore SIGINT: Ctrl-C reaches the whole foreground process group, and it is the
coordinator's to handle (it records the interruption and stops the pool), not each worker's to
print a traceback about.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

#: Seconds between two looks at the parent pid (the fallback where prctl is unavailable).
POLL_S = 0.25
_PR_SET_PDEATHSIG = 1


def _kernel_death_signal() -> None:
    """Linux: SIGKILL this process when its parent dies (no-op elsewhere or on failure)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def _watch(parent_pid: int) -> None:
    while True:
        if os.getppid() != parent_pid:
            os._exit(0)
        time.sleep(POLL_S)


def worker_init(parent_pid: int) -> None:
    """Pool initialiser: end this worker when the process ``parent_pid`` is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _kernel_death_signal()
    if os.getppid() != parent_pid:  # the parent died before we got here
        os._exit(0)
    threading.Thread(target=_watch, args=(parent_pid,), name="casadrone-lifeline",
                     daemon=True).start()
