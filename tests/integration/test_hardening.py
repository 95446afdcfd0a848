"""Issue 11: nothing lost, nothing left half-written, every algorithm resumable.

Run directories under damage (garbage, truncated or empty checkpoints; both checkpoints lost; a
run killed before its first checkpoint; a moved or copied run), the lock under concurrent takeover,
``--out`` refusing other people's folders untouched, and every algorithm the problem schema
accepts running, checkpointing and resuming to the uninterrupted result. Each resumed run is
compared with an uninterrupted run of the same seed: history rows (θ, indices, status) and
pareto.csv byte for byte.
"""

from __future__ import annotations

import json
import shutil
import threading
from pathlib import Path

import numpy as np
import pytest

from casadrone.config.io import ConfigError
from casadrone.config.problem import BackendConfig, ProblemConfig
from casadrone.optimise.algorithms import ALGORITHM_NAMES, REFUSED
from casadrone.optimise.checks import load_problem
from casadrone.optimise.runner import resume, run
from casadrone.rundir.store import NotARunDirectory, RunDamaged, RunInProgress, RunStore

QUICK = "problems/quick.yaml"
TINY = ["algorithm.population=12", "algorithm.generations=3", "algorithm.settings.n_ind_ga=6"]
SERIAL = BackendConfig(name="serial")


def rows(path: Path) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in RunStore(path).history()]


def same_run(a: Path, b: Path) -> None:
    """Two run directories hold the same evaluations and the same front."""
    assert rows(a) == rows(b)
    assert (a / "pareto.csv").read_text() == (b / "pareto.csv").read_text()
    assert json.loads((a / "manifest.json").read_text())["status"] == "completed"


@pytest.fixture(scope="module")
def tiny():
    return load_problem(QUICK, TINY)


@pytest.fixture(scope="module")
def full(tmp_path_factory, tiny):
    out = tmp_path_factory.mktemp("full") / "run"
    run(tiny, out, SERIAL, quiet=True)
    return out


@pytest.fixture
def evaluated(monkeypatch) -> list[int]:
    """Rows each serial evaluation call computes, appended as they are evaluated: the work a run
    does, which "resumed = uninterrupted" comparisons cannot see (redone work is deterministic,
    so a resume that redoes a generation still ends with the same history and front)."""
    from casadrone.optimise.backends import SerialBackend

    calls: list[int] = []
    original = SerialBackend.evaluate

    def counted(self, study, X):
        calls.append(len(np.atleast_2d(X)))
        return original(self, study, X)

    monkeypatch.setattr(SerialBackend, "evaluate", counted)
    return calls


def generation_sizes(path: Path) -> list[int]:
    """History rows per stored generation, in order."""
    store = RunStore(path)
    return [len(store.history(g["generation"])) for g in store.generations()]


@pytest.mark.parametrize("stop_after", [1, 2])
def test_resume_evaluates_exactly_what_the_interrupted_run_had_not(tmp_path, tiny, full,
                                                                   evaluated, stop_after):
    """Work counted, not only results compared: the interrupted run evaluates the rows its
    history holds; the resumed one evaluates every other row of the uninterrupted run, once."""
    out = tmp_path / "run"
    run(tiny, out, SERIAL, quiet=True, stop_after=stop_after)
    before = len(rows(out))
    assert sum(evaluated) == before == sum(generation_sizes(out))
    evaluated.clear()
    resume(out, SERIAL, quiet=True)
    assert sum(evaluated) == len(rows(full)) - before > 0
    same_run(out, full)


def test_resume_from_the_previous_checkpoint_redoes_exactly_one_generation(tmp_path, tiny, full,
                                                                            evaluated):
    """The last checkpoint damaged: the generation after the previous checkpoint is evaluated
    again (its stored rows replaced, not duplicated), and nothing before it."""
    out = tmp_path / "run"
    run(tiny, out, SERIAL, quiet=True, stop_after=2)
    sizes = generation_sizes(out)
    (out / "checkpoint.pkl").write_bytes(b"")
    evaluated.clear()
    resume(out, SERIAL, quiet=True)
    assert sum(evaluated) == len(rows(full)) - sum(sizes[:-1])
    assert len(rows(out)) == len(rows(full))


