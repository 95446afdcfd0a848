"""Trim: the operating point (x0, u0) of hover or level forward flight, by three solvers.

Formulation (the same for every solver). Level flight with world velocity (V, 0, 0), heading
ψ = 0 and body rates p = q = r = 0 leaves six unknowns

    Z = (φ, θ, δ1, δ2, δ3, δ4)        (rad, rad, ESC commands)

from which the whole state follows: body velocity (u, v, w) = R(φ, θ, 0)ᵀ (V, 0, 0), rotor
thrusts T = K δ (the first-order thrust model at rest), position 0. The six residuals Q(Z) are
the body-velocity and body-rate rows of the explicit model f(x, u, p): v̇ = 0 (m/s²) and ω̇ = 0
(rad/s²). The Euler-angle rows vanish because ω = 0 and the thrust rows because T = K δ, so the
system is square, 6 × 6. Hover is V = 0. Positive θ is nose-down: in forward flight θ > 0.

Every solver reports the same ``residual_norm``: the 2-norm of all 13 non-position rows of
f(x0, u0, p), evaluated by one compiled Function after the solver has finished.

Solvers (all built once per process and option set, with p and V as parameters):

* ``ipopt`` — CasADi ``nlpsol`` feasibility problem: objective 0, g(Z) = Q(Z) = 0.
* ``newton`` — CasADi ``rootfinder`` (Newton) on Q(Z) = 0.
* ``nelder-mead`` — the paper's method (Eq. 5–7): scipy Nelder–Mead on the penalised cost
  f(Z) + QᵀHQ with H = diag(weights). The operating-point constraints of Eq. 5 (level flight,
  zero rates, steady thrust) hold by construction of Z, so the objective f(Z) of Eq. 6 is
  eliminated and the cost is QᵀHQ alone. Adaptive simplex, restarted from the best point until
  ‖Q‖ reaches the tolerance or the iteration cap.

Commands outside [0, 1] are not a failure of the equations: the trim is reported (success) and
the message says the command saturates. A pitch or roll beyond ``max_tilt_deg`` is a failure.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Literal

import casadi as ca
import numpy as np
from scipy.optimize import minimize

from casadrone.airframe import PARAM_NAMES, Airframe
from casadrone.codegen import ZeroCopyCall
from casadrone.model import (
    EUL,
    INPUT_NAMES,
    NP,
    NX,
    RATE,
    STATE_NAMES,
    THR,
    VEL,
    quadrotor_model,
    rotation_matrix,
)

Solver = Literal["ipopt", "nelder-mead", "newton"]
Condition = Literal["hover", "forward"]
SOLVERS: tuple[str, ...] = ("ipopt", "nelder-mead", "newton")
CONDITIONS: tuple[str, ...] = ("hover", "forward")
UNKNOWN_NAMES = ("phi", "theta", "delta1", "delta2", "delta3", "delta4")
_K = PARAM_NAMES.index("K")


@dataclass(frozen=True)
class TrimOptions:
    """Solver settings. Tolerances are on the 13-row ``residual_norm`` (SI units of ẋ).

    Attributes:
        tolerance: residual a trim by ``ipopt`` or ``newton`` must reach to succeed.
        nelder_mead_tolerance: residual a ``nelder-mead`` trim must reach to succeed.
        max_iterations: iteration cap of ``ipopt`` and ``newton``.
        nelder_mead_max_iterations: cap on Nelder–Mead iterations, summed over restarts.
        nelder_mead_weights: the diagonal of H (Eq. 7), one weight per residual row
            (u̇, v̇, ẇ, ṗ, q̇, ṙ).
        nelder_mead_step: initial simplex edge, in the units of Z (rad, command).
        initial_guess: Z = (φ, θ, δ1…δ4) to start from; ``None`` is the analytic guess.
        max_tilt_deg: a trim with |φ| or |θ| beyond this is a failure (Euler singularity at 90°).
    """

    tolerance: float = 1e-9
    nelder_mead_tolerance: float = 1e-6
    max_iterations: int = 100
    nelder_mead_max_iterations: int = 20000
    nelder_mead_weights: tuple[float, ...] = (1.0,) * 6
    nelder_mead_step: float = 0.05
    initial_guess: tuple[float, ...] | None = None
    max_tilt_deg: float = 85.0

    def __post_init__(self) -> None:
        if len(self.nelder_mead_weights) != 6 or min(self.nelder_mead_weights) <= 0:
            raise ValueError("nelder_mead_weights: six positive weights expected")
        if self.initial_guess is not None and len(self.initial_guess) != 6:
            raise ValueError("initial_guess: six values (phi, theta, delta1..delta4) expected")
        if self.max_iterations < 1 or self.nelder_mead_max_iterations < 1:
            raise ValueError("max_iterations: must be at least 1")
        if self.tolerance <= 0 or self.nelder_mead_tolerance <= 0:
            raise ValueError("tolerance: must be positive")


@dataclass(frozen=True)
class TrimPoint:
    """An operating point and how it was found.

    Attributes:
        solver, condition, speed_mps: what was asked (speed in m/s, world x).
        x0: state (16, STATE_NAMES order); u0: ESC commands (4); thrusts: rotor thrusts (N),
            equal to ``x0[12:16]``.
        residual_norm: 2-norm of the 13 non-position rows of f(x0, u0, p).
        iterations: iterations reported by the solver (Nelder–Mead: summed over restarts).
        wall_time_s: wall time of the solve, residual evaluation included (s).
        success, message: whether the trim is usable, and why not.
    """

    solver: str
    condition: str
    speed_mps: float
    x0: np.ndarray
    u0: np.ndarray
    thrusts: np.ndarray
    residual_norm: float
    iterations: int
    wall_time_s: float
    success: bool
    message: str
    airframe: str = ""
    state_names: tuple[str, ...] = field(default=STATE_NAMES)
    input_names: tuple[str, ...] = field(default=INPUT_NAMES)

    @property
    def pitch_deg(self) -> float:
        """Trim pitch θ (deg, positive nose-down)."""
        return math.degrees(float(self.x0[EUL][1]))

    @property
    def roll_deg(self) -> float:
        """Trim roll φ (deg)."""
        return math.degrees(float(self.x0[EUL][0]))


# ---------------------------------------------------------------------------------------------
# Compiled functions, built once per process
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _TrimFunctions:
    state: ca.Function  # state(z, p, V) -> (x, u)
    residual: ca.Function  # residual(z, p, V) -> Q (6)
    cost: ca.Function  # cost(z, p, V, h) -> QᵀHQ
    residual_norm: ca.Function  # residual_norm(x, u, p) -> ‖f[3:16]‖₂
    point: ZeroCopyCall  # point(z, p, V) -> (x, u, ‖f[3:16]‖₂) in one zero-copy call


def _state_expr(z, p, V):
    """(x, u) of the unknowns Z at world speed V (symbolic)."""
    phi, theta, delta = z[0], z[1], z[2:6]
    R = rotation_matrix(phi, theta, 0)
    x = ca.vertcat(
        ca.SX.zeros(3), R.T @ ca.vertcat(V, 0, 0), ca.SX.zeros(3), phi, theta, 0, p[_K] * delta
    )
    return x, delta


@lru_cache(maxsize=1)
def _functions() -> _TrimFunctions:
    f = quadrotor_model().f
    z, p, V = ca.SX.sym("z", 6), ca.SX.sym("p", NP), ca.SX.sym("V")
    h = ca.SX.sym("h", 6)
    x, u = _state_expr(z, p, V)
    xdot = f(x, u, p)
    Q = ca.vertcat(xdot[VEL], xdot[RATE])
    xs, us = ca.SX.sym("x", NX), ca.SX.sym("u", 4)
    rows = f(xs, us, p)[3:]
    return _TrimFunctions(
        state=ca.Function("trim_state", [z, p, V], [x, u], ["z", "p", "V"], ["x", "u"]),
        residual=ca.Function("trim_residual", [z, p, V], [Q], ["z", "p", "V"], ["Q"]),
        cost=ca.Function(
            "trim_cost", [z, p, V, h], [ca.dot(Q, h * Q)], ["z", "p", "V", "h"], ["cost"]
        ),
        residual_norm=ca.Function(
            "trim_residual_norm", [xs, us, p], [ca.norm_2(rows)], ["x", "u", "p"], ["norm"]
        ),
        point=ZeroCopyCall(ca.Function(
            "trim_point", [z, p, V], [x, u, ca.norm_2(f(x, u, p)[3:])], ["z", "p", "V"],
            ["x", "u", "norm"],
        )),
    )


@lru_cache(maxsize=8)
def _ipopt(tol: float, max_iter: int) -> ca.Function:
    fn = _functions()
    z, pv = ca.SX.sym("z", 6), ca.SX.sym("pv", NP + 1)
    g = fn.residual(z, pv[:NP], pv[NP])
    opts = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": min(tol * 1e-3, 1e-12),
        "ipopt.constr_viol_tol": min(tol * 1e-3, 1e-12),
        "ipopt.max_iter": max_iter,
        "ipopt.nlp_scaling_method": "none",
    }
    return ca.nlpsol("trim_ipopt", "ipopt", {"x": z, "p": pv, "f": 0, "g": g}, opts)


@lru_cache(maxsize=8)
def _newton(tol: float, max_iter: int) -> ca.Function:
    fn = _functions()
    z, pv = ca.SX.sym("z", 6), ca.SX.sym("pv", NP + 1)
    g = ca.Function("trim_g", [z, pv], [fn.residual(z, pv[:NP], pv[NP])])
    opts = {
        "abstol": min(tol * 1e-3, 1e-12),
        "abstolStep": 1e-14,
        "max_iter": max_iter,
        "error_on_fail": False,
    }
    return ca.rootfinder("trim_newton", "newton", g, opts)


# ---------------------------------------------------------------------------------------------
# Solvers: each maps (Z0, p, V, options) -> (Z, iterations, solver message)
# ---------------------------------------------------------------------------------------------


def _solve_ipopt(z0, p, V, o: TrimOptions):
    solver = _ipopt(o.tolerance, o.max_iterations)
    sol = solver(x0=z0, p=np.append(p, V), lbg=0, ubg=0)
    st = solver.stats()
    return np.asarray(sol["x"]).ravel(), int(st.get("iter_count", 0)), str(st["return_status"])


@lru_cache(maxsize=8)
def _newton_call(tol: float, max_iter: int) -> ZeroCopyCall:
    return ZeroCopyCall(_newton(tol, max_iter))


def _solve_newton(z0, p, V, o: TrimOptions):
    rf = _newton_call(o.tolerance, o.max_iterations)
    (z,) = rf(z0, np.append(p, V))
    st = rf.stats()
    return z.ravel().copy(), int(st.get("iter_count", 0)), str(st["return_status"])


def _solve_nelder_mead(z0, p, V, o: TrimOptions):
    fn = _functions()
    pd, hd = ca.DM(p), ca.DM(o.nelder_mead_weights)  # convert once: each call costs ~40 µs

    def cost(z):
        return float(fn.cost.call([z, pd, V, hd])[0])

    def qnorm(z):
        return float(ca.norm_2(fn.residual.call([z, pd, V])[0]))

    # Aim below the acceptance tolerance so the reported 13-row norm passes with margin.
    target = 0.1 * o.nelder_mead_tolerance
    z, step, nit, runs = np.asarray(z0, dtype=float), o.nelder_mead_step, 0, 0
    status = "iteration cap reached"
    if qnorm(z) <= target:
        return z, 0, "initial guess already within tolerance"
    while nit < o.nelder_mead_max_iterations:
        simplex = z + np.vstack([np.zeros(6), step * np.eye(6)])
        res = minimize(
            cost,
            z,
            method="Nelder-Mead",
            options={
                "adaptive": True,
                "xatol": 1e-12,
                "fatol": 1e-4 * target**2,
                "initial_simplex": simplex,
                "maxfev": 10**9,
                "maxiter": min(2000, o.nelder_mead_max_iterations - nit),
            },
        )
        nit, runs = nit + int(res.nit), runs + 1
        moved = float(np.max(np.abs(res.x - z)))
        if cost(res.x) <= cost(z):
            z = res.x
        if qnorm(z) <= target:
            status = f"converged after {runs} run(s)"
            break
        # Restart around the best point with a simplex the size of the last move.
        step = min(o.nelder_mead_step, max(10.0 * moved, 1e-9))
    return z, nit, status


_SOLVE = {"ipopt": _solve_ipopt, "newton": _solve_newton, "nelder-mead": _solve_nelder_mead}


# ---------------------------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------------------------


def initial_guess(airframe: Airframe, speed_mps: float = 0.0) -> np.ndarray:
    """Analytic guess of Z = (φ, θ, δ1…δ4): hover thrusts, pitch from a small-angle drag balance.

    θ = atan(½ ρ CdA_x V|V| / (m g)); total thrust m g / cos θ split like the hover thrusts.
    """
    a = airframe
    drag = 0.5 * a.air_density * a.drag_area[0] * speed_mps * abs(speed_mps)
    theta = math.atan2(drag, a.mass * a.gravity)
    delta = a.hover_thrusts() / math.cos(theta) / a.thrust_gain
    return np.concatenate([[0.0, theta], delta])


def trim(
    airframe: Airframe,
    condition: Condition = "hover",
    speed_mps: float = 0.0,
    solver: Solver = "ipopt",
    options: TrimOptions | None = None,
) -> TrimPoint:
    """Trim ``airframe`` in hover or level forward flight at ``speed_mps`` (world +x, m/s).

    Never raises for a case the solver cannot solve: the TrimPoint then has ``success=False``
    and a message. Unknown ``condition`` or ``solver``, or hover with a speed, raise ValueError.
    """
    if solver not in _SOLVE:
        raise ValueError(f"unknown trim solver '{solver}'; choose one of {', '.join(SOLVERS)}")
    if condition not in CONDITIONS:
        raise ValueError(f"unknown condition '{condition}'; choose 'hover' or 'forward'")
    if condition == "hover" and speed_mps != 0:
        raise ValueError("hover: speed_mps must be 0 (use condition='forward')")
    if not math.isfinite(speed_mps):
        raise ValueError("speed_mps must be finite")
    o = options or TrimOptions()
    fn = _functions()
    p, V = airframe.p, float(speed_mps)
    z0 = np.asarray(o.initial_guess if o.initial_guess is not None else initial_guess(airframe, V))

    start = time.perf_counter()
    try:
        z, iterations, status = _SOLVE[solver](z0, p, V, o)
        error = None
    except Exception as exc:  # a solver crash is a failed trim, never an exception
        z, iterations, status, error = z0, 0, "", f"{type(exc).__name__}: {exc}"
    x, u, norm = fn.point(z, p, V)
    x0, u0, residual = x.ravel().copy(), u.ravel().copy(), float(norm[0, 0])
    wall = time.perf_counter() - start

    tol = o.nelder_mead_tolerance if solver == "nelder-mead" else o.tolerance
    tilt = math.degrees(max(abs(z[0]), abs(z[1])))
    if error is not None:
        success, message = False, f"{solver} failed: {error}"
    elif not (np.all(np.isfinite(z)) and math.isfinite(residual)):
        success, message = False, f"{solver} returned non-finite values ({status})"
    elif residual > tol:
        success, message = False, f"residual {residual:.3g} above tolerance {tol:.3g} ({status})"
    elif tilt > o.max_tilt_deg:
        success, message = False, f"tilt {tilt:.1f} deg beyond max_tilt_deg {o.max_tilt_deg:g}"
    else:
        success, message = True, f"converged ({status})"
        if np.any(u0 < 0) or np.any(u0 > 1):
            message += f"; commands outside [0, 1] (max {u0.max():.3f}): they saturate in flight"
    return TrimPoint(
        solver=solver,
        condition=condition,
        speed_mps=V,
        x0=x0,
        u0=u0,
        thrusts=x0[THR].copy(),
        residual_norm=residual,
        iterations=int(iterations),
        wall_time_s=wall,
        success=success,
        message=message,
        airframe=airframe.name,
    )


def trim_all(
    airframe: Airframe,
    condition: Condition = "hover",
    speed_mps: float = 0.0,
    solvers: tuple[str, ...] = SOLVERS,
    options: TrimOptions | None = None,
) -> list[TrimPoint]:
    """Trim with each of ``solvers`` (same airframe, condition and options), for comparison."""
    return [trim(airframe, condition, speed_mps, s, options) for s in solvers]
