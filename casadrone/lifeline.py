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
import threading
import time

from casadrone.parentdeath import die_with_parent

#: Seconds between two looks at the parent pid (the fallback where prctl is unavailable).
POLL_S = 0.25
def _watch(parent_pid: int) -> None:
    while True:
        if os.getppid() != parent_pid:
            os._exit(0)
        time.sleep(POLL_S)


def worker_init(parent_pid: int) -> None:
    """Pool initialiser: end this worker when the process ``parent_pid`` is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent()
    if os.getppid() != parent_pid:  # the parent died before we got here
        os._exit(0)
    threading.Thread(target=_watch, args=(parent_pid,), name="casadrone-lifeline",
                     daemon=True).start()
