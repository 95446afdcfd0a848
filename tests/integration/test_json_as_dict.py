"""Every command's ``--json`` is its result's ``as_dict()``: the command's JSON, read back by
``json.loads``, equals the ``as_dict()`` of the result the public API returns for the same input,
made JSON the same way (:func:`casadrone.cli.common.jsonable`), beside what the command was asked.

The oracle is a second path to the same numbers (the API called directly, in this process), and
the property is exact equality after a round trip through a JSON parser: a key written by hand,
renamed, dropped or computed differently in a command fails it. Wall times differ between two
runs of anything and are left out of the comparison.
"""

from __future__ import annotations

import json

import pytest
from typer.testing import CliRunner

from casadrone.cli import app
from casadrone.cli.common import jsonable

#: Keys whose values differ between two runs of the same thing (measured times).
TIMES = {"wall_time_s", "wall_time_median_s", "wall_time_q25_s", "wall_time_q75_s",
         "cpu_time_s", "setup_cpu_s"}


def untimed(value):
    """``value`` with every measured time (:data:`TIMES`) removed, at any depth."""
    if isinstance(value, dict):
        return {k: untimed(v) for k, v in value.items() if k not in TIMES}
    if isinstance(value, list):
        return [untimed(v) for v in value]
    return value


def as_json(result) -> dict:
    """An API result as a command would print it: as_dict, jsonable, a JSON parser's reading."""
    data = result.as_dict() if hasattr(result, "as_dict") else result
    return untimed(json.loads(json.dumps(jsonable(data), allow_nan=False)))


def cli_json(*args: str):
    done = CliRunner().invoke(app, [*args, "--json"])
    assert done.exit_code == 0, done.output
    return untimed(json.loads(done.stdout))


@pytest.fixture(scope="module")
def sy250():
    from casadrone.airframe import build_airframe
    from casadrone.config.airframe import load_airframe

    cfg = load_airframe("SY250")
    return cfg, build_airframe(cfg)


def test_massprops_json_is_its_as_dict():
    from casadrone.config.airframe import load_airframe
    from casadrone.massprops import mass_properties

    out = cli_json("massprops", "SY250-components", "lambda_a_mm=140")
    api = mass_properties(load_airframe("SY250-components", ["lambda_a_mm=140"]))
    assert out == {"airframe": "SY250-components", **as_json(api)}


def test_trim_json_is_each_trim_points_as_dict(sy250):
    from casadrone.trim import trim_all

    _, frame = sy250
    out = cli_json("trim", "SY250", "--solver", "all", "--condition", "forward", "--speed", "8")
    api = trim_all(frame, "forward", 8.0)
    assert out["results"] == [as_json(tp) for tp in api]
    assert out["results"][0]["x0"]["theta"] > 0  # the state by name; nose down to fly forwards


def test_linearise_json_is_the_models_and_comparisons_as_dict(sy250):
    from casadrone.linearise import compare, linearise
    from casadrone.trim import trim

    _, frame = sy250
    out = cli_json("linearise", "SY250", "--method", "both")
    tp = trim(frame, "hover", solver="ipopt")
    exact = linearise(frame, tp, "exact")
    api = as_json(exact) | as_json(compare(exact, linearise(frame, tp, "fd")))
    assert out == {"airframe": "SY250", "condition": "hover", **api, "method": "both"}


def test_lqr_json_is_the_designs_and_ensembles_as_dict(sy250):
    from casadrone import control
    from casadrone.config.controller import load_controller

    _, frame = sy250
    ctrl = load_controller(None)
    out = cli_json("lqr", "SY250", "--ensemble", "5")
    design = control.design_for(frame, ctrl, None)
    ens = control.robustness_ensemble(frame, design, ctrl, 5)
    assert out == {"airframe": "SY250", "controller": ctrl.name,
                   "gain_policy": ctrl.gain_policy, **as_json(design),
                   **{f"ensemble_{k}": v for k, v in as_json(ens).items()}}
    assert out["spectral_radius"] < 1 and out["ensemble_n"] == 5


