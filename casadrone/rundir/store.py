"""The run directory (docs/architecture.md#runs): everything needed to read, report and resume a
run.

- ``config.yaml``: the fully resolved problem;
- ``manifest.json``: config hash, seed, versions, git revision, host, backend, times, status;
- ``history.sqlite``: one row per evaluation (generation, θ, indices, status, stage, reason, wall
  time) and one per generation (evaluations, archive size, feasible fraction, hypervolume, time),
  written by the coordinating process only;
- ``checkpoint.pkl``: the algorithm after the last stored generation, replaced atomically, and
  ``checkpoint.prev.pkl``, the one before it (a damaged checkpoint loses one generation, not the
  run; both damaged, the run is rebuilt from ``history.sqlite``, see :mod:`.runner`);
- ``pareto.csv``: the final Pareto set and front, one column per variable and objective;
- ``run.lock``: held (``flock``) by the one live coordinator; the kernel drops it when that
  process dies, however it dies, so a killed run's lock is never stale.

A generation's rows are written in one transaction *before* its checkpoint, and re-writing a
generation first deletes its rows: a run killed anywhere resumes from the checkpoint, evaluates the
next generation again and ends with each evaluation exactly once. Every file is written to a
temporary name and renamed into place, so a reader never sees half a file. Paths inside a run are
relative to the run directory, so a moved or copied run resumes from its own ``inputs/``.
"""

from __future__ import annotations

import contextlib
import csv
import datetime as _dt
import errno
import fcntl
import hashlib
import io
import json
import os
import platform
import socket
import sqlite3
import subprocess
import sys
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from casadrone.config.io import CONFIG_DIR, load, read_yaml, resolve_config
from casadrone.config.problem import ProblemConfig
from casadrone.outfile import shown_path
from casadrone.results import Record
from casadrone.rundir.checkpoint import dumps, loads
from casadrone.rundir.plugins import import_plugin

if TYPE_CHECKING:
    import numpy as np

CONFIG, MANIFEST, HISTORY, CHECKPOINT, PARETO = (
    "config.yaml", "manifest.json", "history.sqlite", "checkpoint.pkl", "pareto.csv")
PREVIOUS_CHECKPOINT, LOCK = "checkpoint.prev.pkl", "run.lock"
#: Written first when a run directory is created and removed once its manifest is written: a
#: folder holding it and no manifest is a creation killed half way (SIGKILL, power loss), and
#: everything in it is casadrone's own (the folder was new or empty), so a new run clears and
#: reuses it; ``resume`` says so.
CREATING = ".casadrone-creating"


class RunInProgress(RuntimeError):
    """Another live process coordinates this run directory."""


class RunDamaged(RuntimeError):
    """A run directory whose files cannot be read (the message says which and why)."""


class InputsChanged(RunDamaged):
    """A file the run depends on (``config.yaml``, ``inputs/*``) differs from the one it was
    created with: continuing or reading it would mix two problems in one front."""


class NotARunDirectory(RuntimeError):
    """``run --out`` names a folder that holds something else (it is left untouched)."""


