"""Where a build's combinations are co-designed side by side: this process, a spawn process pool
(as :class:`casadrone.optimise.backends.ProcessBackend`), or a Dask cluster (a scheduler's
address, or a LocalCluster), chosen by the problem's ``backend`` section.

One interface for the three: :meth:`Pool.submit` a task, :meth:`Pool.first_done` waits for at
least one and returns the finished ones; a task is a picklable function of picklable arguments.
"""

from __future__ import annotations

import multiprocessing
import os
from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import Any

from casadrone.config.problem import BackendConfig
from casadrone.lifeline import worker_init


class Pool:
    """A pool of ``workers`` for the ``backend`` asked for (module docstring)."""

    def __init__(self, backend: BackendConfig):
        self.name = backend.name
        self.workers = 1 if backend.name == "serial" else backend.workers
        self.executor: Any = None
        self.client: Any = None
        self.cluster: Any = None
        if backend.name == "processes":
            self.executor = ProcessPoolExecutor(
                backend.workers, mp_context=multiprocessing.get_context("spawn"),
                initializer=worker_init, initargs=(os.getpid(),))
        elif backend.name == "dask":
            from distributed import Client, LocalCluster

            if backend.scheduler:
                self.client = Client(backend.scheduler)
            else:
                self.cluster = LocalCluster(n_workers=backend.workers, threads_per_worker=1,
                                            processes=True, dashboard_address=None)
                self.client = Client(self.cluster)
            self.workers = max(1, len(self.client.scheduler_info()["workers"]))

    def submit(self, fn: Callable[..., Any], *args: Any) -> Any:
        """A future of ``fn(*args)`` (this process: done when returned)."""
        if self.client is not None:
            return self.client.submit(fn, *args, pure=False)
        if self.executor is not None:
            return self.executor.submit(fn, *args)
        done: Future = Future()
        done.set_result(fn(*args))
        return done

    def first_done(self, futures: list[Any]) -> list[Any]:
        """The finished ones of ``futures``, waiting until at least one is."""
        if self.client is not None:
            from distributed import wait as dask_wait

            return list(dask_wait(futures, return_when="FIRST_COMPLETED").done)
        return list(wait(futures, return_when=FIRST_COMPLETED).done)

    def close(self) -> None:
        if self.executor is not None:
            self.executor.shutdown(cancel_futures=True)
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()
