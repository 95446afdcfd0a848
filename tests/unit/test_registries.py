"""Extension points: a new export format, trim solver, integrator or target kind is one registry
entry and its implementation; the API, the CLI (and for a target kind the track schema, the NLP,
the re-simulation check and the figures) take it with no other change."""

from __future__ import annotations

import importlib
import runpy
from pathlib import Path

import numpy as np
import pytest
import typer

from casadrone import export as export_mod
from casadrone.cli import app
from casadrone.trim import TRIM_SOLVERS

#: the modules (``casadrone.simulate`` and ``casadrone.trim`` are also the stage functions)
simulate_mod = importlib.import_module("casadrone.simulate")


@pytest.fixture
def registered(monkeypatch):
    """Add ``name: value`` to a registry for one test."""

    def add(registry: dict, name: str, value) -> None:
        monkeypatch.setitem(registry, name, value)

    return add


def test_a_new_export_format_reaches_the_api_and_the_cli(registered, cli_runner, tmp_path):
    def names(src, _options) -> str:  # a format that lists the rotor labels, one a line
        return "".join(f"{label}\n" for label in ("FR", "FL", "RL", "RR"))

    registered(export_mod.FORMATS, "rotors", export_mod.ExportFormat(".txt", "rotor labels", names))
    result = cli_runner.invoke(app, ["export", "SY250", "--format", "rotors"])
    assert result.exit_code == 0, result.output
    assert result.stdout == "FR\nFL\nRL\nRR\n"
    from casadrone.export.source import source_of

    src = source_of("SY250", None, None)
    assert export_mod.default_name(src, "rotors") == "SY250-rotors.txt"


def test_a_new_trim_solver_reaches_trim_and_the_cli(registered, cli_runner):
    calls = []

    def newton_again(z0, p, op, o):  # the newton solver under another name, counted
        calls.append(1)
        return TRIM_SOLVERS["newton"](z0, p, op, o)

    registered(TRIM_SOLVERS, "newton-again", newton_again)
    from casadrone.airframe import build_airframe
    from casadrone.config.airframe import load_airframe

    trim_module = importlib.import_module("casadrone.trim")
    frame = build_airframe(load_airframe("SY250"))
    mine = trim_module.trim(frame, "hover", solver="newton-again")
    ref = trim_module.trim(frame, "hover", solver="newton")
    assert calls and mine.success and mine.solver == "newton-again"
    assert np.array_equal(mine.x0, ref.x0)  # the same solver: the same point, to the bit
    result = cli_runner.invoke(app, ["trim", "SY250", "--solver", "newton-again", "--json"])
    assert result.exit_code == 0, result.output
    assert '"solver": "newton-again"' in result.stdout


def test_a_new_integrator_is_a_cli_and_problem_choice(registered):
    registered(simulate_mod.INTEGRATORS, "rk4-chunked", simulate_mod.INTEGRATORS["rk4"])
    group = typer.main.get_command(app)
    parent = group.make_context("casadrone", ["simulate"], resilient_parsing=True)
    command = group.get_command(parent, "simulate")
    ctx = command.make_context("simulate", ["SY250", "--integrator", "rk4-chunked"],
                               parent=parent)
    assert ctx.params["integrator"] == "rk4-chunked"
    from casadrone.config.problem import read_problem
    from casadrone.optimise.checks import problem_problems

    problem = read_problem("quick", ["integrator=rk4-chunked"])
    assert not [k for k, _ in problem_problems(problem) if k == "integrator"]
    problem = read_problem("quick", ["integrator=euler"])
    assert [k for k, _ in problem_problems(problem) if k == "integrator"] == ["integrator"]


# --------------------------------------------------------------------------------------------
# A new target kind of the limit lap: the shipped example, examples/plugins/ellipse_gate.py
# --------------------------------------------------------------------------------------------

ELLIPSE_PLUGIN = Path(__file__).resolve().parents[2] / "examples" / "plugins" / "ellipse_gate.py"


