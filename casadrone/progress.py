"""What a long call is doing while it does it: progress events the library emits and its caller
shows (docs/getting-started.md, "Progress and quiet output").

The library stays free of printing: a long step calls :func:`emit` with a topic and one line of
text (a limit-lap start with its lap, iterations and CPU; a co-design start; a report section;
a compile). Without a listener nothing happens, except for a compile (``topic="compile"``),
which goes to stderr as it always did: a minute of silence there reads as a hang. The caller
decides where the lines go: the command line installs :func:`printer` on stderr with
:func:`listening` (nothing under ``-q``), a test installs a list's ``append``.

Nesting: a step that runs a whole call of its own inside (a limit lap inside a co-design start,
a grid-continuation start's lap on another grid) runs it under :func:`nested`, so its events
carry a larger ``depth``; :func:`printer` shows the outermost call's (depth 0) and every compile.

Processes: events of a worker process do not reach the parent (the listener lives in one
process); a caller that runs steps in workers emits its event in the parent as each result
returns (:mod:`casadrone.precompile` does).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import IO


@dataclass(frozen=True)
class Event:
    """One progress event: what (``topic``: "compile", "start", "round", "stage", ...), one line
    of text, how deep inside nested calls it was emitted (0: the outermost), and its numbers
    (e.g. ``lap_s``, ``iterations``, ``cpu_s``) for a listener that wants them."""

    topic: str
    text: str
    depth: int = 0
    values: dict[str, float] = field(default_factory=dict)


Listener = Callable[[Event], None]

#: The listener of this process (one at a time; :func:`listening` restores the one before).
#: A process-wide variable, not a context variable: events of a helper thread (a compile
#: waited for off the main thread) reach it too.
_listener: Listener | None = None
_DEPTH: ContextVar[int] = ContextVar("casadrone_progress_depth", default=0)

#: Topics shown on stderr even with no listener installed (the library's old behaviour).
ALWAYS = frozenset({"compile"})


def emit(topic: str, text: str, **values: float) -> None:
    """Tell the listener (if any) that ``text`` happened; a compile without a listener goes to
    stderr. Cheap when nobody listens: build expensive text only when :func:`active`."""
    event = Event(topic, text, _DEPTH.get(), dict(values))
    if _listener is not None:
        _listener(event)
    elif topic in ALWAYS:
        print(f"casadrone: {text}", file=sys.stderr, flush=True)


def active() -> bool:
    """Whether a listener is installed (so a caller may skip composing text nobody reads)."""
    return _listener is not None


@contextmanager
def listening(listener: Listener | None) -> Iterator[None]:
    """Send the events of the block to ``listener`` (None: to nobody, compiles included)."""
    global _listener
    before = _listener
    _listener = listener if listener is not None else _discard
    try:
        yield
    finally:
        _listener = before


def _discard(event: Event) -> None:
    """The listener of ``-q``: every event, compiles included, dropped."""


def silence() -> None:
    """Drop every event of this process from now on (a quiet command's worker processes: a
    process pool's ``initializer``)."""
    global _listener
    _listener = _discard


@contextmanager
def nested() -> Iterator[None]:
    """Run the block one level deeper: its events carry ``depth + 1``."""
    token = _DEPTH.set(_DEPTH.get() + 1)
    try:
        yield
    finally:
        _DEPTH.reset(token)


def cpu_seconds() -> float:
    """CPU seconds of this process and of the children it has waited for (a compiler, a
    finished worker), user and system, and of the live workers a :func:`counting` block
    declares: what the command has cost so far."""
    t = os.times()
    return t.user + t.system + children_cpu_seconds() + sum(f() for f in _WORKERS)


#: CPU (s) of live worker processes, one function per pool in a :func:`counting` block.
_WORKERS: list[Callable[[], float]] = []


@contextmanager
def counting(worker_cpu_s: Callable[[], float]) -> Iterator[None]:
    """Count ``worker_cpu_s()`` (the CPU so far of workers this process has not waited for:
    a live pool's, :meth:`casadrone.pool.ProcessPool.worker_cpu_s`) in :func:`cpu_seconds`
    during the block, so that the progress lines' CPU is the command's, not this process's
    alone. The pool is closed after the block: its reaped workers then count as children."""
    _WORKERS.append(worker_cpu_s)
    try:
        yield
    finally:
        _WORKERS.remove(worker_cpu_s)


def children_cpu_seconds() -> float:
    """CPU seconds, user and system, of the child processes this one has waited for."""
    t = os.times()
    return t.children_user + t.children_system


def printer(prefix: str, stream: IO[str] | None = None, max_depth: int = 0) -> Listener:
    """A listener printing one line per event of depth ≤ ``max_depth`` (and every compile) as
    ``PREFIX: text [CPU c s, wall w s]``, CPU and wall time counted from this call (CPU:
    :func:`cpu_seconds`)."""
    cpu0, wall0 = cpu_seconds(), time.perf_counter()

    def show(event: Event) -> None:
        if event.depth > max_depth and event.topic not in ALWAYS:
            return
        out = stream if stream is not None else sys.stderr
        print(f"{prefix}: {event.text} [CPU {cpu_seconds() - cpu0:.1f} s, wall "
              f"{time.perf_counter() - wall0:.1f} s]", file=out, flush=True)

    return show
