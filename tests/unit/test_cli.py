"""casadrone CLI: validate (exit codes, one line per problem), trim / linearise / lqr JSON shapes,
key=value overrides."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from casadrone.cli import app
from casadrone.config.io import CONFIG_DIR

ROOT = Path(__file__).resolve().parents[2]
BAD = ROOT / "tests" / "data" / "bad"
SY250_FILE = CONFIG_DIR / "airframes" / "SY250.yaml"


def run(cli_runner, *args: str):
    return cli_runner.invoke(app, [str(a) for a in args])


def run_json(cli_runner, *args: str) -> dict:
    result = run(cli_runner, *args, "--json")
    assert result.exit_code == 0, result.output
    return json.loads(result.stdout)


# ---------------------------------------------------------------------------------------------
# validate
# ---------------------------------------------------------------------------------------------


def test_validate_shipped_configs_exit_0(cli_runner):
    files = sorted([*(ROOT / "configs").rglob("*.yaml"), *(ROOT / "problems").rglob("*.yaml")])
    result = run(cli_runner, "validate", *files)
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines() == [f"{f}: ok" for f in files]
    assert result.stderr == ""


def test_validate_folder(cli_runner):
    result = run(cli_runner, "validate", ROOT / "configs" / "airframes")
    assert result.exit_code == 0, result.output
    assert len(result.stdout.splitlines()) == len(list((ROOT / "configs/airframes").glob("*.yaml")))


#: broken file → (dotted key or "line N", message fragment)
BAD_CASES = {
    "misspelt_key.yaml": ("mas_kg", "did you mean 'mass_kg'"),
    "misspelt_nested_key.yaml": ("thrust.gainn", "did you mean 'gain_n'"),
    "wrong_type.yaml": ("mass_kg", "expected a number, got the text 'heavy'"),
    "negative_mass.yaml": ("mass_kg", "Input should be greater than 0 (got -0.32)"),
    "angle_out_of_range.yaml": ("alpha_deg", "Input should be less than 180 (got 200.0)"),
    "missing_reference.yaml": ("reference_airframe",
                               "referenced file not found: does-not-exist.yaml"),
    "malformed.yaml": ("line 3", "malformed YAML"),
    "overlapping_rotors.yaml": ("alpha_deg", "rotors FR and FL overlap"),
    "controller_bad_weights.yaml": ("q.velocty", "did you mean 'velocity'"),
    "bounds_inverted.yaml": ("variables.1.lower", "lower bound 90.0 is not below upper bound 65.0"),
}


@pytest.mark.parametrize("name", sorted(BAD_CASES))
def test_validate_bad_file_exit_2_with_file_key_message(cli_runner, name):
    path = BAD / name
    key, fragment = BAD_CASES[name]
    result = run(cli_runner, "validate", path)
    assert result.exit_code == 2
    lines = result.stderr.splitlines()
    assert any(ln.startswith(f"{path}: {key}") and fragment in ln for ln in lines), lines
    assert lines[-1] == "1 of 1 file(s) invalid"
    assert "Traceback" not in result.output


def test_validate_good_and_bad_together_exit_2(cli_runner):
    result = run(cli_runner, "validate", SY250_FILE, BAD / "negative_mass.yaml")
    assert result.exit_code == 2
    assert result.stdout == f"{SY250_FILE}: ok\n"
    assert "1 of 2 file(s) invalid" in result.stderr


def test_validate_json(cli_runner):
    result = run(cli_runner, "validate", "--json", SY250_FILE, BAD / "several_problems.yaml")
    assert result.exit_code == 2
    report = json.loads(result.stdout)
    assert report["valid"] is False
    assert [f["valid"] for f in report["files"]] == [True, False]
    assert len(report["files"][1]["problems"]) == 3


def test_validate_needs_a_file(cli_runner):
    assert run(cli_runner, "validate").exit_code == 2


def test_validate_subprocess_exit_codes_and_no_traceback(console):
    bad = subprocess.run([*console, "validate", str(BAD / "misspelt_key.yaml"),
                          str(BAD / "malformed.yaml")], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2
    assert "Traceback" not in bad.stderr
    assert f"{BAD / 'misspelt_key.yaml'}: mas_kg: unknown key (did you mean 'mass_kg'?)" in (
        bad.stderr.splitlines())
    assert f"{BAD / 'malformed.yaml'}: line 3, column 19: malformed YAML" in bad.stderr
    good = subprocess.run([*console, "validate", str(SY250_FILE)],
                          capture_output=True, text=True, timeout=60)
    assert good.returncode == 0, good.stderr


@pytest.mark.parametrize("how", ["console", "module", "-c"])
def test_the_program_names_itself_casadrone_however_it_is_started(how, console, tmp_path):
    """The console script, ``python -m casadrone`` and ``python -c '...app()'`` (click would take
    the name from sys.argv[0]: ``-c``) all say ``casadrone`` in a usage error."""
    cmd = {"console": console, "module": [sys.executable, "-m", "casadrone"],
           "-c": [sys.executable, "-c", "from casadrone.cli import app; app()"]}[how]
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    done = subprocess.run([*cmd, "nocommand"], capture_output=True, text=True, timeout=60,
                          cwd=tmp_path, env=env)
    assert done.returncode == 2
    assert done.stderr.strip() == ("casadrone: No such command 'nocommand'. "
                                   "(see 'casadrone --help')")


# ---------------------------------------------------------------------------------------------
# trim
# ---------------------------------------------------------------------------------------------


def test_trim_json_shape_and_hover_oracle(cli_runner):
    out = run_json(cli_runner, "trim", "SY250", "--solver", "newton")
    assert out["airframe"] == "SY250" and out["condition"] == "hover"
    assert out["mass_kg"] == pytest.approx(0.32) and out["kappa_m"] == pytest.approx(0.016)
    assert np.shape(out["rotor_positions_m"]) == (4, 3)
    assert out["rotor_spins"] == [-1, 1, -1, 1]
    (res,) = out["results"]
    assert set(res) >= {"solver", "success", "residual_norm", "iterations", "wall_time_s", "x0",
                        "u0", "thrusts_N"}
    assert res["solver"] == "newton" and res["success"] is True
    assert len(res["x0"]) == 16 and {"theta", "phi", "T1"} <= set(res["x0"])
    assert len(res["u0"]) == 4 and len(res["thrusts_N"]) == 4
    np.testing.assert_allclose(sum(res["thrusts_N"]), 0.32 * 9.81, rtol=1e-9)


def test_trim_json_names_the_propeller_states_rotor_speeds(cli_runner):
    """With ``propeller`` the rotor states are speeds (rad/s), not thrusts: the JSON names them
    omega1..4, and each, through the shipped static law T = CT(0) ρ n² D⁴ (n = ω/2π; the
    airframe file's CT(0), D and sea-level ρ), gives the thrust the trim reports at rest."""
    out = run_json(cli_runner, "trim", "SY250-propeller", "--solver", "newton")
    (res,) = out["results"]
    assert res["success"] is True
    assert not {"T1", "T2", "T3", "T4"} & set(res["x0"])
    omega = np.array([res["x0"][f"omega{i}"] for i in range(1, 5)])
    ct0, diameter, rho = 0.20939, 0.127, 1.225  # SY250-propeller.yaml; ISA sea level
    static = ct0 * rho * (omega / (2 * np.pi)) ** 2 * diameter ** 4
    np.testing.assert_allclose(static, res["thrusts_N"], rtol=1e-3)
    np.testing.assert_allclose(sum(res["thrusts_N"]), 0.32 * 9.81, rtol=1e-9)


def test_trim_override_moves_rotors_as_computed_by_hand(cli_runner):
    out = run_json(cli_runner, "trim", SY250_FILE, "alpha_deg=60", "lambda_a_mm=140",
                   "--solver", "ipopt")
    x, y = 0.14 * math.cos(math.radians(30)), 0.14 * math.sin(math.radians(30))
    front = [[x, -y, 0], [x, y, 0]]
    rear = 0.125 * math.cos(math.radians(45))
    np.testing.assert_allclose(out["rotor_positions_m"],
                               front + [[-rear, rear, 0], [-rear, -rear, 0]], atol=1e-12)
    assert out["results"][0]["success"]


def test_trim_solver_all_table_and_json(cli_runner):
    out = run_json(cli_runner, "trim", "HS200", "--solver", "all")
    assert [r["solver"] for r in out["results"]] == ["ipopt", "nelder-mead", "newton"]
    u0 = np.array([r["u0"] for r in out["results"]])
    np.testing.assert_allclose(u0, np.broadcast_to(u0[0], u0.shape), atol=1e-6)
    text = run(cli_runner, "trim", "HS200", "--solver", "all")
    assert text.exit_code == 0, text.output
    assert "max|du0|" in text.stdout
    assert all(s in text.stdout for s in ("ipopt", "nelder-mead", "newton"))


def test_trim_forward_flight_pitches_nose_down(cli_runner):
    out = run_json(cli_runner, "trim", "SY250", "--condition", "forward", "--speed", "10")
    assert out["condition"] == "forward" and out["speed_mps"] == 10
    assert out["results"][0]["x0"]["theta"] > 0


@pytest.mark.parametrize("args, expected", [
    (["alpha_dg=75"], "alpha_dg: unknown key (did you mean 'alpha_deg'?) [override alpha_dg=75]"),
    (["alpha_deg=200"], "alpha_deg: Input should be less than 180 (got 200)"),
    (["lambda_a_mm=50"], "alpha_deg: rotors FR and FL overlap"),
    (["mass_kg=-1"], "mass_kg: Input should be greater than 0"),
    (["alpha_deg"], "override 'alpha_deg': expected key=value"),
])
def test_bad_override_exits_2_naming_the_key(cli_runner, args, expected):
    result = run(cli_runner, "trim", "SY250", *args)
    assert result.exit_code == 2
    assert expected in result.stderr, result.stderr
    assert result.stderr.startswith(str(SY250_FILE)) and "Traceback" not in result.output


@pytest.mark.parametrize("args, expected", [
    (["SY25"], "SY25: file not found"),
    (["SY250", "--speed", "5"], "--speed: hover has no speed"),
    (["SY250", "--condition", "forward"], "--speed: required"),
    (["SY250", "--solver", "bogus"], ""),
    ([BAD / "negative_mass.yaml"], "mass_kg: Input should be greater than 0"),
])
def test_trim_bad_input_exits_2(cli_runner, args, expected):
    result = run(cli_runner, "trim", *args)
    assert result.exit_code == 2
    assert expected in result.stderr and "Traceback" not in result.output


# ---------------------------------------------------------------------------------------------
# linearise
# ---------------------------------------------------------------------------------------------


def test_linearise_both_json(cli_runner):
    out = run_json(cli_runner, "linearise", "SY250", "--method", "both")
    n, m = len(out["state_names"]), len(out["input_names"])
    assert (n, m) == (16, 4)
    assert np.shape(out["A"]) == (n, n) and np.shape(out["E"]) == (n, n)
    assert np.shape(out["B"]) == (n, m)
    assert out["max_abs_diff_A"] < 1e-4 and out["max_abs_diff_B"] < 1e-4
    assert out["max_rel_diff"] < 1e-6
    # hover structure: ẋ = R v, so ∂ẋ/∂u = 1
    A = np.array(out["A"])
    assert A[out["state_names"].index("x"), out["state_names"].index("u")] == pytest.approx(1.0)


def test_linearise_exact_has_no_diffs_and_override_applies(cli_runner):
    base = run_json(cli_runner, "linearise", "SY250")
    heavy = run_json(cli_runner, "linearise", "SY250", "mass_kg=0.4")
    assert "max_abs_diff_A" not in base
    assert not np.allclose(base["A"], heavy["A"])


def test_linearise_bad_override(cli_runner):
    result = run(cli_runner, "linearise", "SY250", "beta_deg=0")
    assert result.exit_code == 2 and "beta_deg: Input should be greater than 0" in result.stderr


# ---------------------------------------------------------------------------------------------
# lqr
# ---------------------------------------------------------------------------------------------


def test_lqr_json_with_ensemble(cli_runner):
    out = run_json(cli_runner, "lqr", "SY250", "--ensemble", "3")
    K = np.array(out["K"])
    assert K.shape == (4, 20)
    eig = np.array(out["closed_loop_eigenvalues"])
    assert eig.shape == (20, 2)
    assert out["stable"] is True and np.max(np.hypot(eig[:, 0], eig[:, 1])) < 1
    assert out["lyapunov_min_eig"] > 0
    assert out["ensemble_n"] == 3 and isinstance(out["ensemble_stable"], bool)


def test_lqr_without_ensemble_has_no_ensemble_keys(cli_runner):
    out = run_json(cli_runner, "lqr", "HS200", "alpha_deg=85")
    assert "ensemble_n" not in out and out["stable"] is True


def test_lqr_frozen_gain_from_reference(cli_runner, tmp_path):
    ctrl = tmp_path / "frozen.yaml"
    ctrl.write_text("name: frozen\ngain_policy: frozen-command\nreference_airframe: SY250\n")
    frozen = run_json(cli_runner, "lqr", "HS200", "--controller", ctrl)
    reference = run_json(cli_runner, "lqr", "SY250", "--controller", ctrl)
    own = run_json(cli_runner, "lqr", "HS200")
    assert frozen["gain_policy"] == "frozen-command" and own["gain_policy"] == "redesign"
    np.testing.assert_allclose(frozen["K"], reference["K"], rtol=1e-12)
    assert not np.allclose(frozen["K"], own["K"])


def test_text_output(cli_runner):
    lin = run(cli_runner, "linearise", "SY250", "--method", "both")
    assert lin.exit_code == 0 and "exact vs fd: max|dA|" in lin.stdout
    lqr = run(cli_runner, "lqr", "SY250", "--ensemble", "2")
    assert lqr.exit_code == 0 and "closed loop stable" in lqr.stdout
    assert "2 of 2 perturbed plants stable" in lqr.stdout


def test_lqr_bad_controller_exits_2(cli_runner):
    path = BAD / "controller_bad_weights.yaml"
    result = run(cli_runner, "lqr", "SY250", "--controller", path)
    assert result.exit_code == 2
    assert f"{path}: r.1: Input should be greater than 0" in result.stderr


def test_lqr_missing_reference_exits_2(cli_runner):
    path = BAD / "missing_reference.yaml"
    result = run(cli_runner, "lqr", "SY250", "--controller", path)
    assert result.exit_code == 2
    assert f"{path}: reference_airframe: referenced file not found" in result.stderr


def test_lqr_ensemble_must_be_positive(cli_runner):
    assert run(cli_runner, "lqr", "SY250", "--ensemble", "0").exit_code == 2


def test_lqr_plot_saves_robustness_figures(cli_runner, tmp_path):
    out = run_json(cli_runner, "lqr", "SY250", "--ensemble", "3", "--plot", tmp_path / "figs")
    from casadrone.cli.design import LQR_FIGURES

    names = ("eigenvalue-cloud", "disturbance-responses")
    assert names == LQR_FIGURES  # the names checked before any work are the ones written
    expected = [str(tmp_path / "figs" / f"{n}.{ext}") for n in names for ext in ("png", "svg")]
    assert out["figures"] == expected and out["ensemble_n"] == 3
    assert all(Path(p).stat().st_size > 0 for p in expected)


def test_lqr_plot_into_a_file_exits_2(cli_runner, tmp_path):
    (tmp_path / "f").write_text("")
    result = run(cli_runner, "lqr", "SY250", "--plot", tmp_path / "f")
    assert result.exit_code == 2 and "--plot" in result.stderr and "not a folder" in result.stderr


# ---------------------------------------------------------------------------------------------
# simulate
# ---------------------------------------------------------------------------------------------

INTERVAL_KEYS = {"waypoint", "split_time_s", "effort_V", "pair_thrust_max_N", "pair_thrust_min_N",
                 "straight", "n_samples"}  # every field of indices.Interval (its as_dict)


def test_simulate_json_shape_and_values(cli_runner):
    out = run_json(cli_runner, "simulate", "SY250")
    assert out["status"] == "completed" and out["reason"] == "" and out["integrator"] == "rk4"
    assert out["track"] == "paper-rectangle" and out["controller"] == "default"
    assert set(out["indices"]) == {"J1", "J2", "J3", "J4", "J5", "Jp"}
    assert out["index_units"]["J3"] == "s"
    intervals = out["intervals"]
    assert [i["waypoint"] for i in intervals] == [1, 2, 3, 4]
    assert all(set(i) == INTERVAL_KEYS for i in intervals)
    splits = [i["split_time_s"] for i in intervals]
    assert np.all(np.diff(splits) > 0)
    assert out["indices"]["J3"] == splits[-1]  # the lap time is the last split, exactly
    assert out["indices"]["J1"] > out["indices"]["J2"] > 0
    assert all(i["pair_thrust_min_N"] <= i["pair_thrust_max_N"] for i in intervals)
    assert out["wall_time_s"] > 0


def test_simulate_same_chain_as_evaluate_and_overrides_apply(cli_runner):
    from casadrone.config.airframe import load_airframe
    from casadrone.evaluate import default_setup, evaluate, theta_of

    out = run_json(cli_runner, "simulate", "SY250", "alpha_deg=80", "beta_deg=85")
    cfg = load_airframe("SY250", ["alpha_deg=80", "beta_deg=85"])
    ev = evaluate(theta_of(cfg), default_setup())
    assert out["indices"] == ev.indices


def test_simulate_too_heavy_airframe_is_a_failed_lap_not_an_error(cli_runner):
    # 3 kg hovers (weight 29.4 N below the rotors' 36.2 N) but cannot fly the track
    out = run_json(cli_runner, "simulate", "SY250", "mass_kg=3")
    assert out["status"] == "failed" and out["stage"] in {"trim", "control", "lap"}
    assert out["reason"] and out["indices"] == {} and out["intervals"] == []
    text = run(cli_runner, "simulate", "SY250", "mass_kg=3")
    assert text.exit_code == 0 and "lap FAILED" in text.stdout


def test_simulate_airframe_that_cannot_hover_is_bad_input(cli_runner):
    # 4 kg: weight 39.2 N above the four rotors' full thrust, rejected by the config check
    result = run(cli_runner, "simulate", "SY250", "mass_kg=4")
    assert result.exit_code == 2
    assert "mass_kg: cannot hover" in result.stderr and "[override mass_kg=4]" in result.stderr
    assert "Traceback" not in result.output


def test_simulate_text_and_plots(cli_runner, tmp_path):
    result = run(cli_runner, "simulate", "HS200", "--plot", tmp_path)
    assert result.exit_code == 0, result.output
    assert "HS200: track paper-rectangle" in result.stdout and "lap completed" in result.stdout
    for name in ("track-top-view", "track-3d", "time-histories"):
        for ext in ("png", "svg"):
            assert (tmp_path / f"{name}.{ext}").stat().st_size > 0


def test_simulate_track_and_controller_options(cli_runner, tmp_path):
    track = tmp_path / "short.yaml"
    text = (ROOT / "configs" / "tracks" / "paper-rectangle.yaml").read_text()
    track.write_text(text.replace("time_limit_s: 60.0", "time_limit_s: 2.0"))
    out = run_json(cli_runner, "simulate", "SY250", "--track", track, "--controller", "default")
    assert out["status"] == "failed" and "time-out" in out["reason"]


@pytest.mark.parametrize("args, expected", [
    (["SY250", "--track", "nowhere"], "nowhere: file not found"),
    (["SY250", "--controller", BAD / "controller_bad_weights.yaml"], "r.1: Input should be"),
    (["SY250", "--integrator", "euler"], ""),
    (["SY250", "alpha_dg=80"], "did you mean 'alpha_deg'"),
])
def test_simulate_bad_input_exits_2(cli_runner, args, expected):
    result = run(cli_runner, "simulate", *args)
    assert result.exit_code == 2
    assert expected in result.stderr and "Traceback" not in result.output


@pytest.mark.slow
@pytest.mark.parametrize("integrator", ["cvodes", "idas"])
def test_simulate_reference_integrators_agree_with_rk4(cli_runner, integrator):
    fast = run_json(cli_runner, "simulate", "SY250")
    ref = run_json(cli_runner, "simulate", "SY250", "--integrator", integrator)
    assert ref["integrator"] == integrator and ref["status"] == "completed"
    for name, value in fast["indices"].items():
        assert ref["indices"][name] == pytest.approx(value, rel=1e-3, abs=1e-3), name


# ---------------------------------------------------------------------------------------------
# benchmark
# ---------------------------------------------------------------------------------------------


def test_benchmark_json_five_airframes(cli_runner):
    out = run_json(cli_runner, "benchmark")
    assert out["integrator"] == "rk4"
    assert [r["airframe"] for r in out["rows"]] == ["SY250", "SY220", "HS200", "HS210", "NSY200"]
    for r in out["rows"]:
        assert r["status"] == "completed", r["reason"]
        assert len(r["simulated"]) == 4 and len(r["measured"]["split_times_s"]) == 4
        assert r["lap_time_s"] == r["simulated"][-1]["split_time_s"] == r["indices"]["J3"]
    text = run(cli_runner, "benchmark")
    assert text.exit_code == 0 and text.stdout.startswith("Table-4-style benchmark")


# ---------------------------------------------------------------------------------------------
# run, resume, decide, compare, report: bad input (the real runs are in
# tests/integration/test_cli_optimise.py)
# ---------------------------------------------------------------------------------------------

QUICK = ROOT / "problems" / "quick.yaml"


@pytest.mark.parametrize("args, expected", [
    ([BAD / "bounds_inverted.yaml"], "variables.1.lower: lower bound 90.0 is not below"),
    ([QUICK, "objectives.0.index=J9"], "objectives.0.index: unknown index 'J9'"),
    ([QUICK, "algorithm.population"], "expected key=value"),
    ([QUICK, "algorithm.nmae=evmoga"], "algorithm.nmae: unknown key"),
    ([ROOT / "problems" / "nowhere.yaml"], "nowhere.yaml: file not found"),
    ([QUICK, "--backend", "serial", "--scheduler", "tcp://127.0.0.1:1"],
     "--scheduler: only with --backend dask"),
    ([QUICK, "--quiet", "--verbose"], "--quiet and --verbose"),
    ([QUICK, "-j", "0"], ""),
    ([QUICK, "--backend", "cluster"], ""),
])
def test_run_bad_input_exits_2(cli_runner, tmp_path, args, expected):
    result = run(cli_runner, "run", *args, "--out", tmp_path / "run")
    assert result.exit_code == 2, result.output
    assert expected in result.stderr and "Traceback" not in result.output
    assert not (tmp_path / "run").exists()  # nothing started


def test_run_needs_out(cli_runner):
    result = run(cli_runner, "run", QUICK)
    assert result.exit_code == 2 and "--out" in result.stderr


def test_run_into_an_existing_run_exits_2(cli_runner, tmp_path):
    (tmp_path / "manifest.json").write_text("{}")
    result = run(cli_runner, "run", QUICK, "--out", tmp_path)
    assert result.exit_code == 2
    assert f"--out: {tmp_path}: already holds a run; resume it with" in result.stderr


def test_dask_backend_without_extra_exits_2(cli_runner, tmp_path, monkeypatch):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "distributed" else real(name, *a))
    result = run(cli_runner, "run", QUICK, "--backend", "dask", "--out", tmp_path / "run")
    assert result.exit_code == 2
    assert "--backend: name: backend 'dask' needs the dask extra" in result.stderr


