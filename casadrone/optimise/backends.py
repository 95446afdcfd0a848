"""Evaluation backends: this process, a spawn process pool, or a Dask cluster.

Each gets a whole generation at once and returns the records in input order, so the results do
not depend on the backend. Workers receive the picklable :class:`Study` and rows of θ, and build
the evaluation chain once per process (:func:`casadrone.optimise.problem.study_setup`).
"""

from __future__ import annotations

import contextlib
import os
import pickle
from typing import Any

import numpy as np

from casadrone.config.problem import BackendConfig
from casadrone.optimise.mainguard import SpawnWithoutMainContext
from casadrone.optimise.problem import Study, evaluate_rows, study_setup
from casadrone.pool import dask_client, spawn_executor
from casadrone.results import Record


def guided_sizes(rows: int, workers: int) -> list[int]:
    """Chunk sizes for ``rows`` on ``workers``: guided self-scheduling (Polychronopoulos & Kuck
    1987). Each chunk takes ``1 / workers`` of the rows still unassigned, at least
    ``rows / (32 · workers)`` (and 2): the first round hands every worker a large share, then
    the chunks shrink geometrically, so a worker that finishes early takes small ones and the
    idle tail at the end of a generation is about one small chunk, while the chunks (pickling,
    IPC) stay few: 850 rows on 16 workers, 64 chunks of 54 down to 1 row; on 2 workers, 7
    of 425 down to 13. Against one chunk per worker it trades ~4 more round trips per worker
    (0.1 ms each) for the balance of unequal evaluation times (time-outs cost ~3× a completed
    lap): ``benchmarks/bench_backends.py`` projects 94 % vs 81 % at 16 workers."""
    min_rows = max(2, rows // (32 * max(1, workers)))
    sizes, left = [], rows
    while left > 0:
        size = min(left, max(min_rows, -(-left // max(1, workers))))
        sizes.append(size)
        left -= size
    return sizes


def guided_chunks(X: np.ndarray, workers: int) -> list[np.ndarray]:
    """Contiguous, order-preserving chunks of the rows of ``X`` with :func:`guided_sizes`."""
    edges = np.cumsum([0, *guided_sizes(len(X), max(1, workers))])
    return [X[a:b] for a, b in zip(edges[:-1], edges[1:], strict=True)]


_STUDIES: dict[str, Study] = {}  # in a worker process: studies already unpickled, by key


def _evaluate_chunk(key: str, payload: bytes, X: np.ndarray) -> list[Record]:
    """Evaluate rows of a study sent pickled once per generation (``payload``); a worker
    unpickles it the first time it sees ``key`` only."""
    study = _STUDIES.get(key)
    if study is None:
        study = _STUDIES[key] = pickle.loads(payload)
    return evaluate_rows(study, X)


class SerialBackend:
    """Evaluate in the coordinating process."""

    name = "serial"

    def evaluate(self, study: Study, X: np.ndarray) -> list[Record]:
        return evaluate_rows(study, X)

    def close(self) -> None:
        pass


def _warm(study: Study, linger_s: float = 0.0) -> int:
    """Build (and load the compiled lap of) the chain in this worker; return its pid. ``linger_s``
    keeps a fast worker busy so that the others take the remaining warm-up tasks."""
    import time

    if study.problem.test_problem is None:
        study_setup(study)
        evaluate_rows(study, np.mean(np.vstack(study.bounds), axis=0)[None, :])
    time.sleep(linger_s)
    return os.getpid()


#: Seconds a stopped run's workers get to end on SIGTERM (a compiling one kills its compiler and
#: removes its folder in milliseconds) before SIGKILL.
TERMINATE_GRACE_S = 2.0


class ProcessBackend:
    """A pool of ``workers`` spawned processes (no fork: CasADi and BLAS are not fork-safe).

    ``without_main``: the workers do not import the main script (for a script that starts the run
    outside ``if __name__ == "__main__":``, :mod:`casadrone.optimise.mainguard`)."""

    name = "processes"

    def __init__(self, workers: int, without_main: bool = False):
        self.workers = workers
        self.pool = spawn_executor(workers, SpawnWithoutMainContext() if without_main else None)
        self.warm_for: set[str] = set()

    def warm(self, study: Study) -> None:
        """Return once every worker has built the chain for ``study`` (so a generation's wall
        time is evaluation, not start-up)."""
        seen: set[int] = set()
        while len(seen) < self.workers:
            seen |= set(self.pool.map(_warm, [study] * (2 * self.workers),
                                      [0.05] * (2 * self.workers)))
        self.warm_for.add(study.key)

    def evaluate(self, study: Study, X: np.ndarray) -> list[Record]:
        """Guided chunks (:func:`guided_chunks`); the study travels pickled once per
        generation as bytes, and each worker unpickles it once."""
        if study.key not in self.warm_for:
            self.warm(study)
        key, payload = study.key, pickle.dumps(study)
        parts = guided_chunks(np.asarray(X), self.workers)
        out: list[Record] = []
        for recs in self.pool.map(_evaluate_chunk, [key] * len(parts), [payload] * len(parts),
                                  parts):
            out.extend(recs)
        return out

    def close(self) -> None:
        self.pool.shutdown(cancel_futures=True)

    def terminate(self, grace_s: float = TERMINATE_GRACE_S) -> None:
        """Stop now (the run was interrupted): end the workers, do not wait for their tasks.

        SIGTERM first: a worker ends at once, or, while it compiles, after killing its compiler
        and removing its temporary folder (:mod:`casadrone.codegen`); SIGKILL for any worker
        still alive after ``grace_s``."""
        import time

        manager = getattr(self.pool, "_executor_manager_thread", None)  # shutdown forgets it
        procs = list(getattr(self.pool, "_processes", {}).values())
        for proc in procs:
            with contextlib.suppress(OSError, ValueError):
                proc.terminate()
        deadline = time.monotonic() + grace_s
        for proc in procs:
            with contextlib.suppress(OSError, ValueError, AssertionError):
                proc.join(max(0.0, deadline - time.monotonic()))
        for proc in procs:
            with contextlib.suppress(OSError, ValueError, AssertionError):
                if proc.is_alive():
                    proc.kill()
        self.pool.shutdown(wait=False, cancel_futures=True)
        _forget_wakeup(manager)


def _forget_wakeup(thread: Any) -> None:
    """Let the interpreter exit quietly after a killed pool.

    The pool's manager thread sees the killed workers, tears the pool down and closes its wakeup
    pipe; CPython 3.11's exit hook (``concurrent.futures.process._python_exit``) then still
    writes to that pipe and prints ``OSError: [Errno 9] Bad file descriptor`` as the last line
    of an interrupted run (intermittently: it depends on which thread gets there first; 3.12
    checks for a closed pipe). So: wait briefly for the manager thread, then drop its entry from
    the exit hook's table.
    """
    import concurrent.futures.process as cfp

    if thread is None:
        return
    thread.join(timeout=5.0)
    if not thread.is_alive():
        getattr(cfp, "_threads_wakeups", {}).pop(thread, None)


class DaskBackend:
    """A Dask cluster: the scheduler at ``scheduler``, or a LocalCluster of ``workers``
    single-threaded worker processes.

    The study is scattered once (to every worker) and its future is held by the backend until
    :meth:`close`, so back-to-back generations reuse one live key: scattering it again per call
    raced with the previous call's release of the same content-hashed key
    (``FutureCancelledError``). Tasks are pure functions of (study, rows): when a worker dies
    mid-generation the scheduler re-runs its tasks on the others and the results are the same.
    """

    name = "dask"

    def __init__(self, workers: int, scheduler: str | None = None):
        self.client, self.cluster = dask_client(workers, scheduler)
        self.workers = max(1, len(self.client.scheduler_info()["workers"]))
        self.warm_for: set[str] = set()
        self.scattered: dict = {}  # study key -> future of the scattered study, kept alive

    def evaluate(self, study: Study, X: np.ndarray) -> list[Record]:
        if study.key not in self.warm_for:  # every worker builds the chain once, up front
            self.client.run(_warm, study)
            self.warm_for.add(study.key)
        if study.key not in self.scattered:
            self.scattered[study.key] = self.client.scatter(study, broadcast=True, hash=False)
        study_f = self.scattered[study.key]
        workers = max(1, len(self.client.scheduler_info()["workers"]))
        parts = guided_chunks(np.asarray(X), workers)
        futures = self.client.map(evaluate_rows, [study_f] * len(parts), parts, pure=False)
        out: list[Record] = []
        for recs in self.client.gather(futures):
            out.extend(recs)
        return out

    def close(self) -> None:
        self.scattered.clear()
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_backend(cfg: BackendConfig, without_main: bool = False) -> Any:
    """The backend a problem's ``backend`` section asks for (``without_main``: see
    :class:`ProcessBackend`)."""
    if cfg.name == "serial":
        return SerialBackend()
    if cfg.name == "processes":
        return ProcessBackend(cfg.workers, without_main)
    return DaskBackend(cfg.workers, cfg.scheduler)