def atomic_write(path: Path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename (fsynced)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data.encode() if isinstance(data, str) else data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


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

    return {"casadrone": __version__,
            "casadi": casadi.__version__,  # type: ignore[attr-defined]  # absent from the stubs
            "pymoo": pymoo.__version__, "numpy": numpy.__version__,
            "python": platform.python_version()}


def snapshot_inputs(problem: ProblemConfig, path: Path) -> ProblemConfig:
    """Copy the airframe, track and controller files (and a frozen gain's reference airframe)
    into ``path/inputs/`` and point the problem at the copies (relative to the run directory), so
    resuming or reporting a run never depends on files edited after it started."""
    if problem.test_problem is not None:
        return problem
    inputs = path / "inputs"
    inputs.mkdir(exist_ok=True)
    if problem.plugins:  # import each plugin now: an unimportable one fails before any work
        for plugin in problem.plugins:
            import_plugin(plugin)
    assert problem.airframe is not None  # a casadrone problem (not a test problem) names one
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
                atomic_write(inputs / "reference_airframe.yaml", ref_path.read_bytes())
                data["reference_airframe"] = "reference_airframe.yaml"
            atomic_write(dst, f"# copied from {shown_path(src)}\n"
                         + yaml.safe_dump(data, sort_keys=False))
        else:
            atomic_write(dst, Path(src).read_bytes())
        updates[key] = Path("inputs") / dst.name
    return problem.model_copy(update=updates)


def file_sha256(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def input_hashes(path: Path) -> dict[str, str]:
    """SHA-256 of every file a run depends on: ``config.yaml`` and each file under ``inputs/``
    (the airframe, track, controller and a frozen gain's reference airframe), by path relative
    to the run directory."""
    files = [path / CONFIG, *sorted(p for p in (path / "inputs").rglob("*") if p.is_file())]
    return {f.relative_to(path).as_posix(): file_sha256(f) for f in files}


def plugin_hashes(problem: ProblemConfig) -> dict[str, str]:
    """SHA-256 of each plugin's source file, by the file's absolute path: a plugin is code the
    run depends on (it registers the indices the run computes), so an edited one is refused like
    an edited input."""
    if not problem.plugins:
        return {}
    files = (getattr(import_plugin(plugin), "__file__", None) for plugin in problem.plugins)
    return {str(Path(f).resolve()): file_sha256(Path(f)) for f in files if f}


def resolved_yaml(problem: ProblemConfig) -> str:
    """The resolved problem as YAML (input paths relative to the run directory)."""
    return yaml.safe_dump(json.loads(problem.model_dump_json()), sort_keys=False)


def _checkpoint_state(raw: bytes) -> dict:
    state = loads(raw)
    if not isinstance(state, dict) or not {"algorithm", "elapsed_s", "generation"} <= set(state):
        raise ValueError("not a casadrone checkpoint")
    return state


@dataclass
class RunStore:
    """A run directory."""

    path: Path
    _lock_fd: int | None = field(default=None, repr=False, compare=False)

    # -- creation and opening --------------------------------------------------------------

    @classmethod
    def create(cls, path: str | Path, problem: ProblemConfig, variable_names: list[str],
               index_names: list[str], backend: str) -> RunStore:
        """Start a new run directory (refuses one that already holds a run)."""
        import shutil

        path = Path(path)
        check_new_run_dir(path)
        try:
            path.mkdir(parents=True)
            created = True
        except FileExistsError:
            created = False
        store = cls(path)
        store.acquire()  # nothing is written before the lock is held
        try:
            check_new_run_dir(path)  # another run got here first?
            if (path / CREATING).exists():  # a creation killed half way: its files, not the user's
                _clear(path, keep=LOCK)
        except BaseException:
            store.release()
            raise
        try:
            (path / CREATING).touch()
            store._populate(problem, variable_names, index_names, backend)
            (path / CREATING).unlink()
        except BaseException:  # leave the folder as it was: new (gone) or empty
            if created:
                shutil.rmtree(path, ignore_errors=True)
            else:
                _clear(path, keep=LOCK)
            store.release()
            raise
        return store

    def _populate(self, problem: ProblemConfig, variable_names: list[str],
                  index_names: list[str], backend: str) -> None:
        path, store = self.path, self
        problem = snapshot_inputs(problem, path)
        text = resolved_yaml(problem)
        atomic_write(path / CONFIG, text)
        tmp_db = path / f".{HISTORY}.{os.getpid()}.tmp"
        tmp_db.unlink(missing_ok=True)
        with contextlib.closing(sqlite3.connect(tmp_db)) as db, db:
            cols = ", ".join(f'"{n}" REAL' for n in variable_names + index_names)
            db.execute(f"CREATE TABLE evaluations (generation INTEGER, idx INTEGER, {cols}, "
                       "status TEXT, stage TEXT, reason TEXT, wall_time_s REAL, "
                       "PRIMARY KEY (generation, idx))")
            db.execute("CREATE TABLE generations (generation INTEGER PRIMARY KEY, "
                       "n_evaluations INTEGER, archive_size INTEGER, feasible_fraction REAL, "
                       "hypervolume REAL, elapsed_s REAL)")
        os.replace(tmp_db, path / HISTORY)
        store.write_manifest({
            "config_hash": hashlib.sha256(text.encode()).hexdigest(),
            "input_hashes": input_hashes(path),
            "plugin_hashes": plugin_hashes(problem),
            "problem": problem.name, "seed": problem.seed, "versions": versions(),
            "git_revision": git_revision(), "host": socket.gethostname(),
            "platform": platform.platform(), "python_executable": sys.executable,
            "backend": backend, "started": now(), "finished": None, "status": "running",
            "variables": variable_names, "indices": index_names,
        })  # last: a folder with a manifest is a complete run directory

    def connect(self) -> sqlite3.Connection:
        """The history database (which must exist: a missing one is a damaged run)."""
        db_path = self.path / HISTORY
        if not db_path.is_file():
            raise RunDamaged(f"{db_path}: missing")
        return sqlite3.connect(f"file:{db_path}?mode=rw", uri=True, timeout=30)

    @property
    def manifest(self) -> dict:
        try:
            data = json.loads((self.path / MANIFEST).read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise RunDamaged(interrupted_creation(self.path)
                             or f"{self.path / MANIFEST}: missing") from None
        except (OSError, UnicodeDecodeError, ValueError) as exc:
            raise RunDamaged(f"{self.path / MANIFEST}: damaged, not JSON ({exc})") from None
        if not isinstance(data, dict) or not isinstance(data.get("variables"), list) \
                or not isinstance(data.get("indices"), list):
            raise RunDamaged(f"{self.path / MANIFEST}: damaged (no variables and indices lists)")
        return data

    def write_manifest(self, data: dict) -> None:
        atomic_write(self.path / MANIFEST, json.dumps(data, indent=2))

    def update_manifest(self, **changes: Any) -> None:
        self.write_manifest({**self.manifest, **changes})

    def problem(self) -> ProblemConfig:
        """The resolved problem of this run (its input files from the run's own ``inputs/``),
        after :meth:`check_inputs`."""
        try:
            self.check_inputs()
        except InputsChanged:
            load(ProblemConfig, self.path / CONFIG)  # one that no longer reads says so first
            raise
        return load(ProblemConfig, self.path / CONFIG)

    def check_inputs(self) -> None:
        """Raise :class:`InputsChanged` naming the first file the run depends on (its inputs and
        its plugins' sources) that is missing or differs from the one the run was created with
        (hashes in the manifest; a run from before input hashes is checked on ``config.yaml``
        alone)."""
        m = self.manifest
        recorded = m.get("input_hashes")
        if not isinstance(recorded, dict):
            recorded = {CONFIG: m["config_hash"]} if "config_hash" in m else {}
        files = [(self.path / name, digest) for name, digest in recorded.items()]
        files += [(Path(name), digest) for name, digest in (m.get("plugin_hashes") or {}).items()]
        for f, digest in files:
            try:
                same = file_sha256(f) == digest
            except FileNotFoundError:
                raise InputsChanged(f"{f}: missing; the run depends on it (restore it from a "
                                    "copy of the run)") from None
            if not same:
                raise InputsChanged(
                    f"{f}: changed since the run was created (its SHA-256 is in {MANIFEST}); "
                    "a run only continues and reads its front on the inputs it started with. "
                    "Undo the edit, or start a new run from the edited inputs: casadrone run "
                    f"{self.path / CONFIG} --out NEW_DIR")

    # -- history ----------------------------------------------------------------------------

    @contextlib.contextmanager
    def database(self, doing: str) -> Iterator[sqlite3.Connection]:
        """The history database; its errors (damaged file, disk full) name the file."""
        try:
            with contextlib.closing(self.connect()) as db, db:
                yield db
        except sqlite3.Error as exc:
            raise RunDamaged(f"{self.path / HISTORY}: cannot {doing} ({exc})") from None

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
        with self.database("write the generation") as db:
            db.execute("DELETE FROM evaluations WHERE generation >= ?", (generation,))
            db.execute("DELETE FROM generations WHERE generation >= ?", (generation,))
            db.executemany(f"INSERT INTO evaluations (generation, idx, {cols}, status, stage, "
                           f"reason, wall_time_s) VALUES ({marks})", rows)
            db.execute("INSERT INTO generations VALUES (?, ?, ?, ?, ?, ?)",
                       (generation, stats["n_evaluations"], stats["archive_size"],
                        stats["feasible_fraction"], stats["hypervolume"], stats["elapsed_s"]))

    def history(self, generation: int | None = None) -> list[dict]:
        """All evaluations (or one ``generation``'s), ordered by generation and position."""
        where, args = ("", ()) if generation is None else ("WHERE generation = ?", (generation,))
        with self.database("read the evaluations") as db:
            db.row_factory = sqlite3.Row
            return [dict(r) for r in db.execute(
                f"SELECT * FROM evaluations {where} ORDER BY generation, idx", args)]

    def generations(self) -> list[dict]:
        """One row per stored generation (statistics), in order."""
        with self.database("read the generations") as db:
            db.row_factory = sqlite3.Row
            return [dict(r) for r in db.execute("SELECT * FROM generations ORDER BY generation")]

    # -- one coordinator at a time ----------------------------------------------------------

    def acquire(self) -> None:
        """Take the run's lock: an exclusive ``flock`` on ``run.lock`` (which then holds this
        pid, for people). A second ``run``/``resume`` on a directory whose coordinator is alive
        is refused; a dead coordinator's lock was dropped by the kernel with its process, so
        taking it over is the same atomic call and exactly one contender wins."""
        if self._lock_fd is not None:
            return
        fd = os.open(self.path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            os.close(fd)
            if exc.errno not in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise
            try:
                pid = (self.path / LOCK).read_text().strip() or "?"
            except OSError:
                pid = "?"
            raise RunInProgress(f"{self.path}: run in progress (coordinator pid {pid}); "
                                "wait for it or stop it before resuming") from None
        os.ftruncate(fd, 0)
        os.write(fd, str(os.getpid()).encode())
        self._lock_fd = fd

    def release(self) -> None:
        """Drop the lock (the file stays: unlinking it would let two processes lock two
        different files of the same name)."""
        fd = self._lock_fd
        if fd is not None:
            self._lock_fd = None
            os.close(fd)

    # -- checkpoint and front -----------------------------------------------------------------

    def save_checkpoint(self, state: dict) -> None:
        """Pickle the run state and replace the checkpoint atomically, keeping the one before
        as ``checkpoint.prev.pkl``."""
        self.write_checkpoint(dumps(state))

    def write_checkpoint(self, data: bytes) -> None:
        """Replace the checkpoint by ``data`` (a pickled run state) atomically, keeping the one
        before as ``checkpoint.prev.pkl``."""
        tmp = self.path / f".{CHECKPOINT}.{os.getpid()}.tmp"
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        if (self.path / CHECKPOINT).exists():
            os.replace(self.path / CHECKPOINT, self.path / PREVIOUS_CHECKPOINT)
        os.replace(tmp, self.path / CHECKPOINT)

    def load_checkpoint(self) -> dict:
        """The newest readable checkpoint (the previous one when the last is damaged).

        Raises RunDamaged listing why each is unusable (none at all: FileNotFoundError)."""
        why = []
        for name in (CHECKPOINT, PREVIOUS_CHECKPOINT):
            f = self.path / name
            if not f.exists():
                why.append(f"{name}: missing")
                continue
            try:
                return _checkpoint_state(f.read_bytes())
            except Exception as exc:  # noqa: BLE001 (a damaged pickle raises anything)
                why.append(f"{name}: damaged ({type(exc).__name__}: {exc})"[:200])
        if all(w.endswith("missing") for w in why):
            raise FileNotFoundError(f"{self.path}: no checkpoint")
        raise RunDamaged(f"{self.path}: " + "; ".join(why))

    def write_pareto(self, variable_names: Sequence[str], objective_names: Sequence[str],
                     X: np.ndarray | Sequence[Sequence[float]],
                     values: np.ndarray | Sequence[Sequence[float]]) -> Path:
        """Write ``pareto.csv``: variables then objectives (in their own units and sense)."""
        out = self.path / PARETO
        buf = io.StringIO(newline="")
        w = csv.writer(buf)
        w.writerow(list(variable_names) + list(objective_names))
        for x, f in zip(X, values, strict=True):
            w.writerow([repr(float(v)) for v in (*x, *f)])
        atomic_write(out, buf.getvalue())
        return out

    def read_pareto(self) -> tuple[list[str], list[list[float]]]:
        try:
            with open(self.path / PARETO, newline="", encoding="utf-8") as fh:
                rows = list(csv.reader(fh))
            if any(len(r) != len(rows[0]) for r in rows[1:]):
                raise ValueError("rows of different lengths")
            return rows[0], [[float(v) for v in r] for r in rows[1:]]
        except (IndexError, ValueError, UnicodeDecodeError, csv.Error) as exc:
            raise RunDamaged(f"{self.path / PARETO}: damaged ({exc})") from None


def record_of(row: dict, manifest: dict) -> Record:
    """One row of ``history.sqlite``'s evaluations as the :class:`Record` that was stored (an
    index stored as NULL is NaN)."""
    return Record(theta={v: row[v] for v in manifest["variables"]}, status=row["status"],
                  stage=row["stage"] or "", reason=row["reason"] or "",
                  indices={k: float("nan") if row[k] is None else row[k]
                           for k in manifest["indices"]},
                  wall_time_s=row["wall_time_s"] or 0.0)


def interrupted_creation(path: Path) -> str | None:
    """What to tell about ``path`` when its creation was killed half way (no manifest, the
    :data:`CREATING` marker left), else ``None``."""
    if (path / MANIFEST).exists() or not (path / CREATING).exists():
        return None
    return (f"{path}: its creation was interrupted before the first generation, so there is "
            f"nothing to resume; start it again with 'casadrone run PROBLEM --out {path}'")


def _clear(path: Path, keep: str) -> None:
    """Remove every entry of ``path`` but ``keep`` (files a run directory's creation made)."""
    import shutil

    for entry in path.iterdir():
        if entry.name == keep:
            continue
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)
        else:
            entry.unlink(missing_ok=True)


def check_new_run_dir(path: Path) -> None:
    """Refuse a ``--out`` that is not a new or empty folder, without touching it: a folder
    holding a run is to be resumed, any other content is the user's. A lone ``run.lock`` and
    the files of a creation killed half way (:data:`CREATING`) are casadrone's: accepted."""
    if not path.exists():
        return
    if not path.is_dir():
        raise NotARunDirectory(f"{path}: exists and is not a directory")
    if (path / MANIFEST).exists():
        raise NotARunDirectory(f"{path}: already holds a run; resume it with 'casadrone resume "
                               f"{path}' or choose another --out")
    if (path / CREATING).exists():
        return
    try:
        entries = sorted(e.name for e in os.scandir(path) if e.name != LOCK)
    except OSError as exc:
        raise NotARunDirectory(f"{path}: cannot read the folder ({exc.strerror})") from None
    if entries:
        shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise NotARunDirectory(f"{path}: not empty ({shown}); a run needs a new or empty "
                               "folder, and nothing in this one was touched")