def make_run_dir(path: Path, finished: bool = True, checkpoint: bool = False) -> Path:
    """A run directory of the quick problem with a hand-made two-design front."""
    from casadrone.optimise.checks import load_problem
    from casadrone.optimise.problem import Study
    from casadrone.rundir.store import RunStore

    problem = load_problem(QUICK, ["objectives=[{index: J3, sense: min}, {index: J4}]"])
    study = Study(problem)
    store = RunStore.create(path, problem, study.variable_names, study.objective_names, "serial")
    if checkpoint:
        store.save_checkpoint({"algorithm": None})
    if finished:
        X = np.array([[120.0, 125.0, 85.0, 80.0, 0.0021, 0.0017, 0.0036],
                      [125.0, 125.0, 90.0, 90.0, 0.0022, 0.0017, 0.0036]])
        store.write_pareto(study.variable_names, study.objective_names, X,
                           np.array([[16.5, 14.0], [16.6, 15.0]]))
        store.update_manifest(status="completed", n_evaluations=2, finished="2026-01-01")
    store.release()
    return path


@pytest.mark.parametrize("command", ["resume", "decide", "compare", "report"])
def test_run_dir_commands_on_a_missing_or_foreign_dir_exit_2(cli_runner, tmp_path, command):
    missing = run(cli_runner, command, tmp_path / "nowhere")
    assert missing.exit_code == 2
    assert missing.stderr == f"{tmp_path / 'nowhere'}: no such run directory\n"
    foreign = run(cli_runner, command, tmp_path)
    assert foreign.exit_code == 2
    assert f"{tmp_path}: not a run directory (no config.yaml, manifest.json)" in foreign.stderr
    damaged = make_run_dir(tmp_path / "damaged")
    (damaged / "config.yaml").write_text("name: [unclosed\n")
    bad = run(cli_runner, command, damaged)
    assert bad.exit_code == 2 and "config.yaml: not a valid resolved problem" in bad.stderr
    assert "Traceback" not in missing.output + foreign.output + bad.output


