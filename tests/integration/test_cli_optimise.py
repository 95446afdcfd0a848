"""The optimisation commands end to end: run → decide → compare, and a SIGKILLed run resumed.

``casadrone run problems/quick.yaml`` on a tiny budget (the quick problem's physics, 16 + G × 8
evaluations, the serial backend), then ``decide --json`` and ``compare --json`` on its directory.
The kill test starts a run as a separate process, kills it with SIGKILL once generation 2 is in
history.sqlite, resumes it, and checks that it ends exactly as an uninterrupted run.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

from casadrone.cli import app

ROOT = Path(__file__).resolve().parents[2]
QUICK = ROOT / "problems" / "quick.yaml"
POPULATION, CHILDREN = 16, 8
TINY = [f"algorithm.population={POPULATION}", "algorithm.generations=4",
        f"algorithm.settings.n_ind_ga={CHILDREN}"]
KILL_GENERATIONS = 8


def console() -> list[str]:
    """The console script installed beside this python (never looked up on PATH)."""
    exe = Path(sys.executable).parent / "casadrone"
    assert exe.is_file(), f"no casadrone console script beside {sys.executable}"
    return [str(exe)]


def invoke(cli_runner, *args):
    return cli_runner.invoke(app, [str(a) for a in args])


def pareto_rows(run_dir: Path) -> tuple[list[str], list[list[float]]]:
    with open(run_dir / "pareto.csv", newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], [[float(v) for v in r] for r in rows[1:]]


def history(run_dir: Path) -> list[dict]:
    with sqlite3.connect(run_dir / "history.sqlite") as db:
        db.row_factory = sqlite3.Row
        return [dict(r) for r in db.execute("SELECT * FROM evaluations ORDER BY generation, idx")]


def without_wall_time(rows: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in rows]


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    from typer.testing import CliRunner

    out = tmp_path_factory.mktemp("cli") / "run"
    result = invoke(CliRunner(), "run", QUICK, *TINY, "--backend", "serial", "--quiet",
                    "--out", out)
    assert result.exit_code == 0, result.output
    return out, result


def test_run_prints_the_directory_and_a_front_summary(tiny_run):
    out, result = tiny_run
    assert result.stderr == ""  # --quiet
    lines = result.stdout.splitlines()
    header, rows = pareto_rows(out)
    assert lines[0] == f"run directory: {out}"
    assert lines[1] == (f"Pareto front: {len(rows)} design(s) from {POPULATION + 4 * CHILDREN} "
                        "evaluations (pareto.csv)")
    for name in ("J1", "J2", "J3", "J4", "Jp"):
        assert any(line.strip().startswith(name) for line in lines[2:])
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["backend"]["name"] == "serial"  # --backend overrides the problem's processes
    assert config["algorithm"]["generations"] == 4


def test_run_verbose_and_progress(cli_runner, tmp_path):
    out = tmp_path / "run"
    result = invoke(cli_runner, "run", QUICK, *TINY, "--backend", "serial", "-v", "--out", out)
    assert result.exit_code == 0, result.output
    err = result.stderr.splitlines()
    assert err[0].startswith("problem quick: 7 variables, objectives J1 (max)")
    assert "backend serial (1 worker(s))" in err[0] and err[0].endswith(f"-> {out}")
    gens = [ln for ln in err if ln.startswith("gen ")]  # one line per generation, no bar
    assert [ln.split()[1] for ln in gens] == [f"{g}/4" for g in range(5)]
    n = POPULATION + 4 * CHILDREN
    assert any(ln.endswith(f"of {n} evaluations completed") for ln in err)
    assert result.stdout.startswith(f"run directory: {out}")


def test_decide_json_reproduces_pareto_rows(cli_runner, tiny_run):
    out, _ = tiny_run
    result = invoke(cli_runner, "decide", out, "--json")
    assert result.exit_code == 0, result.output
    decisions = json.loads(result.stdout)
    header, rows = pareto_rows(out)
    variables = [v["name"] for v in yaml.safe_load((out / "config.yaml").read_text())["variables"]]
    objectives = ["J1", "J2", "J3", "J4", "Jp"]
    assert header == variables + objectives
    assert [d["method"] for d in decisions] == ["utopian", "compromise", "extreme"]
    for d in decisions:
        assert list(d["theta"]) == variables and list(d["objectives"]) == objectives
        row = [*d["theta"].values(), *d["objectives"].values()]
        assert row == rows[d["row"]]  # exactly a pareto.csv row
    extreme = decisions[2]
    assert extreme["objective"] == "J1"  # the first objective, maximised
    assert extreme["objectives"]["J1"] == max(r[len(variables)] for r in rows)
    (j3,) = json.loads(invoke(cli_runner, "decide", out, "--method", "extreme", "--objective",
                              "J3", "--json").stdout)
    assert j3["objectives"]["J3"] == min(r[len(variables) + 2] for r in rows)


GAIN_KEYS = {"candidate", "method", "reference", "basis", "interval", "time_gain_pct",
             "effort_gain_pct", "thrust_max_gain_pct", "thrust_min_gain_pct"}


def test_compare_json_rows(cli_runner, tiny_run):
    out, _ = tiny_run
    default = json.loads(invoke(cli_runner, "compare", out, "--json").stdout)
    # off by default: the gains against the paper's measured Table 4 (another time base)
    assert len(default) == 12 and {r["basis"] for r in default} == {"simulated"}
    result = invoke(cli_runner, "compare", out, "--json", "--measured")
    assert result.exit_code == 0, result.output
    rows = json.loads(result.stdout)
    # 3 candidates × SY250 × 4 simulated intervals, then the same × 4 measured, apart
    assert len(rows) == 24 and all(set(r) == GAIN_KEYS for r in rows)
    assert rows[:12] == default
    assert {r["reference"] for r in rows} == {"SY250"}
    assert [r["candidate"] for r in rows[:12:4]] == ["A", "B", "C"]
    assert [(r["basis"], r["interval"]) for r in rows[:4] + rows[12:16]] == (
        [("simulated", j) for j in (1, 2, 3, 4)] + [("measured", j) for j in (1, 2, 3, 4)])
    for r in rows:
        assert isinstance(r["time_gain_pct"], float)
    # the measured laps take hundreds of seconds: a ~17 s simulated lap is > 90 % "faster"
    assert all(r["time_gain_pct"] > 90 for r in rows if r["basis"] == "measured")
    # every simulated candidate of the quick problem flies the lap within ±5 % of SY250
    assert all(abs(r["time_gain_pct"]) < 5 for r in rows if r["basis"] == "simulated")


def test_compare_candidate_with_itself_is_zero(cli_runner, tiny_run, tmp_path):
    out, _ = tiny_run
    (a,) = json.loads(invoke(cli_runner, "decide", out, "--method", "utopian", "--json").stdout)
    template = yaml.safe_load((ROOT / "configs" / "airframes" / "SY250.yaml").read_text())
    own = tmp_path / "candidate-A.yaml"
    own.write_text(yaml.safe_dump({**template, **a["theta"], "name": "candidate-A"}))
    result = invoke(cli_runner, "compare", out, "--reference", own, "--json")
    assert result.exit_code == 0, result.output
    rows = [r for r in json.loads(result.stdout) if r["candidate"] == "A"]
    assert len(rows) == 4 and {r["basis"] for r in rows} == {"simulated"}  # no measured row
    for r in rows:
        assert r["reference"] == "candidate-A"
        assert r["time_gain_pct"] == 0.0
        gains = [r[k] for k in ("effort_gain_pct", "thrust_max_gain_pct", "thrust_min_gain_pct")]
        assert gains == [0.0, 0.0, 0.0], r


def test_compare_text(cli_runner, tiny_run):
    out, _ = tiny_run
    result = invoke(cli_runner, "compare", out, "--reference", "SY250", "--reference", "HS200")
    assert result.exit_code == 0, result.output
    assert "paper Eq. 21: positive = better" in result.stdout
    assert "HS200" in result.stdout and " measured " not in result.stdout
    both = invoke(cli_runner, "compare", out, "--reference", "HS200", "--measured").stdout
    simulated_part, _, measured_part = both.partition("Against the paper's measured Table 4")
    assert " simulated " in simulated_part and " measured " not in simulated_part
    assert " measured " in measured_part and " simulated " not in measured_part


def test_resume_of_the_finished_run_is_a_no_op(cli_runner, tiny_run):
    out, _ = tiny_run
    before = (out / "pareto.csv").read_text(), without_wall_time(history(out))
    result = invoke(cli_runner, "resume", out)
    assert result.exit_code == 0 and "already complete" in result.stdout
    assert ((out / "pareto.csv").read_text(), without_wall_time(history(out))) == before


# ---------------------------------------------------------------------------------------------
# The kill test
# ---------------------------------------------------------------------------------------------


def stored_generation(run_dir: Path) -> int:
    """Highest generation in history.sqlite, −1 before the first (or while it is locked)."""
    path = run_dir / "history.sqlite"
    if not path.exists():
        return -1
    try:
        with sqlite3.connect(f"file:{path}?mode=ro", uri=True, timeout=0.05) as db:
            value = db.execute("SELECT MAX(generation) FROM evaluations").fetchone()[0]
    except sqlite3.OperationalError:  # table not created yet, or a write in progress
        return -1
    return -1 if value is None else int(value)


def stop_at_generation(args: list[str], run_dir: Path, generation: int, sig: int,
                       whole_group: bool = False, timeout: float = 120.0,
                       **popen) -> tuple[int, int, str]:
    """Start ``casadrone ARGS --out RUN_DIR``, send ``sig`` to it (to its whole process group
    with ``whole_group``) once ``generation`` is stored; its pid, exit status and stderr."""
    proc = subprocess.Popen([*console(), *args, "--out", str(run_dir)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, cwd=ROOT, **popen)
    deadline = time.monotonic() + timeout
    try:
        while stored_generation(run_dir) < generation:
            if proc.poll() is not None:
                pytest.fail(f"the run ended before generation {generation} was stored: "
                            f"{proc.stderr.read().decode()}")
            if time.monotonic() > deadline:
                pytest.fail(f"generation {generation} not stored within {timeout} s")
            time.sleep(0.005)
        if whole_group:
            os.killpg(proc.pid, sig)
        else:
            os.kill(proc.pid, sig)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    return proc.pid, proc.returncode, err.decode()


def kill_at_generation(args: list[str], run_dir: Path, generation: int, timeout: float = 120.0,
                       **popen) -> int:
    """Start ``casadrone ARGS --out RUN_DIR``, SIGKILL it once ``generation`` is stored; its pid
    (with ``start_new_session``, the run and its worker processes are killed together)."""
    pid, code, _ = stop_at_generation(args, run_dir, generation, signal.SIGKILL,
                                      whole_group=bool(popen.get("start_new_session")),
                                      timeout=timeout, **popen)
    assert code == -signal.SIGKILL
    return pid


def live_processes_in_group(pgid: int) -> list[int]:
    """Pids of the processes (zombies excluded) in process group ``pgid``, from /proc."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            found.append(int(stat.parent.name))
    return found


