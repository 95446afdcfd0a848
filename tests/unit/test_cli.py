"""casadrone CLI: validate (exit codes, one line per problem), trim / linearise / lqr JSON shapes,
key=value overrides."""

from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from casadrone.cli import app

ROOT = Path(__file__).resolve().parents[2]
BAD = ROOT / "tests" / "data" / "bad"
SY250_FILE = ROOT / "configs" / "airframes" / "SY250.yaml"


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
    "wrong_type.yaml": ("mass_kg", "Input should be a valid number"),
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


def _console() -> list[str]:
    exe = shutil.which("casadrone")
    return [exe] if exe else [sys.executable, "-c", "from casadrone.cli import app; app()"]


def test_validate_subprocess_exit_codes_and_no_traceback():
    bad = subprocess.run([*_console(), "validate", str(BAD / "misspelt_key.yaml"),
                          str(BAD / "malformed.yaml")], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2
    assert "Traceback" not in bad.stderr
    assert f"{BAD / 'misspelt_key.yaml'}: mas_kg: unknown key (did you mean 'mass_kg'?)" in (
        bad.stderr.splitlines())
    assert f"{BAD / 'malformed.yaml'}: line 3, column 19: malformed YAML" in bad.stderr
    good = subprocess.run([*_console(), "validate", str(SY250_FILE)],
                          capture_output=True, text=True, timeout=60)
    assert good.returncode == 0, good.stderr


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
    ctrl.write_text("name: frozen\ngain_policy: frozen\nreference_airframe: SY250\n")
    frozen = run_json(cli_runner, "lqr", "HS200", "--controller", ctrl)
    reference = run_json(cli_runner, "lqr", "SY250", "--controller", ctrl)
    own = run_json(cli_runner, "lqr", "HS200")
    assert frozen["gain_policy"] == "frozen" and own["gain_policy"] == "redesign"
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
