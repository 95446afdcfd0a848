"""The limit lap's effort under the ``propeller`` propulsion model (casadrone.model.rotor_thrusts,
casadrone.indices.limit_lap_effort, casadrone.codesign.nlp.effort).

Oracles: at zero inflow the thrust is the static curve ρ c_T0 D⁴ n² of
:func:`casadrone.propulsion.static_thrust` (a closed form written apart from the model); with
inflow, T = ρ (c₀ D⁴ n² + c₁ D³ n v + c₂ D² v²) recomputed here with numpy from the rotor positions
and the smoothed positive inflow of the module docstring; the effort of a lap held at rest equals
the paper formula on those static thrusts; and the co-design NLP's lifted effort equals that
numpy recomputation from the unpacked nodes and the index of the same lap.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.config import load_airframe
from casadrone.indices import EFFORT_SMOOTHING_N, INDICES
from casadrone.limit.lap import LimitLap
from casadrone.model import rotor_thrust_function
from casadrone.propulsion import airframe_values, static_thrust

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def frame():
    return build_airframe(load_airframe(ROOT / "configs/airframes/SY250-propeller.yaml"))


def numpy_thrusts(frame, vel, rates, w):
    """T_i of each rotor (N) from body velocity, rates and rotor speeds (rad/s), with numpy."""
    q = airframe_values(frame)
    r = np.asarray(frame.rotor_positions, float)
    v_ax = (vel[None, :] + np.cross(rates[None, :], r))[:, 2]
    eps = q["inflow_eps"]
    v = 0.5 * (v_ax + np.sqrt(v_ax ** 2 + eps ** 2)) - 0.5 * eps  # smoothed max(v, 0)
    n, D = w / (2 * np.pi), q["prop_D"]
    return q["rho"] * (q["ct0"] * D**4 * n**2 + q["ct1"] * D**3 * n * v + q["ct2"] * D**2 * v**2)


def test_thrust_at_zero_inflow_is_the_static_curve(frame):
    rng = np.random.default_rng(0)
    w = rng.uniform(0.0, 3000.0, 4)
    T = np.asarray(rotor_thrust_function("propeller")(np.zeros(3), np.zeros(3), w, frame.p))
    expected = [static_thrust(airframe_values(frame), wi) for wi in w]
    np.testing.assert_allclose(T.ravel(), expected, rtol=1e-12)  # observed ~1e-16
    # paper: the rotor states are the thrusts
    paper = build_airframe(load_airframe(ROOT / "configs/airframes/SY250.yaml"))
    np.testing.assert_array_equal(
        np.asarray(rotor_thrust_function("paper")(np.ones(3), np.ones(3), w, paper.p)).ravel(),
        w)


def test_thrust_with_inflow_equals_numpy(frame):
    rng = np.random.default_rng(1)
    for _ in range(5):
        vel, rates = rng.normal(0, 8, 3), rng.normal(0, 5, 3)
        w = rng.uniform(500.0, 3000.0, 4)
        T = np.asarray(rotor_thrust_function("propeller")(vel, rates, w, frame.p)).ravel()
        np.testing.assert_allclose(T, numpy_thrusts(frame, vel, rates, w), rtol=1e-12)
        # axial inflow through a disc lowers its thrust below the static curve's (c₁, c₂ < 0)
        through = (vel + np.cross(rates, frame.rotor_positions))[:, 2] > 0.5
        static = np.array([static_thrust(airframe_values(frame), wi) for wi in w])
        assert np.all(T[through] < static[through])


def test_effort_index_at_rest_is_the_paper_formula_on_static_thrusts(frame):
    """Rotor speeds held at 1500 rad/s for 1 s then 2500 rad/s for 0.5 s, the frame at rest:
    effort = 4 (T(1500)^1.5 · 1 + T(2500)^1.5 · 0.5), T the static curve (the δ = 0.01 N smoothing
    changes it by ~1e-5 relative); without the airframe vector the index refuses."""
    t = np.array([0.0, 1.0, 1.5])
    x = np.zeros((3, 16))
    x[0, 12:16], x[1, 12:16], x[2, 12:16] = 1500.0, 2500.0, 800.0  # the last node holds none
    lap = LimitLap(status="completed", reason="", lap_time_s=1.5, t=t, x=x, u=np.zeros((2, 4)),
                   propulsion="propeller", params=np.asarray(frame.p, float))
    q = airframe_values(frame)
    expected = 4 * (static_thrust(q, 1500.0) ** 1.5 * 1.0 + static_thrust(q, 2500.0) ** 1.5 * 0.5)
    assert INDICES["effort"](lap) == pytest.approx(expected, rel=1e-4)
    # the same states read as paper thrusts would be 1500 N: the kind decides what they are
    assert INDICES["effort"](replace(lap, propulsion="paper")) > 1e3 * expected
    with pytest.raises(ValueError, match="airframe vector"):
        INDICES["effort"](replace(lap, params=np.zeros(0)))


def test_effort_is_posed_for_a_propeller_airframe():
    """A problem with the effort index on a propeller airframe has no finding about it."""
    from casadrone.config.problem import ProblemConfig
    from casadrone.optimise.checks import problem_problems

    def problem(airframe: str):
        return ProblemConfig.model_validate({
            "name": "p", "airframe": f"configs/airframes/{airframe}.yaml",
            "variables": [{"name": "alpha_deg", "lower": 70.0, "upper": 90.0}],
            "objectives": [{"index": "J3_limit"}, {"index": "effort"}]})

    for name in ("SY250-propeller", "SY250"):
        assert not [m for _, m in problem_problems(problem(name)) if "effort" in m]


def test_codesign_effort_equals_numpy_and_the_index():
    """The co-design NLP's lifted effort (ε row on effort, short track, 16 intervals, ~12 s)
    equals the effort recomputed with numpy from the unpacked nodes (thrusts by
    :func:`numpy_thrusts` on the frame p(θ)) and the index of the same lap as a LimitLap."""
    from casadrone.codesign.checks import load_codesign_problem
    from casadrone.codesign.driver import constrained, initial_vector, prepare, start_points
    from casadrone.limit.starts import trajectory

    prep = prepare(load_codesign_problem(
        str(ROOT / "tests/data/codesign/short-propeller.yaml"), []))
    (_, theta), *_ = start_points(prep)
    z0 = initial_vector(prep, theta)
    assert z0 is not None
    eps = constrained(prep, ("effort",))
    z = eps.nlp.full(z0)
    ws, _ = prep.nlp.split(z0)
    part = prep.nlp.parts[0]
    legs, X, _ = part.nlp.unpack(ws[0])
    cfg = prep.config(theta)
    fr = build_airframe(cfg)
    n = part.nlp.layout.intervals
    h = np.repeat(legs / n, n)
    T = np.array([numpy_thrusts(fr, x[3:6], x[6:9], x[12:16]) for x in X[:-1]])
    power = np.sum((T ** 2 + EFFORT_SMOOTHING_N ** 2) ** 0.75, axis=1)
    np.testing.assert_allclose(z[len(z0):], np.cumsum(power * h), rtol=1e-9)  # observed 1e-15
    lap = replace(trajectory(part.nlp, ws[0], part.nlp.layout), propulsion="propeller",
                  params=np.asarray(fr.p, float))
    assert INDICES["effort"](lap) == pytest.approx(z[-1], rel=1e-9)
    # and the rotor speeds are not thrusts: read as thrusts the sum would be ~10³ larger
    assert np.sum((X[:-1, 12:16] ** 2) ** 0.75 @ np.ones(4) * h) > 100 * z[-1]
