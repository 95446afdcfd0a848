"""Bad limit-lap input found in an audit of ``casadrone limit-lap``: each is refused before any
solve, exit code 2 and one line on stderr naming the file and the key (it was a failed lap with
exit code 0, or a second line about a key the file does not have)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.limit.problem import check_inputs
from casadrone.limit.result import LimitLapOptions

#: One straight leg east from the ground, the keys of each case added.
STRAIGHT = "name: straight\nwaypoints_m: [[20, 0, 1]]\nstraight: [true]\n"
#: A gate track of one gate, its centre given as ``{centre}``.
ONE_GATE = ("name: gate\ngates:\n  - {{centre_m: {centre}, heading_deg: 0, width_m: 1.5, "
            "height_m: 1.5}}\nstraight: [true]\n")


def _refused(cli_runner, path: Path) -> str:
    """The one stderr line of ``limit-lap SY250 --track path`` (asserting exit code 2)."""
    from casadrone.cli import app

    r = cli_runner.invoke(app, ["limit-lap", "SY250", "--track", str(path), "--intervals", "2",
                                "--grid-rounds", "0", "--json"])
    lines = r.stderr.splitlines()
    assert r.exit_code == 2, (r.exit_code, r.output)
    assert len(lines) == 1, lines
    assert str(path) in lines[0] and "Traceback" not in r.output
    return lines[0]


@pytest.mark.parametrize("text, keys", [
    # the climb point's 1 m ball wholly above the ceiling (IPOPT: restoration failed, exit 0)
    ("climb_to_m: [0, 0, 50]\nceiling_m: 30\n", ("ceiling_m", "climb_to_m")),
    # ... and wholly below the floor
    ("start_position_m: [0, 0, 5]\nclimb_to_m: [0, 0, 1]\nfloor_m: 3\n",
     ("floor_m", "climb_to_m")),
    # a time limit below the limit lap's shortest leg (1 ms): "Ill-posed problem", exit 0
    ("time_limit_s: 0.0005\n", ("time_limit_s",)),
])
def test_limit_lap_refuses_what_its_box_cannot_hold(cli_runner, tmp_path, text, keys):
    path = tmp_path / "track.yaml"
    path.write_text(text + STRAIGHT.replace("[[20, 0, 1]]", "[[20, 0, 5]]"))
    line = _refused(cli_runner, path)
    assert all(k in line for k in keys), line


def test_target_below_the_default_floor_is_refused_naming_floor_m(cli_runner, tmp_path):
    """No floor_m: the limit lap's floor is 0.1 m below the start or the ground, and a waypoint
    wholly below it was an "infeasible" lap (exit 0) that did not say why."""
    path = tmp_path / "track.yaml"
    path.write_text("name: pit\nwaypoints_m: [[20, 0, -5]]\nstraight: [true]\n")
    line = _refused(cli_runner, path)
    assert "floor_m" in line and "waypoint 1" in line and "no floor_m given" in line


def test_default_floor_check_keeps_what_the_box_keeps():
    """The edges: a ball that reaches the default floor, an explicit floor_m below the
    waypoint, and a given start state (the box has no default floor then) are all posed."""
    ok = {"reaches": "name: t\nwaypoints_m: [[20, 0, -1.05]]\nstraight: [true]\n",
          "floor": "name: t\nwaypoints_m: [[20, 0, -5]]\nstraight: [true]\nfloor_m: -6\n"}
    for name, text in ok.items():
        trk = TrackConfig.model_validate(yaml.safe_load(text))
        assert check_inputs(trk, LimitLapOptions(intervals=10)) == "", name
    trk = TrackConfig.model_validate({"name": "t", "waypoints_m": [[20, 0, -5]],
                                      "straight": [True]})
    assert check_inputs(trk, LimitLapOptions(intervals=10, start_state=(0.0,) * 16)) == ""
    assert check_inputs(trk, LimitLapOptions(intervals=10)).startswith("floor_m: waypoint 1")


@pytest.mark.parametrize("centre", ["[1, 2]", "[1, 2, .nan]", "[1, 2, 1e12]", "abc"])
def test_bad_gate_centre_is_one_line_naming_the_gate(cli_runner, tmp_path, centre):
    """The waypoints are copied from the gate centres; a bad centre was reported twice, once
    under waypoints_m, a key the file does not have."""
    path = tmp_path / "gates.yaml"
    path.write_text(ONE_GATE.format(centre=centre))
    line = _refused(cli_runner, path)
    assert "gates.0.centre_m" in line and "waypoints_m" not in line


def test_good_gate_centres_are_still_the_waypoints():
    trk = load(TrackConfig, "configs/tracks/multigp-cdra-gates.yaml")
    assert trk.gates is not None
    assert [tuple(g.centre_m) for g in trk.gates] == [tuple(w) for w in trk.waypoints_m]


def test_top_speed_counts_the_finish():
    """A lap has one node more than commands; a lap that finishes on a straight is fastest at
    its last node, which the top speed (and the thrusts there) left out."""
    import numpy as np

    from casadrone.airframe import build_airframe
    from casadrone.config.airframe import load_airframe
    from casadrone.limit.check import lap_propulsion

    x = np.zeros((3, 16))
    x[:, 3], x[:, 12:16] = [0.0, 20.0, 35.0], [[0.5] * 4, [0.6] * 4, [0.7, 0.8, 0.9, 1.0]]
    r = lap_propulsion(build_airframe(load_airframe("SY250")), x, np.full((2, 4), 1.0))
    assert r["top_speed_m_s"] == 35.0
    assert r["thrust_at_top_speed_n"] == [0.7, 0.8, 0.9, 1.0]
    assert len(r["speed_m_s"]) == 2  # per node: the nodes with a command (the figure's pairs)


def test_text_names_a_missing_reference_and_the_rotor_units():
    """No point-mass reference converged (a 30 m straight at 20 intervals): the text said
    "point-mass reference nan s"; the start state's rotor states came without a unit, N with
    ``paper`` and rad/s with ``propeller``."""
    import math

    from casadrone.cli.limit import _reference_text, _start_text

    assert _reference_text(math.nan, 3.88) == "point-mass reference: none converged"
    assert _reference_text(3.6977, 3.88) == "point-mass reference 3.698 s"
    # a relaxation's optimum cannot be slower than the lap: such a figure is a local optimum
    slower = _reference_text(1.192, 0.996)
    assert slower.startswith("point-mass reference 1.192 s") and "no bound" in slower
    x = [0.0] * 12 + [0.78] * 4
    assert _start_text({"start_state": x})[0].endswith("rotor thrusts (0.78, 0.78, 0.78, 0.78) N")
    assert _start_text({"start_state": x[:12] + [1500.0] * 4}, "propeller")[0].endswith(
        "rotor speeds (1500, 1500, 1500, 1500) rad/s")


@pytest.mark.parametrize("track", ["", "  "])
def test_empty_track_name_is_refused_not_the_default_track(cli_runner, track):
    """``--track ""`` (an unset shell variable) read as no --track and flew the paper track for
    minutes; it is refused, naming the flag and the shipped tracks."""
    from casadrone.cli import app

    r = cli_runner.invoke(app, ["limit-lap", "SY250", "--track", track, "--json"])
    lines = r.stderr.splitlines()
    assert r.exit_code == 2 and len(lines) == 1, (r.exit_code, r.output)
    assert lines[0].startswith("--track") and "paper-rectangle" in lines[0]
    assert r.stdout == ""


def test_track_limits_section_names_only_track_keys_and_result_keys():
    """docs/concepts/limit-lap.md, "Track limits", lists the track YAML's limit-lap keys; a bare
    key there reads as one. ``gate_clearance_m`` was given bare, but it is a LimitLapOptions
    field (a track with it is refused: unknown key); options are named with their class."""
    import dataclasses
    import re

    from casadrone.config.track import BodyRateLimit, GateConfig, StartConfig
    from casadrone.limit.result import LimitLap

    text = (Path(__file__).parents[2] / "docs" / "concepts" / "limit-lap.md").read_text(
        encoding="utf-8")
    section = text[text.index("## Track limits"):text.index("## Starts and checks")]
    bare = set(re.findall(r"(?<![.\w])`([a-z][a-z0-9]*_[a-z0-9_]+)`", section))
    known = set().union(*(m.model_fields for m in (TrackConfig, GateConfig, StartConfig,
                                                     BodyRateLimit)))
    known |= {f.name for f in dataclasses.fields(LimitLap)}  # what the result reports
    assert bare <= known, sorted(bare - known)


def test_json_param_sensitivity_is_keyed_by_parameter_name():
    """--json's param_sensitivity was a bare list; each value now stands by its parameter's
    name (the model's order), and a failed lap (no values) gives none."""
    from casadrone.cli.limit import named_parameters
    from casadrone.model import param_names

    names = param_names("paper")
    named = named_parameters(range(len(names)), "paper")
    assert list(named) == list(names) and named["K"] == names.index("K")
    assert named_parameters([], "paper") == {}
    assert len(named_parameters([0.0] * len(param_names("propeller")), "propeller")) == len(
        param_names("propeller"))



def test_a_start_without_a_guess_is_listed_with_why(monkeypatch, tmp_path):
    """A cold start whose guess needs a lap of its own (the point-mass reference, a coarse or
    fine grid's lap) was left out of the result when that lap failed: asked for alone, the lap
    said "no start ran". It is now a failed start saying why, in ``starts`` and the reason."""
    import casadrone.limit.starts as starts
    from casadrone.config.airframe import load_airframe
    from casadrone.limit.lap import design_limit_lap

    monkeypatch.setitem(starts.COLD_STARTS, "point-mass", lambda pb, lap_of: None)
    path = tmp_path / "straight.yaml"
    path.write_text(STRAIGHT, encoding="utf-8")
    lap = design_limit_lap(load_airframe("SY250"), load(TrackConfig, path),
                           LimitLapOptions(intervals=10, starts=("point-mass",),
                                           fallback_reference=None, point_mass_reference=False,
                                           sensitivities=False))
    assert not lap.completed
    (only,) = lap.starts
    assert only.start == "point-mass" and not only.success
    assert only.return_status == "not run: no point-mass reference converged"
    assert "point-mass: not run: no point-mass reference converged" in lap.reason
