"""Trim conditions beyond hover: level flight, climb, descent and the coordinated turn, each against
a force balance written out here by hand (numpy, scipy's brentq on one scalar), never the model.

Oracles: level flight pitches so that tan θ = D_x / (m g − D_z), D the airframe drag in the world
frame (for a drag along −v, isotropic, this is the textbook tan θ = D / (m g)); a drag-free
climb or descent needs the weight alone (θ = 0, ΣT = m g); a climb with drag balances the
point-mass forces along and across the path; a drag-free coordinated turn banks by
tan φ = −V Ω / g (left turn, left wing down: φ < 0) with ΣT = m √(g² + (V Ω)²), and its rotor
moments balance the gyroscopic moment ω × J ω.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import brentq

from casadrone.airframe import build_airframe
from casadrone.conditions import CONDITION_REGISTRY, CONDITIONS, operating_vector
from casadrone.config import load_airframe
from casadrone.trim import SOLVERS, initial_guess, trim, trim_all

#: Agreement with the hand solutions (rad, N, N·m), about 10x the largest observed: ipopt and
#: newton ≤ 1e-15, Nelder–Mead ≤ 4e-13 (it stops at a residual far below its 1e-6 acceptance).
ATOL = {"ipopt": 1e-14, "newton": 1e-14, "nelder-mead": 5e-12}


@pytest.fixture(scope="module")
def hs210():
    return build_airframe(load_airframe("HS210"))


def isotropic(frame, cda=0.01):
    """``frame`` with the same drag area on every body axis (m²)."""
    return dataclasses.replace(frame, drag_area=np.full(3, cda))


def drag_free(frame):
    return dataclasses.replace(frame, drag_area=np.zeros(3))


def rotation(phi, theta):
    """Body → world R = Ry(θ) Rx(φ) at ψ = 0, written out (positive θ: nose down)."""
    cph, sph, cth, sth = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    Ry = np.array([[cth, 0, sth], [0, 1, 0], [-sth, 0, cth]])
    Rx = np.array([[1, 0, 0], [0, cph, -sph], [0, sph, cph]])
    return Ry @ Rx


def world_drag(frame, theta, v_world):
    """Per-axis quadratic body drag −½ ρ CdA_i |v_i| v_i, rotated to the world (wings level)."""
    R = rotation(0.0, theta)
    vb = R.T @ v_world
    return R @ (-0.5 * frame.air_density * frame.drag_area * np.abs(vb) * vb)


def pitch_by_hand(frame, V, gamma):
    """θ of straight flight along (cos γ, 0, sin γ) at V: the thrust (sin θ, 0, cos θ) T cancels
    weight and drag, so T sin θ = −D_x and T cos θ = m g − D_z; one scalar root in θ."""
    v = V * np.array([math.cos(gamma), 0.0, math.sin(gamma)])
    mg = frame.mass * frame.gravity

    def gap(theta):
        D = world_drag(frame, theta, v)
        return math.sin(theta) * (mg - D[2]) + math.cos(theta) * D[0]

    return brentq(gap, -1.2, 1.2, xtol=1e-15)


def gyro_moment(frame, tp):
    """ω × J ω at the trim's body rates (N·m)."""
    w = tp.x0[6:9]
    return np.cross(w, frame.inertia @ w)


def rotor_moments(frame, T):
    ez = np.array([0.0, 0.0, 1.0])
    return sum(np.cross(r, t * ez) + s * frame.kappa * t * ez
               for r, t, s in zip(frame.rotor_positions, T, frame.rotor_spins, strict=True))


@pytest.mark.parametrize("V", [5.0, 20.0, 40.0])
def test_level_flight_pitch_against_the_drag_balance(hs210, V):
    frame = isotropic(hs210)
    theta = pitch_by_hand(frame, V, 0.0)
    D = world_drag(frame, theta, np.array([V, 0.0, 0.0]))
    mg = frame.mass * frame.gravity
    assert math.tan(theta) == pytest.approx(-D[0] / (mg - D[2]), rel=1e-12)
    for tp in trim_all(frame, "forward", V):
        assert tp.success, tp.message
        atol = ATOL[tp.solver]
        np.testing.assert_allclose(tp.x0[10], theta, rtol=0, atol=atol)


@pytest.mark.parametrize("gamma_deg", [30.0, -30.0, 90.0])
def test_drag_free_climb_and_descent_need_the_weight_alone(hs210, gamma_deg):
    frame = drag_free(hs210)
    for tp in trim_all(frame, "climb", 8.0, climb_angle_deg=gamma_deg):
        assert tp.success, tp.message
        atol = ATOL[tp.solver]
        np.testing.assert_allclose(tp.x0[9:11], 0.0, atol=atol)
        np.testing.assert_allclose(tp.thrusts.sum(), frame.mass * frame.gravity, atol=atol)
        np.testing.assert_allclose(tp.thrusts, frame.hover_thrusts(), atol=atol)