def test_resume_of_a_finished_run_reports_it_complete(cli_runner, tmp_path):
    d = make_run_dir(tmp_path / "run")
    before = (d / "manifest.json").read_text()
    result = run(cli_runner, "resume", d)
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith(f"{d}: the run is already complete (finished 2026-01-01)")
    assert "Pareto front: 2 design(s) from 2 evaluations" in result.stdout
    assert (d / "manifest.json").read_text() == before  # untouched


def test_decide_unfinished_run_and_unknown_objective_exit_2(cli_runner, tmp_path):
    d = make_run_dir(tmp_path / "running", finished=False)
    result = run(cli_runner, "decide", d)
    assert result.exit_code == 2 and "no pareto.csv: the run has not finished" in result.stderr
    done = make_run_dir(tmp_path / "done")
    result = run(cli_runner, "decide", done, "--objective", "J9")
    assert result.exit_code == 2
    assert f"{done}: unknown objective 'J9'; objectives of this run: J3, J4" in result.stderr
    assert run(cli_runner, "decide", done, "--method", "nearest").exit_code == 2


def test_decide_on_a_hand_made_front(cli_runner, tmp_path):
    d = make_run_dir(tmp_path / "run")
    out = json.loads(run(cli_runner, "decide", d, "--json").stdout)
    assert [c["method"] for c in out] == ["utopian", "compromise", "extreme"]
    assert [c["candidate"] for c in out] == ["A", "B", "C"]
    # J3 min and J4 max conflict: extreme on J3 (the first objective) is row 0
    assert out[2]["row"] == 0 and out[2]["objective"] == "J3"
    assert out[2]["objectives"] == {"J3": 16.5, "J4": 14.0}
    (j4,) = json.loads(run(cli_runner, "decide", d, "--method", "extreme", "--objective", "J4",
                           "--json").stdout)
    assert j4["row"] == 1 and j4["theta"]["alpha_deg"] == 90.0
    text = run(cli_runner, "decide", d)
    assert text.exit_code == 0 and text.stdout.startswith("A utopian: pareto.csv row")


