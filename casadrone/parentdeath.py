"""A process that the kernel ends when its parent dies (Linux), for the processes casadrone
forks or spawns: pool workers (:mod:`casadrone.lifeline`) and guarded solves
(:mod:`casadrone.limit.watchdog`)."""

from __future__ import annotations

import signal
import sys

#: Linux's prctl option that sends a signal to this process when its parent dies.
_PR_SET_PDEATHSIG = 1


def die_with_parent() -> None:
    """Linux: SIGKILL this process when its parent dies (``prctl(PR_SET_PDEATHSIG)``); a no-op
    elsewhere or where prctl is missing. The caller checks ``os.getppid()`` afterwards: a parent
    that died before the call is not signalled."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass
