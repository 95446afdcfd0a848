"""The co-design problem schema: shipped files load, closed-loop indices are refused by name."""

from __future__ import annotations

from pathlib import Path

import pytest

from casadrone.codesign.checks import load_codesign_problem
from casadrone.config.io import ConfigError

ROOT = Path(__file__).resolve().parents[2]


def test_shipped_codesign_problems_load():
    paper = load_codesign_problem("codesign-paper")
    season = load_codesign_problem("codesign-season")
    assert paper.track is not None and not paper.codesign.tracks
    assert set(season.codesign.tracks) == {"paper", "gates"}
    assert all(Path(t.track).is_file() for t in season.codesign.tracks.values())


def test_an_ordinary_problem_with_a_closed_loop_index_is_refused_by_name():
    """limit-lap.yaml optimises J3_limit against J5 (closed loop): co-design names J5."""
    with pytest.raises(ConfigError) as info:
        load_codesign_problem(ROOT / "problems" / "limit-lap.yaml")
    text = "\n".join(info.value.lines)
    assert "objectives.1.index" in text and "'J5' is a closed-loop index" in text


@pytest.mark.parametrize("override, key", [
    ("codesign.combine=best", "codesign.combine"),
    ("codesign.starts=-1", "codesign.starts"),
    ("limit_lap.intervals=1", "limit_lap.intervals"),
    ("limit_lap.starts=[]", "limit_lap.starts"),
    ("limit_lap.starts=[straight]", "limit_lap.starts.0"),
])
def test_bad_codesign_settings_name_their_key(override, key):
    with pytest.raises(ConfigError) as info:
        load_codesign_problem("codesign-paper", [override])
    assert any(f": {key}:" in line for line in info.value.lines), info.value.lines


def test_lap_starts_are_the_limit_laps_cold_starts():
    """The schema repeats the limit lap's start names (the config stage comes first): the same
    names, and each one a registered cold start of the limit lap."""
    from typing import get_args

    from casadrone.config.codesign import LapStart
    from casadrone.limit.result import Start
    from casadrone.limit.starts import COLD_STARTS

    assert get_args(LapStart) == get_args(Start)
    assert set(get_args(LapStart)) == set(COLD_STARTS) | {"library"}  # and the shipped laps
    cfg = load_codesign_problem("codesign-paper", ["limit_lap.starts=[closed-loop,point-mass]"])
    assert cfg.limit_lap.starts == ("closed-loop", "point-mass")


def _template_options(problem):
    from casadrone.codesign.checks import codesign_lap_options, template_of

    return codesign_lap_options(problem, template_of(problem), 0.1)


def test_limit_lap_section_reaches_the_template_laps_options():
    """The problem's limit_lap.starts and intervals are the options of co-design's limit laps
    (the template's lap, every frame's warm start, the certificate's cold re-solve)."""
    cfg = load_codesign_problem("codesign-paper", ["limit_lap.starts=[point-mass,fine-grid]",
                                                   "limit_lap.intervals=24"])
    options = _template_options(cfg)
    assert options.starts == ("point-mass", "fine-grid")
    assert options.intervals == 24 and options.gate_clearance_m == 0.1
    # the shipped file's own starts: the closed-loop start alone (codesign-paper.yaml)
    assert _template_options(load_codesign_problem("codesign-paper")).starts == ("closed-loop",)


def test_codesign_default_starts_and_intervals():
    """No limit_lap section: co-design's own three starts (not the limit lap's fast-path two,
    coarse-grid and fine-grid; docs/concepts/co-design.md) and the limit lap's grid for the
    paper propulsion model, 40 intervals per leg (docs/concepts/limit-lap.md)."""
    options = _template_options(load_codesign_problem("codesign-season"))
    assert options.starts == ("closed-loop", "point-mass", "coarse-grid")
    assert options.intervals == 40
    assert not options.point_mass_reference and not options.sensitivities


@pytest.mark.parametrize("old, new", [("lap_starts", "limit_lap.starts"),
                                      ("intervals", "limit_lap.intervals")])
