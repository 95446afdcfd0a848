"""Where a build's combinations are co-designed side by side: this process, a spawn process pool
or a Dask cluster (a scheduler's address, or a LocalCluster), made as the limit lap's and the
optimiser's are (:func:`casadrone.pool.spawn_executor`, :func:`casadrone.pool.dask_client`),
chosen by the problem's ``backend`` section.

One interface for the three: :meth:`Pool.submit` a task, :meth:`Pool.first_done` waits for at
least one and returns the finished ones; a task is a picklable function of picklable arguments.
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import FIRST_COMPLETED, Future, wait
from typing import Any

from casadrone.config.problem import BackendConfig
from casadrone.pool import dask_client, spawn_executor


class Pool:
    """A pool of ``workers`` for the ``backend`` asked for (module docstring)."""

    def __init__(self, backend: BackendConfig):
        self.name = backend.name
        self.workers = 1 if backend.name == "serial" else backend.workers
        self.executor: Any = None
        self.client: Any = None
        self.cluster: Any = None
        if backend.name == "processes":
            self.executor = spawn_executor(backend.workers)
        elif backend.name == "dask":
            self.client, self.cluster = dask_client(backend.workers, backend.scheduler)
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