def test_decide_ends_with_the_verdict_against_the_baseline(cli_runner, tmp_path):
    # The hand-made front: row 0 J3 16.5 s, J4 14.0 m/s²; row 1 J3 16.6 s, J4 15.0 m/s². SY250
    # on quick.yaml's platform (rk4): J3 16.653747 s, J4 13.635615 m/s² (its own gain equals the
    # frozen wrench gain designed on it; benchmarks/RESULTS-sensitivity.md, rk4 column). Row 0
    # by hand: J3 (16.5 − 16.653747)/16.653747 = −0.92 % (min: better), J4 +2.7 % (better).
    d = make_run_dir(tmp_path / "run")
    text = run(cli_runner, "decide", d, "--method", "extreme")
    assert text.exit_code == 0
    block = text.stdout.split("Verdict against SY250:\n", 1)[1].splitlines()
    assert block[0].startswith("  C dominates SY250: yes;")
    assert block[1] == "    J3 -0.92 % better; J4 +2.7 % better"
    assert "noise of each value" in block[2]
    bad = run(cli_runner, "decide", d, "--reference", "SY25")
    assert bad.exit_code == 2 and bad.stdout == "" and "did you mean 'SY250'" in bad.stderr


def test_compare_bad_reference_exits_2(cli_runner, tmp_path):
    d = make_run_dir(tmp_path / "run")
    result = run(cli_runner, "compare", d, "--reference", "SY25")
    assert result.exit_code == 2 and "did you mean 'SY250'" in result.stderr


