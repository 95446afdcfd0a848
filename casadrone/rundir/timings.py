"""Where a run's time goes, per generation: ``timings.csv`` in the run directory.

The runner appends one row per generation after its checkpoint (so a resumed run keeps the rows of
the generations before the stop and adds its own): the wall-clock seconds of each step of the
coordinator loop, the coordinator's CPU seconds, and the archive size. A generation that ran twice
(killed after its history but before its checkpoint) keeps its last row.

Columns (seconds unless named otherwise):

- ``ask_s``: making the children (ev-MOGA's crossover and mutation);
- ``evaluate_s``: evaluating them on the backend (the parallel part);
- ``advance_s``: the algorithm's update (ev-MOGA: archive and P);
- ``statistics_s``: the progress statistics (front, hypervolume);
- ``history_s``: waiting for the writes of the generation's files (``history.sqlite``, the
  checkpoint, this row): they run in the background behind the next generation's evaluation
  (:mod:`casadrone.rundir.writer`), so this is the wait for the previous generation's, usually
  0; with ``runner.BACKGROUND_WRITES`` off, the writes of this generation;
- ``checkpoint_s``: pickling the algorithm for the checkpoint;
- ``write_s``: the seconds the writes of the generation's history and checkpoint took (in the
  background they overlap the next generation, and their CPU time falls in its evaluation step);
- ``wall_s``: the whole generation until its files are handed to the writer (the progress line
  after it is not included);
- ``cpu_s``: CPU time of the coordinating process over the generation (with the serial backend it
  includes the evaluations, except fatrop's limit-lap solves, which run in forked children:
  :mod:`casadrone.limit.watchdog`);
- ``coordinator_s``: ``wall_s - evaluate_s``;
- ``coordinator_cpu_s``: ``cpu_s`` less the coordinator's CPU time during the evaluation step.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any

TIMINGS = "timings.csv"
FIELDS = ("generation", "n_evaluations", "archive_size", "ask_s", "evaluate_s", "advance_s",
          "statistics_s", "history_s", "checkpoint_s", "wall_s", "cpu_s", "coordinator_s",
          "coordinator_cpu_s", "finished", "write_s")


def append_timings(run_dir: Path, row: dict) -> None:
    """Append one generation's row (keys of ``FIELDS``) to the run's ``timings.csv``. A file
    with other columns (a run started by an older casadrone) is first rewritten with these, the
    missing ones left empty."""
    path = Path(run_dir) / TIMINGS
    new = not path.exists()
    if not new:
        with open(path, newline="") as fh:
            header = next(csv.reader(fh), None)
        if header != list(FIELDS):
            with open(path, newline="") as fh:
                old = list(csv.DictReader(fh))
            tmp = path.with_name(f".{TIMINGS}.tmp")
            with open(tmp, "w", newline="") as fh:
                writer = csv.DictWriter(fh, fieldnames=FIELDS, extrasaction="ignore")
                writer.writeheader()
                writer.writerows(old)
            os.replace(tmp, path)
    with open(path, "a", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=FIELDS)
        if new:
            writer.writeheader()
        writer.writerow({k: row.get(k) for k in FIELDS})


def read_timings(run_dir: Path) -> list[dict]:
    """The run's per-generation rows, one per generation (the last written), in order; numbers
    as int or float. Empty if the run has none."""
    path = Path(run_dir) / TIMINGS
    if not path.exists():
        return []
    rows: dict[int, dict] = {}
    with open(path, newline="") as fh:
        for raw in csv.DictReader(fh):
            row: dict[str, Any] = {
                k: (v if k == "finished" else float(v) if v not in ("", None) else None)
                for k, v in raw.items()}
            for k in ("generation", "n_evaluations", "archive_size"):
                row[k] = int(row[k])
            rows[row["generation"]] = row
    return [rows[g] for g in sorted(rows)]