def test_simulate_json_is_the_evaluations_as_dict(sy250):
    from casadrone.evaluate import default_setup, evaluate, theta_of

    cfg, _ = sy250
    out = cli_json("simulate", "SY250")
    api = evaluate(theta_of(cfg), default_setup("SY250"))
    expected = as_json(api)
    assert {k: out[k] for k in expected} == expected
    assert set(out) - set(expected) == {"airframe", "track", "controller", "integrator",
                                         "index_units", "rotors"}
    assert [r["position"] for r in out["rotors"]] == ["FR", "FL", "RL", "RR"]


def test_benchmark_json_is_the_tables_as_dict():
    from casadrone.benchmark import run_benchmark

    assert cli_json("benchmark") == as_json(run_benchmark("rk4"))


def test_validate_json_is_each_files_report(tmp_path):
    from casadrone.config.io import ConfigError
    from casadrone.config.validation import FileReport, check_config_file

    bad = tmp_path / "track.yaml"
    bad.write_text("name: t\nwaypoints_m: [[1, 0, 1]]\nstraight: [true]\nlook_ahead_m: -1\n")
    done = CliRunner().invoke(app, ["validate", str(bad), "--json"])
    assert done.exit_code == 2
    with pytest.raises(ConfigError) as err:
        check_config_file(bad)
    expected = FileReport(str(bad), False, tuple(err.value.lines))
    assert json.loads(done.stdout) == {"valid": False, "files": [as_json(expected)]}
    assert "look_ahead_m" in err.value.lines[0]


def test_decide_json_is_each_candidates_as_dict(tmp_path):
    from casadrone.compare import run_candidates
    from tests.unit.test_cli import make_run_dir

    run_dir = make_run_dir(tmp_path / "run")
    out = cli_json("decide", str(run_dir))
    api = run_candidates(run_dir, None, None)
    assert out == [as_json(c) | {"candidate": c.label, "method": c.method} for c in api]
    assert [c["candidate"] for c in out] == [c.label for c in api] and len(out) >= 2


def test_compare_json_is_each_gain_rows_as_dict(tmp_path):
    from casadrone.compare import compare_run
    from tests.unit.test_cli import make_run_dir

    run_dir = make_run_dir(tmp_path / "run")
    out = cli_json("compare", str(run_dir))
    api = [r for r in compare_run(run_dir, ("SY250",), None) if r.basis == "simulated"]
    assert out == [as_json(r) for r in api] and out


def test_trim_study_json_is_the_studys_as_dict(sy250):
    from casadrone.trimstudy import StudyOptions, trim_study

    out = cli_json("trim-study", "SY250", "--conditions", "hover,forward:10", "--starts", "3",
                   "--solvers", "newton,ipopt")
    options = StudyOptions(starts=3, solvers=("newton", "ipopt"))
    api = trim_study(sy250[1], "hover,forward:10", options)
    assert out == as_json(api)
    assert [p["point"]["condition"] for p in out["points"]] == ["hover", "forward"]


@pytest.mark.slow
def test_limit_lap_json_is_the_laps_as_dict(tmp_path, sy250):
    """The short track of the optimality test (seconds a solve), flown by the command and by the
    API: the lap's as_dict beside the propulsion figures."""
    from casadrone.cli.limit import PROPULSION_KEYS, named_parameters
    from casadrone.limit.lap import LimitLapOptions, design_limit_lap
    from casadrone.limit.search import search_options
    from tests.integration.test_limitlap_optimality import TRACK

    cfg, _ = sy250
    track = tmp_path / "track.yaml"
    track.write_text(json.dumps(TRACK.model_dump(mode="json")))
    out = cli_json("limit-lap", "SY250", "--track", str(track), "--intervals", "20")
    lap = design_limit_lap(cfg, TRACK, search_options("fast", LimitLapOptions(intervals=20),
                                                      periodic=False))
    expected = as_json(lap)  # the command's options (its default search, the fast path)
    # dT/dp keyed by the model's parameter names (the lap keeps the bare vector)
    expected["param_sensitivity"] = as_json(named_parameters(lap.param_sensitivity, "paper"))
    assert {k: out[k] for k in expected} == expected
    assert set(out) - set(expected) == set(PROPULSION_KEYS)