def test_report_calls_write_report(cli_runner, tmp_path, monkeypatch):
    import types

    calls = []

    def write_report(run_dir, references=None, out=None):
        calls.append((Path(run_dir), references, out))
        return Path(out or Path(run_dir) / "report.html")

    monkeypatch.setitem(sys.modules, "casadrone.report",
                        types.SimpleNamespace(write_report=write_report))
    d = make_run_dir(tmp_path / "run")
    result = run(cli_runner, "report", d)
    assert result.exit_code == 0 and result.stdout == f"{d / 'report.html'}\n"
    result = run(cli_runner, "report", d, "--reference", "SY250", "--reference", "NSY200",
                 "--out", tmp_path / "r.html")
    assert result.exit_code == 0 and result.stdout == f"{tmp_path / 'r.html'}\n"
    assert calls == [(d, None, None), (d, ("SY250", "NSY200"), tmp_path / "r.html")]


def test_report_without_the_report_module_exits_1(cli_runner, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "casadrone.report", None)  # import raises ImportError
    result = run(cli_runner, "report", make_run_dir(tmp_path / "run"))
    assert result.exit_code == 1, result.output
    assert "casadrone.report is not available" in result.stderr


def test_version(cli_runner):
    from casadrone import __version__

    result = run(cli_runner, "--version")
    assert result.exit_code == 0 and result.stdout.strip() == f"casadrone {__version__}"