@pytest.mark.parametrize("gamma_deg", [20.0, -20.0])
def test_climb_against_the_point_mass_force_balance(hs210, gamma_deg):
    V, gamma = 12.0, math.radians(gamma_deg)
    theta = pitch_by_hand(hs210, V, gamma)
    D = world_drag(hs210, theta, V * np.array([math.cos(gamma), 0.0, math.sin(gamma)]))
    thrust = (hs210.mass * hs210.gravity - D[2]) / math.cos(theta)
    for tp in trim_all(hs210, "climb", V, climb_angle_deg=gamma_deg):
        assert tp.success, tp.message
        atol = ATOL[tp.solver]
        np.testing.assert_allclose(tp.x0[10], theta, rtol=0, atol=atol)
        np.testing.assert_allclose(tp.thrusts.sum(), thrust, rtol=0, atol=atol)
        np.testing.assert_allclose(rotor_moments(hs210, tp.thrusts), 0.0, atol=atol)
        # the body sees the path: world velocity R v_b along (cos γ, 0, sin γ)
        v_world = rotation(tp.x0[9], tp.x0[10]) @ tp.x0[3:6]
        np.testing.assert_allclose(v_world, V * np.array([math.cos(gamma), 0, math.sin(gamma)]),
                                   atol=1e-12)


@pytest.mark.parametrize(("V", "rate_dps"), [(10.0, 60.0), (20.0, -30.0), (30.0, 45.0)])
def test_coordinated_turn_banks_by_tan_phi_equal_V_omega_over_g(hs210, V, rate_dps):
    frame = drag_free(hs210)
    Omega, g = math.radians(rate_dps), frame.gravity
    phi = -math.atan(V * Omega / g)
    for tp in trim_all(frame, "turn", V, turn_rate_dps=rate_dps):
        assert tp.success, tp.message
        atol = ATOL[tp.solver]
        np.testing.assert_allclose(tp.x0[9], phi, rtol=0, atol=atol)
        np.testing.assert_allclose(tp.x0[10], 0.0, atol=atol)
        np.testing.assert_allclose(tp.thrusts.sum(), frame.mass * math.hypot(g, V * Omega),
                                   rtol=0, atol=atol)
        # body rates turn the heading alone: ω = Ω (0, sin φ, cos φ) at θ = 0
        np.testing.assert_allclose(tp.x0[6:9], Omega * np.array([0, math.sin(phi),
                                                                  math.cos(phi)]), atol=atol)
        np.testing.assert_allclose(rotor_moments(frame, tp.thrusts), gyro_moment(frame, tp),
                                   atol=atol)


def test_turn_with_drag_balances_forces_in_the_world_frame(hs210):
    V, Omega = 15.0, math.radians(40.0)
    for tp in trim_all(hs210, "turn", V, turn_rate_dps=40.0):
        assert tp.success, tp.message
        R = rotation(tp.x0[9], tp.x0[10])
        vb = tp.x0[3:6]
        np.testing.assert_allclose(R @ vb, [V, 0, 0], atol=1e-12)
        drag = R @ (-0.5 * hs210.air_density * hs210.drag_area * np.abs(vb) * vb)
        thrust = R @ np.array([0.0, 0.0, tp.thrusts.sum()])
        weight = np.array([0.0, 0.0, -hs210.mass * hs210.gravity])
        centripetal = hs210.mass * np.array([0.0, V * Omega, 0.0])  # Ω e_z × V e_x
        atol = ATOL[tp.solver]
        np.testing.assert_allclose(thrust + drag + weight, centripetal, atol=atol)


def test_analytic_guess_is_the_drag_free_turn(hs210):
    frame = drag_free(hs210)
    z = initial_guess(frame, 10.0, turn_rate_dps=60.0)
    assert z[0] == pytest.approx(-math.atan(10.0 * math.radians(60.0) / frame.gravity), abs=1e-15)
    assert z[1] == 0.0


def test_registry_names_every_condition_and_its_parameters():
    assert CONDITIONS == ("hover", "forward", "climb", "turn")
    assert CONDITION_REGISTRY["turn"].parameters == ("speed_mps", "turn_rate_dps")
    np.testing.assert_allclose(operating_vector("climb", 3.0, 90.0), [3.0, math.pi / 2, 0.0])


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"condition": "hover", "turn_rate_dps": 10.0}, "hover: turn_rate_dps must be 0"),
    ({"condition": "forward", "speed_mps": 5.0, "climb_angle_deg": 5.0},
     "forward: climb_angle_deg must be 0"),
    ({"condition": "climb", "speed_mps": 5.0, "climb_angle_deg": 95.0}, "climb_angle_deg"),
    ({"condition": "turn", "speed_mps": -5.0, "turn_rate_dps": 5.0}, "speed_mps must be >= 0"),
    ({"condition": "turn", "speed_mps": 5.0, "turn_rate_dps": math.inf}, "turn_rate_dps"),
])
def test_bad_operating_points_raise_naming_the_parameter(hs210, kwargs, match):
    with pytest.raises(ValueError, match=match):
        trim(hs210, **kwargs)


def test_solvers_registered(hs210):
    assert SOLVERS == ("ipopt", "nelder-mead", "newton")
