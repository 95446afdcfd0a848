"""The run directory (DESIGN.md §9): everything needed to read, report and resume a run.

- ``config.yaml``: the fully resolved problem;
- ``manifest.json``: config hash, seed, versions, git revision, host, backend, times, status;
- ``history.sqlite``: one row per evaluation (generation, θ, indices, status, stage, reason, wall
  time) and one per generation (evaluations, archive size, feasible fraction, hypervolume, time),
  written by the coordinating process only;
- ``checkpoint.pkl``: the algorithm after the last stored generation, replaced atomically;
- ``pareto.csv``: the final Pareto set and front, one column per variable and objective.

A generation's rows are written in one transaction *before* its checkpoint, and re-writing a
generation first deletes its rows: a run killed anywhere resumes from the checkpoint, evaluates the
next generation again and ends with each evaluation exactly once.
"""

from __future__ import annotations

import csv
import datetime as _dt
import hashlib
import json
import os
import pickle
import platform
import socket
import sqlite3
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import yaml

from casadrone.optimise.problem import Record
from casadrone.problemconfig import ProblemConfig

CONFIG, MANIFEST, HISTORY, CHECKPOINT, PARETO = (
    "config.yaml", "manifest.json", "history.sqlite", "checkpoint.pkl", "pareto.csv")


class RunInProgress(RuntimeError):
    """Another live process coordinates this run directory."""


def _alive(pid: int) -> bool:
    """Whether a process with this pid exists (and is not a zombie)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] != "Z"
    except (OSError, IndexError):
        return True


def now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def git_revision() -> str | None:
    """The casadrone checkout's git revision, if it is one."""
    root = Path(__file__).resolve().parents[2]
    try:
        out = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=5, check=True)
        return out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None


def versions() -> dict[str, str]:
    import casadi
    import numpy
    import pymoo

    from casadrone import __version__

    return {"casadrone": __version__, "casadi": casadi.__version__,
            "pymoo": pymoo.__version__, "numpy": numpy.__version__,
            "python": platform.python_version()}


def snapshot_inputs(problem: ProblemConfig, path: Path) -> ProblemConfig:
    """Copy the airframe, track and controller files (and a frozen gain's reference airframe)
    into ``path/inputs/`` and point the problem at the copies (relative to the run directory), so
    resuming or reporting a run never depends on files edited after it started."""
    import shutil

    from casadrone.configio import CONFIG_DIR, read_yaml, resolve_config

    if problem.test_problem is not None:
        return problem
    inputs = path / "inputs"
    inputs.mkdir(exist_ok=True)
    sources = {
        "airframe": resolve_config(problem.airframe, "airframes"),
        "track": Path(problem.track or CONFIG_DIR / "tracks" / "paper-rectangle.yaml"),
        "controller": resolve_config(problem.controller or "default", "controllers"),
    }
    updates = {}
    for key, src in sources.items():
        dst = inputs / f"{key}.yaml"
        if key == "controller":
            data = read_yaml(src)
            ref = data.get("reference_airframe")
            if ref:
                ref_path = Path(ref) if Path(ref).is_absolute() else src.parent / ref
                if not ref_path.is_file():
                    ref_path = resolve_config(ref, "airframes")
                shutil.copyfile(ref_path, inputs / "reference_airframe.yaml")
                data["reference_airframe"] = "reference_airframe.yaml"
            dst.write_text(f"# copied from {src}\n" + yaml.safe_dump(data, sort_keys=False))
        else:
            shutil.copyfile(src, dst)
        updates[key] = Path("inputs") / dst.name
    return problem.model_copy(update=updates)


def resolved_yaml(problem: ProblemConfig) -> str:
    """The resolved problem as YAML (paths as absolute strings)."""
    return yaml.safe_dump(json.loads(problem.model_dump_json()), sort_keys=False)


