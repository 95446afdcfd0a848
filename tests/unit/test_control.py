"""LQR-I: gain against independent Riccati solutions, stability and the robustness ensemble."""

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.controller import ControllerConfig, load_controller
from casadrone.control import (
    augment,
    certify,
    design_for,
    design_lqri,
    discretise,
    hover_point,
    robustness_ensemble,
    weights,
)
from casadrone.linearise import linearise

REFERENCES = ["SY250", "SY220", "HS200", "HS210", "NSY200"]


@pytest.fixture(scope="module")
def ctrl():
    return load_controller()


def riccati_iteration(A, B, Q, R, iters=200000, tol=1e-14):
    """Value iteration of the Riccati difference equation from S = Q until it stops moving: an
    oracle sharing no code with scipy's Schur-based DARE solver."""
    S = Q.copy()
    for _ in range(iters):
        K = np.linalg.solve(R + B.T @ S @ B, B.T @ S @ A)
        S_next = Q + A.T @ S @ (A - B @ K)
        S_next = 0.5 * (S_next + S_next.T)
        if np.max(np.abs(S_next - S)) <= tol * np.max(np.abs(S_next)):
            return np.linalg.solve(R + B.T @ S_next @ B, B.T @ S_next @ A)
        S = S_next
    raise AssertionError("Riccati iteration did not converge")


def test_scalar_integrator_lqr_analytic():
    """Discrete integrator x⁺ = x + b u with q, r: S solves S = q + S − S² b²/(r + b² S), i.e.
    S = (q + √(q² + 4 q r / b²)) / 2, and K = b S / (r + b² S)."""
    import scipy.linalg as sla

    b, q, r = 0.1, 2.0, 0.5
    S = (q + np.sqrt(q**2 + 4 * q * r / b**2)) / 2
    K = b * S / (r + b**2 * S)
    S_num = sla.solve_discrete_are(np.eye(1), np.array([[b]]), np.array([[q]]), np.array([[r]]))
    assert S_num[0, 0] == pytest.approx(S, rel=1e-12)
    assert riccati_iteration(np.eye(1), np.array([[b]]), np.eye(1) * q, np.eye(1) * r)[0, 0] == \
        pytest.approx(K, rel=1e-10)


@pytest.mark.parametrize("name", ["SY250", "HS210"])
def test_gain_matches_python_control_and_riccati_iteration(name, ctrl):
    a = build_airframe(load_airframe(name))
    lin = linearise(a, hover_point(a))
    d = design_lqri(lin, ctrl)
    Aa, Ba = augment(*discretise(lin.A, lin.B, ctrl.sample_time_s), ctrl.sample_time_s)
    Q, R = weights(ctrl)
    import control

    K_ctrl, _, _ = control.dlqr(Aa, Ba, Q, R)
    np.testing.assert_allclose(d.K, K_ctrl, rtol=0, atol=1e-8)
    np.testing.assert_allclose(d.K, riccati_iteration(Aa, Ba, Q, R), rtol=0, atol=1e-8)


def test_zoh_discretisation_of_double_integrator():
    """ẍ = u held for T: x⁺ = x + T v + T²/2 u, v⁺ = v + T u."""
    T = 0.01
    Ad, Bd = discretise(np.array([[0, 1.0], [0, 0]]), np.array([[0], [1.0]]), T)
    np.testing.assert_allclose(Ad, [[1, T], [0, 1]], atol=1e-15)
    np.testing.assert_allclose(Bd, [[T**2 / 2], [T]], atol=1e-15)


def test_integral_states_accumulate_position_and_yaw_error():
    Ad, Bd = np.eye(16), np.zeros((16, 4))
    Aa, Ba = augment(Ad, Bd, 0.01)
    x = np.zeros(20)
    x[0], x[1], x[2], x[11] = 1.0, 2.0, 3.0, 0.5  # x, y, z, psi
    np.testing.assert_allclose((Aa @ x)[16:], 0.01 * np.array([1, 2, 3, 0.5]))


@pytest.mark.parametrize("name", REFERENCES)
def test_closed_loop_stable_with_certificate_and_robust(name, ctrl):
    a = build_airframe(load_airframe(name))
    d = design_for(a, ctrl)
    assert d.stable
    assert np.max(np.abs(d.closed_loop_eigenvalues)) < 1.0
    # Lyapunov certificate: P ≻ 0 and A_clᵀ P A_cl − P = −I holds
    Acl = d.Ad - d.Bd @ d.K
    assert d.lyapunov_min_eig > 0
    import scipy.linalg as sla

    P = sla.solve_discrete_lyapunov(Acl.T, np.eye(20))
    np.testing.assert_allclose(Acl.T @ P @ Acl - P, -np.eye(20), atol=1e-6 * np.abs(P).max())
    ens = robustness_ensemble(a, d, ctrl)
    assert ens.n == 50 and ens.eigenvalues.shape == (50, 20)
    assert ens.stable, f"{name}: {np.sum(~ens.stable_each)} perturbed plants unstable"