def test_a_moved_codesign_key_is_refused_with_its_new_place(tmp_path, cli_runner, old, new):
    """An old problem file with codesign.lap_starts or codesign.intervals: one line naming the
    file, the key and where it moved, exit 2, before any solve."""
    from casadrone.cli import app

    value = "[closed-loop]" if old == "lap_starts" else "40"
    path = tmp_path / "old.yaml"
    path.write_text(f"name: old\nairframe: {ROOT}/configs/airframes/SY250-components.yaml\n"
                    f"track: {ROOT}/tests/data/codesign/short-track.yaml\n"
                    f"objectives: [{{index: J3_limit}}]\n"
                    "variables: [{name: lambda_a_mm, lower: 100.0, upper: 150.0}]\n"
                    f"codesign: {{starts: 0, {old}: {value}}}\n")
    result = cli_runner.invoke(app, ["codesign", str(path)])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert lines == [f"{path}: codesign.{old}: moved: use {new}"], lines


@pytest.mark.parametrize("overrides", [
    ["limit_lap.attitude=quaternion", "limit_lap.tilt=cone"], ["limit_lap.tilt=cone"],
    ["limit_lap.solver=fatrop"], ["limit_lap.grid_rounds=1"], ["limit_lap.search=certify"],
    ["limit_lap.rotor_step=exponential"], ["limit_lap.substeps=4"]])
def test_a_limit_lap_setting_codesign_cannot_honour_is_refused(cli_runner, overrides):
    """Co-design poses every lap as euler, axes, ipopt, rk4 x 3, no grid rounds and checks it
    with its own certificate: any other value is refused by key (exit 2, one line each), not
    ignored (quaternion needs a tilt other than axes, itself refused)."""
    from casadrone.cli import app

    result = cli_runner.invoke(app, ["codesign", "codesign-paper", *overrides])
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    keys = [o.partition("=")[0] for o in overrides]
    assert len(lines) == len(keys), lines
    for key, line in zip(keys, lines, strict=True):
        assert f"codesign-paper.yaml: {key}: co-design" in line, lines
    assert "Traceback" not in result.output


def test_the_values_codesign_poses_are_accepted():
    cfg = load_codesign_problem("codesign-paper", [
        "limit_lap.attitude=euler", "limit_lap.tilt=axes", "limit_lap.solver=ipopt",
        "limit_lap.grid_rounds=0", "limit_lap.search=fast", "limit_lap.substeps=3"])
    assert cfg.limit_lap.solver == "ipopt"


def test_cli_refuses_a_closed_loop_index_with_exit_code_2(cli_runner):
    from casadrone.cli import app

    result = cli_runner.invoke(app, ["codesign", str(ROOT / "problems" / "limit-lap.yaml")])
    assert result.exit_code == 2
    assert "'J5' is a closed-loop index" in result.stderr
    assert "Traceback" not in result.output


def test_legs_resimulation_reaches_every_lap_and_the_certificate(monkeypatch):
    """``limit_lap.resimulation=legs`` is honoured, not refused: every lap co-design poses checks
    each leg from its own node, and so does the certificate's re-simulation (a lap that is
    accurate but drifts open loop over the whole lap would fail it otherwise)."""
    from types import SimpleNamespace

    from casadrone.codesign import certificate
    from casadrone.codesign.checks import codesign_lap_options, template_of

    for value, legs in (("legs", True), ("lap", False)):
        problem = load_codesign_problem("codesign-paper", [f"limit_lap.resimulation={value}"])
        options = codesign_lap_options(problem, template_of(problem), 0.0)
        assert options.resimulation == value
        seen: dict[str, bool] = {}

        def miss(*args, legs=False, seen=seen):
            seen["legs"] = legs
            return 0.0
        monkeypatch.setattr(certificate, "trajectory", lambda *a: "lap")
        monkeypatch.setattr(certificate, "resimulation_miss", miss)
        pb = SimpleNamespace(options=options, frame=None, full=None, layout=None,
                             targets=SimpleNamespace(vector=None, kinds=()))
        certificate._miss(pb, SimpleNamespace(success=True, point=SimpleNamespace(w=None)))
        assert seen["legs"] is legs
