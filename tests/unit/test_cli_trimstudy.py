"""``casadrone trim-study``: JSON is the study's as-dict, figures from --plot, every bad option
exits 2 with one line naming it."""

from __future__ import annotations

import json

import numpy as np
import pytest

from casadrone.cli import app


def invoke(cli_runner, *args):
    return cli_runner.invoke(app, ["trim-study", *[str(a) for a in args]])


def test_json_study_with_the_hover_oracle(cli_runner):
    res = invoke(cli_runner, "SY250", "--conditions", "hover,forward:20", "--starts", "2",
                 "--solvers", "ipopt,newton", "--seed", "5", "--json")
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["airframe"] == "SY250" and out["options"]["seed"] == 5
    assert [p["point"]["label"] for p in out["points"]] == ["hover", "forward 20 m/s"]
    hover = out["points"][0]
    assert np.shape(hover["starts"]) == (3, 6) and len(hover["results"]) == 6
    # SY250 is symmetric: four equal hover thrusts of m g / 4 (m = 0.32 kg, g = 9.81, K = 9.0519)
    np.testing.assert_allclose(hover["reference"][2:], 0.32 * 9.81 / 4 / 9.0519, rtol=1e-12)
    assert {s["solver"] for s in hover["summaries"]} == {"ipopt", "newton"}


def test_text_table_and_figures(cli_runner, tmp_path):
    res = invoke(cli_runner, "HS210", "--conditions", "forward:10", "--starts", "1",
                 "--solvers", "newton,ipopt", "--basin-grid", "3", "--plot", tmp_path)
    assert res.exit_code == 0, res.output
    assert "forward 10 m/s (reference by newton" in res.stdout
    for name in ("envelope", "basins", "residuals"):
        assert (tmp_path / f"trim-study-{name}.png").stat().st_size > 1000
    from casadrone.cli.common import figure_paths
    from casadrone.cli.trimstudy import TRIM_STUDY_FIGURES

    # the names checked before any work are the ones written
    assert sorted(tmp_path.iterdir()) == sorted(figure_paths(tmp_path, TRIM_STUDY_FIGURES))


@pytest.mark.parametrize(("args", "line"), [
    (["--starts", "-1"], "--starts: -1 is out of range"),
    (["--solvers", "ipopt,bfgs"], "--solvers: "),
    (["--angle-spread", "95"], "--angle-spread: 95.0 is out of range"),
    (["--command-spread", "1.5"], "--command-spread: 1.5 is out of range"),
    (["--reference", "simplex"], "--reference: 'simplex' is out of range"),
    (["--distinct-tolerance", "0"], "--distinct-tolerance: 0.0 is out of range"),
    (["--conditions", "hover,loop"], "--conditions: 'loop': unknown condition"),
    (["--conditions", "climb:10:120"], "--conditions: 'climb:10:120': climb_angle_deg"),
    (["--plot-point", "forward:10,forward:20"], "--plot-point: "),
    (["--basin-grid", "1"], "--basin-grid: 1 is out of range"),
    (["--seed", "-3"], "--seed: -3 is out of range"),
])
def test_bad_options_exit_2_naming_the_option(cli_runner, args, line):
    res = invoke(cli_runner, "SY250", *args)
    assert res.exit_code == 2, res.output
    assert res.stderr.startswith(line) and len(res.stderr.splitlines()) == 1
    assert "Traceback" not in res.output