def check_resumed_equals_uninterrupted(killed: Path, full: Path, timeout: int = 300) -> None:
    """Run the same budget uninterrupted (serial) into ``full`` and compare it with the resumed
    run ``killed``: same front, same history, every evaluation exactly once, completed."""
    done = subprocess.run([*console(), "run", str(QUICK), *KILL_BUDGET, "--backend", "serial",
                           "--quiet", "--out", str(full)], capture_output=True, text=True,
                          cwd=ROOT, timeout=timeout)
    assert done.returncode == 0, done.stderr
    assert (killed / "pareto.csv").read_text() == (full / "pareto.csv").read_text()
    h_killed, h_full = history(killed), history(full)
    assert without_wall_time(h_killed) == without_wall_time(h_full)
    n = POPULATION + KILL_GENERATIONS * CHILDREN
    keys = [(r["generation"], r["idx"]) for r in h_killed]
    expected = [(0, i) for i in range(POPULATION)] + [
        (g, i) for g in range(1, KILL_GENERATIONS + 1) for i in range(CHILDREN)]
    assert len(keys) == n and keys == expected  # none duplicated, none missing
    assert json.loads((killed / "manifest.json").read_text())["status"] == "completed"


KILL_BUDGET = [f"algorithm.population={POPULATION}", f"algorithm.generations={KILL_GENERATIONS}",
               f"algorithm.settings.n_ind_ga={CHILDREN}"]