@pytest.fixture
def ellipse():
    """The example's kind, registered by running the plugin, and unregistered after the test."""
    from casadrone.targets import TARGET_KINDS

    saved = dict(TARGET_KINDS)
    yield runpy.run_path(str(ELLIPSE_PLUGIN))["ELLIPSE"]
    TARGET_KINDS.clear()
    TARGET_KINDS.update(saved)


def _elliptic_gate_track(shape: str = "ellipse", width_m: float = 2.0, height_m: float = 1.0):
    from casadrone.config.track import TrackConfig

    return TrackConfig.model_validate({
        "name": "one gate", "start_position_m": [0, 0, 2], "straight": [True, True],
        "waypoints_m": [[10, 0, 2], [20, 0, 2]],
        "gates": [{"centre_m": [10, 0, 2], "heading_deg": 0, "shape": shape,
                   "width_m": width_m, "height_m": height_m},
                  {"centre_m": [20, 0, 2], "heading_deg": 0, "width_m": 2, "height_m": 2}]})


def test_a_new_target_kind_is_a_track_shape_with_its_own_packing_and_refusal(ellipse):
    """The track schema takes the new shape only while the kind is registered; the targets pack
    the ellipse as the kind says (semi-axes 1 × 0.5 m scaled by 1 − 0.1 / 0.5 = 0.8, by hand);
    a clearance of the smaller semi-axis is refused, naming the gate."""
    from pydantic import ValidationError

    from casadrone.limit.lap import LimitLapOptions, check_inputs, track_targets
    from casadrone.targets import TARGET_KINDS, TARGET_SIZE

    track = _elliptic_gate_track()
    targets = track_targets(track, LimitLapOptions(gate_clearance_m=0.1))
    assert targets.kinds == ("ellipse", "gate")
    first = targets.vector[:TARGET_SIZE]
    np.testing.assert_allclose(first[12:14], [0.8, 0.4], rtol=1e-15)
    assert check_inputs(track, LimitLapOptions(gate_clearance_m=0.49)) == ""
    assert check_inputs(track, LimitLapOptions(gate_clearance_m=0.5)).startswith("gate 1:")
    del TARGET_KINDS["ellipse"]
    with pytest.raises(ValidationError, match="shape"):
        _elliptic_gate_track()


def test_a_new_target_kind_reaches_the_nlp_rows_the_check_and_the_outline(ellipse):
    """One property ties the three together: at random points of the gate plane the NLP's rows
    accept exactly the points the re-simulation check gives a zero miss; outside, the miss is
    never below the distance to the ellipse found by sampling its boundary densely (an
    independent measure); the outline the figures draw lies on the boundary."""
    import casadi as ca

    from casadrone.limit.lap import LimitLapOptions, track_targets
    from casadrone.plots import target_outlines
    from casadrone.targets import TARGET_SIZE, target_miss, target_outline, target_rows

    targets = track_targets(_elliptic_gate_track(), LimitLapOptions(gate_clearance_m=0.0))
    tp = targets.vector[:TARGET_SIZE]
    x, vw = ca.SX.sym("x", 16), ca.SX.sym("v", 3)
    rows = target_rows(x, vw, ca.DM(tp), "ellipse")
    g = ca.Function("g", [x, vw], [ca.vertcat(*[r[0] for r in rows])])
    lower = np.array([r[1] for r in rows])
    upper = np.array([r[2] for r in rows])
    rng = np.random.default_rng(21)
    for lat, up in rng.uniform(-1.5, 1.5, (400, 2)):
        pos = np.array([10.0, lat, 2.0 + up])  # the gate plane x = 10, flown east
        values = np.array(g(np.r_[pos, np.zeros(13)], [1.0, 0.0, 0.0])).ravel()
        accepted = bool(np.all(values >= lower - 1e-12) and np.all(values <= upper + 1e-12))
        miss = target_miss(pos, tp, "ellipse")
        assert accepted == (miss == 0.0), (lat, up, miss)
        if not accepted:
            s = np.linspace(0, 2 * np.pi, 200_001)
            sampled = np.min(np.hypot(lat - np.cos(s), up - 0.5 * np.sin(s)))
            assert miss >= sampled - 1e-9
    outline = target_outline(tp, "ellipse")
    np.testing.assert_allclose(((outline[:, 1] / 1.0) ** 2 + ((outline[:, 2] - 2.0) / 0.5) ** 2),
                               1.0, rtol=1e-12)
    assert max(target_miss(p, tp, "ellipse") for p in outline) < 1e-12
    assert np.array_equal(target_outlines(targets)[0], outline)  # what the figures draw