def test_ensemble_plants_really_differ(ctrl):
    a = build_airframe(load_airframe("SY250"))
    d = design_for(a, ctrl)
    ens = robustness_ensemble(a, d, ctrl, n=5)
    spreads = [np.max(np.abs(ens.plants[i][0] - d.Ad)) for i in range(5)]
    assert min(spreads) > 1e-4


def test_certificate_rejects_unstable_loop():
    eig, stable, lmin = certify(np.diag([0.5, 1.01]))
    assert not stable and np.isnan(lmin)


def test_stability_without_certificate():
    """Skipping the Lyapunov solve (the optimiser's path) must not change the verdict."""
    assert certify(np.diag([0.5, 0.99]), lyapunov=False)[1]
    assert not certify(np.diag([0.5, 1.01]), lyapunov=False)[1]
    a = build_airframe(load_airframe("HS200"))
    ctrl = load_controller()
    d = design_for(a, ctrl, certificate=False)
    assert d.stable and np.isnan(d.lyapunov_min_eig)


def test_frozen_policy_uses_reference_gain_on_own_plant():
    cfg = ControllerConfig(gain_policy="frozen-command",
                           reference_airframe="configs/airframes/SY250.yaml")
    ref = build_airframe(load_airframe("SY250"))
    cand = build_airframe(load_airframe("NSY200"))
    frozen = design_for(cand, cfg, reference=ref)
    own = design_for(ref, cfg.model_copy(update={"gain_policy": "redesign"}))
    np.testing.assert_allclose(frozen.K, own.K)
    np.testing.assert_allclose(frozen.u0, hover_point(cand).u0)
    np.testing.assert_allclose(np.linalg.eigvals(frozen.Ad - frozen.Bd @ frozen.K),
                               frozen.closed_loop_eigenvalues)
    assert frozen.stable


@pytest.mark.parametrize("seed", [0, 1])
def test_doubling_dare_matches_scipy(seed, ctrl):
    """solve_dare (structure-preserving doubling) against scipy's QZ-based DARE on the LQR-I
    plants of the reference airframes and random Table 1 geometries: S and K agree to 1e-8
    relative, S is symmetric, satisfies the Riccati equation, and its closed loop is stable."""
    import scipy.linalg as sla

    from casadrone.airframe import random_thetas, with_theta
    from casadrone.control import solve_dare

    template = load_airframe("SY250")
    thetas, _ = random_thetas(template, 6, seed=seed)
    frames = [build_airframe(load_airframe(n)) for n in ("SY250", "HS210", "NSY200")]
    frames += [build_airframe(with_theta(template, th)) for th in thetas]
    Q, R = weights(ctrl)
    for a in frames:
        lin = linearise(a, hover_point(a))
        Aa, Ba = augment(*discretise(lin.A, lin.B, ctrl.sample_time_s), ctrl.sample_time_s)
        S, S_ref = solve_dare(Aa, Ba, Q, R), sla.solve_discrete_are(Aa, Ba, Q, R)
        np.testing.assert_allclose(S, S_ref, rtol=0, atol=1e-8 * np.abs(S_ref).max())
        np.testing.assert_array_equal(S, S.T)
        K = np.linalg.solve(R + Ba.T @ S @ Ba, Ba.T @ S @ Aa)
        K_ref = np.linalg.solve(R + Ba.T @ S_ref @ Ba, Ba.T @ S_ref @ Aa)
        np.testing.assert_allclose(K, K_ref, rtol=0, atol=1e-8 * np.abs(K_ref).max())
        residual = Aa.T @ S @ Aa - Aa.T @ S @ Ba @ K + Q - S
        assert np.abs(residual).max() <= 1e-9 * np.abs(S).max()
        assert np.abs(np.linalg.eigvals(Aa - Ba @ K)).max() < 1.0


def test_doubling_dare_scalar_integrator():
    """The scalar integrator of test_scalar_integrator_lqr_analytic, by doubling."""
    from casadrone.control import solve_dare

    b, q, r = 0.1, 2.0, 0.5
    S = (q + np.sqrt(q**2 + 4 * q * r / b**2)) / 2
    S_num = solve_dare(np.eye(1), np.array([[b]]), np.array([[q]]), np.array([[r]]))
    assert S_num[0, 0] == pytest.approx(S, rel=1e-12)


# ---------------------------------------------------------------------------------------------
# frozen-wrench: the reference gain in force/torque space, each frame mixed by its own allocation
# ---------------------------------------------------------------------------------------------

ASYMMETRIC = ["lambda_a_mm=145", "lambda_b_mm=105", "alpha_deg=70", "beta_deg=84"]


