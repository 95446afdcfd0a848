"""Linearisation: exact (AD) vs finite differences, and the structure of the hover model."""

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.control import hover_point
from casadrone.linearise import compare, linearise
from casadrone.model import IDX
from casadrone.trim import trim

REFERENCES = ["SY250", "SY220", "HS200", "HS210", "NSY200"]


@pytest.mark.parametrize("name", REFERENCES)
@pytest.mark.parametrize("condition", ["hover", "forward"])
def test_exact_and_finite_difference_jacobians_agree(name, condition):
    """Forward differences with step h = √ε·max(1, |z|) carry a truncation error ~h·|F''|/2 and
    a rounding error ~ε·|F|/h, both ~√ε ≈ 1.5e-8 relative to the entries' scale. So every entry
    of E, A′, B′ must agree within 1e-6 of its matrix's largest entry (60x margin), and no better
    than ~1e-12 would be suspicious (the FD would then not be independent)."""
    a = build_airframe(load_airframe(name))
    speed = 10.0 if condition == "forward" else 0.0
    tp = trim(a, condition, speed, solver="newton")
    exact, fd = linearise(a, tp, "exact"), linearise(a, tp, "fd")
    diff = compare(exact, fd)
    assert diff.max_rel_diff < 1e-6
    assert diff.max_rel_diff > 1e-12
    for key in ("E", "A_prime", "B_prime"):
        M, N = getattr(exact, key), getattr(fd, key)
        np.testing.assert_allclose(N, M, rtol=0, atol=1e-6 * np.abs(M).max())


def test_hover_model_structure():
    """About hover, derived by hand: ẋ = u (kinematics), gravity tilts into the body axes, thrust
    lag 1/τ, moment arms over inertia."""
    a = build_airframe(load_airframe("HS210"))
    lin = linearise(a, hover_point(a))
    A, B, g, tau, K = lin.A, lin.B, a.gravity, a.thrust_time_constant, a.thrust_gain
    # position rates are the body velocities at zero attitude
    for p, v in (("x", "u"), ("y", "v"), ("z", "w")):
        assert A[IDX[p], IDX[v]] == pytest.approx(1.0)
    # gravity in body axes is Rᵀ(0, 0, −g): Ry(θ)ᵀ gives (g sin θ, 0, −g cos θ), so nose-down
    # (θ > 0) accelerates forward, u̇ = +g θ; Rx(φ)ᵀ gives (0, −g sin φ, ·): roll right (φ > 0,
    # left side up) accelerates to the right, v̇ = −g φ (y is to the left)
    assert A[IDX["u"], IDX["theta"]] == pytest.approx(g)
    assert A[IDX["v"], IDX["phi"]] == pytest.approx(-g)
    # vertical: each thrust adds 1/m to ẇ
    np.testing.assert_allclose(A[IDX["w"], 12:16], 1.0 / a.mass)
    # Euler rates equal body rates at zero attitude
    for e, w in (("phi", "p"), ("theta", "q"), ("psi", "r")):
        assert A[IDX[e], IDX[w]] == pytest.approx(1.0)
    # first-order thrust lag: Ṫ = (K δ − T)/τ
    np.testing.assert_allclose(np.diag(A)[12:16], -1.0 / tau)
    np.testing.assert_allclose(B[12:16], np.eye(4) * K / tau)
    # roll acceleration per newton of rotor i is y_i / Ixx (diagonal inertia)
    np.testing.assert_allclose(A[IDX["p"], 12:16], a.rotor_positions[:, 1] / a.inertia[0, 0])
    np.testing.assert_allclose(A[IDX["q"], 12:16], -a.rotor_positions[:, 0] / a.inertia[1, 1])
    np.testing.assert_allclose(A[IDX["r"], 12:16], a.rotor_spins * a.kappa / a.inertia[2, 2])


def test_E_is_block_diagonal_mass_inertia_tau():
    a = build_airframe(load_airframe("SY250"))
    lin = linearise(a, hover_point(a))
    expected = np.zeros((16, 16))
    expected[0:3, 0:3] = np.eye(3)
    expected[3:6, 3:6] = a.mass * np.eye(3)
    expected[6:9, 6:9] = a.inertia
    expected[9:12, 9:12] = np.eye(3)
    expected[12:16, 12:16] = a.thrust_time_constant * np.eye(4)
    np.testing.assert_allclose(lin.E, expected, atol=1e-15)
    np.testing.assert_allclose(lin.A, -np.linalg.solve(lin.E, lin.A_prime))


def test_unknown_method_is_an_error():
    a = build_airframe(load_airframe("SY250"))
    with pytest.raises(ValueError, match="unknown linearisation method"):
        linearise(a, hover_point(a), "central")