@dataclass
class RunStore:
    """A run directory."""

    path: Path

    # -- creation and opening --------------------------------------------------------------

    @classmethod
    def create(cls, path: str | Path, problem: ProblemConfig, variable_names: list[str],
               index_names: list[str], backend: str) -> RunStore:
        """Start a new run directory (refuses one that already holds a run)."""
        path = Path(path)
        if (path / MANIFEST).exists():
            raise FileExistsError(f"{path}: already holds a run; resume it with "
                                  f"'casadrone resume {path}' or choose another --out")
        path.mkdir(parents=True, exist_ok=True)
        problem = snapshot_inputs(problem, path)
        text = resolved_yaml(problem)
        (path / CONFIG).write_text(text)
        store = cls(path)
        store.write_manifest({
            "config_hash": hashlib.sha256(text.encode()).hexdigest(),
            "problem": problem.name, "seed": problem.seed, "versions": versions(),
            "git_revision": git_revision(), "host": socket.gethostname(),
            "platform": platform.platform(), "python_executable": sys.executable,
            "backend": backend, "started": now(), "finished": None, "status": "running",
            "variables": variable_names, "indices": index_names,
        })
        with store.connect() as db:
            cols = ", ".join(f'"{n}" REAL' for n in variable_names + index_names)
            db.execute(f"CREATE TABLE evaluations (generation INTEGER, idx INTEGER, {cols}, "
                       "status TEXT, stage TEXT, reason TEXT, wall_time_s REAL, "
                       "PRIMARY KEY (generation, idx))")
            db.execute("CREATE TABLE generations (generation INTEGER PRIMARY KEY, "
                       "n_evaluations INTEGER, archive_size INTEGER, feasible_fraction REAL, "
                       "hypervolume REAL, elapsed_s REAL)")
        return store

    def connect(self) -> sqlite3.Connection:
        return sqlite3.connect(self.path / HISTORY, timeout=30)

    @property
    def manifest(self) -> dict:
        return json.loads((self.path / MANIFEST).read_text())

    def write_manifest(self, data: dict) -> None:
        tmp = self.path / (MANIFEST + ".tmp")
        tmp.write_text(json.dumps(data, indent=2))
        os.replace(tmp, self.path / MANIFEST)

    def update_manifest(self, **changes) -> None:
        self.write_manifest({**self.manifest, **changes})

    def problem(self) -> ProblemConfig:
        """The resolved problem of this run (its input files from the run's own ``inputs/``)."""
        from casadrone.configio import load

        return load(ProblemConfig, self.path / CONFIG)

    # -- history ----------------------------------------------------------------------------

    def write_generation(self, generation: int, records: list[Record], stats: dict) -> None:
        """Store one generation's evaluations and statistics in one transaction."""
        m = self.manifest
        names = m["variables"] + m["indices"]
        cols = ", ".join(f'"{n}"' for n in names)
        marks = ", ".join("?" for _ in range(len(names) + 6))
        rows = [
            (generation, i, *[r.theta.get(n) for n in m["variables"]],
             *[r.indices.get(n) for n in m["indices"]], r.status, r.stage, r.reason,
             r.wall_time_s)
            for i, r in enumerate(records)
        ]
        with self.connect() as db:
            db.execute("DELETE FROM evaluations WHERE generation >= ?", (generation,))
            db.execute("DELETE FROM generations WHERE generation >= ?", (generation,))
            db.executemany(f"INSERT INTO evaluations (generation, idx, {cols}, status, stage, "
                           f"reason, wall_time_s) VALUES ({marks})", rows)
            db.execute("INSERT INTO generations VALUES (?, ?, ?, ?, ?, ?)",
                       (generation, stats["n_evaluations"], stats["archive_size"],
                        stats["feasible_fraction"], stats["hypervolume"], stats["elapsed_s"]))

    def history(self) -> list[dict]:
        """All evaluations, ordered by generation and position."""
        with self.connect() as db:
            db.row_factory = sqlite3.Row
            return [dict(r) for r in db.execute(
                "SELECT * FROM evaluations ORDER BY generation, idx")]

    def generations(self) -> list[dict]:
        with self.connect() as db:
            db.row_factory = sqlite3.Row
            return [dict(r) for r in db.execute("SELECT * FROM generations ORDER BY generation")]

    # -- one coordinator at a time ----------------------------------------------------------

    def acquire(self) -> None:
        """Take the run's lock (``run.lock`` holding this pid): a second ``run``/``resume`` on a
        directory whose coordinator is still alive is refused; a dead coordinator's (killed) lock
        is taken over."""
        lock = self.path / "run.lock"
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            try:
                pid = int(lock.read_text().strip() or 0)
            except (OSError, ValueError):
                pid = 0
            if pid and pid != os.getpid() and _alive(pid):
                raise RunInProgress(f"{self.path}: run in progress (coordinator pid {pid}); "
                                   "wait for it or kill it before resuming") from None
            lock.write_text(str(os.getpid()))
            return
        with os.fdopen(fd, "w") as fh:
            fh.write(str(os.getpid()))

    def release(self) -> None:
        (self.path / "run.lock").unlink(missing_ok=True)

    # -- checkpoint and front -----------------------------------------------------------------

    def save_checkpoint(self, state: dict) -> None:
        """Pickle the run state and replace the checkpoint atomically."""
        tmp = self.path / (CHECKPOINT + ".tmp")
        with open(tmp, "wb") as fh:
            pickle.dump(state, fh, protocol=pickle.HIGHEST_PROTOCOL)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, self.path / CHECKPOINT)

    def load_checkpoint(self) -> dict:
        with open(self.path / CHECKPOINT, "rb") as fh:
            return pickle.load(fh)

    def write_pareto(self, variable_names, objective_names, X, values) -> Path:
        """Write ``pareto.csv``: variables then objectives (in their own units and sense)."""
        out = self.path / PARETO
        tmp = out.with_suffix(".csv.tmp")
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(list(variable_names) + list(objective_names))
            for x, f in zip(X, values, strict=True):
                w.writerow([repr(float(v)) for v in (*x, *f)])
        os.replace(tmp, out)
        return out

    def read_pareto(self) -> tuple[list[str], list[list[float]]]:
        with open(self.path / PARETO, newline="") as fh:
            rows = list(csv.reader(fh))
        return rows[0], [[float(v) for v in r] for r in rows[1:]]
