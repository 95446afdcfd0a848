"""Every shipped airframe runs every command that takes an airframe, through the CLI (issue 47,
point 0b: ``limit-lap SY250-components`` ended its whole solve in an internal error, because the
lap time's sensitivities asked a parts-based airframe for the inertia it derives).

The cheapest options each command allows (the short co-design test track, one trim solver, no
random starts, 8 intervals per leg); the limit lap of every airframe is slow (4-40 s of CPU
each) and marked so; its crash path, the sensitivities of a parts-based airframe, runs in the
default suite through :func:`casadrone.limit.check.theta_sensitivities` with hand-made
gradients.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from casadrone.cli import app
from casadrone.config.io import DATA_DIR

AIRFRAMES = sorted(p.stem for p in (DATA_DIR / "configs" / "airframes").glob("*.yaml"))
SHORT = Path(__file__).resolve().parents[1] / "data" / "codesign" / "short-track.yaml"
#: The decision variables of each mass model, typed from paper Table 1 and the components
#: model's documentation (geometry only: mass and inertia follow from the parts).
GEOMETRY = ["lambda_a_mm", "lambda_b_mm", "alpha_deg", "beta_deg"]
TABLE1 = GEOMETRY + ["ixx_kgm2", "iyy_kgm2", "izz_kgm2"]

#: The cheap commands, each with the fewest options it needs; run for every airframe.
CHEAP = {
    "validate": ["validate"],
    "massprops": ["massprops"],
    "trim-hover": ["trim"],
    "trim-all-turn": ["trim", "--condition", "turn", "--speed", "8", "--turn-rate", "30",
                      "--solver", "all"],
    "linearise": ["linearise", "--method", "both"],
    "lqr": ["lqr"],
    **{f"export-{f}": ["export", "--format", f]
       for f in ("betaflight", "px4", "px4-shell", "urdf", "svg", "dxf")},
    "trim-study": ["trim-study", "--conditions", "hover,forward:10", "--starts", "1",
                   "--solvers", "newton"],
    "simulate": ["simulate", "--track", str(SHORT)],
}


def mass_model(airframe: str) -> str:
    """The airframe's mass model, read from its YAML (not through casadrone's loader)."""
    text = (DATA_DIR / "configs" / "airframes" / f"{airframe}.yaml").read_text()
    return yaml.safe_load(text).get("mass_model", "free")


def run(args: list[str]):
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, (args, result.output)
    assert "Traceback" not in result.output and "internal error" not in result.output
    return result


def test_every_shipped_airframe_is_found():
    assert len(AIRFRAMES) >= 12 and {"SY250", "SY250-components",
                                     "SY250-components-propeller"} <= set(AIRFRAMES)
    assert {mass_model(a) for a in AIRFRAMES} == {"free", "components"}


@pytest.mark.parametrize("command", list(CHEAP))
@pytest.mark.parametrize("airframe", AIRFRAMES)
def test_every_airframe_runs_every_cheap_command(airframe, command):
    args = CHEAP[command]
    result = run([args[0], airframe, *args[1:]])
    assert result.stdout.strip()


@pytest.mark.slow
@pytest.mark.parametrize("airframe", AIRFRAMES)
def test_every_airframe_flies_a_limit_lap_with_its_sensitivities(airframe):
    """The lap's dT/dθ over the airframe's own decision variables: the seven of Table 1 for a
    free mass model, the four geometry keys where mass and inertia come from the parts."""
    result = run(["limit-lap", airframe, "--track", str(SHORT), "--intervals", "8",
                  "--grid-rounds", "0", "--json"])
    data = json.loads(result.stdout)
    assert data["status"] == "completed", data["reason"]
    expected = GEOMETRY if mass_model(airframe) == "components" else TABLE1
    assert list(data["sensitivities"]) == expected
    assert all(v is not None and np.isfinite(v) for v in data["sensitivities"].values())


def _sensitivities(airframe: str, param: str) -> dict[str, float]:
    """dT/dθ of a lap whose only dependence is dT/d(param) = 1 s per SI unit."""
    from casadrone.airframe import PARAM_NAMES
    from casadrone.config.airframe import load_airframe
    from casadrone.limit.check import theta_sensitivities

    cfg = load_airframe(airframe)
    dT_dp = np.zeros(len(PARAM_NAMES))
    dT_dp[PARAM_NAMES.index(param)] = 1.0
    return theta_sensitivities(cfg, dT_dp, np.zeros(3), lambda frame: np.zeros(3))


def test_sensitivities_of_a_parts_based_airframe_are_over_its_geometry():
    """The crash of 0b without its solve: ``float(None)`` for the derived ``ixx_kgm2``. Oracle:
    a lap that depends on the mass alone changes with an arm length by the mass of the two arms
    it lengthens (arm_linear_density_kgpm of the YAML, per mm)."""
    sens = _sensitivities("SY250-components", "mass")
    assert list(sens) == GEOMETRY
    text = (DATA_DIR / "configs" / "airframes" / "SY250-components.yaml").read_text()
    density = yaml.safe_load(text)["components"]["arm_linear_density_kgpm"]  # kg/m
    for key in ("lambda_a_mm", "lambda_b_mm"):
        np.testing.assert_allclose(sens[key], 2 * density / 1000, rtol=1e-6)
    for key in ("alpha_deg", "beta_deg"):  # the arms' angles move no mass
        assert abs(sens[key]) < 1e-9


def test_sensitivities_of_a_free_airframe_keep_its_inertia_keys():
    """With mass_model free the inertia is a decision variable given in the file: dIxx/dixx_kgm2
    is 1 and it moves nothing else."""
    sens = _sensitivities("SY250", "Ixx")
    assert list(sens) == TABLE1
    np.testing.assert_allclose(sens["ixx_kgm2"], 1.0, rtol=1e-6)
    assert all(abs(v) < 1e-9 for k, v in sens.items() if k != "ixx_kgm2")


def test_a_derived_key_asked_for_is_named():
    from casadrone.config.airframe import load_airframe
    from casadrone.limit.check import theta_sensitivities

    with pytest.raises(ValueError, match="ixx_kgm2, iyy_kgm2, izz_kgm2: not given by "
                                         "airframe SY250-components"):
        theta_sensitivities(load_airframe("SY250-components"), np.zeros(31), np.zeros(1),
                            lambda frame: np.zeros(1), keys=tuple(TABLE1))
