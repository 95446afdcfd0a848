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
    ("codesign.intervals=1", "codesign.intervals"),
    ("codesign.lap_starts=[]", "codesign.lap_starts"),
    ("codesign.lap_starts=[straight]", "codesign.lap_starts.0"),
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
    assert set(get_args(LapStart)) == set(COLD_STARTS)
    cfg = load_codesign_problem("codesign-paper", ["codesign.lap_starts=[closed-loop,point-mass]"])
    assert cfg.codesign.lap_starts == ("closed-loop", "point-mass")


def test_cli_refuses_a_closed_loop_index_with_exit_code_2(cli_runner):
    from casadrone.cli import app

    result = cli_runner.invoke(app, ["codesign", str(ROOT / "problems" / "limit-lap.yaml")])
    assert result.exit_code == 2
    assert "'J5' is a closed-loop index" in result.stderr
    assert "Traceback" not in result.output