def test_validate_configs_problems_outside_the_checkout_checks_the_shipped_files(
        cli_runner, tmp_path, monkeypatch):
    from casadrone.config.io import DATA_DIR

    monkeypatch.chdir(tmp_path)  # no configs/ or problems/ here: the shipped ones are meant
    shipped = sorted(DATA_DIR.rglob("*.yaml"))
    result = run(cli_runner, "validate", "configs", "problems", "--json")
    assert result.exit_code == 0, result.output
    files = sorted(Path(f["file"]) for f in json.loads(result.stdout)["files"])
    assert files == shipped


@pytest.mark.parametrize("command", ["validate", "trim", "simulate"])
def test_impossible_inertia_is_bad_input(cli_runner, tmp_path, command):
    """An airframe with Izz > Ixx + Iyy: exit 2 naming the triangle inequality, no traceback."""
    frame = tmp_path / "impossible.yaml"
    text = (ROOT / "configs" / "airframes" / "SY250.yaml").read_text()
    frame.write_text(text.replace("izz_kgm2: 0.0036", "izz_kgm2: 0.0045"))
    result = run(cli_runner, command, frame)
    assert result.exit_code == 2, result.output
    assert f"{frame}: izz_kgm2: Ixx + Iyy ≥ Izz violated" in result.stderr
    assert "Traceback" not in result.output


def test_impossible_inertia_override_is_bad_input(cli_runner):
    result = run(cli_runner, "simulate", "SY250", "izz_kgm2=0.0045", "--json")
    assert result.exit_code == 2
    assert "izz_kgm2: Ixx + Iyy ≥ Izz violated" in result.stderr
    assert "[override izz_kgm2=0.0045]" in result.stderr


def test_impossible_inertia_is_a_failed_evaluation_at_geometry():
    from casadrone.evaluate import default_setup, evaluate

    ev = evaluate({"ixx_kgm2": 0.0014, "iyy_kgm2": 0.0012, "izz_kgm2": 0.0042},
                  default_setup("SY250", "frozen-wrench-sy250"))
    assert ev.status == "failed" and ev.stage == "geometry"
    assert "Ixx + Iyy ≥ Izz violated" in ev.reason