def _frozen(policy: str) -> ControllerConfig:
    return ControllerConfig(gain_policy=policy, reference_airframe="configs/airframes/SY250.yaml")


def test_frozen_wrench_equals_frozen_command_on_the_reference():
    ref = build_airframe(load_airframe("SY250"))
    wrench = design_for(ref, _frozen("frozen-wrench"), reference=ref)
    command = design_for(ref, _frozen("frozen-command"), reference=ref)
    np.testing.assert_allclose(wrench.K, command.K, rtol=1e-12, atol=1e-14)


def test_frozen_wrench_commands_the_reference_wrench_on_an_asymmetric_frame():
    """Allocation round-trip: for any rigid-body error, thrust error and integrator state, the
    wrench the asymmetric frame's commands produce in steady state, K_g A (δ − u0), equals the
    wrench the reference controller demands for the same rigid-body errors and the same wrench
    error A δT (read through the reference's allocation)."""
    ref = build_airframe(load_airframe("SY250"))
    cand = build_airframe(load_airframe("SY250", ASYMMETRIC))
    design = design_for(cand, _frozen("frozen-wrench"), reference=ref)
    K_ref = design_for(ref, _frozen("frozen-command"), reference=ref).K
    A, A_ref = cand.allocation_matrix, ref.allocation_matrix
    assert not np.allclose(A, A_ref)  # the frames really mix differently
    rng = np.random.default_rng(0)
    for _ in range(5):
        z = rng.normal(size=20)
        dT = z[12:16]
        z_ref = z.copy()
        z_ref[12:16] = np.linalg.solve(A_ref, A @ dT)  # same wrench error, reference's rotors
        wrench = cand.thrust_gain * A @ (-design.K @ z)
        wrench_ref = ref.thrust_gain * A_ref @ (-K_ref @ z_ref)
        np.testing.assert_allclose(wrench, wrench_ref, rtol=1e-10, atol=1e-12)
    # frozen-command flies the reference's mixer: the same commands, hence another wrench
    command = design_for(cand, _frozen("frozen-command"), reference=ref)
    z = rng.normal(size=20)
    assert not np.allclose(A @ command.K @ z, A_ref @ K_ref @ z, rtol=1e-3)


def test_frozen_wrench_collective_does_not_pitch_an_unequal_arm_frame():
    """A pure altitude error asks for collective thrust only: with the frame's own mixer the
    commanded pitch and roll torques are zero; through the SY250 mixer (frozen-command) a frame
    with λa ≠ λb gets a pitch torque."""
    ref = build_airframe(load_airframe("SY250"))
    cand = build_airframe(load_airframe("SY250", ["lambda_a_mm=145", "lambda_b_mm=105"]))
    z = np.zeros(20)
    z[2] = -1.0  # 1 m below the reference
    wrench = {p: cand.allocation_matrix @ design_for(cand, _frozen(p), reference=ref).K @ z
              for p in ("frozen-wrench", "frozen-command")}
    assert abs(wrench["frozen-wrench"][0]) > 0.1
    np.testing.assert_allclose(wrench["frozen-wrench"][1:], 0.0, atol=1e-12)
    assert abs(wrench["frozen-command"][2]) > 1e-3 * abs(wrench["frozen-command"][0])


def test_frozen_wrench_scales_with_the_thrust_gain():
    """A frame with stronger motors needs proportionally smaller commands for the same wrench."""
    ref = build_airframe(load_airframe("SY250"))
    strong = build_airframe(load_airframe("SY250", ["thrust.gain_n=18.1038"]))
    K = design_for(strong, _frozen("frozen-wrench"), reference=ref).K
    K_ref = design_for(ref, _frozen("frozen-command"), reference=ref).K
    np.testing.assert_allclose(K, K_ref / 2, rtol=1e-12)


def test_perturbed_inertia_stays_a_possible_body():
    """Scaling Ixx, Iyy, Izz independently by ±30 % can break Izz ≤ Ixx + Iyy (SY250: 0.0036 ·
    1.3 > 0.0039 · 0.7); the ensemble perturbs the body's second moments instead."""
    from casadrone.config.airframe import inertia_problems
    from casadrone.control import perturb_inertia

    J = build_airframe(load_airframe("SY250")).inertia
    d = np.array([0.7, 0.7, 1.3])
    assert inertia_problems((J * np.sqrt(np.outer(d, d))).tolist())  # the naive scaling
    rng = np.random.default_rng(0)
    for _ in range(200):
        d = rng.uniform(0.7, 1.3, 3)
        Jp = perturb_inertia(J, d)
        assert inertia_problems(Jp.tolist()) == []
        ratio = np.diag(Jp) / np.diag(J)
        assert np.all((ratio >= d.min() - 1e-12) & (ratio <= d.max() + 1e-12))
    np.testing.assert_allclose(perturb_inertia(J, np.ones(3)), J, rtol=1e-12)