def test_sigkilled_run_resumes_to_the_uninterrupted_result(tmp_path):
    args = ["run", str(QUICK), *KILL_BUDGET, "--backend", "serial", "--quiet"]
    d1, d2 = tmp_path / "D1", tmp_path / "D2"
    kill_at_generation(args, d1, 2)
    assert not (d1 / "pareto.csv").exists(), "killed too late: the run had already finished"
    assert json.loads((d1 / "manifest.json").read_text())["status"] == "running"
    assert 2 <= stored_generation(d1) < KILL_GENERATIONS

    resumed = subprocess.run([*console(), "resume", str(d1)], capture_output=True, text=True,
                             cwd=ROOT, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert resumed.stdout.startswith(f"run directory: {d1}")
    # progress: one line per generation still to run, on stderr (not a terminal: no bar)
    progress = [ln for ln in resumed.stderr.splitlines() if ln.startswith("gen ")]
    assert progress and progress[-1].startswith(f"gen    {KILL_GENERATIONS}/{KILL_GENERATIONS}")

    check_resumed_equals_uninterrupted(d1, d2)


@pytest.mark.slow
def test_sigkilled_process_pool_run_resumes_to_the_serial_result(tmp_path):
    """The processes backend: the run and its spawned workers are killed together (own session,
    killpg), none survives, and the resumed run equals an uninterrupted serial one."""
    args = ["run", str(QUICK), *KILL_BUDGET, "--backend", "processes", "-j", "2", "--quiet"]
    d1, d2 = tmp_path / "D1", tmp_path / "D2"
    pgid = kill_at_generation(args, d1, 2, start_new_session=True)
    deadline = time.monotonic() + 10
    while live_processes_in_group(pgid):
        if time.monotonic() > deadline:
            pytest.fail(f"processes survived the kill: {live_processes_in_group(pgid)}")
        time.sleep(0.05)
    assert not (d1 / "pareto.csv").exists(), "killed too late: the run had already finished"
    resumed = subprocess.run([*console(), "resume", str(d1), "--backend", "processes", "-j", "2",
                              "--quiet"], capture_output=True, text=True, cwd=ROOT, timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    check_resumed_equals_uninterrupted(d1, d2, timeout=600)


@pytest.mark.parametrize("fmt", ["betaflight", "px4", "urdf", "svg", "dxf"])
def test_export_a_run_candidate(cli_runner, tiny_run, tmp_path, fmt):
    out, _ = tiny_run
    (a,) = json.loads(invoke(cli_runner, "decide", out, "--method", "utopian", "--json").stdout)
    target = tmp_path / f"A.{fmt}"
    result = invoke(cli_runner, "export", out, "--candidate", "A", "--format", fmt, "--out",
                    target)
    assert result.exit_code == 0, result.output
    text = target.read_text(encoding="utf-8")
    # the run by its name, never the machine's absolute path (shared files)
    assert f"run {out.name} (template" in text and str(out.parent) not in text
    assert f"A (utopian, pareto.csv row {a['row']})" in text
    # the candidate's own geometry, not the template's
    assert f"lambda_a_mm={a['theta']['lambda_a_mm']:g}" in text
    by_row = invoke(cli_runner, "export", out, "--candidate", str(a["row"]), "--format", fmt)
    assert by_row.exit_code == 0, by_row.output
    if fmt == "betaflight":  # the same mix whether named by letter or by row
        mix = [line for line in text.splitlines() if line.startswith("mmix ")]
        assert mix == [line for line in by_row.stdout.splitlines() if line.startswith("mmix ")]


def test_export_bad_candidate_is_one_line_exit_2(cli_runner, tiny_run):
    out, _ = tiny_run
    for bad in (["--candidate", "Z"], ["--candidate", "9999"], []):
        result = invoke(cli_runner, "export", out, "--format", "px4", *bad)
        assert result.exit_code == 2, (bad, result.output)
        assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.output


def assert_group_gone_within(pgid: int, seconds: float) -> None:
    """No live process of the run (its process group: coordinator, workers, resource tracker)
    remains ``seconds`` after the coordinator died."""
    deadline = time.monotonic() + seconds
    while live_processes_in_group(pgid):
        if time.monotonic() > deadline:
            pytest.fail(f"processes of the run still alive {seconds} s after the coordinator "
                        f"died: {live_processes_in_group(pgid)}")
        time.sleep(0.05)


POOL = ["--backend", "processes", "-j", "2", "--quiet"]


def test_sigkill_of_a_pool_coordinator_leaves_no_worker(tmp_path):
    """Only the coordinator is killed (not its group): its workers must notice and end."""
    args = ["run", str(QUICK), *KILL_BUDGET, *POOL]
    pid, code, _ = stop_at_generation(args, tmp_path / "D", 1, signal.SIGKILL,
                                      start_new_session=True)
    assert code == -signal.SIGKILL
    assert_group_gone_within(pid, 5.0)


def test_sigterm_of_a_pool_coordinator_records_state_and_resumes(tmp_path):
    """SIGTERM (timeout, batch schedulers, docker stop): exit 143, one line saying how to
    resume, manifest "interrupted", no process left; the resumed run equals the serial one."""
    args = ["run", str(QUICK), *KILL_BUDGET, *POOL]
    d1, d2 = tmp_path / "D1", tmp_path / "D2"
    pid, code, err = stop_at_generation(args, d1, 1, signal.SIGTERM, start_new_session=True)
    assert code == 128 + signal.SIGTERM, err
    assert err.strip().splitlines()[-1] == (
        f"interrupted (SIGTERM); state recorded, continue with: casadrone resume {d1}"), err
    assert "Traceback" not in err
    manifest = json.loads((d1 / "manifest.json").read_text())
    assert manifest["status"] == "interrupted" and manifest["signal"] == "SIGTERM"
    assert_group_gone_within(pid, 5.0)
    resumed = subprocess.run([*console(), "resume", str(d1), "--backend", "serial", "--quiet"],
                             capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    check_resumed_equals_uninterrupted(d1, d2)


def test_ctrl_c_exits_130_with_a_hint_and_records_the_state(tmp_path):
    args = ["run", str(QUICK), *KILL_BUDGET, "--backend", "serial", "--quiet"]
    d = tmp_path / "D"
    _, code, err = stop_at_generation(args, d, 1, signal.SIGINT)
    assert code == 130, err
    assert err.strip().splitlines() == [
        f"interrupted (SIGINT); state recorded, continue with: casadrone resume {d}"]
    assert json.loads((d / "manifest.json").read_text())["status"] == "interrupted"
