"""A solve run in a forked child that is given up when it stops evaluating the NLP.

Why: fatrop (casadi 3.8.2 ships fatrop 1.1.8) can loop forever inside one iteration. Its search
direction (``IpSearchDirImpl::compute_search_dir``, ``ip_search_dir.hxx`` of the fatrop sources)
refactorises the KKT system in a ``while (!solved)`` loop: an indefinite system raises the
Hessian shift δ_w by a factor with no upper limit, and a rank-deficient one sets the
constraint shift to the same δ_c = δ_c,stripe·μ^κ_c on every pass. Where neither cures the
factorisation, the loop never ends and fatrop never returns (IPOPT gives up at
``max_hessian_perturbation`` instead). Observed: ``casadrone limit-lap SY250 --solver fatrop
--intervals 10`` spent minutes of CPU in that loop (py-spy: ``compute_search_dir`` →
``AugSystemSolver::solve``) without evaluating the NLP again.

A C loop cannot be interrupted from Python (signal handlers run between bytecodes), so the solve
runs in a forked child. The child calls :func:`beat` at every evaluation of the NLP's objective
and rows (every iteration and line-search trial: :class:`casadrone.limit.stagewise.Beating`);
the parent ends the child when no beat has come for ``stall_s`` seconds, a silence no finishing
solve has: an iteration of the largest NLPs casadrone builds takes well under a second (the
19-waypoint three-lap course: about 2 300 intervals). The child's CPU time comes back with its
result (``resource.RUSAGE_CHILDREN`` in the parent also counts it once it has been waited for).
On Linux the child is killed with its parent (``prctl(PR_SET_PDEATHSIG)``), so a stalled solve
never outlives a killed run. Where ``os.fork`` does not exist the solve runs in this process,
unguarded.
"""

from __future__ import annotations

import mmap
import os
import pickle
import select
import signal
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

from casadrone.parentdeath import die_with_parent

#: Seconds without an evaluation after which a guarded solve is given up (module docstring).
STALL_S = 30.0

Outcome = Literal["ok", "error", "stalled", "died"]

_BEAT: mmap.mmap | None = None  # set in a guarded child: the parent's shared heartbeat


def beat() -> None:
    """Tell the guarding parent (if any) that the solve is still evaluating the NLP."""
    if _BEAT is not None:
        struct.pack_into("d", _BEAT, 0, time.monotonic())


@dataclass(frozen=True)
class Guarded:
    """What a guarded call gave: ``outcome`` "ok" (``value`` is the call's result), "error" (the
    call raised: ``message``), "stalled" (no evaluation for ``stall_s``: ended by the parent) or
    "died" (the child ended without an answer); ``cpu_s`` the child's CPU time."""

    outcome: Outcome
    value: Any = None
    message: str = ""
    cpu_s: float = 0.0


def _child(fn: Callable[[], Any], beat_buf: mmap.mmap, w: int, parent: int) -> None:
    global _BEAT
    die_with_parent()  # a stalled solve must not outlive a killed run
    if os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)
    _BEAT = beat_buf
    c0 = time.process_time()
    try:
        payload: tuple = ("ok", fn(), "")
    except Exception as exc:  # noqa: BLE001 (every failure goes back to the parent as text)
        payload = ("error", None, f"{type(exc).__name__}: {exc}")
    data = pickle.dumps(payload + (time.process_time() - c0,))
    with os.fdopen(w, "wb") as f:
        f.write(data)


def run_guarded(fn: Callable[[], Any], stall_s: float = STALL_S, fork: bool = True) -> Guarded:
    """``fn()`` in a forked child, given up after ``stall_s`` seconds without :func:`beat`
    (``fork=False``, or no ``os.fork``: in this process, unguarded)."""
    if not fork or not hasattr(os, "fork"):
        c0 = time.process_time()
        try:
            return Guarded("ok", fn(), "", time.process_time() - c0)
        except Exception as exc:  # noqa: BLE001
            return Guarded("error", None, f"{type(exc).__name__}: {exc}",
                           time.process_time() - c0)
    beat_buf = mmap.mmap(-1, 8)
    struct.pack_into("d", beat_buf, 0, time.monotonic())
    r, w = os.pipe()
    parent = os.getpid()
    pid = os.fork()
    if pid == 0:  # the child: answer through the pipe, never return into the caller's code
        try:
            os.close(r)
            _child(fn, beat_buf, w, parent)
        finally:
            os._exit(0)
    os.close(w)
    chunks: list[bytes] = []
    stalled, ended = 0.0, False
    try:
        while True:
            ready, _, _ = select.select([r], [], [], min(1.0, stall_s / 4))
            if ready:
                chunk = os.read(r, 1 << 20)
                if not chunk:
                    ended = True
                    break
                chunks.append(chunk)
                continue
            silence = time.monotonic() - struct.unpack_from("d", beat_buf, 0)[0]
            if silence > stall_s:
                stalled = silence
                break
    finally:  # the child never outlives this call (a stall, or an interrupt of the parent)
        os.close(r)
        if not ended:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        os.waitpid(pid, 0)
        beat_buf.close()
    if stalled:
        return Guarded("stalled", None, f"no evaluation for {stalled:.0f} s: ended")
    try:
        outcome, value, message, cpu = pickle.loads(b"".join(chunks))
    except Exception:  # noqa: BLE001 (nothing, or a truncated answer: the child died)
        return Guarded("died", None, "the solve's process ended without an answer")
    return Guarded(outcome, value, message, cpu)
