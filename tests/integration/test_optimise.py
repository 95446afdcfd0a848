"""Optimisation runs: resume equals uninterrupted, backends agree, failures stay recorded."""

import numpy as np
import pytest

from casadrone.config.io import ConfigError
from casadrone.config.problem import BackendConfig
from casadrone.optimise.checks import load_problem
from casadrone.optimise.runner import resume, run
from casadrone.rundir.store import RunStore

QUICK = "problems/quick.yaml"
TINY = ["algorithm.population=16", "algorithm.generations=3", "algorithm.settings.n_ind_ga=8"]


def strip(history):
    """History rows without the (machine-dependent) wall time."""
    return [{k: v for k, v in r.items() if k != "wall_time_s"} for r in history]


def csv_text(path):
    return (path / "pareto.csv").read_text()


@pytest.fixture(scope="module")
def tiny():
    return load_problem(QUICK, TINY)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory, tiny):
    out = tmp_path_factory.mktemp("full") / "run"
    run(tiny, out, BackendConfig(name="serial"), quiet=True)
    return out


def test_run_directory_contents(uninterrupted, tiny):
    store = RunStore(uninterrupted)
    m = store.manifest
    assert m["status"] == "completed" and m["seed"] == tiny.seed
    assert {"casadrone", "casadi", "pymoo", "numpy", "python"} <= set(m["versions"])
    # population + generations x children evaluations, each stored exactly once
    n = tiny.algorithm.population + tiny.algorithm.generations * 8
    hist = store.history()
    assert len(hist) == n == m["n_evaluations"]
    assert len({(r["generation"], r["idx"]) for r in hist}) == n
    header, rows = store.read_pareto()
    assert header == [v.name for v in tiny.variables] + [o.index for o in tiny.objectives]
    assert rows, "a feasible front exists"
    # every front member is a completed evaluation of the history with the same indices
    completed = [r for r in hist if r["status"] == "completed"]
    for row in rows:
        match = [r for r in completed
                 if np.allclose([r[v.name] for v in tiny.variables], row[:7], rtol=0, atol=0)]
        assert match, "front member not in history"
        np.testing.assert_allclose([match[0][o.index] for o in tiny.objectives], row[7:])


def test_failed_candidates_are_recorded_with_reason(uninterrupted):
    failed = [r for r in RunStore(uninterrupted).history() if r["status"] == "failed"]
    # Table 1 allows alpha = 65 deg with lambda = 100 mm, where 5-inch props overlap
    assert failed, "the quick problem's bounds contain overlapping-rotor frames"
    for r in failed:
        assert r["stage"] in {"geometry", "trim", "control", "lap"} and r["reason"]
        assert r["J3"] is None


def test_resume_after_stop_equals_uninterrupted(tmp_path, tiny, uninterrupted):
    out = tmp_path / "run"
    run(tiny, out, BackendConfig(name="serial"), quiet=True, stop_after=2)
    assert RunStore(out).manifest["status"] == "running"
    assert not (out / "pareto.csv").exists()
    resume(out, quiet=True)
    assert strip(RunStore(out).history()) == strip(RunStore(uninterrupted).history())
    assert csv_text(out) == csv_text(uninterrupted)


def test_processes_backend_equals_serial(tmp_path, tiny, uninterrupted):
    out = tmp_path / "run"
    run(tiny, out, BackendConfig(name="processes", workers=2), quiet=True)
    assert strip(RunStore(out).history()) == strip(RunStore(uninterrupted).history())
    assert csv_text(out) == csv_text(uninterrupted)


@pytest.mark.slow
def test_dask_local_cluster_equals_serial(tmp_path, tiny, uninterrupted):
    pytest.importorskip("distributed")
    out = tmp_path / "run"
    run(tiny, out, BackendConfig(name="dask", workers=2), quiet=True)
    assert strip(RunStore(out).history()) == strip(RunStore(uninterrupted).history())
    assert csv_text(out) == csv_text(uninterrupted)


def test_existing_run_directory_is_not_overwritten(uninterrupted, tiny):
    from casadrone.rundir.store import NotARunDirectory

    before = {p.name: p.stat().st_mtime_ns for p in uninterrupted.iterdir()}
    with pytest.raises(NotARunDirectory, match="resume"):
        run(tiny, uninterrupted, BackendConfig(name="serial"), quiet=True)
    assert {p.name: p.stat().st_mtime_ns for p in uninterrupted.iterdir()} == before


def test_same_seed_same_front_different_seed_differs(tmp_path, tiny, uninterrupted):
    other = tiny.model_copy(update={"seed": tiny.seed + 1})
    run(other, tmp_path / "b", BackendConfig(name="serial"), quiet=True)
    assert csv_text(tmp_path / "b") != csv_text(uninterrupted)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (["objectives.0.index=J9"], "unknown index 'J9'"),
        (["algorithm.name=nsga9"], "unknown algorithm 'nsga9'"),
    ],
)
def test_bad_problem_overrides_fail_at_load(overrides, message):
    with pytest.raises(ConfigError) as err:
        load_problem(QUICK, overrides)
    assert any(message in line for line in err.value.lines), err.value.lines


BAD_PROBLEM = """
name: bad
airframe: SY250
objectives:
  - {index: J3, sense: min}
  - {index: J3, sense: min}
variables:
  - {name: alpha_deg, lower: 90, upper: 65}
  - {name: lamda_a_mm, lower: 100, upper: 150}
algorithm: {name: evmoga, population: 10, generations: 2}
"""


