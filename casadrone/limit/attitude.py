"""Attitude without singularity for the limit lap: the quadrotor with a unit quaternion.

The Euler model (:mod:`casadrone.model`) is singular at 90° of pitch (its Euler-rate matrix has
1/cos θ), so a lap on it cannot fly a split-S, a loop or anything inverted. This model carries
the attitude as a quaternion q = (w, x, y, z), body → world, Hamilton convention, and builds
forces, torques and rotor dynamics on the same :func:`casadrone.model.airframe_terms` with the
same parameter vector p, so it is the same vehicle wherever both are regular (checked by
``tests/unit/test_limitlap.py`` on random states and by a lap in ``tests/integration``).

State (17): position (world, m), body velocity (m/s), body rates (rad/s), q (4), rotor states.

- q̇ = ½ q ⊗ (0, ω) keeps |q| constant along the exact flow; RK4 changes it by its local error
  only. The rotation is built as R(q / |q|) (each quadratic term divided by |q|²), so a
  quaternion off unit length still gives a proper rotation and the dynamics never depend on |q|
  (Shuster, "A survey of attitude representations", J. Astronaut. Sci. 41(4), 1993, eq. 161).
- rotor_dot comes from the rotor residual, which is linear in it (``INTERFACE.md``).
"""

from __future__ import annotations

import math
from functools import lru_cache

import casadi as ca
import numpy as np

from casadrone.model import NU, airframe_terms, n_params, rotation_matrix, unpack_params

NQ = 17  # states of the quaternion model
QUAT = slice(9, 13)


def quat_rotation(q):
    """Body → world rotation of q = (w, x, y, z), normalised: R(q / |q|) (symbolic or float)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    s = 2 / (w * w + x * x + y * y + z * z)
    return ca.vertcat(
        ca.horzcat(1 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)),
        ca.horzcat(s * (x * y + w * z), 1 - s * (x * x + z * z), s * (y * z - w * x)),
        ca.horzcat(s * (x * z - w * y), s * (y * z + w * x), 1 - s * (x * x + y * y)),
    )


def quat_rate(q, omega):
    """q̇ = ½ q ⊗ (0, ω) for body rates ω (rad/s)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    p, r_q, r = omega[0], omega[1], omega[2]
    return 0.5 * ca.vertcat(
        -x * p - y * r_q - z * r,
        w * p + y * r - z * r_q,
        w * r_q + z * p - x * r,
        w * r + x * r_q - y * p,
    )


def quaternion_dynamics(x, u, p, propulsion: str = "paper"):
    """ẋ of the 17-state quaternion model (symbolic), from :func:`airframe_terms`."""
    g, J, _, _, _ = unpack_params(p)
    m, grav = g["mass"], g["g"]
    vel, omega, q, rotor = x[3:6], x[6:9], x[QUAT], x[13:17]
    R = quat_rotation(q)
    rd = ca.SX.sym("rotor_dot", rotor.numel())
    rr = airframe_terms(vel, omega, rotor, rd, u, p, propulsion).rotor_residual
    # rotor_residual is linear in rotor_dot: rr = A rd + b, so rd = -A⁻¹ b
    A = ca.jacobian(rr, rd)
    b = ca.substitute(rr, rd, ca.SX.zeros(rotor.numel()))
    rotor_dot = -ca.solve(A, b)
    terms = airframe_terms(vel, omega, rotor, rotor_dot, u, p, propulsion)
    gravity_body = R.T @ ca.vertcat(0, 0, -m * grav)
    vel_dot = (terms.thrust + terms.drag + gravity_body) / m - ca.cross(omega, vel)
    rate_dot = ca.solve(J, terms.torque - ca.cross(omega, J @ omega))
    return ca.vertcat(R @ vel, vel_dot, rate_dot, quat_rate(q, omega), rotor_dot)


@lru_cache(maxsize=4)
def quaternion_f(propulsion: str = "paper") -> ca.Function:
    """``f(x, u, p) -> xdot`` of the quaternion model, built once per process and kind."""
    x = ca.SX.sym("x", NQ)
    u = ca.SX.sym("u", NU)
    p = ca.SX.sym("p", n_params(propulsion))
    return ca.Function("f_quat", [x, u, p],
                       [ca.simplify(quaternion_dynamics(x, u, p, propulsion))],
                       ["x", "u", "p"], ["xdot"])


def euler_to_quat(phi: float, theta: float, psi: float) -> np.ndarray:
    """q = (w, x, y, z) of ZYX Euler angles (R = Rz(ψ) Ry(θ) Rx(φ), :func:`rotation_matrix`)."""
    cr, sr = math.cos(phi / 2), math.sin(phi / 2)
    cp, sp = math.cos(theta / 2), math.sin(theta / 2)
    cy, sy = math.cos(psi / 2), math.sin(psi / 2)
    return np.array([cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                     cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy])


def quat_to_euler(q: np.ndarray) -> np.ndarray:
    """ZYX Euler angles (φ, θ, ψ) of q (normalised first; θ clipped to ±90° at the pole)."""
    w, x, y, z = np.asarray(q, float) / np.linalg.norm(q)
    phi = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    theta = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    psi = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.array([phi, theta, psi])


def euler_states_to_quat(X: np.ndarray) -> np.ndarray:
    """Rows of 16 Euler-model states as rows of 17 quaternion-model states (q sign-continuous
    from row to row, so interpolating between rows stays near the shorter rotation)."""
    X = np.atleast_2d(np.asarray(X, float))
    out = np.zeros((len(X), NQ))
    out[:, 0:9] = X[:, 0:9]
    out[:, 13:17] = X[:, 12:16]
    prev = None
    for i, row in enumerate(X):
        q = euler_to_quat(*row[9:12])
        if prev is not None and float(q @ prev) < 0:
            q = -q
        out[i, QUAT] = prev = q
    return out


def quat_states_to_euler(X: np.ndarray) -> np.ndarray:
    """Rows of 17 quaternion-model states as 16 Euler-model states (angles unwrapped in ψ)."""
    X = np.atleast_2d(np.asarray(X, float))
    out = np.zeros((len(X), 16))
    out[:, 0:9] = X[:, 0:9]
    out[:, 12:16] = X[:, 13:17]
    out[:, 9:12] = np.array([quat_to_euler(q) for q in X[:, QUAT]]).reshape(-1, 3)
    out[:, 9:12] = np.unwrap(out[:, 9:12], axis=0)
    return out


def euler_rotation_np(phi: float, theta: float, psi: float) -> np.ndarray:
    """:func:`rotation_matrix` as a numpy array."""
    return np.asarray(ca.DM(rotation_matrix(phi, theta, psi))).reshape(3, 3)
