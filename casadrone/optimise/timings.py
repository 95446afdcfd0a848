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
- ``history_s``: writing the generation to ``history.sqlite``;
- ``checkpoint_s``: pickling and writing the checkpoint;
- ``wall_s``: the whole generation (the progress line after it is not included);
- ``cpu_s``: CPU time of the coordinating process over the generation (with the serial backend it
  includes the evaluations);
- ``coordinator_s``: ``wall_s - evaluate_s``;
- ``coordinator_cpu_s``: ``cpu_s`` less the coordinator's CPU time during the evaluation step.
"""

from __future__ import annotations

import csv
from pathlib import Path

TIMINGS = "timings.csv"
FIELDS = ("generation", "n_evaluations", "archive_size", "ask_s", "evaluate_s", "advance_s",
          "statistics_s", "history_s", "checkpoint_s", "wall_s", "cpu_s", "coordinator_s",
          "coordinator_cpu_s", "finished")


def append_timings(run_dir: Path, row: dict) -> None:
    """Append one generation's row (keys of ``FIELDS``) to the run's ``timings.csv``."""
    path = Path(run_dir) / TIMINGS
    new = not path.exists()
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
            row = {k: (v if k == "finished" else float(v) if v not in ("", None) else None)
                   for k, v in raw.items()}
            for k in ("generation", "n_evaluations", "archive_size"):
                row[k] = int(row[k])
            rows[row["generation"]] = row
    return [rows[g] for g in sorted(rows)]
