"""Trim-solver study: the starts as stated, same seed same study, every outcome recorded (never an
exception), roots checked against hand solutions.

Oracles: the hover reference's thrusts sum to m g with zero net moment (numpy, by hand); the
inverted hover root (φ = π) carries ΣT = −m g, thrust pulling "down" in the body = up in the
world; the starts lie in the stated box; the residual history ends where the uncapped solve ends.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.cli.common import jsonable
from casadrone.conditions import OperatingPoint, envelope
from casadrone.config import load_airframe
from casadrone.trim import TrimOptions, initial_guess, residual_norm, trim
from casadrone.trimstudy import (
    OUTCOMES,
    StudyOptions,
    basin_slice,
    draw_starts,
    outcome_of,
    residual_history,
    study_point,
    trim_study,
)

FAST = ("ipopt", "newton")  # Nelder–Mead's ~800 iterations are kept to the tests that need it


@pytest.fixture(scope="module")
def hs210():
    return build_airframe(load_airframe("HS210"))


@pytest.fixture(scope="module")
def small_study(hs210):
    return trim_study(hs210, "hover,forward:40,turn:20:30",
                      StudyOptions(starts=8, seed=3, solvers=FAST))


def net_wrench(frame, T):
    ez = np.array([0.0, 0.0, 1.0])
    M = sum(np.cross(r, t * ez) + s * frame.kappa * t * ez
            for r, t, s in zip(frame.rotor_positions, T, frame.rotor_spins, strict=True))
    return np.concatenate([[np.sum(T)], M])


def test_starts_lie_in_the_stated_box_and_depend_on_the_point_alone(hs210):
    o = StudyOptions(starts=200, seed=7, angle_spread_deg=30.0, command_spread=0.25)
    point = OperatingPoint("forward", 20.0)
    guess = initial_guess(hs210, 20.0)
    starts = draw_starts(guess, point, o)
    assert starts.shape == (201, 6)
    np.testing.assert_array_equal(starts[0], guess)
    assert np.all(np.abs(starts[1:, :2] - guess[:2]) <= math.radians(30.0))
    ratio = starts[1:, 2:] / guess[2:]
    assert np.all((ratio >= 0.75) & (ratio <= 1.25))
    # uniform, not bunched: each half of the box holds about half of the draws (binomial, 5 σ)
    assert abs(np.mean(ratio > 1.0) - 0.5) < 5 * math.sqrt(0.25 / ratio.size)
    np.testing.assert_array_equal(draw_starts(guess, point, o), starts)
    other = draw_starts(guess, OperatingPoint("forward", 25.0), o)
    assert not np.array_equal(other[1:], starts[1:])


def strip_times(study):
    d = study.as_dict()
    d.pop("wall_time_s")
    for p in d["points"]:
        for r in p["results"]:
            r.pop("wall_time_s")
        for s in p["summaries"]:
            for k in [k for k in s if k.startswith("wall_time")]:
                s.pop(k)
    return json.dumps(jsonable(d), sort_keys=True)


def test_same_seed_same_study_other_seed_other_starts(hs210, small_study):
    again = trim_study(hs210, "hover,forward:40,turn:20:30",
                       StudyOptions(starts=8, seed=3, solvers=FAST))
    assert strip_times(again) == strip_times(small_study)
    other = trim_study(hs210, "forward:40", StudyOptions(starts=8, seed=4, solvers=FAST))
    assert not np.array_equal(other.points[0].starts[1:], small_study.points[1].starts[1:])


def test_every_start_has_one_outcome_and_summaries_count_them(small_study):
    for p in small_study.points:
        assert len(p.results) == len(FAST) * 9
        for s in p.summaries:
            assert sum(s.outcomes.values()) == s.starts == 9
            ok = s.outcomes["converged"] + s.outcomes["other-trim"]
            assert s.success_rate == pytest.approx(ok / 9)
            assert s.from_guess == "converged"  # the analytic guess lies in the basin
        for r in p.results:
            assert r.outcome in OUTCOMES
            if r.outcome == "converged":
                assert r.distance <= 1e-4 and r.solution >= 0
        # every solution's representative really is a root: residual by the trim's own norm
        for sol in p.solutions:
            assert residual_norm(p_frame(small_study), sol.z, p.point.condition,
                                 **p.point.kwargs) <= 1e-9


def p_frame(study):
    return build_airframe(load_airframe(study.airframe))


def test_hover_reference_balances_weight_and_moments_by_hand(hs210, small_study):
    hover = small_study.points[0]
    T = hover.reference[2:] * hs210.thrust_gain
    wrench = net_wrench(hs210, T)
    np.testing.assert_allclose(wrench[0], hs210.mass * hs210.gravity, rtol=0, atol=1e-12)
    np.testing.assert_allclose(wrench[1:], 0.0, atol=1e-14)  # observed ~1e-17 N·m


def test_inverted_hover_is_an_out_of_domain_root_with_negative_thrust(hs210):
    guess = initial_guess(hs210)
    z0 = np.r_[math.pi - 0.2, 0.1, -guess[2:]]
    tp = trim(hs210, solver="newton", options=TrimOptions(initial_guess=tuple(z0)))
    assert not tp.success and "tilt" in tp.message
    assert tp.residual_norm < 1e-9
    np.testing.assert_allclose(tp.thrusts.sum(), -hs210.mass * hs210.gravity, atol=1e-12)
    assert outcome_of(tp, math.nan, StudyOptions()) == "out-of-domain"


def test_a_diverging_start_is_an_outcome_not_an_exception(hs210):
    nan_start = TrimOptions(initial_guess=(math.nan,) * 6)
    for solver in ("ipopt", "newton", "nelder-mead"):
        tp = trim(hs210, "forward", 10.0, solver, nan_start)
        assert outcome_of(tp, math.nan, StudyOptions()) == "diverged", tp.message
    capped = StudyOptions(starts=5, solvers=FAST, trim=TrimOptions(max_iterations=1))
    p = study_point(hs210, OperatingPoint("forward", 30.0), capped)
    counts = {o: sum(s.outcomes[o] for s in p.summaries) for o in OUTCOMES}
    assert counts["failed"] > 0 and sum(counts.values()) == 12


def test_nelder_mead_from_the_study_agrees_with_newton(hs210):
    o = StudyOptions(starts=1, seed=0, angle_spread_deg=10.0, command_spread=0.2)
    p = study_point(hs210, OperatingPoint("climb", 10.0, -30.0), o)
    nm = [r for r in p.results if r.solver == "nelder-mead"]
    assert [r.outcome for r in nm] == ["converged", "converged"]
    assert max(r.distance for r in nm) < 6e-12  # observed 6e-13


def test_residual_history_starts_at_the_start_and_ends_at_the_solve(hs210):
    point = OperatingPoint("turn", 10.0, turn_rate_dps=60.0)
    z0 = initial_guess(hs210, 10.0, turn_rate_dps=60.0) + np.r_[0.3, -0.2, 0, 0, 0, 0]
    for solver in FAST:
        h = residual_history(hs210, point, solver, z0)
        full = trim(hs210, "turn", 10.0, solver, TrimOptions(initial_guess=tuple(z0)),
                    turn_rate_dps=60.0)
        assert h.iterations[0] == 0 and h.iterations[-1] == full.iterations
        assert h.residual_norm[0] == pytest.approx(
            residual_norm(hs210, z0, "turn", 10.0, turn_rate_dps=60.0), rel=1e-12)
        assert h.residual_norm[-1] == full.residual_norm


def test_basin_slice_centre_is_the_analytic_guess(hs210):
    o = StudyOptions(solvers=FAST, angle_spread_deg=40.0)
    b = basin_slice(hs210, OperatingPoint("forward", 20.0), o, grid=3)
    np.testing.assert_allclose(b.phi_offset_deg, [-40, 0, 40])
    for solver in FAST:
        assert b.outcomes[solver].shape == (3, 3)
        assert OUTCOMES[b.outcomes[solver][1, 1]] == "converged"


def test_as_dict_is_json(small_study):
    d = json.loads(json.dumps(jsonable(small_study.as_dict())))
    assert d["airframe"] == "HS210" and len(d["points"]) == 3
    assert d["points"][2]["point"] == {"condition": "turn", "label": "turn 20 m/s 30°/s",
                                       "speed_mps": 20.0, "climb_angle_deg": 0.0,
                                       "turn_rate_dps": 30.0}
    assert d["options"]["seed"] == 3 and d["options"]["trim"]["tolerance"] == 1e-9


@pytest.mark.parametrize(("field", "value"), [
    ("starts", -1), ("angle_spread_deg", 90.0), ("command_spread", 1.0),
    ("solvers", ("bfgs",)), ("solvers", ("newton", "newton")), ("reference_solver", "x"),
    ("distinct_tolerance", 0.0), ("seed", -1),
])
def test_bad_study_options_name_the_field(field, value):
    with pytest.raises(ValueError, match=f"^{field}: "):
        StudyOptions(**{field: value})


def test_study_results_are_frozen(small_study):
    with pytest.raises(dataclasses.FrozenInstanceError):
        small_study.points[0].summaries[0].success_rate = 1.0  # type: ignore[misc]


def test_envelope_spec():
    pts = envelope("hover,forward:0..40/10,climb:10:-30,turn:10:60")
    assert [p.label for p in pts] == ["hover", "forward 0 m/s", "forward 10 m/s",
                                      "forward 20 m/s", "forward 30 m/s", "forward 40 m/s",
                                      "climb 10 m/s -30°", "turn 10 m/s 60°/s"]
    default = envelope()
    assert max(p.speed_mps for p in default if p.condition == "forward") >= 40
    assert {p.condition for p in default} == {"hover", "forward", "climb", "turn"}
    assert any(p.climb_angle_deg < 0 for p in default) and any(
        p.climb_angle_deg > 0 for p in default)
    for bad, words in [("loop", "unknown condition"), ("climb:10", "takes 2 value"),
                       ("forward:10..0/5", "speed range"), ("turn:10:nan", "turn_rate_dps")]:
        with pytest.raises(ValueError, match=words):
            envelope(bad)


def test_study_of_a_propeller_frame_varies_the_shared_unknowns():
    # rotor speeds are further unknowns of the propeller model: the starts vary (φ, θ, δ) and
    # the trim starts the rotors at its own guess; hover's roots still balance the weight
    frame = build_airframe(load_airframe("SY250-propeller"))
    study = trim_study(frame, "hover,forward:10", StudyOptions(starts=3, solvers=("newton",)))
    for p in study.points:
        assert p.starts.shape == (4, 6)
        assert p.summary("newton").from_guess == "converged"
    ref = study.points[0].reference
    tp = trim(frame, "hover", solver="newton", options=TrimOptions(initial_guess=tuple(ref)))
    np.testing.assert_allclose(tp.thrusts.sum(), frame.mass * frame.gravity, rtol=2e-15)  # 2e-16


def test_an_unconverged_solve_is_no_root(hs210):
    """Capped at 3 iterations, both solvers reach the forward-flight trim from the analytic guess
    (3 iterations) and from none of the 6 drawn starts (seed 0: residuals 1e-3 to 18): the
    failed solves belong to no solution and have no distance; the one solution is a root
    (residual by the trim's own norm) found once by each solver."""
    capped = StudyOptions(starts=6, seed=0, solvers=FAST, trim=TrimOptions(max_iterations=3))
    p = study_point(hs210, OperatingPoint("forward", 20.0), capped)
    failed = [r for r in p.results if r.outcome == "failed"]
    assert {r.outcome for r in p.results if r.start == 0} == {"converged"}
    assert len(failed) == len(p.results) - len(FAST)  # the situation the test is about
    assert all(r.residual_norm > 1e-9 for r in failed)
    for r in failed:
        assert r.solution == -1 and math.isnan(r.distance), (r.solver, r.start)
    assert len(p.solutions) == 1 and p.solutions[0].found_by == {s: 1 for s in FAST}
    assert residual_norm(hs210, p.solutions[0].z, "forward", 20.0) <= 1e-9
    assert [p.summary(s).solutions for s in FAST] == [1, 1]


@pytest.mark.parametrize("eps", [1e-6, 1e-3])
def test_roots_either_side_of_phi_pi_are_one(eps):
    """φ = π − ε and φ = −π + ε are 2ε apart (the angle wraps at ±π): the same root within
    the study's tolerance, one cluster; φ = 0 against π − ε is π − ε apart. Likewise θ."""
    from casadrone.trimstudy import _cluster, _distance

    commands = np.array([-0.3, -0.3, -0.3, -0.3])
    for angle in (0, 1):  # φ, then θ
        a, b = np.r_[0.1, 0.1, commands], np.r_[0.1, 0.1, commands]
        a[angle], b[angle] = math.pi - eps, -math.pi + eps
        assert _distance(a, b) == pytest.approx(2 * eps, rel=1e-6)
        assert _distance(b, a) == pytest.approx(2 * eps, rel=1e-6)
        labels, reps = _cluster([a, b], tol=3 * eps)
        assert labels == [0, 0] and len(reps) == 1
        c = a.copy()
        c[angle] = 0.0
        assert _distance(c, a) == pytest.approx(math.pi - eps, rel=1e-9)
