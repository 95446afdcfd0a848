"""Trim: three solvers agree on every reference airframe; analytic oracles computed by hand here.

Oracles: hover thrusts sum to m·g with zero net moment (r_i × T_i e_z + s_i κ T_i e_z, numpy);
an asymmetric frame's front/rear thrust split from pitch and yaw moment balance; forward-flight
force balance in the world frame with body drag ½ρ CdA |v| v, written out here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from casadrone.airframe import build_airframe, random_thetas, with_theta
from casadrone.config.airframe import load_airframe
from casadrone.model import STATE_NAMES
from casadrone.trim import SOLVERS, TrimOptions, TrimPoint, initial_guess, trim, trim_all

REFERENCE = ("SY250", "SY220", "HS200", "HS210", "NSY200")
CASES = [("hover", 0.0), ("forward", 10.0)]
TOL = {"ipopt": 1e-9, "newton": 1e-9, "nelder-mead": 1e-6}


@pytest.fixture(scope="module")
def frames():
    return {name: build_airframe(load_airframe(name)) for name in REFERENCE}


@pytest.fixture(scope="module")
def trims(frames):
    """Every reference airframe × condition × solver, trimmed once for the module."""
    return {
        (name, cond): trim_all(frame, cond, speed)
        for name, frame in frames.items()
        for cond, speed in CASES
    }


def net_wrench(frame, T):
    """[Σ T (N), Mx, My, Mz (N·m)] of rotor thrusts T, by hand: Σ r_i × T_i e_z + s_i κ T_i e_z."""
    ez = np.array([0.0, 0.0, 1.0])
    M = sum(
        np.cross(r, t * ez) + s * frame.kappa * t * ez
        for r, t, s in zip(frame.rotor_positions, T, frame.rotor_spins, strict=True)
    )
    return np.concatenate([[np.sum(T)], M])


def body_to_world(phi, theta):
    """R = Ry(θ) Rx(φ) (ψ = 0), written out: positive θ tips body z towards world +x."""
    cph, sph, cth, sth = math.cos(phi), math.sin(phi), math.cos(theta), math.sin(theta)
    Ry = np.array([[cth, 0, sth], [0, 1, 0], [-sth, 0, cth]])
    Rx = np.array([[1, 0, 0], [0, cph, -sph], [0, sph, cph]])
    return Ry @ Rx


# ---------------------------------------------------------------------------------------------
# Convergence and agreement of the three solvers
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("cond", [c for c, _ in CASES])
@pytest.mark.parametrize("name", REFERENCE)
def test_all_solvers_converge_and_agree(trims, name, cond):
    points = trims[(name, cond)]
    assert [tp.solver for tp in points] == list(SOLVERS)
    for tp in points:
        assert tp.success, f"{name} {cond} {tp.solver}: {tp.message}"
        assert tp.residual_norm <= TOL[tp.solver], (tp.solver, tp.residual_norm)
        assert tp.x0.shape == (16,) and tp.u0.shape == (4,) and tp.thrusts.shape == (4,)
        np.testing.assert_array_equal(tp.thrusts, tp.x0[12:16])
        assert tp.state_names == STATE_NAMES
        np.testing.assert_allclose(tp.x0[[0, 1, 2, 6, 7, 8, 11]], 0.0, atol=0)  # pos, rates, ψ
    ref = points[0].u0
    for tp in points[1:]:
        np.testing.assert_allclose(tp.u0, ref, rtol=0, atol=1e-4)


@pytest.mark.parametrize("solver", SOLVERS)
def test_converges_from_a_perturbed_guess(frames, solver):
    frame = frames["HS210"]
    z0 = initial_guess(frame, 10.0) * [1, 1, 1.3, 0.8, 1.1, 0.9] + [0.1, -0.1, 0, 0, 0, 0]
    tp = trim(frame, "forward", 10.0, solver, TrimOptions(initial_guess=tuple(z0)))
    assert tp.success, tp.message
    assert tp.residual_norm <= TOL[solver]
    ref = trim(frame, "forward", 10.0, "newton")
    np.testing.assert_allclose(tp.u0, ref.u0, rtol=0, atol=1e-4)


def test_nelder_mead_weights_are_used(frames):
    frame = frames["SY250"]
    tp = trim(
        frame, solver="nelder-mead", options=TrimOptions(nelder_mead_weights=(1, 1, 1, 10, 10, 10))
    )
    assert tp.success and tp.residual_norm <= 1e-6
    with pytest.raises(ValueError, match="weights"):
        TrimOptions(nelder_mead_weights=(1.0, 1.0))


def test_trim_point_is_frozen(trims):
    tp = trims[("SY250", "hover")][0]
    assert isinstance(tp, TrimPoint)
    with pytest.raises(AttributeError):
        tp.success = False  # type: ignore[misc]


# ---------------------------------------------------------------------------------------------
# Hover oracles
# ---------------------------------------------------------------------------------------------


def check_hover_oracle(frame, tp, atol=1e-10):
    assert tp.success, tp.message
    wrench = net_wrench(frame, tp.thrusts)
    np.testing.assert_allclose(wrench[0], frame.mass * frame.gravity, rtol=0, atol=atol)
    np.testing.assert_allclose(wrench[1:], 0.0, atol=atol)
    np.testing.assert_allclose(tp.x0[9:11], 0.0, atol=atol)  # level: φ = θ = 0
    np.testing.assert_allclose(tp.u0, tp.thrusts / frame.thrust_gain, rtol=1e-12)


@pytest.mark.parametrize("name", REFERENCE)
def test_hover_thrusts_balance_weight_and_moments(frames, trims, name):
    for tp in trims[(name, "hover")]:
        if tp.solver != "nelder-mead":
            check_hover_oracle(frames[name], tp)


def random_table1_frames(n: int, seed: int = 0):
    """``n`` random airframes inside paper Table 1; geometries with overlapping rotors resampled."""
    base = load_airframe("SY250")
    thetas, _ = random_thetas(base, n, seed)
    return [build_airframe(with_theta(base, th, name=f"rand{i}")) for i, th in enumerate(thetas)]


@pytest.mark.parametrize("solver", SOLVERS)
def test_hover_oracle_on_random_table1_geometries(solver):
    # Nelder–Mead (residual ≤ 1e-6 m/s², rad/s²) checked to a force/moment tolerance of 1e-6.
    atol = 1e-6 if solver == "nelder-mead" else 1e-10
    for frame in random_table1_frames(20):
        # Start away from the analytic answer so the solver does the work.
        z0 = initial_guess(frame) * [1, 1, 1.2, 0.9, 1.1, 0.8] + [0.05, -0.05, 0, 0, 0, 0]
        tp = trim(frame, solver=solver, options=TrimOptions(initial_guess=tuple(z0)))
        check_hover_oracle(frame, tp, atol)


def test_asymmetric_frame_front_rear_split_by_hand():
    # λb = 120 mm, not 110: at β = 70° and 110 mm the tail props (127 mm) would overlap.
    cfg = with_theta(
        load_airframe("SY250"),
        {"alpha_deg": 90.0, "beta_deg": 70.0, "lambda_a_mm": 150.0, "lambda_b_mm": 120.0},
    )
    frame = build_airframe(cfg)
    m, g = frame.mass, frame.gravity
    x_front = 0.150 * math.cos(math.radians(90.0 / 2))
    x_rear = 0.120 * math.cos(math.radians(70.0 / 2))
    # Left/right symmetric, so each pair shares its thrust: 2 Tf + 2 Tr = m g (vertical) and
    # Tf x_front = Tr x_rear (pitch). Yaw: FR, RL spin one way and FL, RR the other, and each
    # pair holds one front and one rear rotor, so yaw balances with these thrusts.
    T_front = m * g / 2 * x_rear / (x_front + x_rear)
    T_rear = m * g / 2 * x_front / (x_front + x_rear)
    assert T_front < T_rear  # the longer nose arm has the smaller share
    for solver in SOLVERS:
        tp = trim(frame, solver=solver)
        atol = 1e-9 if solver != "nelder-mead" else 1e-6
        assert tp.success, tp.message
        np.testing.assert_allclose(
            tp.thrusts, [T_front, T_front, T_rear, T_rear], rtol=0, atol=atol
        )


# ---------------------------------------------------------------------------------------------
# Forward-flight oracle
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", REFERENCE)
def test_forward_flight_balances_drag_and_weight(frames, trims, name):
    frame = frames[name]
    V, rho, cda = 10.0, frame.air_density, frame.drag_area
    for tp in trims[(name, "forward")]:
        phi, theta = tp.x0[9], tp.x0[10]
        assert 0.0 < theta < math.radians(45), "level forward flight pitches nose-down"
        assert abs(phi) < 1e-6
        R = body_to_world(phi, theta)
        v_body = R.T @ np.array([V, 0.0, 0.0])
        np.testing.assert_allclose(tp.x0[3:6], v_body, atol=1e-9)
        drag_body = -0.5 * rho * cda * np.abs(v_body) * v_body
        thrust_world = R @ np.array([0.0, 0.0, tp.thrusts.sum()])
        drag_world = R @ drag_body
        atol = 1e-6 if tp.solver == "nelder-mead" else 1e-9
        np.testing.assert_allclose(thrust_world[0], -drag_world[0], rtol=0, atol=atol)  # horizontal
        np.testing.assert_allclose(
            thrust_world[2] + drag_world[2], frame.mass * frame.gravity, rtol=0, atol=atol
        )  # vertical
        np.testing.assert_allclose(net_wrench(frame, tp.thrusts)[1:], 0.0, atol=atol)


# ---------------------------------------------------------------------------------------------
# Failure and bad arguments
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("solver", SOLVERS)
def test_iteration_cap_from_a_bad_guess_fails_without_raising(frames, solver):
    opts = TrimOptions(
        max_iterations=1, nelder_mead_max_iterations=1, initial_guess=(0.5, 0.5, 0.3, 0.3, 0.3, 0.3)
    )
    tp = trim(frames["HS200"], "forward", 10.0, solver, opts)
    assert not tp.success
    assert "residual" in tp.message and tp.residual_norm > TOL[solver]
    assert tp.iterations <= 1


@pytest.mark.parametrize("solver", ["ipopt", "newton"])
def test_pitch_near_ninety_degrees_fails_without_raising(solver):
    # 100 m/s (within Mach 0.3) against a body of 0.5 m² frontal drag area (a parachute, ~40×
    # SY250's): drag ½ρv²·CdA ≈ 3 kN against ~7 N of weight needs a pitch of nearly 90°
    frame = build_airframe(load_airframe("SY250", ["drag_area_m2=[0.5, 0.5, 1.0]"]))
    tp = trim(frame, "forward", 100.0, solver)
    assert not tp.success
    assert "tilt" in tp.message or "residual" in tp.message


def test_a_speed_beyond_mach_0_3_is_refused_naming_the_limit(frames):
    with pytest.raises(ValueError, match=r"speed_mps: 1000 m/s is beyond 102.9 m/s \(Mach 0.3"):
        trim(frames["SY250"], "forward", 1000.0, "newton")


def test_commands_above_one_are_reported_not_failed(frames):
    tp = trim(frames["SY250"], "forward", 100.0, "newton")
    assert tp.success and tp.u0.max() > 1
    assert "outside [0, 1]" in tp.message


def test_bad_arguments_raise(frames):
    frame = frames["SY250"]
    with pytest.raises(ValueError, match="unknown trim solver"):
        trim(frame, solver="bfgs")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="unknown condition"):
        trim(frame, condition="loop")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="hover"):
        trim(frame, "hover", 5.0)
