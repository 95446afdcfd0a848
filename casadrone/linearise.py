"""Linearisation of the implicit model about a trim point: E, A′, B′ and A = −E⁻¹A′, B = −E⁻¹B′.

``exact`` differentiates F(ẋ, x, u, p) with CasADi's algorithmic differentiation; ``fd`` uses the
Newton (forward difference) quotient of paper Eq. 1 on the same compiled residual.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import casadi as ca
import numpy as np

from casadrone.airframe import Airframe
from casadrone.codegen import ZeroCopyCall
from casadrone.config.io import ConfigError
from casadrone.model import INPUT_NAMES, NU, NX, STATE_NAMES, quadrotor_model, state_names
from casadrone.propulsion import propulsion_model
from casadrone.results import AsDict

Method = Literal["exact", "fd"]


@dataclass(frozen=True)
class LinearModel(AsDict):
    """δẋ = A δx + B δu about (x0, u0); E, A′, B′ are the Jacobians of the implicit F."""

    E: np.ndarray
    A_prime: np.ndarray
    B_prime: np.ndarray
    A: np.ndarray
    B: np.ndarray
    x0: np.ndarray
    u0: np.ndarray
    xdot0: np.ndarray
    method: str
    state_names: tuple[str, ...] = STATE_NAMES
    input_names: tuple[str, ...] = INPUT_NAMES


@lru_cache(maxsize=4)
def _fd_residual(propulsion: str = "paper") -> ca.Function:
    """F evaluated on the 1 + NX + NX + NU perturbed points of a forward difference at once."""
    n = 1 + 2 * NX + NU
    return quadrotor_model(propulsion).F.map(n)


def jacobians_fd(xdot0, x0, u0, p, propulsion: str = "paper"
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """E, A′, B′ by forward differences with step √ε·max(1, |z|) per variable."""
    z0 = np.concatenate([xdot0, x0, u0])
    h = np.sqrt(np.finfo(float).eps) * np.maximum(1.0, np.abs(z0))
    Z = np.tile(z0[:, None], (1, 1 + z0.size))
    Z[np.arange(z0.size), 1 + np.arange(z0.size)] += h
    P = np.tile(np.asarray(p, float)[:, None], (1, Z.shape[1]))
    Fv = np.array(_fd_residual(propulsion)(Z[:NX], Z[NX : 2 * NX], Z[2 * NX :], P))
    D = (Fv[:, 1:] - Fv[:, :1]) / h
    return D[:, :NX], D[:, NX : 2 * NX], D[:, 2 * NX :]


@lru_cache(maxsize=4)
def _linear_parts(propulsion: str = "paper") -> ZeroCopyCall:
    """ẋ0 and the exact E, A′, B′ in one zero-copy call (built once per process and kind)."""
    return ZeroCopyCall(quadrotor_model(propulsion).linear_parts)


def linearise(airframe: Airframe, trim_point, method: Method = "exact") -> LinearModel:
    """Linearise about ``trim_point`` (anything with ``x0`` and ``u0``)."""
    if method not in ("exact", "fd"):
        raise ValueError(f"unknown linearisation method {method!r}; use 'exact' or 'fd'")
    if propulsion_model(airframe.propulsion).lagless and airframe.thrust_time_constant == 0:
        raise ConfigError([f"{airframe.name}: thrust.time_constant_s: 0 (no thrust lag) is an "
                           "idealisation of the limit lap only; the closed loop (linearisation, "
                           "LQR, simulation) needs a lag > 0"])
    p = airframe.p
    x0 = np.asarray(trim_point.x0, float)
    u0 = np.asarray(trim_point.u0, float)
    xdot0, E, Ap, Bp = (np.array(M.T) for M in _linear_parts(airframe.propulsion)(x0, u0, p))
    xdot0 = xdot0.ravel()
    if method == "fd":
        E, Ap, Bp = jacobians_fd(xdot0, x0, u0, p, airframe.propulsion)
    A = -np.linalg.solve(E, Ap)
    B = -np.linalg.solve(E, Bp)
    return LinearModel(E=E, A_prime=Ap, B_prime=Bp, A=A, B=B, x0=x0, u0=u0, xdot0=xdot0,
                       method=method, state_names=state_names(airframe.propulsion))


@dataclass(frozen=True)
class JacobianComparison(AsDict):
    """Largest differences between two linearisations."""

    max_abs_diff_A: float
    max_abs_diff_B: float
    max_rel_diff: float


def compare(a: LinearModel, b: LinearModel) -> JacobianComparison:
    """Max absolute differences of A and B, and the largest difference of any of E, A′, B′
    relative to that matrix's largest entry."""
    def rel_diff(k: str) -> float:
        Ma, Mb = getattr(a, k), getattr(b, k)
        return float(np.max(np.abs(Ma - Mb)) / max(np.max(np.abs(Ma)), 1e-300))

    rel = max(rel_diff(k) for k in ("E", "A_prime", "B_prime", "A", "B"))
    return JacobianComparison(
        max_abs_diff_A=float(np.max(np.abs(a.A - b.A))),
        max_abs_diff_B=float(np.max(np.abs(a.B - b.B))),
        max_rel_diff=rel,
    )