def test_bad_problem_file_reports_every_problem(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(BAD_PROBLEM)
    with pytest.raises(ConfigError) as err:
        load_problem(path)
    text = "\n".join(err.value.lines)
    assert f"{path}: variables.0.lower: lower bound 90.0 is not below upper bound 65.0" in text
    assert "did you mean 'lambda_a_mm'" in text
    assert "objective 'J3' is listed twice" in text


def test_dask_backend_without_extra_fails_at_load(monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "distributed" else real(name, *a))
    with pytest.raises(ConfigError) as err:
        load_problem(QUICK, ["backend.name=dask"])
    assert any("backend.name: backend 'dask' needs the dask extra" in line
               for line in err.value.lines), err.value.lines


def test_second_coordinator_is_refused_while_first_is_alive(uninterrupted):
    import os
    import subprocess
    import sys

    store = RunStore(uninterrupted)
    holder = ("import fcntl, os, sys, time\n"
              "fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT)\n"
              "fcntl.flock(fd, fcntl.LOCK_EX)\n"
              "os.ftruncate(fd, 0); os.write(fd, str(os.getpid()).encode())\n"
              "print('locked', flush=True); time.sleep(60)\n")
    sleeper = subprocess.Popen([sys.executable, "-c", holder, str(uninterrupted / "run.lock")],
                               stdout=subprocess.PIPE, text=True)
    try:
        assert sleeper.stdout.readline().strip() == "locked"
        expected = f"run in progress \\(coordinator pid {sleeper.pid}\\)"
        with pytest.raises(RuntimeError, match=expected):
            store.acquire()
    finally:
        sleeper.kill()
        sleeper.wait()
    store.acquire()  # the dead coordinator's lock is taken over
    assert (uninterrupted / "run.lock").read_text() == str(os.getpid())
    with pytest.raises(RuntimeError, match="run in progress"):
        RunStore(uninterrupted).acquire()  # even from this same process
    store.release()
    other = RunStore(uninterrupted)
    other.acquire()  # released: free again
    other.release()


def test_run_keeps_its_own_copies_of_input_files(uninterrupted, tmp_path):
    """Resume and report use the run's inputs/ copies, not files edited after the run began."""
    inputs = uninterrupted / "inputs"
    assert sorted(p.name for p in inputs.iterdir()) == [
        "airframe.yaml", "controller.yaml", "reference_airframe.yaml", "track.yaml"]
    problem = RunStore(uninterrupted).problem()
    assert problem.airframe == inputs / "airframe.yaml"
    assert problem.track == inputs / "track.yaml"
    from casadrone.config.controller import load_controller

    ctrl = load_controller(problem.controller)
    assert ctrl.gain_policy == "frozen-wrench"
    assert ctrl.reference_airframe == inputs / "reference_airframe.yaml"


def _possible(ixx, iyy, izz):
    return izz <= ixx + iyy and ixx <= iyy + izz and iyy <= ixx + izz


def test_no_impossible_body_is_completed_or_on_the_front(uninterrupted):
    """Issue acceptance: the quick problem keeps the Table 1 box, about 29 % of which violates
    Izz ≤ Ixx + Iyy; those candidates fail at stage geometry, never fly, never reach the front."""
    store = RunStore(uninterrupted)
    hist = store.history()
    for r in hist:
        if r["status"] == "completed":
            assert _possible(r["ixx_kgm2"], r["iyy_kgm2"], r["izz_kgm2"]), r
    impossible = [r for r in hist if not _possible(r["ixx_kgm2"], r["iyy_kgm2"], r["izz_kgm2"])]
    assert impossible, "the Table 1 box holds impossible bodies, some must have been drawn"
    for r in impossible:
        assert r["status"] == "failed" and r["stage"] == "geometry"
        assert "violated" in r["reason"]
    header, rows = store.read_pareto()
    col = {name: header.index(name) for name in ("ixx_kgm2", "iyy_kgm2", "izz_kgm2")}
    for row in rows:
        assert _possible(row[col["ixx_kgm2"]], row[col["iyy_kgm2"]], row[col["izz_kgm2"]])


def test_components_study_optimises_the_geometry_only(tmp_path):
    """mass_model: components end to end: four decision variables, mass and inertia from the
    parts for every candidate, frozen-wrench on SY250-components."""
    geometry = "[" + ", ".join(
        f"{{name: {k}, lower: {lo}, upper: {hi}}}" for k, lo, hi in (
            ("lambda_a_mm", 100, 150), ("lambda_b_mm", 100, 150), ("alpha_deg", 65, 90),
            ("beta_deg", 65, 90))) + "]"
    problem = load_problem(QUICK, TINY + ["airframe=SY250-components", f"variables={geometry}",
                                          "controller=frozen-wrench-sy250-components"])
    out = tmp_path / "run"
    run(problem, out, BackendConfig(name="serial"), quiet=True)
    store = RunStore(out)
    header, rows = store.read_pareto()
    assert header[:4] == ["lambda_a_mm", "lambda_b_mm", "alpha_deg", "beta_deg"] and rows
    completed = [r for r in store.history() if r["status"] == "completed"]
    assert len({r["lambda_a_mm"] for r in completed}) > 5