def _gate_lap(kind: str, half_width: float, half_height: float) -> tuple[float, float]:
    """(lap time, sideways position at the gate) of a double integrator (|a| ≤ 2 per axis)
    from rest at the origin through a gate at x = 5 whose centre is 6 m to the left, flown east,
    to (10, 0, 0) (the sideways flight sets the time)."""
    from casadrone.limit.nlp import Layout, build_nlp, solve
    from casadrone.targets import TARGET_SIZE
    from tests.unit.test_limitlap import _double_integrator

    kinds, N = (kind, "ball"), 20
    nlp = build_nlp(_double_integrator(), Layout(kinds, N))
    targets = np.zeros((2, TARGET_SIZE))
    targets[:, 0:3] = [[5, 6, 0], [10, 0, 0]]
    targets[:, 3:12] = np.eye(3).ravel()  # n east, a north (left), b up
    targets[0, 12:14] = half_width, half_height
    targets[:, 15:] = np.tile([0.0, 0.0, 1.0], 8)
    P = np.concatenate([[0.0], np.zeros(6), targets.ravel()])
    M = 2 * N
    lbx = nlp.pack(np.full(2, 1e-2), np.r_[np.zeros((1, 6)), np.full((M, 6), -np.inf)],
                   np.full((M, 3), -2.0))
    ubx = nlp.pack(np.full(2, 1e2), np.r_[np.zeros((1, 6)), np.full((M, 6), np.inf)],
                   np.full((M, 3), 2.0))
    X0 = np.zeros((M + 1, 6))
    X0[:, 0] = np.linspace(0, 10, M + 1)
    sol = solve(nlp, nlp.pack(np.full(2, 1.5), X0, np.zeros((M, 3))), P, lbx, ubx)
    assert sol.success, sol.return_status
    T, X, _ = nlp.unpack(sol.point.w)
    return float(T.sum()), float(X[N, 1])


def test_a_lap_through_a_new_target_kind_matches_the_kinds_it_generalises(ellipse):
    """Solved through the new kind's NLP rows: an ellipse with equal axes is the circle of the
    built-in kind (the same lap); a 2 × 1 m ellipse lies inside the 2 × 1 m rectangle and
    touches it where the lap passes (at the side, level with the centre), so its lap is the
    rectangle's (no faster, to the solver's tolerance) and passes at y = 6 − 1."""
    t_ellipse, y_ellipse = _gate_lap("ellipse", 0.5, 0.5)
    t_circle, y_circle = _gate_lap("circle", 0.5, 0.5)
    np.testing.assert_allclose(t_ellipse, t_circle, rtol=1e-8)  # observed 8e-10
    np.testing.assert_allclose(y_ellipse, y_circle, atol=1e-7)  # observed 7.5e-9 m
    t_wide, y_wide = _gate_lap("ellipse", 1.0, 0.5)
    t_rect, _ = _gate_lap("gate", 1.0, 0.5)
    assert t_rect * (1 - 1e-8) <= t_wide <= t_rect * (1 + 1e-8)  # observed +5.5e-10
    np.testing.assert_allclose(y_wide, 5.0, atol=1e-7)  # observed 5e-9 m
