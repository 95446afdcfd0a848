"""Independent tasks side by side: in this process, in spawned processes on this machine, or on
a Dask cluster beyond it.

A pool maps a module-level function over rows of arguments and yields the results **in input
order** as they arrive, so what a caller builds from them does not depend on the pool or on
which task ended first. The limit lap's independent starts and grid-round solves run on one
(:mod:`casadrone.limit.parallel`); the optimiser's evaluation backends
(:mod:`casadrone.optimise.backends`) make their processes and Dask clients here.

CPU: a task is run through :func:`_timed`, which returns the worker's pid and its process CPU
time before and after, so the pool knows what its workers spent wherever they run
(:meth:`ProcessPool.worker_cpu_s`): a spawned worker counts from its start (its imports and
set-up included), a worker of a cluster that is not ours from its first task for us.
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from typing import Any, Protocol

from casadrone.lifeline import worker_init


class Pool(Protocol):
    """What a caller of independent tasks needs: how many run at once, an ordered map, the CPU
    its workers spent, and close."""

    workers: int

    def map(self, fn: Callable[..., Any], rows: Iterable[tuple]) -> Iterator[Any]: ...

    def worker_cpu_s(self) -> float: ...

    def close(self) -> None: ...


def usable_cores() -> int:
    """The CPUs this process may run on (its affinity where the platform says, else the
    machine's count)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def spawn_executor(workers: int, context: Any = None) -> ProcessPoolExecutor:
    """A pool of ``workers`` spawned processes (no fork: CasADi and BLAS are not fork-safe) that
    end with this process (:func:`casadrone.lifeline.worker_init`); ``context`` another
    spawn context (:class:`casadrone.optimise.mainguard.SpawnWithoutMainContext`)."""
    return ProcessPoolExecutor(workers, mp_context=context or multiprocessing.get_context("spawn"),
                               initializer=worker_init, initargs=(os.getpid(),))


def dask_client(workers: int, scheduler: str | None = None) -> tuple[Any, Any]:
    """(client, cluster): a client of the Dask scheduler at ``scheduler``, or of a new
    LocalCluster of ``workers`` single-threaded worker processes (then also returned, to be
    closed; None otherwise). Dask is an optional extra, imported here only."""
    from distributed import Client, LocalCluster

    if scheduler:
        return Client(scheduler), None
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    return Client(cluster), cluster


def _timed(fn: Callable[..., Any], *args: Any) -> tuple[Any, int, float, float]:
    """``fn(*args)``, this worker's pid, and its process CPU time (s) before and after."""
    c0 = time.process_time()
    out = fn(*args)
    return out, os.getpid(), c0, time.process_time()


class _WorkerCpu:
    """CPU seconds per worker pid, from each one's tasks (:func:`_timed`): a worker counts from
    0 (its whole life, imports included) when ``own`` (spawned for this pool), else from the
    start of its first task seen here."""

    def __init__(self, own: bool):
        self.own = own
        self.first: dict[int, float] = {}
        self.last: dict[int, float] = {}

    def record(self, pid: int, start: float, end: float) -> None:
        self.first.setdefault(pid, 0.0 if self.own else start)
        self.last[pid] = max(end, self.last.get(pid, 0.0))

    def total(self) -> float:
        return sum(self.last[p] - self.first[p] for p in self.last)


def _unwrap(timed: Iterable[tuple[Any, int, float, float]], cpu: _WorkerCpu) -> Iterator[Any]:
    for out, pid, start, end in timed:
        cpu.record(pid, start, end)
        yield out


class SerialPool:
    """Every task in this process, one after the other (its CPU is this process's own)."""

    workers = 1

    def map(self, fn: Callable[..., Any], rows: Iterable[tuple]) -> Iterator[Any]:
        return (fn(*row) for row in rows)

    def worker_cpu_s(self) -> float:
        return 0.0

    def close(self) -> None:
        pass


class ProcessPool:
    """``workers`` spawned processes on this machine (:func:`spawn_executor`), started when the
    first tasks arrive and kept for later maps until :meth:`close`."""

    def __init__(self, workers: int):
        self.workers = workers
        self.executor = spawn_executor(workers)
        self.cpu = _WorkerCpu(own=True)

    def map(self, fn: Callable[..., Any], rows: Iterable[tuple]) -> Iterator[Any]:
        rows = list(rows)
        futures = [self.executor.submit(_timed, fn, *row) for row in rows]
        return _unwrap((f.result() for f in futures), self.cpu)

    def worker_cpu_s(self) -> float:
        return self.cpu.total()

    def close(self) -> None:
        self.executor.shutdown(wait=True, cancel_futures=True)


class DaskPool:
    """The workers of a Dask cluster: the scheduler at ``scheduler``, or a LocalCluster of
    ``workers`` processes (:func:`dask_client`). Tasks are submitted impure (each runs)."""

    def __init__(self, workers: int = 1, scheduler: str | None = None):
        self.client, self.cluster = dask_client(workers, scheduler)
        self.workers = max(1, len(self.client.scheduler_info()["workers"]))
        self.cpu = _WorkerCpu(own=self.cluster is not None)

    def map(self, fn: Callable[..., Any], rows: Iterable[tuple]) -> Iterator[Any]:
        futures = [self.client.submit(_timed, fn, *row, pure=False) for row in rows]
        return _unwrap((f.result() for f in futures), self.cpu)

    def worker_cpu_s(self) -> float:
        return self.cpu.total()

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def pool_spec(text: str) -> tuple[int, str | None]:
    """(workers, Dask scheduler address or None) of a command line's ``--workers``: a whole
    number of processes (at least 1), or a scheduler's address (``tcp://host:port``: its
    cluster's workers). ValueError says what is wrong."""
    if "://" in text:
        return 1, text
    try:
        n = int(text)
    except ValueError:
        raise ValueError(f"{text!r} is neither a number of processes nor a Dask scheduler "
                         "address (tcp://host:port)") from None
    if n < 1:
        raise ValueError(f"{n}: at least 1 process")
    return n, None


def make_pool(workers: int = 1, scheduler: str | None = None) -> Pool:
    """The pool of ``workers`` (1: this process; more: spawned processes), or of the Dask
    scheduler at ``scheduler`` ("local": a LocalCluster of ``workers`` processes)."""
    if scheduler:
        return DaskPool(workers, None if scheduler == "local" else scheduler)
    return ProcessPool(workers) if workers > 1 else SerialPool()