# --------------------------------------------------------------------------------------------
# Damaged checkpoints, history rebuild, killed before the first checkpoint, moved runs
# --------------------------------------------------------------------------------------------

DAMAGE = {
    "garbage": lambda b: b"this is not a pickle\n" * 3,
    "truncated": lambda b: b[: len(b) // 2],
    "empty": lambda b: b"",
}


@pytest.mark.parametrize("damage", sorted(DAMAGE))
def test_damaged_checkpoint_resumes_from_the_previous_one(tmp_path, tiny, full, damage):
    out = tmp_path / "run"
    run(tiny, out, SERIAL, quiet=True, stop_after=2)
    ck = out / "checkpoint.pkl"
    assert (out / "checkpoint.prev.pkl").is_file()  # the generation before is kept
    ck.write_bytes(DAMAGE[damage](ck.read_bytes()))
    resume(out, SERIAL, quiet=True)
    same_run(out, full)


def test_both_checkpoints_damaged_rebuilds_from_history(tmp_path, tiny, full, capsys,
                                                        evaluated):
    out = tmp_path / "run"
    run(tiny, out, SERIAL, quiet=True, stop_after=3)
    (out / "checkpoint.pkl").write_bytes(b"\x80\x05garbage")
    (out / "checkpoint.prev.pkl").write_bytes(b"")
    before = rows(out)
    evaluated.clear()
    resume(out, SERIAL)
    assert "rebuilding from history.sqlite (3 stored generation(s))" in capsys.readouterr().err
    same_run(out, full)
    assert rows(out)[: len(before)] == before
    assert sum(evaluated) == len(rows(full)) - len(before)  # the stored rows are replayed


def test_run_killed_before_its_first_checkpoint_restarts_in_place(tmp_path, tiny, full):
    """A directory as a kill during the first generation leaves it: created, nothing stored."""
    from casadrone.indices import INDICES
    from casadrone.optimise.problem import Study

    out = tmp_path / "run"
    study = Study(tiny.model_copy(update={"backend": SERIAL}))
    RunStore.create(out, study.problem, study.variable_names, list(INDICES), "serial").release()
    assert not (out / "checkpoint.pkl").exists()
    resume(out, SERIAL, quiet=True)
    same_run(out, full)


def test_unrebuildable_history_is_said_plainly(tmp_path, tiny):
    out = tmp_path / "run"
    run(tiny, out, SERIAL, quiet=True, stop_after=2)
    for name in ("checkpoint.pkl", "checkpoint.prev.pkl"):
        (out / name).write_bytes(b"junk")
    with RunStore(out).connect() as db:  # tamper with a stored candidate
        db.execute('UPDATE evaluations SET "alpha_deg" = 1.0 WHERE generation = 0 AND idx = 0')
    with pytest.raises(RunDamaged, match="checkpoint.pkl: damaged .*cannot rebuild"):
        resume(out, SERIAL, quiet=True)


def test_moved_run_resumes_from_its_own_inputs(tmp_path, tiny, full):
    first = tmp_path / "first"
    run(tiny, first, SERIAL, quiet=True, stop_after=2)
    moved = tmp_path / "elsewhere" / "moved"
    moved.parent.mkdir()
    shutil.move(first, moved)
    assert not first.exists()
    resume(moved, SERIAL, quiet=True)
    same_run(moved, full)
    text = (moved / "config.yaml").read_text()
    assert str(tmp_path) not in text and "inputs/airframe.yaml" in text  # relative paths


def test_copied_run_never_reads_the_originals_inputs(tmp_path, tiny, full):
    original = tmp_path / "original"
    run(tiny, original, SERIAL, quiet=True, stop_after=2)
    copy = tmp_path / "copy"
    shutil.copytree(original, copy)
    # sabotage the original's inputs: reading them would change every evaluation
    airframe = original / "inputs" / "airframe.yaml"
    airframe.write_text(airframe.read_text().replace("mass_kg: 0.32", "mass_kg: 0.6"))
    assert "mass_kg: 0.6" in airframe.read_text()
    resume(copy, SERIAL, quiet=True)
    same_run(copy, full)


# --------------------------------------------------------------------------------------------
# --out and the lock
# --------------------------------------------------------------------------------------------


def test_foreign_non_empty_out_is_refused_and_untouched(tmp_path, tiny):
    out = tmp_path / "notes"
    out.mkdir()
    (out / "config.yaml").write_text("notes\n")
    (out / "inputs").mkdir()
    with pytest.raises(NotARunDirectory, match="not empty"):
        run(tiny, out, SERIAL, quiet=True)
    assert sorted(p.name for p in out.iterdir()) == ["config.yaml", "inputs"]
    assert (out / "config.yaml").read_text() == "notes\n"
    assert not any((out / "inputs").iterdir())


def test_empty_existing_out_is_used(tmp_path, tiny, full):
    out = tmp_path / "empty"
    out.mkdir()
    run(tiny, out, SERIAL, quiet=True)
    same_run(out, full)


def test_invalid_problem_creates_no_directory(tmp_path):
    with pytest.raises(ConfigError):
        load_problem(QUICK, [*TINY, "fixed.mass_kg=-1"])
    # an algorithm that its constructor refuses is refused before the directory exists
    bad = load_problem(QUICK, TINY).model_copy(update={"seed": 1})
    object.__setattr__(bad.algorithm, "settings", {"n_ind_ga": 7})  # past the schema
    with pytest.raises(ValueError, match="n_ind_ga"):
        run(bad, tmp_path / "never", SERIAL, quiet=True)
    assert not (tmp_path / "never").exists()


def stale_lock_dir(tmp_path: Path) -> Path:
    d = tmp_path / "run"
    d.mkdir(parents=True)
    (d / "run.lock").write_text("999999999")  # a dead coordinator's pid
    return d


def race(attempt, n: int, refusals: tuple[type[Exception], ...]) -> tuple[list, list]:
    """Run ``attempt()`` in ``n`` threads released together by a barrier: (what the winners
    returned, the refusals raised)."""
    barrier = threading.Barrier(n)
    won, refused = [], []

    def contend():
        barrier.wait()
        try:
            won.append(attempt())
        except refusals as exc:
            refused.append(exc)

    threads = [threading.Thread(target=contend) for _ in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return won, refused


def test_stale_lock_takeover_lets_exactly_one_through(tmp_path):
    """200 synchronised trials, 4 contenders each (threads: flock is per open file, so threads
    of one process contend exactly as processes do)."""
    for trial in range(200):
        d = stale_lock_dir(tmp_path / str(trial))

        def take(d=d):
            store = RunStore(d)
            store.acquire()
            return store

        won, refused = race(take, 4, (RunInProgress,))
        assert len(won) == 1 and len(refused) == 3, trial
        won[0].release()


@pytest.mark.slow
def test_stale_lock_takeover_across_processes(tmp_path):
    """The same with real processes (fewer trials: each spawns interpreters; ~30 s)."""
    import multiprocessing as mp

    ctx = mp.get_context("spawn")
    for trial in range(5):
        d = stale_lock_dir(tmp_path / str(trial))
        barrier, results = ctx.Barrier(3), ctx.Queue()
        procs = [ctx.Process(target=_contend_and_hold, args=(str(d), barrier, results))
                 for _ in range(3)]
        for p in procs:
            p.start()
        outcome = sorted(results.get(timeout=60) for _ in procs)
        for p in procs:
            p.join(timeout=60)
        assert outcome == ["refused", "refused", "won"], trial


def _contend_and_hold(d: str, barrier, results) -> None:
    import time

    store = RunStore(Path(d))
    barrier.wait()
    try:
        store.acquire()
    except RunInProgress:
        results.put("refused")
        return
    results.put("won")
    time.sleep(1.0)  # hold it while the others try
    store.release()


def test_two_runs_into_one_new_out_one_wins(tmp_path, tiny):
    from casadrone.indices import INDICES
    from casadrone.optimise.problem import Study

    study = Study(tiny)
    for trial in range(20):
        out = tmp_path / f"out{trial}"
        won, refused = race(lambda out=out: RunStore.create(
            out, tiny, study.variable_names, list(INDICES), "serial"), 2,
            (RunInProgress, NotARunDirectory))
        assert len(won) == 1 and len(refused) == 1, (trial, refused)
        won[0].release()


def test_refused_resume_writes_nothing(tmp_path, tiny):
    out = tmp_path / "run"
    run(tiny, out, SERIAL, quiet=True, stop_after=1)
    holder = RunStore(out)
    holder.acquire()  # a live coordinator
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    try:
        with pytest.raises(RunInProgress):
            resume(out, SERIAL, quiet=True)
        after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
        assert after == before
    finally:
        holder.release()


# --------------------------------------------------------------------------------------------
# Every algorithm the problem schema accepts: a tiny run, and stop/resume to the same end
# --------------------------------------------------------------------------------------------

ACCEPTED = [a for a in ALGORITHM_NAMES if a not in REFUSED]


def test_refused_algorithms_are_refused_at_load():
    for name in REFUSED:
        with pytest.raises(ConfigError, match=f"algorithm.name: {name} cannot run"):
            load_problem(QUICK, [f"algorithm.name={name}", "algorithm.settings={}"])
    with pytest.raises(ConfigError, match="eliminate_duplicates: spea2 with duplicate elim"):
        load_problem(QUICK, ["algorithm.name=spea2", "algorithm.settings={}"])


@pytest.mark.parametrize("name", ["nsga3", "unsga3", "smsemoa", "spea2"])
def test_tie_breaks_draw_from_the_seeded_generator(name):
    """pymoo 0.6.2 breaks tournament ties with an OS-seeded generator; under seeded_defaults
    two identical runs on a problem full of ties (candidates infeasible alike) agree."""
    from pymoo.core.problem import Problem

    from casadrone.optimise.algorithms import make_algorithm, seeded_defaults

    class AllFail(Problem):  # violations in three levels (failure stages): many exact ties
        def __init__(self):
            super().__init__(n_var=3, n_obj=2, n_ieq_constr=1, xl=0.0, xu=1.0)

        def _evaluate(self, X, out, *args, **kwargs):
            out["F"] = np.column_stack([X[:, 0], 1 - X[:, 0]])
            out["G"] = np.floor(3 * X[:, 1:2]) + 1.0

    def final_population():
        settings = {"eliminate_duplicates": False} if name == "spea2" else {}
        a = make_algorithm(name, settings, pop_size=8, n_obj=2)
        a.setup(AllFail(), termination=("n_gen", 8), seed=3, verbose=False)
        while a.has_next():
            with seeded_defaults(a):
                a.next()
        return a.pop.get("X")

    np.testing.assert_array_equal(final_population(), final_population())


def algorithm_problem(name: str) -> ProblemConfig:
    settings = {"evmoga": "{n_ind_ga: 4, n_div: 5}",
                "spea2": "{eliminate_duplicates: false}"}.get(name, "{}")
    return load_problem(QUICK, [f"algorithm.name={name}", "algorithm.population=8",
                                "algorithm.generations=3", f"algorithm.settings={settings}",
                                "objectives=[{index: J1}, {index: J3}]"])


@pytest.mark.parametrize("name", ACCEPTED)
def test_every_algorithm_runs_and_resumes_identically(tmp_path, name):
    problem = algorithm_problem(name)
    whole = run(problem, tmp_path / "whole", SERIAL, quiet=True)
    assert whole.n_evaluations > 8 and (tmp_path / "whole" / "pareto.csv").is_file()
    run(problem, tmp_path / "part", SERIAL, quiet=True, stop_after=2)
    assert not (tmp_path / "part" / "pareto.csv").exists()
    resume(tmp_path / "part", SERIAL, quiet=True)
    same_run(tmp_path / "part", tmp_path / "whole")
    np.testing.assert_array_equal(RunStore(tmp_path / "part").read_pareto()[1],
                                  RunStore(tmp_path / "whole").read_pareto()[1])


# --------------------------------------------------------------------------------------------
# The command line: damaged run directories, expected failures, bugs
# --------------------------------------------------------------------------------------------


def cli(*args):
    from typer.testing import CliRunner

    from casadrone.cli import app

    return CliRunner().invoke(app, [str(a) for a in args])


def one_line_exit_2(result) -> str:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    return lines[0]


FILE_DAMAGE = {"garbage": b"\x00\xffnot this file at all\n" * 20, "empty": b"",
               "truncated": None}


@pytest.mark.parametrize("target", ["manifest.json", "history.sqlite", "pareto.csv"])
@pytest.mark.parametrize("damage", sorted(FILE_DAMAGE))
@pytest.mark.parametrize("command", ["resume", "decide", "compare", "report"])
def test_damaged_run_files_give_one_line_never_a_traceback(tmp_path, full, target, damage,
                                                           command):
    d = tmp_path / "run"
    shutil.copytree(full, d)
    if command == "resume":  # an unfinished run, so that resume has work to do
        m = json.loads((d / "manifest.json").read_text())
        (d / "manifest.json").write_text(json.dumps({**m, "status": "running"}))
        if target != "pareto.csv":
            (d / "pareto.csv").unlink()
    f = d / target
    f.write_bytes(FILE_DAMAGE[damage] if FILE_DAMAGE[damage] is not None
                  else f.read_bytes()[: f.stat().st_size // 3])
    result = cli(command, d)
    if result.exit_code == 0:  # decide and compare read only config.yaml and pareto.csv
        if command == "resume":  # finishing the run writes pareto.csv afresh
            assert target == "pareto.csv", result.output
            assert f.read_bytes() == (full / "pareto.csv").read_bytes()
            return
        assert command in ("decide", "compare") and target != "pareto.csv", result.output
        return
    line = one_line_exit_2(result)
    assert target in line or "history database" in line, line


def test_resume_with_every_checkpoint_and_the_history_damaged_says_why(tmp_path, tiny):
    d = tmp_path / "run"
    run(tiny, d, SERIAL, quiet=True, stop_after=2)
    for name in ("checkpoint.pkl", "checkpoint.prev.pkl", "history.sqlite"):
        (d / name).write_bytes(b"garbage")
    line = one_line_exit_2(cli("resume", d))
    assert "checkpoint.pkl: damaged" in line and "history" in line and "cannot rebuild" in line


def test_run_into_a_foreign_folder_from_the_cli_is_refused_untouched(tmp_path, monkeypatch):
    d = tmp_path / "d"
    d.mkdir()
    (d / "config.yaml").write_text("notes\n")
    line = one_line_exit_2(cli("run", QUICK, *TINY, "--backend", "serial", "--out", d))
    assert line.startswith(f"--out: {d}: not empty (config.yaml)")
    assert [p.name for p in d.iterdir()] == ["config.yaml"]
    assert (d / "config.yaml").read_text() == "notes\n"
    monkeypatch.chdir(d)  # --out . is the same folder
    one_line_exit_2(cli("run", QUICK, *TINY, "--backend", "serial", "--out", "."))
    assert [p.name for p in d.iterdir()] == ["config.yaml"]


@pytest.mark.parametrize("override, key", [
    ("fixed.mass_kg=-1", "fixed.mass_kg"),
    ("fixed.mass_kg=true", "fixed.mass_kg"),
    ("seed=-1", "seed"),
    ("algorithm.settings.n_ind_ga=7", "algorithm.settings.n_ind_ga"),
    ("algorithm.settings.n_div=0", "algorithm.settings.n_div"),
    ("algorithm.settings.n_ind_gaa=6", "algorithm.settings.n_ind_gaa"),
    ("algorithm.name=moead", "algorithm.name"),
    ("variables=[{name: lambda_a_mm, lower: -2.0, upper: -1.0}]", "variables.0.lower"),
    ("variables=[{name: name, lower: 0.0, upper: 1.0}]", "variables.0.name"),
    ("algorithm.population=.inf", "algorithm.population"),
    ("constraints.0.max=.nan", "constraints.0.max"),
])
def test_bad_run_values_exit_2_before_anything_is_written(tmp_path, override, key):
    out = tmp_path / "never"
    result = cli("run", QUICK, *TINY, override, "--backend", "serial", "--out", out)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert any(f": {key}: " in ln for ln in result.stderr.splitlines()), result.stderr
    assert not out.exists()


@pytest.mark.parametrize("args, fragment", [
    (["trim", "SY250", "mass_kg=true"], "mass_kg: expected a number, got the boolean true"),
    (["trim", "SY250", "ixx_kgm2=.inf"], "ixx_kgm2: expected a finite number"),
    (["trim", "SY250", "lambda_a_mm=1e308"], "lambda_a_mm: 1e+308 is beyond"),
    (["trim", "SY250", "--condition", "forward", "--speed", "1e308"], "--speed: forward flight"),
    (["trim", "SY250", "--condition", "forward", "--speed", "-5"], "--speed: forward flight"),
    (["simulate", "SY250", "drag_area_m2=[0.01, .nan, 0.02]"], "drag_area_m2: expected a finite"),
])
def test_bad_values_at_every_door_exit_2(args, fragment):
    result = cli(*args)
    assert result.exit_code == 2, result.output
    assert fragment in result.stderr and "Traceback" not in result.output


def test_report_out_naming_a_directory_exits_2_at_once(full, tmp_path, monkeypatch):
    """Refused before any work (it used to read and evaluate the run first, 19 s): the run is
    never read."""
    import casadrone.report as report_mod

    def no_work(*args, **kwargs):
        raise AssertionError("the run was read before --out was checked")

    monkeypatch.setattr(report_mod, "read_run", no_work)
    line = one_line_exit_2(cli("report", full, "--out", tmp_path))
    assert "is a directory" in line


def test_disk_full_in_the_history_write_is_one_line(tmp_path, monkeypatch):
    import sqlite3

    real = sqlite3.connect

    class FullDisk:  # a connection whose inserts fail as on a full disk
        def __init__(self, *args, **kwargs):
            self.db = real(*args, **kwargs)

        def __getattr__(self, name):
            return getattr(self.db, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return self.db.__exit__(*exc)

        def executemany(self, *args):
            raise sqlite3.OperationalError("database or disk is full")

    monkeypatch.setattr(sqlite3, "connect", FullDisk)
    d = tmp_path / "run"
    line = one_line_exit_2(cli("run", QUICK, *TINY, "--backend", "serial", "--quiet",
                               "--out", d))
    assert line.startswith(f"{d / 'history.sqlite'}: cannot write the generation (database or "
                           "disk is full) (the disk is full")
    assert line.endswith(f"continue with: casadrone resume {d}")
    m = json.loads((d / "manifest.json").read_text())
    assert m["status"] == "stopped" and "disk is full" in m["error"]


def test_an_unexpected_error_is_one_line_and_a_log_file(tmp_path, monkeypatch):
    import casadrone.optimise.runner as runner_mod

    monkeypatch.setenv("CASADRONE_CACHE", str(tmp_path / "cache"))

    def bug(*args, **kwargs):
        raise KeyError("a bug")

    monkeypatch.setattr(runner_mod, "run", bug)
    result = cli("run", QUICK, *TINY, "--backend", "serial", "--out", tmp_path / "run")
    assert result.exit_code == 1 and "Traceback" not in result.output
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("casadrone: internal error: KeyError: 'a bug' (traceback in ")
    log = Path(line.rsplit("traceback in ", 1)[1].rstrip(")"))
    assert log.is_file() and "Traceback" in log.read_text() and "a bug" in log.read_text()


@pytest.mark.parametrize("args, fragment", [
    (["run", "quick", "-j", "0", "--out", "x"], "casadrone run: Invalid value for '-j'"),
    (["trim", "SY250", "--solver", "xyz"], "casadrone trim: Invalid value for '--solver'"),
    (["nocommand"], "casadrone: No such command 'nocommand'"),
])
def test_bad_command_line_options_are_one_line_from_the_console(tmp_path, args, fragment,
                                                                console):
    import subprocess

    done = subprocess.run([*console, *args], capture_output=True, text=True, cwd=tmp_path,
                          timeout=120)
    assert done.returncode == 2
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith(fragment) and line.endswith("--help')")
    assert not (tmp_path / "x").exists()


def test_a_failed_creation_leaves_no_half_run(tmp_path, tiny, monkeypatch):
    import casadrone.rundir.store as store_mod

    def no_space(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(store_mod, "versions", no_space)  # fails just before the manifest
    with pytest.raises(OSError, match="No space"):
        run(tiny, tmp_path / "new", SERIAL, quiet=True)
    assert not (tmp_path / "new").exists()
    (tmp_path / "empty").mkdir()
    with pytest.raises(OSError, match="No space"):
        run(tiny, tmp_path / "empty", SERIAL, quiet=True)
    assert [p.name for p in (tmp_path / "empty").iterdir()] in ([], ["run.lock"])
    monkeypatch.undo()
    run(tiny, tmp_path / "empty", SERIAL, quiet=True, stop_after=1)  # usable afterwards


KILLED_WHILE_CREATING = """
import os, signal, sys
from casadrone.rundir import store
from casadrone.optimise.runner import run
from casadrone.config.problem import BackendConfig
from casadrone.optimise.checks import load_problem

def killed(self, data):  # SIGKILL (no cleanup can run) just before the manifest is written
    os.kill(os.getpid(), signal.SIGKILL)

store.RunStore.write_manifest = killed
run(load_problem(sys.argv[1], sys.argv[3:]), sys.argv[2], BackendConfig(name="serial"),
    quiet=True)
"""


@pytest.mark.parametrize("existing", [False, True])
def test_a_creation_killed_half_way_is_reused_by_run_and_named_by_resume(tmp_path, tiny, full,
                                                                         existing):
    """SIGKILL while the run directory is being created (config, inputs and history written,
    no manifest): the folder is not the user's, so ``run`` clears and reuses it and ends like
    an uninterrupted run; ``resume`` says in one line that there is nothing to resume. Both
    a new folder and an empty one the user made."""
    import subprocess
    import sys

    out = tmp_path / "run"
    if existing:
        out.mkdir()
    done = subprocess.run([sys.executable, "-c", KILLED_WHILE_CREATING, QUICK, str(out), *TINY],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == -9, done.stderr
    left = {p.name for p in out.iterdir()}
    assert {"config.yaml", "history.sqlite", ".casadrone-creating"} <= left
    assert "manifest.json" not in left
    line = one_line_exit_2(cli("resume", out))
    assert "creation was interrupted" in line and "casadrone run" in line
    assert {p.name for p in out.iterdir()} == left  # resume wrote nothing
    run(tiny, out, SERIAL, quiet=True)
    same_run(out, full)
    assert not (out / ".casadrone-creating").exists()


def test_checkpoints_hold_no_path_of_the_run(tmp_path, tiny):
    out = tmp_path / "somewhere-unique"
    run(tiny, out, SERIAL, quiet=True, stop_after=2)
    for name in ("checkpoint.pkl", "checkpoint.prev.pkl", "config.yaml", "manifest.json"):
        assert b"somewhere-unique" not in (out / name).read_bytes(), name
