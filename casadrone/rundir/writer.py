"""A generation's files written behind the next generation's evaluation.

After a generation the coordinator has three things to store, in this order: its evaluations and
statistics (``history.sqlite``), the checkpoint (the algorithm pickled *by the coordinator*, at
the end of the generation) and its row of ``timings.csv``. Writing them costs little CPU but
waits on the disk (sqlite's and the checkpoint's fsyncs: 10-25 ms a generation at paper scale,
more on a busy disk), so :class:`GenerationWriter` writes them in one background thread while the
coordinator goes on with the next generation, whose evaluation takes ~0.7 s.

What the files say is unchanged: one generation's writes at a time, in the order above, each
atomic (one sqlite transaction; temporary file and rename), so a run killed anywhere, even in the
middle of them, finds a history that holds every generation up to its checkpoint's and resumes
exactly as before. A failed write is raised in the coordinator at its next :meth:`submit` or at
:meth:`close`, and nothing after it is written; :meth:`close` waits for the writes in flight
(the runner calls it before it releases the run's lock, marks a run completed, or lets a signal
end the process).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from casadrone.results import Record
from casadrone.rundir.store import RunStore
from casadrone.rundir.timings import append_timings


class GenerationWriter:
    """Writes generations (history, checkpoint, timings row) of ``store`` in the background, one
    at a time; ``background=False`` writes each at once in :meth:`submit` (same files)."""

    def __init__(self, store: RunStore, background: bool = True):
        self.store, self.background = store, background
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None

    def submit(self, generation: int, records: list[Record], stats: dict, checkpoint: bytes,
               timings: dict) -> float:
        """Write one generation: its history rows and statistics, then the ``checkpoint``
        (pickled state), then its ``timings`` row with ``write_s`` (the seconds these writes
        took) added. Waits for the previous generation's writes first; returns the seconds it
        waited (0 when they were done)."""
        waited = self.wait()
        job = self._job(generation, records, stats, checkpoint, timings)
        if self.background:
            self._thread = threading.Thread(target=self._run, args=(job,), daemon=True,
                                            name=f"casadrone-writer-{generation}")
            self._thread.start()
        else:
            job()
        return waited

    def wait(self) -> float:
        """Wait for the writes in flight; raise the error of a failed one. Returns the seconds
        waited."""
        start = time.perf_counter()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join()
        if self._error is not None:
            error, self._error = self._error, None
            raise error
        return time.perf_counter() - start

    def close(self, raise_errors: bool = True) -> None:
        """Wait for the writes in flight (their error raised only with ``raise_errors``)."""
        try:
            self.wait()
        except BaseException:
            if raise_errors:
                raise

    def _job(self, generation: int, records: list[Record], stats: dict, checkpoint: bytes,
             timings: dict) -> Callable[[], None]:
        def job() -> None:
            start = time.perf_counter()
            self.store.write_generation(generation, records, stats)
            self.store.write_checkpoint(checkpoint)
            took = time.perf_counter() - start
            row = {**timings, "write_s": took}
            if not self.background:  # the coordinator waited for the writes: its history step
                row.update(history_s=row["history_s"] + took, wall_s=row["wall_s"] + took,
                           coordinator_s=row["coordinator_s"] + took)
            append_timings(self.store.path, row)
        return job

    def _run(self, job: Callable[[], None]) -> None:
        try:
            job()
        except BaseException as exc:  # noqa: BLE001 (handed to the coordinator)
            self._error = exc
