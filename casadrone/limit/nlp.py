"""Construction of the limit-lap NLP: a minimum-time problem through targets, built once per layout.

Transcription: **direct multiple shooting with RK4** (``substeps`` steps per interval) and
piecewise-constant commands, the default; Radau collocation (``method="collocation"``) is kept
for comparison. Measured on SY250 (paper track): collocation (20 intervals per leg, degree 3) is
cheaper per IPOPT iteration (the exact Hessian needs only f's second derivatives, not those of a
composed integrator) but its optimum exploits the discretisation, with chattering bang-bang
commands whose collocation states miss the true flow by up to 0.7 m/s per interval (checked
with CVODES); RK4 shooting's intervals miss it by millimetres per second, so only shooting laps
survive the re-simulation check. Commands are held over an interval, exactly what an ESC
receives and what the re-simulation integrates.

Phases: one per leg (route segment), each with its own free duration T_k and ``intervals``
uniform intervals of length T_k / N. The end node of leg k must lie in target k: a **ball**
(|p − c| ≤ r) or a **gate** (rectangle, circle or polygon of any orientation: on its plane,
inside its opening shrunk by a clearance, crossing it forwards; :mod:`casadrone.targets`).
Objective: Σ T_k.

Everything that varies between airframes or track geometries is an NLP *parameter*
``P = [p (model parameters), x_start (start state), targets (TARGET_SIZE per leg)]``; bounds (tilt,
ground, command range) are solver inputs. So one NLP and one IPOPT instance serve every
candidate on a track layout (number and kind of legs), and ``lam_p`` of the solution is
∂(lap)/∂P by the envelope theorem.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import casadi as ca
import numpy as np

from casadrone.codegen import compile_recipe, compile_with_reverse, recipe_fingerprint, vector_flags
from casadrone.config.limitlap import SOLVERS
from casadrone.drag import body_drag
from casadrone.limit.attitude import QUAT, quat_rotation, quaternion_f
from casadrone.limit.gates import (  # noqa: F401 (re-exported: the NLP's target layout)
    TARGET_SIZE,
    TargetKind,
    target_rows,
    target_vector,
)
from casadrone.limit.stagewise import StageError, fatrop_solver, solve_stagewise
from casadrone.limit.watchdog import STALL_S, run_guarded
from casadrone.model import EUL, n_params, named, quadrotor_model, rotation_matrix, unpack_params
from casadrone.propulsion import advance_margins, propulsion_model


@dataclass(frozen=True)
class OcpModel:
    """Dynamics ``f(x, u, p) -> xdot`` of an optimal-control model and how to read its state.

    ``rates`` and ``rotor`` are the state slices of the body rates and the rotor states (None
    where the model has none); ``up_z(x)`` is the world-vertical component of the body z axis,
    cos(total tilt), for the tilt cone (None: the model has no attitude state); ``attitude``
    names the representation ("euler", "quaternion", or "none"). ``scale`` (one positive number
    per state, or None for none) is the unit of each state in the NLP: the decision vector holds
    x / scale, and the dynamics rows are divided by it (:func:`state_scale`); ``f`` and every
    other member stay in the model's own units.
    """

    name: str
    f: ca.Function
    world_velocity: Callable  # (x: SX) -> SX (3,), world-frame velocity (m/s)
    rates: slice | None = None
    rotor: slice | None = None
    up_z: Callable | None = None
    attitude: str = "none"
    scale: tuple[float, ...] | None = None
    velocity: slice | None = None  # the body-frame velocity (m/s), for the rotors' inflow
    #: ``rate(p) -> λ`` (1/s): the rotor states' linear decay rate, integrated exactly by the
    #: exponential step (:func:`exponential_rotor`, :func:`etdrk4_step`); None: classical RK4
    rotor_rate: Callable | None = None
    propulsion: str = "paper"  # the propulsion kind (per-kind solver settings: ipopt_options)
    #: ``(rows(x_i, x_next, u_i, p) -> g, lower, upper)``: rows of every shooting interval on its
    #: two end nodes and its command (model units), with their bounds (numbers or arrays); the
    #: NLP maps them over the intervals and differentiates them with CasADi's own AD, beside the
    #: compiled interval blocks. A model whose commands are not the ESC commands bounds them
    #: here (benchmarks/bench_flat_rotor.py). IPOPT only: a row on two stages is not a gap row,
    #: so the stage order of fatrop refuses it (:func:`casadrone.limit.stagewise.stage_order`).
    #: None: none
    interval_rows: tuple | None = None

    @property
    def nx(self) -> int:
        return self.f.size1_in(0)

    @property
    def nu(self) -> int:
        return self.f.size1_in(1)

    @property
    def np(self) -> int:
        return self.f.size1_in(2)


def state_scale(nx: int, rotor: slice, propulsion: str) -> tuple[float, ...] | None:
    """The NLP unit of each of ``nx`` states (:attr:`OcpModel.scale`): None (the model's own
    units, every state) with ``paper``, whose rotor states are thrusts of a few newtons; else the
    rotor states in the propulsion model's ``rotor_scale`` (``propeller``: krad/s,
    :data:`casadrone.propulsion.propeller.ROTOR_SPEED_UNIT_RAD_S`)."""
    unit = propulsion_model(propulsion).rotor_scale
    if unit is None:
        return None
    scale = np.ones(nx)
    scale[rotor] = unit
    return tuple(float(s) for s in scale)


def quadrotor_ocp_model(propulsion: str = "paper") -> OcpModel:
    """The 16-state ZYX-Euler model of :mod:`casadrone.model` (rotor dynamics included) with the
    airframe's propulsion kind."""

    def vw(x):
        return rotation_matrix(x[9], x[10], x[11]) @ x[3:6]

    name = "quadrotor" + propulsion_model(propulsion).suffix
    return OcpModel(name, quadrotor_model(propulsion).f, vw, rates=slice(6, 9),
                    rotor=slice(12, 16), up_z=lambda x: ca.cos(x[9]) * ca.cos(x[10]),
                    attitude="euler", scale=state_scale(16, slice(12, 16), propulsion),
                    velocity=slice(3, 6), propulsion=propulsion)


def quaternion_ocp_model(propulsion: str = "paper") -> OcpModel:
    """The 17-state quaternion model of :mod:`casadrone.limit.attitude`: no singularity."""
    def up_z(x):
        q = x[QUAT]
        return (q[0] ** 2 + q[3] ** 2 - q[1] ** 2 - q[2] ** 2) / ca.sumsqr(q)

    name = "quadrotor-quat" + propulsion_model(propulsion).suffix
    return OcpModel(name, quaternion_f(propulsion), lambda x: quat_rotation(x[QUAT]) @ x[3:6],
                    rates=slice(6, 9), rotor=slice(13, 17), up_z=up_z, attitude="quaternion",
                    scale=state_scale(17, slice(13, 17), propulsion), velocity=slice(3, 6),
                    propulsion=propulsion)


#: Full-state models of the limit lap, by attitude representation.
ATTITUDE_MODELS: dict[str, Callable[..., OcpModel]] = {
    "euler": quadrotor_ocp_model, "quaternion": quaternion_ocp_model}


def point_mass_ocp_model(propulsion: str = "paper") -> OcpModel:
    """Attitude dynamics removed: state (world position, world velocity), controls (φ, θ, ψ,
    total thrust). The attitude and total thrust change instantly; mass, gravity and the *same*
    body drag (the airframe's form, :func:`casadrone.drag.body_drag`, evaluated at the
    commanded attitude) act as in the full model.

    Every flight of the full model is a flight of this one (take its attitude and Σ T_i as the
    controls; Σ T_i ≤ 4K because each lagged thrust stays below K; with the ``propeller``
    kind the bound is :func:`casadrone.propulsion.rotor_thrust_bound`, the largest steady
    full-command thrust over every airspeed, which a rotor can exceed only in a transient of
    its ~20 ms time constant: see :func:`casadrone.propulsion.thrust_bound`), so its minimum time
    is a lower bound of the limit lap. Rotor drag (the propeller kind's in-plane H-force) has no
    counterpart here: it opposes
    the rotors' in-plane airflow, so it mostly slows the full model, but a force off the body z
    axis can also help it turn, so with rotor drag on the bound holds only approximately (exactly
    with ``rotor_drag_n_s2_per_m: 0``). Mass and drag do not depend on the arm geometry, so with the
    paper's free mass model the bound is the same for every geometry.
    """
    x = ca.SX.sym("x", 6)
    u = ca.SX.sym("u", 4)
    p = ca.SX.sym("p", n_params(propulsion))
    g, _, _, _, cda = unpack_params(p)
    R = rotation_matrix(u[0], u[1], u[2])
    vb = R.T @ x[3:6]
    drag_b = body_drag(vb, g["rho"], cda, named(p, propulsion))
    acc = R @ (ca.vertcat(0, 0, u[3]) + drag_b) / g["mass"] - ca.vertcat(0, 0, g["g"])
    f = ca.Function("f_point_mass", [x, u, p], [ca.vertcat(x[3:6], acc)],
                    ["x", "u", "p"], ["xdot"])
    name = "point-mass" + propulsion_model(propulsion).suffix
    return OcpModel(name, f, lambda s: s[3:6])


@dataclass(frozen=True)
class Layout:
    """What fixes the NLP's structure (everything else is a parameter or a bound)."""

    kinds: tuple[TargetKind, ...]  # one target per leg
    intervals: int = 40  # per leg
    degree: int = 3  # Radau collocation points per interval (collocation)
    method: Literal["shooting", "collocation"] = "shooting"
    substeps: int = 3  # RK4 steps per interval (shooting)

    @property
    def n_coll(self) -> int:
        """Collocation states per interval (none for shooting)."""
        return self.degree if self.method == "collocation" else 0
    end_at_rest: bool = False  # world velocity fixed at the last target (at rest by default)
    tilt_cone: bool = False  # a row per node after the start: up_z(x) ≥ cos(largest tilt)
    #: x(T) − x(0) rows (and |q(0)|² = 1 with a quaternion): the periodic lap
    #: (:func:`_periodic_rows`); which of them bind, and the start state's freedom, are bounds
    periodic: bool = False
    #: propeller kind: four rows per node after the start, J_max n_i D − v_a,i ≥ 0, that keep
    #: every rotor inside its propeller data (:func:`advance_rows`); None: none
    max_advance_ratio: float | None = None
    #: propeller kind with a pack's C rating / a motor's max_current_a: the pack current and
    #: each motor's current at both ends of every interval at most these (A)
    #: (:func:`current_rows`); None: no rows
    max_pack_current_a: float | None = None
    max_motor_current_a: float | None = None

    @property
    def n_legs(self) -> int:
        return len(self.kinds)

    @property
    def n_intervals(self) -> int:
        return self.n_legs * self.intervals


@dataclass(frozen=True)
class Nlp:
    """A built NLP: the IPOPT solvers (cold and warm-start options), its sizes and bounds."""

    model: OcpModel
    layout: Layout
    cold: ca.Function
    warm: ca.Function
    lbg: np.ndarray
    ubg: np.ndarray
    #: The symbolic NLP ``{"x": w, "p": P, "f": objective, "g": constraints}`` (co-design wraps
    #: it: θ appended to w, p = p(θ) substituted); ``nlpsol`` gets the same rows with the step
    #: compiled (:func:`step_block`: the same numbers). Its row bounds are :meth:`row_bounds`,
    #: the box on w the limit lap's ``bounds``.
    problem: dict = field(default_factory=dict, compare=False, repr=False)
    #: The derivative functions given to ``nlpsol`` with it (``jac_g``, ``hess_lag``: assembled
    #: from the compiled interval blocks; empty: CasADi's own AD), for the stage-ordered solver.
    derivatives: dict = field(default_factory=dict, compare=False, repr=False)
    #: What ``nlpsol`` solves: ``problem`` with the rows as IPOPT evaluates them (the compiled
    #: step), for other IPOPT settings on the same NLP (:func:`ipopt_solver`).
    oracle: dict = field(default_factory=dict, compare=False, repr=False)
    tol: float = 1e-8  # the solvers' convergence tolerance and iteration limit
    max_iter: int = 1000
    #: IPOPT with the warm start of a start near the optimum (:data:`NEAR_VIOLATION`); None:
    #: ``warm`` serves every warm start
    near: ca.Function | None = field(default=None, compare=False, repr=False)

    def row_bounds(self, cos_tilt: float = -np.inf,
                   end_velocity: np.ndarray | tuple[float, float, float] | None = None,
                   periodic_position: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(lbg, ubg) with the tilt cone's rows at ``cos_tilt`` (cos of the largest total tilt)
        and the end rows at the world ``end_velocity`` (m/s; default at rest). A periodic layout
        ties the end state to the start state and frees the start rows: with
        ``periodic_position`` (a track whose start is its finish) all of them, so the lap starts
        wherever it ends, inside the last target; otherwise all but position (the given start
        position) and the end position is not tied."""
        lbg, ubg = self.lbg.copy(), self.ubg.copy()
        n_path = self.layout.n_intervals if self.layout.tilt_cone else 0
        if n_path:
            lbg[len(lbg) - n_path:] = cos_tilt
        n_per = periodic_row_count(self.model) if self.layout.periodic else 0
        if self.layout.end_at_rest and end_velocity is not None:
            at = slice(len(lbg) - n_path - n_per - 3, len(lbg) - n_path - n_per)
            lbg[at] = ubg[at] = np.asarray(end_velocity, float)
        if n_per:  # the start rows past position, or all of them
            start, stop = self.start_row + (0 if periodic_position else 3), \
                self.start_row + self.model.nx
            lbg[start:stop], ubg[start:stop] = -np.inf, np.inf
            if not periodic_position:
                first = len(lbg) - n_path - n_per
                lbg[first:first + 3], ubg[first:first + 3] = -np.inf, np.inf
        return lbg, ubg

    @property
    def start_row(self) -> int:
        """Index of the first start-state row (X_0 − x_start): after the dynamics (and
        collocation) rows and the tied durations, in both transcriptions."""
        lay, nx = self.layout, self.model.nx
        return nx * (lay.n_coll + 1) * lay.n_intervals + lay.n_intervals - lay.n_legs

    def pack(self, T: np.ndarray, X: np.ndarray, U: np.ndarray, Z: np.ndarray | None = None
             ) -> np.ndarray:
        """Decision vector from leg durations (L,), node states (M+1, nx), commands (M, nu) and
        collocation states (M, degree, nx; default: linear between the nodes)."""
        X = np.asarray(X, float)
        if self.layout.n_coll == 0:
            Z = np.zeros((len(X) - 1, 0))
        elif Z is None:
            tau = np.asarray(ca.collocation_points(self.layout.degree, "radau"))
            Z = X[:-1, None, :] + tau[None, :, None] * (X[1:] - X[:-1])[:, None, :]
        h = np.repeat(np.asarray(T, float), self.layout.intervals)
        if self.model.scale is not None:  # the NLP's units (OcpModel.scale)
            unit = np.asarray(self.model.scale)
            X = X / unit
            if self.layout.n_coll:
                Z = np.asarray(Z, float) / unit
        parts = [np.column_stack([h, np.asarray(U, float).reshape(len(h), -1),
                                  np.asarray(Z, float).reshape(len(h), -1), X[:-1]]).ravel(),
                 X[-1]]
        return np.concatenate(parts)

    def unpack(self, w: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(leg durations, node states (M+1, nx), commands (M, nu)) of a decision vector."""
        N, M, nx, nu = self.layout.intervals, self.layout.n_intervals, self.model.nx, \
            self.model.nu
        w = np.asarray(w, float).ravel()
        per = 1 + nu + nx * self.layout.n_coll + nx
        blocks = w[:M * per].reshape(M, per)
        X = np.vstack([blocks[:, per - nx:], w[M * per:][None, :]])
        if self.model.scale is not None:  # back to the model's units
            X = X * np.asarray(self.model.scale)
        return blocks[::N, 0], X, blocks[:, 1:1 + nu]


def rk4_step(model: OcpModel, substeps: int) -> ca.Function:
    """``step(x, u, p, h) -> x_next``: ``substeps`` RK4 steps of total length h (classical RK4,
    or ETDRK4 for a model with a rotor decay rate: :func:`etdrk4_step`)."""
    if model.rotor_rate is not None:
        return etdrk4_step(model, substeps)
    x = ca.SX.sym("x", model.nx)
    u = ca.SX.sym("u", model.nu)
    p = ca.SX.sym("p", model.np)
    h = ca.SX.sym("h")
    dt = h / substeps
    xk = x
    for _ in range(substeps):
        k1 = model.f(xk, u, p)
        k2 = model.f(xk + dt / 2 * k1, u, p)
        k3 = model.f(xk + dt / 2 * k2, u, p)
        k4 = model.f(xk + dt * k3, u, p)
        xk = xk + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return ca.Function("step", [x, u, p, h], [xk], ["x", "u", "p", "h"], ["x_next"])


#: Below this |z| = λ·dt the φ functions of :func:`phi_functions` are summed as their Taylor
#: series (degree :data:`PHI_TERMS` − 1: truncation below 1e-15 there), above it taken in closed
#: form (cancellation below 1e-12 there): both stay accurate, and so do their derivatives.
PHI_SERIES_BELOW = 0.2
PHI_TERMS = 12


def phi_functions(z) -> tuple:
    """(e^z, φ₁(z), φ₂(z), φ₃(z)) with φ_j(z) = Σ_k z^k / (k + j)!, the functions of exponential
    integrators (φ₁ = (e^z − 1)/z, φ₂ = (e^z − 1 − z)/z², φ₃ = (e^z − 1 − z − z²/2)/z³),
    symbolic (SX) or numeric; exact limits 1, 1/2, 1/6 at z = 0."""
    from math import factorial

    small = ca.fabs(z) < PHI_SERIES_BELOW
    zs = ca.if_else(small, 0.5, z)  # the closed form is taken at a safe z where it is unused
    es = ca.exp(zs)
    closed = ((es - 1) / zs, (es - 1 - zs) / zs**2, (es - 1 - zs - zs**2 / 2) / zs**3)
    out = [ca.exp(z)]
    for j in (1, 2, 3):
        series = sum(z**k / factorial(k + j) for k in range(PHI_TERMS))
        out.append(ca.if_else(small, series, closed[j - 1]))
    return tuple(out)


def etdrk4_step(model: OcpModel, substeps: int) -> ca.Function:
    """``step(x, u, p, h) -> x_next``: ``substeps`` steps of ETDRK4 (Cox & Matthews 2002,
    J. Comput. Phys. 176, 430, eq. 26–29; coefficients in φ functions as in Hochbruck &
    Ostermann 2010, Acta Numerica 19, 209) with the linear part L = −λ(p) on the rotor states
    (``model.rotor_rate``) and L = 0 on every other state, where the scheme is classical RK4.

    Why: with the ``propeller`` kind's DC motor the rotor speeds relax with a time constant of
    ~20–28 ms (back-EMF damping 1/(J_r R K_V²) plus the propeller's load), and classical RK4's
    local error grows as (λ dt)⁵: 40 intervals of 3 steps re-simulated 0.30 m off on the paper
    track. ETDRK4 integrates u' = L u + N(u) exactly for constant N and is fourth order in N's
    variation, so only the rotors' slower nonlinear part (the propeller's load, the pack's sag)
    is left to the step (benchmarks/RESULTS-propulsion.md, "Exponential rotor step")."""
    assert model.rotor_rate is not None and model.rotor is not None
    x = ca.SX.sym("x", model.nx)
    u = ca.SX.sym("u", model.nu)
    p = ca.SX.sym("p", model.np)
    h = ca.SX.sym("h")
    dt = h / substeps
    rot = np.zeros(model.nx, dtype=bool)
    rot[model.rotor] = True
    lam = model.rotor_rate(p)
    z = -lam * dt
    e, phi1, phi2, phi3 = phi_functions(z)
    e2, phi1_2, _, _ = phi_functions(z / 2)

    def per_state(rotor_value, other_value):
        return ca.vertcat(*[rotor_value if r else other_value for r in rot])

    L = per_state(-lam, 0.0)
    E, E2 = per_state(e, 1.0), per_state(e2, 1.0)
    half = per_state(dt / 2 * phi1_2, dt / 2)  # L⁻¹(e^{L dt/2} − 1)
    # weights of N(x), N(a) + N(b), N(c) (Cox & Matthews' f₁, 2f₂, f₃ as φ functions)
    w1 = per_state(dt * (phi1 - 3 * phi2 + 4 * phi3), dt / 6)
    w2 = per_state(dt * 2 * (phi2 - 2 * phi3), dt / 3)
    w3 = per_state(dt * (4 * phi3 - phi2), dt / 6)

    def nonlinear(xs):
        return model.f(xs, u, p) - L * xs

    xk = x
    for _ in range(substeps):
        n0 = nonlinear(xk)
        a = E2 * xk + half * n0
        na = nonlinear(a)
        b = E2 * xk + half * na
        nb = nonlinear(b)
        c = E2 * a + half * (2 * nb - n0)
        nc = nonlinear(c)
        xk = E * xk + w1 * n0 + w2 * (na + nb) + w3 * nc
    return ca.Function("step", [x, u, p, h], [xk], ["x", "u", "p", "h"], ["x_next"])


def exponential_rotor(model: OcpModel) -> OcpModel:
    """``model`` with its rotor states stepped by ETDRK4 (:func:`etdrk4_step`) at the rotor
    decay rate of its propulsion model
    (:meth:`casadrone.propulsion.base.PropulsionModel.decay_rate`), under its own name (its own
    NLP and compiled blocks)."""
    propulsion = model.propulsion

    def rate(p):
        return propulsion_model(propulsion).decay_rate(named(p, propulsion))

    return replace(model, name=f"{model.name}-etd", rotor_rate=rate)


def collocation_interval(model: OcpModel, degree: int) -> ca.Function:
    """``interval(x, z, u, p, h) -> (res, x_end)``: Radau collocation residuals of one interval
    (x the start state, z the ``degree`` collocation states side by side, u held, length h)."""
    tau = [0.0] + list(ca.collocation_points(degree, "radau"))
    C = np.zeros((degree + 1, degree + 1))
    for j in range(degree + 1):
        poly = np.poly1d([1.0])
        for r in range(degree + 1):
            if r != j:
                poly *= np.poly1d([1.0, -tau[r]]) / (tau[j] - tau[r])
        dpoly = np.polyder(poly)
        C[j] = [dpoly(t) for t in tau]
    x = ca.SX.sym("x", model.nx)
    z = ca.SX.sym("z", model.nx, degree)
    u = ca.SX.sym("u", model.nu)
    p = ca.SX.sym("p", model.np)
    h = ca.SX.sym("h")
    pts = [x] + [z[:, r] for r in range(degree)]
    res = [sum(C[j, r] * pts[j] for j in range(degree + 1)) - h * model.f(pts[r], u, p)
           for r in range(1, degree + 1)]
    return ca.Function("interval", [x, z, u, p, h], [ca.vertcat(*res), z[:, -1]],
                       ["x", "z", "u", "p", "h"], ["res", "x_end"])


def advance_rows(model: OcpModel, j_max: float, M: int) -> ca.Function:
    """``rows(X, p) -> g`` (4 M): J_max n_i D − v_a,i of each rotor at each of the M nodes
    (columns of X, model units) of a ``propeller`` model
    (:func:`casadrone.propulsion.advance_margins`); g ≥ 0 keeps every rotor at J ≤ J_max.

    Why at the NLP's assembly, not in the model: the wind-tunnel data of the shipped propeller
    end at J = 0.62, and a limit lap without the rows flew 4–6 % of its rotor-nodes beyond them,
    some nearly stopped in 27 m/s of inflow with the extrapolated quadratic giving negative
    thrust (braking the data do not support). The rows are linear in the rotor speed and the
    inflow (no division by n), and, like the tilt cone, they are differentiated by CasADi beside
    the compiled interval blocks, which stay as they are (no recompile)."""
    if model.velocity is None or model.rates is None or model.rotor is None:
        raise ValueError(f"model {model.name} has no rotors for an advance-ratio bound")
    x = ca.SX.sym("x", model.nx)
    p = ca.SX.sym("p", model.np)
    _, _, r, _, _ = unpack_params(p)
    g = advance_margins(x[model.velocity], x[model.rates], x[model.rotor], named(p), r, j_max)
    node = ca.Function("advance_rows", [x, p], [g], ["x", "p"], ["g"])
    X = ca.MX.sym("X", model.nx, M)
    P = ca.MX.sym("p", model.np)
    return ca.Function("advance_rows_map", [X, P], [ca.vec(node.map(M)(X, P))], ["X", "p"],
                       ["g"])


def _interval_rows(model: OcpModel, M: int, X, U, p) -> list:
    """The model's :attr:`OcpModel.interval_rows` on each of the M intervals (none if it has
    none): one block of rows per interval, in interval order."""
    if model.interval_rows is None:
        return []
    rows, lower, upper = model.interval_rows
    x0, x1 = ca.SX.sym("x0", model.nx), ca.SX.sym("x1", model.nx)
    u, p_ = ca.SX.sym("u", model.nu), ca.SX.sym("p", model.np)
    g = rows(x0, x1, u, p_)
    one = ca.Function("interval_rows", [x0, x1, u, p_], [g])
    n = g.numel()
    lo = np.tile(np.broadcast_to(np.asarray(lower, float), (n,)), M)
    hi = np.tile(np.broadcast_to(np.asarray(upper, float), (n,)), M)
    return [(ca.vec(one.map(M)(X[:, :M], X[:, 1:M + 1], U, p)), lo, hi)]


#: The current rows bound the currents at this share below their limits (relative): they hold
#: at the nodes of the RK4 grid, and CVODES flying the same commands peaks a little higher
#: between and at them. Measured on SY250-propeller, paper track, rows at the limits (65 A pack,
#: 25 A motors): re-simulated peaks 65.022 A (+0.034 %) and 25.099 A (+0.40 %); 1 % is 2.5x
#: the larger (tests/integration/test_race.py).
CURRENT_MARGIN = 0.01


def current_rows(model: OcpModel, layout: Layout, X, U, p) -> list:
    """The current limits (none where the layout has none): the pack current
    (≤ ``max_pack_current_a``) and each motor's (≤ ``max_motor_current_a``) of the propulsion
    kind (:meth:`casadrone.propulsion.base.PropulsionModel.currents`) at both ends of every
    interval under its held command, X in the model's units.

    Why both ends: with the command held, the currents are affine in the rotor speeds (the DC
    motor's I = (δ V − ω/K_V)/R, V affine in ω), and the rotor speeds move monotonically within
    an interval far shorter than their ~20 ms time constant, so the largest current of an
    interval sits at one of its ends; the re-simulation checks every sample
    (:func:`casadrone.limit.energy.flight_energy`) against the limits themselves, the rows sitting
    :data:`CURRENT_MARGIN` below them. Like the advance-ratio rows they are differentiated by
    CasADi beside the compiled interval blocks."""
    pack_a, motor_a = layout.max_pack_current_a, layout.max_motor_current_a
    if pack_a is None and motor_a is None:
        return []

    x, u, ps = ca.SX.sym("x", model.nx), ca.SX.sym("u", model.nu), ca.SX.sym("p", model.np)
    if model.rotor is None:
        raise ValueError(f"model {model.name} has no rotors for a current limit")
    out = propulsion_model(model.propulsion).currents(x[model.rotor], u,
                                                      named(ps, model.propulsion))
    if out is None:
        raise ValueError(f"propulsion {model.propulsion} has no currents to limit")
    rows, upper = [], []
    if pack_a is not None:
        rows.append(out[0])
        upper.append(pack_a)
    if motor_a is not None:
        rows.append(out[1])
        upper += [motor_a] * 4
    node = ca.Function("current_rows", [x, u, ps], [ca.vertcat(*rows)])
    M = layout.n_intervals
    g = ca.vertcat(ca.vec(node.map(M)(X[:, :M], U, p)), ca.vec(node.map(M)(X[:, 1:M + 1], U, p)))
    hi = np.tile(np.asarray(upper, float) * (1 - CURRENT_MARGIN), 2 * M)
    return [(g, np.full(hi.size, -np.inf), hi)]


def _leg_end_rows(model: OcpModel, layout: Layout, X, targets, p) -> list:
    """Constraint rows of every leg's end node (its target) and, if asked, rest at the end;
    first, if asked, the advance-ratio rows of every node after the start (the rows whose
    bounds :meth:`Nlp.row_bounds` sets stay last)."""
    N = layout.intervals
    rows = []
    if layout.max_advance_ratio is not None:
        M = layout.n_intervals
        rows.append((advance_rows(model, layout.max_advance_ratio, M)(X[:, 1:M + 1], p),
                     0.0, np.inf))
    for k, kind in enumerate(layout.kinds):
        xe = X[:, (k + 1) * N]
        rows += target_rows(xe, model.world_velocity(xe),
                             targets[TARGET_SIZE * k:TARGET_SIZE * (k + 1)], kind)
    if layout.end_at_rest:
        rows.append((model.world_velocity(X[:, layout.n_intervals]), 0.0, 0.0))
    if layout.periodic:
        rows += _periodic_rows(model, X[:, 0], X[:, layout.n_intervals])
    if layout.tilt_cone:  # the bound (cos of the largest tilt) is set by Nlp.row_bounds
        if model.up_z is None:
            raise ValueError(f"model {model.name} has no attitude for a tilt cone")
        rows.append((ca.vertcat(*[model.up_z(X[:, i]) for i in range(1, layout.n_intervals + 1)]),
                     -np.inf, np.inf))
    return rows


def periodic_row_count(model: OcpModel) -> int:
    """Rows of :func:`_periodic_rows`: one per state (a quaternion's four are three rows of
    its relative rotation and one of its norm)."""
    return model.nx


def _periodic_rows(model: OcpModel, x_first, x_last) -> list:
    """The periodic lap: the end state equals the start state, row by row in the NLP's units
    (each state divided by its ``scale``), position first (its three rows are freed by
    :meth:`Nlp.row_bounds` where the track's start is not its finish; where it is, the start
    position is free as well, the lap boundary anywhere in the last target, as every lap
    boundary inside a multi-lap flight).

    Attitude is periodic as a rotation, any number of full turns allowed:

    - Euler angles: sin((a(T) − a(0))/2) = 0 for φ, θ, ψ, so a(T) = a(0) + 2πk (one smooth
      row per angle whose gradient ±½ never vanishes there, unlike sin(Δ) that also admits π);
    - quaternion: the vector part of q(0)* ⊗ q(T) is zero, so q(T) is parallel to q(0), with
      either sign (q and −q are the same attitude: an odd number of full turns), plus
      |q(0)|² = 1. q(T) − q(0) = 0 instead would also pin |q(T)| = |q(0)|, which RK4 keeps only
      to its discretisation error: a spurious row on the trajectory. The norm row fixes the
      quaternion's free scale (the rotation is that of q / |q|); without it the KKT system is
      singular along q(0).
    """
    unit = ca.DM.ones(model.nx) if model.scale is None else ca.DM(model.scale)
    diff = (x_last - x_first) / unit
    if model.attitude == "euler":
        at = EUL  # the Euler angles of the 16-state model
        return [(ca.vertcat(diff[:at.start], ca.sin(diff[at] / 2), diff[at.stop:]), 0.0, 0.0)]
    if model.attitude == "quaternion":
        q0, q1 = x_first[QUAT], x_last[QUAT]
        w0, v0, w1, v1 = q0[0], q0[1:4], q1[0], q1[1:4]
        relative = w0 * v1 - w1 * v0 - ca.cross(v0, v1)  # vector part of q0* ⊗ q1
        return [(ca.vertcat(diff[:QUAT.start], relative, diff[QUAT.stop:]), 0.0, 0.0),
                (ca.sumsqr(q0), 1.0, 1.0)]
    return [(diff, 0.0, 0.0)]


def _bounds_of(rows) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds of constraint rows (expression, lower, upper)."""
    return (np.concatenate([np.full(r[0].numel(), r[1]) for r in rows]),
            np.concatenate([np.full(r[0].numel(), r[2]) for r in rows]))


def ipopt_options(tol: float, max_iter: int, warm: bool, near: bool = False,
                  propulsion: str = "paper") -> dict:
    """IPOPT settings (MUMPS, exact Hessian, quiet); ``warm`` adds primal-dual warm start, for a
    start far from the optimum (a neighbouring frame's lap), with the settings of the
    ``propulsion`` kind (its ``warm_ipopt``); ``near`` one for a start close to it
    (:data:`NEAR_VIOLATION`)."""
    ipopt = {"tol": tol, "acceptable_tol": 1e3 * tol, "max_iter": max_iter, "print_level": 0,
             "linear_solver": "mumps", "sb": "yes", "mu_strategy": "adaptive",
             "mumps_mem_percent": MUMPS_MEM_PERCENT}
    if warm and near:
        # Measured (benchmarks/RESULTS-limitlap-solvers.md, "Warm starts"; 10 random Table 1
        # frames): from a frame's own lap, 6 iterations (median) where the far setting below
        # takes 9.5 to bring μ down again; from the frame moved by 1 % of the Table 1 range in
        # every key, 16 against 20.5; the same laps.
        # tol 100× tighter: stopped at tol, a near start ends ~1e-5 s of lap from where the far
        # setting (whose adaptive μ runs on to ~1e-10) ends, enough to spoil finite differences
        # of warm re-solves (tests/integration/test_limitlap_optimality.py); the extra
        # iterations are few (from the frame's own lap 6 against 3, median).
        push = 1e-6
        ipopt.update({"warm_start_init_point": "yes", "mu_init": 1e-4, "tol": 1e-2 * tol,
                      **{f"warm_start_{k}": push for k in (
                          "bound_push", "bound_frac", "slack_bound_push", "slack_bound_frac",
                          "mult_bound_push")}})
    elif warm:
        # Measured on SY250-components → six neighbours (one key moved by 3–20 mm or deg), tol
        # 1e-6: μ₀ = 1e-2 with pushes 1e-4 took 37–55 iterations (one neighbour ended on a
        # 0.2 % slower local optimum); μ₀ = 1e-3 with pushes 1e-5, 53–80; μ₀ = 1e-6 with
        # pushes 1e-9, 87–955, and twice "converged" to a lap that exploits the integrator
        # (rejected by the re-simulation check); a primal-only start 54–108. Re-measured from
        # the nearest of 10 random Table 1 frames (RESULTS-limitlap-solvers.md): this setting
        # 43 iterations (median), μ₀ 1e-4 or 1e-6 with pushes 1e-6 or 1e-8 50–51, any of
        # them with the monotone μ strategy 52–109.
        ipopt.update({"warm_start_init_point": "yes", "warm_start_bound_push": 1e-4,
                      "warm_start_mult_bound_push": 1e-4, "warm_start_slack_bound_push": 1e-4,
                      "mu_init": 1e-2})
        ipopt.update(propulsion_model(propulsion).warm_ipopt)
    # show_eval_warnings off: a trial step that overflows the model (Inf/NaN in g) is IPOPT's
    # to handle (it shortens the step); CasADi would print a warning line for each.
    return {"ipopt": ipopt, "print_time": False, "error_on_fail": False,
            "show_eval_warnings": False}


#: MUMPS's working space above its own estimate, in per cent (IPOPT's ``mumps_mem_percent``;
#: IPOPT's default 1000). Measured on a warm solve of the paper track (200 intervals): the
#: factorisation needs 4 % above the estimate (at 1 % IPOPT reports MUMPS's INFO(1) = -9 and
#: doubles it twice, as it does whenever the space runs short), and at 1000 % each of the ~60
#: factorisations maps and faults in ten times the space: 0.30 s of system time in a 2.8 s
#: solve, 0.02–0.04 s at 10 %, the same iterates and lap to the last bit
#: (benchmarks/RESULTS-limitlap-solvers.md, "MUMPS's working space").
MUMPS_MEM_PERCENT = 20

#: A warm start whose largest constraint violation (the NLP's units: m, m/s, rad, rad/s, N)
#: is at most this is solved with the ``near`` setting of :func:`ipopt_options`, any other with
#: the far one. A neighbouring Table 1 frame's lap starts 4–5 away (body rates: the inertias
#: differ); a frame's own lap moved by 1 % of the Table 1 range, 0.05–0.5; by 3 %, 0.16–1.3,
#: where neither setting wins (measured: RESULTS-limitlap-solvers.md, "Warm starts").
NEAR_VIOLATION = 0.5


_NLPS: dict[tuple, Nlp] = {}
_BLOCKS: dict[tuple, tuple] = {}

#: How the interval blocks are generated (:func:`interval_blocks`):
#:
#: - ``substep-chain`` (the default): one RK4 step's derivatives chained over the steps
#:   (:func:`chained_block_functions`): the quadrotor's paper block is 1.1 MB of C, 14-23 s of
#:   CPU to compile at -O2 -mavx2, 9.8 MB for every shipped block, at the whole step's cost per
#:   solve (1.47 against 1.41 s of blocks per 68-iteration solve);
#: - ``whole-step``: CasADi's symbolic Jacobian and Hessian of the whole interval (its RK4 steps
#:   in one SX graph; :func:`interval_block_functions`): 4.4 MB, 157-198 s, 31 MB for every
#:   shipped block (the default until the fast path started from the shipped laps).
#:
#: The two give the same derivatives to rounding (~1e-16), not to the last bit, and IPOPT's path
#: from a cold start follows the last bits: SY250's fine-grid start ended at 3.8800 s with the
#: chain and 3.8914 s with the whole step, HS210's at 3.8833 s and 3.8307 s
#: (benchmarks/RESULTS-limitlap-compile.md). A warm start from a shipped lap does not: SY250
#: 3.8795 s from either (casadrone.limit.library). So the chain is the default, for a first
#: limit lap in about 25 s of CPU on an empty cache instead of four minutes;
#: ``$CASADRONE_BLOCKS=whole-step`` gives every lap as before, to the bit.
BLOCK_DESIGNS: tuple[str, ...] = ("substep-chain", "whole-step")


def block_design() -> str:
    """The interval blocks' design: ``$CASADRONE_BLOCKS`` or ``substep-chain``
    (:data:`BLOCK_DESIGNS`). Raises ValueError naming the variable for another value."""
    design = os.environ.get("CASADRONE_BLOCKS") or BLOCK_DESIGNS[0]
    if design not in BLOCK_DESIGNS:
        raise ValueError(f"CASADRONE_BLOCKS: {design!r} is not one of {', '.join(BLOCK_DESIGNS)}")
    return design


def interval_blocks(model: OcpModel, substeps: int, design: str | None = None
                    ) -> tuple[ca.Function, ca.Function, np.ndarray, np.ndarray]:
    """Compiled derivatives of one shooting interval, the same for every interval and layout.

    With ``z = [S, u, x]`` (the interval's leg duration, command and start node, in the order of
    the decision vector) and ``h = S · inv_n``:

    - ``jac(z, p, inv_n) -> (x_next, J)``: the RK4 step and its Jacobian ∂x_next/∂z (dense);
    - ``hess(z, p, inv_n, lam) -> H``: the structural nonzeros of triu(∂²(lam·x_next)/∂z²).

    Returns (jac, hess, rows, cols) with H's row and column indices in z. They are generated as
    C and compiled once per machine (:mod:`casadrone.codegen`); the NLP maps them over its
    intervals, so the compiled code is one interval's, whatever the number of intervals (the
    whole NLP's Hessian as generated C is hundreds of MB; evaluated by CasADi's virtual machine
    it costs ~0.1 s per IPOPT iteration, most of a solve). ``design``: one of
    :data:`BLOCK_DESIGNS` (default :func:`block_design`).
    """
    design = block_design() if design is None else design
    key = (model.name, substeps, design)
    if key not in _BLOCKS:
        names = tuple(f"limit_{part}_{_block_tag(model, substeps)}"
                      for part in ("jac", "hess", "hess_pattern"))
        fingerprint, build = block_recipe(
            design, rk4_step(model, substeps), interval_block_functions,
            (chained_block_functions, staged_substep_functions, chains_stages, stage_functions,
             rk4_stages, substep_block_functions, hessian_pattern, chained_substeps))
        jac, hess, pattern = compile_recipe(names, fingerprint, lambda: build(model, substeps),
                                            BLOCK_FLAGS)
        rows, cols = (np.asarray(a, dtype=int).ravel() for a in pattern.call([]))
        _BLOCKS[key] = (jac, hess, rows, cols)
    return _BLOCKS[key]


def block_recipe(design: str, step: ca.Function, whole_step: Callable, chained: tuple
                 ) -> tuple[str, Callable]:
    """(fingerprint, builder) of a block library in ``design`` (:data:`BLOCK_DESIGNS`):
    ``whole_step``, fingerprinted as before the chain existed (the same cache names), or
    ``chained[0]`` with the helpers ``chained[1:]`` in its fingerprint (a change to any of them
    is a new library)."""
    if design == "whole-step":
        return recipe_fingerprint(step, whole_step), whole_step
    return recipe_fingerprint(step, *chained), chained[0]


def _block_tag(model: OcpModel, substeps: int) -> str:
    return f"{model.name.replace('-', '_')}_rk4x{substeps}"


def interval_block_functions(model: OcpModel, substeps: int
                             ) -> tuple[ca.Function, ca.Function, ca.Function]:
    """:func:`interval_blocks`' functions as SX (uncompiled): ``jac``, ``hess`` and
    ``hess_pattern() -> (rows, cols)``, H's structural nonzeros' indices in z as constants (kept
    in the compiled library, so that a process which finds it cached builds no Hessian)."""
    nx, nu = model.nx, model.nu
    z = ca.SX.sym("z", 1 + nu + nx)
    p = ca.SX.sym("p", model.np)
    inv_n = ca.SX.sym("inv_n")
    lam = ca.SX.sym("lam", nx)
    step = rk4_step(model, substeps)
    x_next = step(z[1 + nu:], z[1:1 + nu], p, z[0] * inv_n)
    H = ca.triu(ca.hessian(ca.dot(lam, x_next), z)[0])
    rows, cols = H.sparsity().get_triplet()
    tag = _block_tag(model, substeps)
    jac = ca.Function(f"limit_jac_{tag}", [z, p, inv_n], [x_next, ca.densify(
        ca.jacobian(x_next, z))], ["z", "p", "inv_n"], ["x_next", "J"])
    nonzeros = ca.vertcat(*H.nonzeros())  # type: ignore[call-overload]  # SXElem: not in stubs
    hess = ca.Function(f"limit_hess_{tag}", [z, p, inv_n, lam], [nonzeros],
                       ["z", "p", "inv_n", "lam"], ["H"])
    pattern = ca.Function(f"limit_hess_pattern_{tag}", [], [ca.DM(rows), ca.DM(cols)],
                          [], ["rows", "cols"])
    return jac, hess, pattern


def chained_block_functions(model: OcpModel, substeps: int
                            ) -> tuple[ca.Function, ca.Function, ca.Function]:
    """:func:`interval_block_functions` as the ``substep-chain`` design builds them (the same
    inputs, outputs and Hessian pattern): ``jac`` and ``hess`` are the chain rule over the
    interval's ``substeps`` RK4 steps, each step
    one call of the two small functions of :func:`substep_block_functions` (generated as C once,
    called ``substeps`` times). With y_k = [S, u, x_k], D_k = ∂y_k/∂z, A_k = ∂x_{k+1}/∂y_k:

    - forward: D_{k+1} = [[I, 0]; A_k D_k], so ∂x_next/∂z = A_{K-1} D_{K-1};
    - adjoint: μ_K = lam, μ_k = (∂x_{k+1}/∂x_k)ᵀ μ_{k+1};
    - H = Σ_k D_kᵀ ∇²_y(μ_{k+1}·x_{k+1})(y_k) D_k (the exact Hessian of lam·x_next).

    The same derivatives as CasADi's symbolic Hessian of the whole step (to rounding, ~1e-16
    relative; tests/unit/test_codegen.py), in a quarter of the C: the quadrotor's paper block is
    1.1 MB instead of 4.4, and compiles at -O2 in ~23 s of CPU instead of ~2 min
    (benchmarks/RESULTS-limitlap-compile.md)."""
    nx, nu = model.nx, model.nu
    per = 1 + nu + nx
    sub_jac, sub_hess = staged_substep_functions(model, substeps)
    z = ca.MX.sym("z", per)
    p = ca.MX.sym("p", model.np)
    inv_n = ca.MX.sym("inv_n")
    lam = ca.MX.sym("lam", nx)
    x_next, dx, H, _ = chained_substeps(sub_jac, sub_hess, z, 1 + nu, (p, inv_n), lam,
                                        substeps)
    rows, cols = hessian_pattern(model, substeps)
    tag = _block_tag(model, substeps)
    jac = ca.Function(f"limit_jac_{tag}", [z, p, inv_n], [x_next, ca.densify(dx)],
                      ["z", "p", "inv_n"], ["x_next", "J"])
    hess = ca.Function(f"limit_hess_{tag}", [z, p, inv_n, lam],
                       [ca.densify(H).nz[(rows + per * cols).tolist()]],
                       ["z", "p", "inv_n", "lam"], ["H"])
    pattern = ca.Function(f"limit_hess_pattern_{tag}", [], [ca.DM(rows), ca.DM(cols)],
                          [], ["rows", "cols"])
    return jac, hess, pattern


def chained_substeps(sub_jac: ca.Function, sub_hess: ca.Function, v: ca.MX, n_head: int,
                     args: tuple, lam: ca.MX, substeps: int, columns: list[int] | None = None
                     ) -> tuple[ca.MX, ca.MX, ca.MX, list]:
    """The chain rule of :func:`interval_block_functions` over ``substeps`` steps: with
    v = [head (``n_head`` entries held over the interval), x_0], ``sub_jac(y, *args) -> (x_next,
    ∂x_next/∂y)`` and ``sub_hess(y, *args, mu) -> ∇²_y(mu·x_next)`` of one step, returns
    (x_K, ∂x_K/∂v, ∇²_v(lam·x_K) (full), [(y_k, μ_{k+1})]: each step's point and adjoint, for
    other first derivatives along the chain). With ``columns`` only those columns of the
    Hessian, from ``sub_hess(y, *args, mu, V) -> ∇²_y(mu·x_next) V`` (Hessian-vector products
    along the columns V of ∂y_k/∂v: less C than the whole step Hessian when they are few)."""
    nv = v.numel()
    nx = nv - n_head
    head = ca.horzcat(ca.DM.eye(n_head), ca.DM(n_head, nx))  # ∂(head)/∂v
    y, dx = v, ca.MX(ca.horzcat(ca.DM(nx, n_head), ca.DM.eye(nx)))  # y_0 = v, ∂x_0/∂v
    points, dys, steps = [], [], []
    for _ in range(substeps):
        dy = ca.vertcat(head, dx)
        x_k, A = sub_jac(y, *args)
        points.append(y)
        dys.append(dy)
        steps.append(A)
        dx = ca.mtimes(A, dy)
        y = ca.vertcat(v[:n_head], x_k)
    H, mu, adjoints = ca.MX(nv, nv if columns is None else len(columns)), lam, []
    for y_k, dy, A in zip(reversed(points), reversed(dys), reversed(steps), strict=True):
        adjoints.append(mu)
        if columns is None:
            H = H + ca.mtimes(dy.T, ca.mtimes(sub_hess(y_k, *args, mu), dy))
        else:
            H = H + ca.mtimes(dy.T, sub_hess(y_k, *args, mu, dy[:, columns]))
        mu = ca.mtimes(A[:, n_head:].T, mu)
    return y[n_head:], dx, H, list(zip(points, reversed(adjoints), strict=True))


def substep_block_functions(model: OcpModel, substeps: int) -> tuple[ca.Function, ca.Function]:
    """One of an interval's ``substeps`` RK4 steps (:func:`rk4_step`, h = S · inv_n / substeps)
    on y = [S, u, x], as SX:

    - ``sub_jac(y, p, inv_n) -> (x_next, A)``: the step and A = ∂x_next/∂y (dense);
    - ``sub_hess(y, p, inv_n, mu) -> H``: ∇²_y(mu·x_next), full (both triangles).

    What :func:`interval_block_functions` chains over the substeps."""
    nx, nu = model.nx, model.nu
    y = ca.SX.sym("y", 1 + nu + nx)
    p = ca.SX.sym("p", model.np)
    inv_n = ca.SX.sym("inv_n")
    mu = ca.SX.sym("mu", nx)
    x_next = rk4_step(model, 1)(y[1 + nu:], y[1:1 + nu], p, y[0] * inv_n / substeps)
    tag = _block_tag(model, substeps)
    sub_jac = ca.Function(f"limit_subjac_{tag}", [y, p, inv_n],
                          [x_next, ca.densify(ca.jacobian(x_next, y))],
                          ["y", "p", "inv_n"], ["x_next", "A"])
    sub_hess = ca.Function(f"limit_subhess_{tag}", [y, p, inv_n, mu],
                           [ca.hessian(ca.dot(mu, x_next), y)[0]],
                           ["y", "p", "inv_n", "mu"], ["H"])
    return sub_jac, sub_hess


def stage_functions(g: ca.Function, name: str, with_gp: bool = False
                    ) -> tuple[ca.Function, ...]:
    """The derivatives of one evaluation of ``g(w, *q) -> k`` (an ODE right-hand side on
    w = [ξ, c]: the state and what a step holds constant), as SX: ``{name}_stagejac(w, *q) ->
    (k, G)`` (G = ∂k/∂w, sparse), ``{name}_stagehess(w, *q, a) -> ∇²_w(a·k)`` (sparse) and, with
    ``with_gp``, ``{name}_stagegp(w, *q, a) -> ∂(a·k)/∂q₀``. What :func:`rk4_stages` calls four
    times per RK4 step."""
    w = ca.SX.sym("w", g.size1_in(0))
    q = [ca.SX.sym(g.name_in(i), g.sparsity_in(i)) for i in range(1, g.n_in())]
    a = ca.SX.sym("a", g.size1_out(0))
    k = g(w, *q)
    L = ca.dot(a, k)
    names = ["w", *(g.name_in(i) for i in range(1, g.n_in()))]
    # G and the Hessian keep their structural zeros: the chain's products skip them
    out = [ca.Function(f"{name}_stagejac", [w, *q], [k, ca.jacobian(k, w)], names, ["k", "G"]),
           ca.Function(f"{name}_stagehess", [w, *q, a], [ca.hessian(L, w)[0]], [*names, "a"],
                       ["H"])]
    if with_gp:
        out.append(ca.Function(f"{name}_stagegp", [w, *q, a],
                               [ca.densify(ca.gradient(L, q[0]))], [*names, "a"], ["gp"]))
    return tuple(out)


#: Classical RK4: ξ_{i+1} = x + RK4_NODES[i] h k_i, x_next = x + h Σ RK4_WEIGHTS[i] k_i.
RK4_NODES = (0.5, 0.5, 1.0)
RK4_WEIGHTS = (1 / 6, 1 / 3, 1 / 3, 1 / 6)


def rk4_stages(stage_jac: ca.Function, stage_hess: ca.Function | None, y: ca.MX, nc: int,
               q: tuple, h_per_s: ca.MX, mu: ca.MX | None = None
               ) -> tuple[ca.MX, ca.MX, ca.MX | None, list[tuple[ca.MX, ca.MX]]]:
    """One classical RK4 step of x' = g([x, c], *q) on y = [S, c, x] (step h = S · h_per_s),
    its derivatives by the chain rule over the four stage evaluations k_i = g(w_i), w_i =
    [ξ_i, c] (:func:`stage_functions`, each generated as C once instead of four nested copies
    inside one step's symbolic derivatives). Returns (x_next, A = ∂x_next/∂y, H =
    ∇²_y(mu·x_next) (full; None without ``mu``), [(w_i, ā_i)]: each stage's point and adjoint).

    The step's only nonlinear operations are the four g's and the products h·k_i (h is linear
    in S). With b_i the adjoint of h·k_i — b_4 = μ/6, b_i = w_i μ + n_i ξ̄_{i+1}
    (RK4_WEIGHTS w, RK4_NODES n), ξ̄_i = G_{i,ξ}ᵀ ā_i, ā_i = h b_i the adjoint of k_i — the
    Hessian is Σ_i W_iᵀ ∇²_w(ā_i·g)(w_i) W_i + eₛᵀ(b_iᵀ Dk_i) + (Dk_i)ᵀ b_i eₛ, W_i = ∂w_i/∂y,
    Dk_i = G_i W_i, eₛ = ∂h/∂y: exact, the same derivatives as CasADi's symbolic Hessian of the
    whole step to rounding (tests/unit/test_codegen.py)."""
    ny = y.numel()
    nx = ny - 1 - nc
    c, x = y[1:1 + nc], y[1 + nc:]
    h = y[0] * h_per_s
    Ex = ca.MX(ca.horzcat(ca.DM(nx, 1 + nc), ca.DM.eye(nx)))
    Ec = ca.MX(ca.horzcat(ca.DM(nc, 1), ca.DM.eye(nc), ca.DM(nc, nx)))
    es = ca.horzcat(h_per_s, ca.MX(1, nc + nx))  # ∂h/∂y
    xi, dxi = x, Ex
    ws, Ws, ks, Dks, Gs = [], [], [], [], []
    for i in range(4):
        w, W = ca.vertcat(xi, c), ca.vertcat(dxi, Ec)
        k, G = stage_jac(w, *q)
        Dk = ca.mtimes(G, W)
        ws.append(w)
        Ws.append(W)
        ks.append(k)
        Dks.append(Dk)
        Gs.append(G)
        if i < 3:
            xi = x + RK4_NODES[i] * h * k
            dxi = Ex + RK4_NODES[i] * (h * Dk + ca.mtimes(k, es))
    K = sum((wt * k for wt, k in zip(RK4_WEIGHTS, ks, strict=True)), ca.MX(nx, 1))
    DK = sum((wt * Dk for wt, Dk in zip(RK4_WEIGHTS, Dks, strict=True)), ca.MX(nx, ny))
    x_next = x + h * K
    A = Ex + h * DK + ca.mtimes(K, es)
    if mu is None or stage_hess is None:
        return x_next, A, None, []
    bs: list[ca.MX] = [ca.MX()] * 4
    xibar = None
    for i in reversed(range(4)):
        bs[i] = RK4_WEIGHTS[i] * mu + (0 if xibar is None else RK4_NODES[i] * xibar)
        xibar = ca.mtimes(Gs[i][:, :nx].T, h * bs[i])
    H = ca.MX(ny, ny)
    for w, W, Dk, b in zip(ws, Ws, Dks, bs, strict=True):
        H = H + ca.mtimes(W.T, ca.mtimes(stage_hess(w, *q, h * b), W))
        r = ca.mtimes(b.T, Dk)
        H = H + ca.mtimes(es.T, r) + ca.mtimes(r.T, es)
    return x_next, A, H, [(w, h * b) for w, b in zip(ws, bs, strict=True)]


#: Right-hand sides of at least this many SX instructions get their RK4 steps' derivatives from
#: the four stages (:func:`rk4_stages`), smaller ones from the whole step's SX (the chain's
#: small dense products cost about the same per interval whatever the model). Measured on the
#: compiled interval blocks, mapped over 200 intervals (a quiet AMD EPYC core): the propeller
#: model (768 instructions) from its stages compiles every shipped propeller block in 28 s of
#: CPU instead of 234 s, its Jacobian and Hessian blocks 18.3 and 58.6 ms per call against the
#: whole step's 17.2 and 53.9; the paper model (301) from its stages ran 4x slower than the
#: whole step (9.6 and 32.0 ms against 2.5 and 8.3), so it keeps the per-step chain
#: (benchmarks/RESULTS-limitlap-compile.md).
STAGE_CHAIN_MIN_INSTRUCTIONS = 500


def chains_stages(model: OcpModel) -> bool:
    """Whether ``model``'s interval blocks chain the RK4 stages (classical RK4 and a right-hand
    side of at least STAGE_CHAIN_MIN_INSTRUCTIONS instructions; ETDRK4 steps do not)."""
    return model.rotor_rate is None and \
        model.f.n_instructions() >= STAGE_CHAIN_MIN_INSTRUCTIONS


def staged_substep_functions(model: OcpModel, substeps: int
                             ) -> tuple[ca.Function, ca.Function]:
    """:func:`substep_block_functions` built from the four stages of classical RK4
    (:func:`rk4_stages`) where :func:`chains_stages`: the same ``sub_jac`` and ``sub_hess``,
    with the model's right-hand side and its derivatives generated once instead of inside the
    step's symbolic derivatives; otherwise :func:`substep_block_functions`."""
    if not chains_stages(model):
        return substep_block_functions(model, substeps)
    nx, nu = model.nx, model.nu
    tag = _block_tag(model, substeps)
    wx = ca.SX.sym("w", nx + nu)
    ps = ca.SX.sym("p", model.np)
    g = ca.Function("g", [wx, ps], [model.f(wx[:nx], wx[nx:], ps)], ["w", "p"], ["k"])
    stage_jac, stage_hess = stage_functions(g, f"limit_{tag}")
    y = ca.MX.sym("y", 1 + nu + nx)
    p = ca.MX.sym("p", model.np)
    inv_n = ca.MX.sym("inv_n")
    mu = ca.MX.sym("mu", nx)
    x_next, A, H, _ = rk4_stages(stage_jac, stage_hess, y, nu, (p,), inv_n / substeps, mu)
    assert H is not None  # given mu
    return (ca.Function(f"limit_subjac_{tag}", [y, p, inv_n], [x_next, ca.densify(A)],
                        ["y", "p", "inv_n"], ["x_next", "A"]),
            ca.Function(f"limit_subhess_{tag}", [y, p, inv_n, mu], [ca.densify(H)],
                        ["y", "p", "inv_n", "mu"], ["H"]))


def hessian_pattern(model: OcpModel, substeps: int) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) of the structural nonzeros of triu(∂²(lam·x_next)/∂z²) of one interval
    (:func:`rk4_step`, z = [S, u, x]), column by column: from CasADi's symbolic Hessian of the
    whole step (a fraction of a second; its C is never generated)."""
    nx, nu = model.nx, model.nu
    z = ca.SX.sym("z", 1 + nu + nx)
    lam = ca.SX.sym("lam", nx)
    x_next = rk4_step(model, substeps)(z[1 + nu:], z[1:1 + nu], ca.SX.sym("p", model.np),
                                       z[0] * ca.SX.sym("inv_n"))
    H = ca.triu(ca.hessian(ca.dot(lam, x_next), z)[0])
    rows, cols = H.sparsity().get_triplet()
    return np.asarray(rows, dtype=int), np.asarray(cols, dtype=int)


_STEPS: dict[tuple, ca.Function] = {}


def step_block(model: OcpModel, substeps: int) -> ca.Function:
    """:func:`rk4_step` compiled with its reverse derivative (:func:`casadrone.codegen.
    compile_with_reverse`), once per model and substeps: what the NLP's rows evaluate in every
    IPOPT iteration (nlp_g, jac_g's g) and ∂L/∂P reverses through once per solve. The same
    numbers as the SX step to the last bit; its C is a few per cent of the Hessian block's."""
    key = (model.name, substeps)
    if key not in _STEPS:
        step = rk4_step(model, substeps)
        ins = step.sx_in()
        name = f"limit_step_{model.name.replace('-', '_')}_rk4x{substeps}"
        _STEPS[key] = compile_with_reverse(
            ca.Function(name, ins, step.call(ins), step.name_in(), step.name_out()),
            BLOCK_FLAGS)
    return _STEPS[key]


#: Compiler flags of the interval blocks: -O2 with AVX2 where the CPU has it
#: (:func:`casadrone.codegen.vector_flags`). GCC 12's -O2 packs the Hessian block's straight-line
#: code into 256-bit vector instructions: 7.3 against 11.6 ms per 200 intervals on an AMD EPYC
#: (Zen 3), the same numbers to the last bit; -O2 alone or -O1 run as slow as each other
#: (benchmarks/RESULTS-limitlap-solvers.md, "The interval blocks in vector registers").
BLOCK_FLAGS: tuple[str, ...] = ("-O2", *vector_flags())


def _assemble(nrow: int, ncol: int, rows: np.ndarray, cols: np.ndarray, values: ca.MX
              ) -> ca.MX:
    """The sparse matrix with ``values[t]`` added at (rows[t], cols[t]) (duplicates summed)."""
    import scipy.sparse as sps

    n = len(rows)
    pattern = sps.csc_matrix((np.ones(n), (rows, cols)), shape=(nrow, ncol))
    pattern.sum_duplicates()
    pattern.sort_indices()
    sp = ca.Sparsity(nrow, ncol, pattern.indptr.tolist(), pattern.indices.tolist())
    # nonzero index (column-major) of each triplet
    order = np.lexsort((rows, cols))
    key = cols[order].astype(np.int64) * nrow + rows[order]
    first = np.r_[True, key[1:] != key[:-1]]
    nz = np.empty(n, dtype=int)
    nz[order] = np.cumsum(first) - 1
    A = ca.DM(ca.Sparsity.triplet(sp.nnz(), n, nz.tolist(), list(range(n))), 1.0)
    return ca.sparsity_cast(ca.mtimes(A, values), sp)


def _shooting_nlp(model: OcpModel, layout: Layout) -> tuple[dict, np.ndarray, np.ndarray, dict]:
    """Multiple shooting as an MX NLP whose constraint Jacobian and Lagrangian Hessian are
    assembled from the compiled interval blocks (:func:`interval_blocks`), mapped over the
    intervals; CasADi's own AD serves only the rest (the target rows, and ∂L/∂P for the
    sensitivities, once per solve). Same decision vector, constraints and bounds as the SX build.
    """
    L, N, M, nx, nu = layout.n_legs, layout.intervals, layout.n_intervals, model.nx, model.nu
    per = 1 + nu + nx
    nw = M * per + nx
    W = ca.MX.sym("w", nw)
    p = ca.MX.sym("p", model.np)
    x_start = ca.MX.sym("x_start", nx)
    targets = ca.MX.sym("targets", TARGET_SIZE * L)
    P = ca.vertcat(p, x_start, targets)
    Zb = ca.reshape(W[:M * per], per, M)  # column i: z_i = [S_i, u_i, x_i] (NLP units)
    Xs = ca.horzcat(Zb[1 + nu:, :], W[M * per:])
    S = Zb[0, :]
    # OcpModel.scale: W holds x / d; the blocks and targets see x = d·x_s, the dynamics and start
    # rows are divided by d (x_s,i+1 − step(x_i)/d), so every row is in the NLP's units as well
    d = None if model.scale is None else np.asarray(model.scale, float)
    X = Xs if d is None else Xs * ca.DM(np.tile(d[:, None], (1, M + 1)))
    Zp = Zb if d is None else Zb * ca.DM(np.tile(np.r_[np.ones(1 + nu), d][:, None], (1, M)))
    if d is not None:
        x_start = x_start / ca.DM(d)

    def dynamics(step: ca.Function) -> ca.MX:
        x_next = step.map(M)(X[:, :M], Zb[1:1 + nu, :], p, S / N)
        if d is not None:
            x_next = x_next / ca.DM(np.tile(d[:, None], (1, M)))
        return ca.vec(Xs[:, 1:] - x_next)

    same_i = np.array([i for i in range(1, M) if i % N], dtype=int)
    trows = _interval_rows(model, M, X, Zb[1:1 + nu, :], p) + \
        current_rows(model, layout, X, Zb[1:1 + nu, :], p) + \
        _leg_end_rows(model, layout, X, targets, p)
    gt = ca.vertcat(*[r[0] for r in trows])
    rows = [(dynamics(rk4_step(model, layout.substeps)), 0.0, 0.0),
            ((S[same_i] - S[same_i - 1]).T, 0.0, 0.0), (Xs[:, 0] - x_start, 0.0, 0.0), *trows]
    lbg, ubg = _bounds_of(rows)
    # The rows as IPOPT evaluates them (nlp_g, and jac_g's g): the same graph with the step
    # compiled (step_block: the same numbers to the last bit, ~7x faster than CasADi's virtual
    # machine, which took 5.5 of the 9.3 ms of a paper-track jac_g call and all of nlp_g's);
    # the symbolic NLP keeps the step as SX, for co-design's composition and any AD order.
    g_sym = ca.vertcat(*[r[0] for r in rows])
    g = ca.vertcat(dynamics(step_block(model, layout.substeps)),
                   *[r[0] for r in rows[1:]])
    f = ca.sum2(S[::N])
    n_dyn, n_same = nx * M, len(same_i)
    ng = g.numel()

    # constraint Jacobian: blocks −J_i, identities, ±1 of the tied durations, target rows
    jac, hess, hr, hc = interval_blocks(model, layout.substeps)
    J = jac.map(M)(Zp, p, 1.0 / N)[1]
    dz = np.ones(per) if d is None else np.r_[np.ones(1 + nu), d]  # units of z
    if d is not None:  # ∂(step(d_z z_s)/d)/∂z_s = J d_z / d, row by row
        J = J * ca.DM(np.tile(np.outer(1 / d, dz), (1, M)))
    r_, c_, i_ = np.meshgrid(np.arange(nx), np.arange(per), np.arange(M), indexing="ij")
    tr = [(nx * i_ + r_).ravel(order="F")]  # matches vec(J) of the mapped output
    tc = [(per * i_ + c_).ravel(order="F")]
    vals: list[Any] = [-ca.vec(J)]
    node = np.arange(1, M + 1)[:, None] * per + (1 + nu) + np.arange(nx)[None, :]
    node[-1] = M * per + np.arange(nx)  # x_{i+1}: the next block's state, or the last node
    for r_idx, c_idx in ((np.arange(n_dyn), node.ravel()),
                         (n_dyn + np.arange(n_same), per * same_i),
                         (n_dyn + np.arange(n_same), per * (same_i - 1)),
                         (n_dyn + n_same + np.arange(nx), 1 + nu + np.arange(nx))):
        tr.append(r_idx)
        tc.append(c_idx)
    consts = np.concatenate([np.ones(n_dyn), np.ones(n_same), -np.ones(n_same), np.ones(nx)])
    vals.append(ca.DM(consts))
    Jt = ca.jacobian(gt, W)
    jr, jc = (np.array(a, dtype=int) for a in Jt.sparsity().get_triplet())
    tr.append(n_dyn + n_same + nx + jr)
    tc.append(jc)
    vals.append(ca.vec(Jt.nz[:]) if Jt.nnz() else ca.MX(0, 1))  # a column even for one row
    Jg = _assemble(ng, nw, np.concatenate(tr), np.concatenate(tc), ca.vertcat(*vals))
    jac_g = ca.Function("nlp_jac_g", [W, P], [g, Jg], ["x", "p"], ["g", "jac_g_x"])

    # Lagrangian Hessian (upper triangle): interval blocks of −lam_i·step, plus the target rows
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", ng)
    lam_dyn = -ca.reshape(lam_g[:n_dyn], nx, M)
    if d is not None:  # the rows are step/d: multipliers lam/d; z = d_z z_s on both sides
        lam_dyn = lam_dyn / ca.DM(np.tile(d[:, None], (1, M)))
    Hb = hess.map(M)(Zp, p, 1.0 / N, lam_dyn)
    if d is not None:
        Hb = Hb * ca.DM(np.tile((dz[hr] * dz[hc])[:, None], (1, M)))
    i2 = np.repeat(np.arange(M), len(hr))
    hrow = [np.tile(hr, M) + per * i2]
    hcol = [np.tile(hc, M) + per * i2]
    hvals = [ca.vec(Hb)]
    lam_t = lam_g[n_dyn + n_same + nx:]
    Ht = ca.triu(ca.hessian(ca.dot(lam_t, gt), W)[0]) if gt.numel() else ca.MX(nw, nw)
    if Ht.nnz():
        a, b = (np.array(v, dtype=int) for v in Ht.sparsity().get_triplet())
        hrow.append(a)
        hcol.append(b)
        hvals.append(Ht.nz[:])
    H = _assemble(nw, nw, np.concatenate(hrow), np.concatenate(hcol), ca.vertcat(*hvals))
    hess_lag = ca.Function("nlp_hess_l", [W, P, lam_f, lam_g], [H],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    nlp = {"x": W, "p": P, "f": f, "g": g_sym}
    return nlp, lbg, ubg, {"jac_g": jac_g, "hess_lag": hess_lag, "g": g}


def _collocation_nlp(model: OcpModel, layout: Layout) -> tuple[dict, np.ndarray, np.ndarray,
                                                                dict]:
    """Radau collocation as an SX NLP (CasADi's own derivatives), kept for comparison."""
    L, N, M, nx, nu = layout.n_legs, layout.intervals, layout.n_intervals, model.nx, model.nu
    d = layout.n_coll
    if model.interval_rows is not None:
        raise ValueError(f"model {model.name}: interval rows are a shooting NLP's")
    # per interval i: its leg's duration S_i (its length is S_i / N), command, collocation
    # states, start node; then the last node. S is one unknown per interval, equal within a leg
    # (S_i = S_{i-1}): a leg's duration then couples neighbours only, and the KKT matrix stays
    # banded for MUMPS (one duration per leg would couple all of the leg's intervals).
    S = ca.SX.sym("S", 1, M)
    h = S / N
    U = ca.SX.sym("U", nu, M)
    Z = ca.SX.sym("Z", nx * d, M)
    X = ca.SX.sym("X", nx, M + 1)
    p = ca.SX.sym("p", model.np)
    x_start = ca.SX.sym("x_start", nx)
    targets = ca.SX.sym("targets", TARGET_SIZE * L)
    interval = collocation_interval(model, d)
    # OcpModel.scale: X and Z hold x / unit; rows divided by the unit (as in _shooting_nlp)
    unit = ca.DM.ones(nx) if model.scale is None else ca.DM(model.scale)
    Xp = X if model.scale is None else X * ca.repmat(unit, 1, M + 1)
    Zp = Z if model.scale is None else Z * ca.repmat(unit, d, M)
    res, x_end = [], []
    for i in range(M):
        r, e = interval(Xp[:, i], ca.reshape(Zp[:, i], nx, d), U[:, i], p, h[i])
        res.append(r if model.scale is None else r / ca.repmat(unit, d, 1))
        x_end.append(X[:, i + 1] - (e if model.scale is None else e / unit))
    same = [S[i] - S[i - 1] for i in range(1, M) if i % N]
    x0 = x_start if model.scale is None else x_start / unit
    rows = [(ca.vertcat(*res), 0.0, 0.0), (ca.vertcat(*x_end), 0.0, 0.0),
            (ca.vertcat(*same), 0.0, 0.0), (X[:, 0] - x0, 0.0, 0.0),
            *current_rows(model, layout, Xp, U, p),
            *_leg_end_rows(model, layout, Xp, targets, p)]
    lbg, ubg = _bounds_of(rows)
    w = ca.vertcat(ca.vec(ca.vertcat(S, U, Z, X[:, :M])), X[:, M])
    nlp = {"x": w, "p": ca.vertcat(p, x_start, targets), "f": ca.sum2(S[::N]),
           "g": ca.vertcat(*[r[0] for r in rows])}
    return nlp, lbg, ubg, {}


def build_nlp(model: OcpModel, layout: Layout, tol: float = 1e-8, max_iter: int = 1000) -> Nlp:
    """The NLP of ``layout`` on ``model``, built once per process and cached (never per airframe).
    """
    key = (model.name, model.scale, model.propulsion, layout, tol, max_iter)
    if key in _NLPS:
        return _NLPS[key]
    make = _shooting_nlp if layout.method == "shooting" else _collocation_nlp
    nlp, lbg, ubg, extra = make(model, layout)
    # the rows as IPOPT evaluates them, where they differ from the symbolic ones (shooting: the
    # compiled step); the remaining entries are nlpsol's derivative options
    extra = dict(extra)
    solved = nlp | {"g": extra.pop("g")} if "g" in extra else nlp
    name = f"limit_{model.name.replace('-', '_')}_{layout.n_legs}x{layout.intervals}"
    built = Nlp(model=model, layout=layout,
                cold=ca.nlpsol(name, "ipopt", solved,
                               ipopt_options(tol, max_iter, False) | extra),
                warm=ca.nlpsol(name + "_warm", "ipopt", solved,
                               ipopt_options(tol, max_iter, True,
                                             propulsion=model.propulsion) | extra),
                near=ca.nlpsol(name + "_near", "ipopt", solved,
                               ipopt_options(tol, max_iter, True, near=True) | extra),
                lbg=lbg, ubg=ubg, problem=dict(nlp), derivatives=dict(extra), oracle=solved,
                tol=tol, max_iter=max_iter)
    _NLPS[key] = built
    return built


def ipopt_solver(nlp: Nlp, name: str, overrides: dict, warm: bool = False) -> ca.Function:
    """IPOPT on ``nlp``'s own oracle and derivatives (what :attr:`Nlp.cold` solves) with
    ``overrides`` on top of :func:`ipopt_options` (cold, or the far warm setting), for measuring
    other IPOPT settings on the same NLP."""
    opts = ipopt_options(nlp.tol, nlp.max_iter, warm, propulsion=nlp.model.propulsion)
    opts["ipopt"].update(overrides)
    return ca.nlpsol(name, "ipopt", nlp.oracle or nlp.problem, opts | nlp.derivatives)


@dataclass(frozen=True)
class NlpPoint:
    """A primal-dual point of an NLP (a solution, kept for warm starts and sensitivities)."""

    w: np.ndarray
    lam_x: np.ndarray
    lam_g: np.ndarray
    lam_p: np.ndarray


@dataclass(frozen=True)
class NlpSolution:
    """One solve (IPOPT, or fatrop with IPOPT as its fallback)."""

    success: bool
    return_status: str
    objective: float
    point: NlpPoint
    iterations: int
    wall_time_s: float
    solver: str = "ipopt"  # the solver whose point this is
    #: fatrop's (status, iterations, wall time in s) when it ran, whether or not it converged
    fatrop: tuple[str, int, float] | None = None




def solve(nlp: Nlp, w0: np.ndarray, P: np.ndarray, lbx: np.ndarray, ubx: np.ndarray,
          warm: NlpPoint | None = None, lbg: np.ndarray | None = None,
          ubg: np.ndarray | None = None, solver: str = "ipopt", near: bool = False
          ) -> NlpSolution:
    """Solve from ``w0`` (or from a primal-dual ``warm`` point); never raises. Row bounds
    default to the NLP's own (:meth:`Nlp.row_bounds` gives others). ``solver="fatrop"`` solves
    the stage-ordered NLP with fatrop and falls back to IPOPT from the same start when fatrop
    does not converge (the result says which solver's point it is). ``near``: IPOPT's warm
    setting is chosen by the start's constraint violation (:func:`warm_solver`) instead of the
    far one always.

    Why ``near`` is not the default: it returns the same laps (≤ 0.01 %), but its points differ
    from the far setting's at the 1e-7 level, and downstream cold starts are chaotic in them: on
    the co-design test's short track a cold start of the certificate then found a lap 0.86 %
    faster than the co-design optimum (the certificate failed, honestly) where it had ended in
    restoration failure. Which callers should use it is for their owners to measure."""
    lbg = nlp.lbg if lbg is None else lbg
    ubg = nlp.ubg if ubg is None else ubg
    if solver == "fatrop":
        first = _solve_fatrop(nlp, w0, P, lbx, ubx, warm, lbg, ubg)
        if first.success:
            return first
        fallback = _solve_ipopt(nlp, w0, P, lbx, ubx, warm, lbg, ubg, near)
        return replace(fallback, wall_time_s=first.wall_time_s + fallback.wall_time_s,
                       fatrop=first.fatrop)
    if solver != "ipopt":
        raise ValueError(f"unknown solver {solver!r} (one of {', '.join(SOLVERS)})")
    return _solve_ipopt(nlp, w0, P, lbx, ubx, warm, lbg, ubg, near)


def _failed_point(nlp: Nlp, w0: np.ndarray, P: np.ndarray) -> NlpPoint:
    return NlpPoint(np.asarray(w0, float), np.zeros(len(w0)), np.zeros(len(nlp.lbg)),
                    np.zeros(len(P)))


def _solve_fatrop(nlp: Nlp, w0, P, lbx, ubx, warm, lbg, ubg,
                  stall_s: float | None = None, guard: bool = True) -> NlpSolution:
    """fatrop alone, in a forked child given up after ``stall_s`` seconds (default
    :data:`casadrone.limit.watchdog.STALL_S`) without an evaluation: fatrop can loop forever
    inside an iteration (the module docstring of :mod:`casadrone.limit.watchdog`). A stalled
    or failed solve is a failed solution, and :func:`solve` falls back to IPOPT. ``guard=False``
    solves in this process (for the solver's own statistics; it can hang)."""
    import time


    start = time.perf_counter()
    x0 = np.clip(w0 if warm is None else warm.w, lbx, ubx)
    try:
        fs = fatrop_solver(nlp, nlp.tol, nlp.max_iter)  # built here, once: the child inherits it
    except StageError as exc:
        status = f"error: {str(exc).splitlines()[-1][:100]}"
        wall = time.perf_counter() - start
        return NlpSolution(False, status, np.nan, _failed_point(nlp, w0, P), 0, wall, "fatrop",
                           (status, 0, wall))
    run = run_guarded(lambda: solve_stagewise(fs, x0, P, lbx, ubx, lbg, ubg, warm is not None),
                      STALL_S if stall_s is None else stall_s, fork=guard)
    if run.outcome == "ok":
        success, status, f, point, iters = run.value
        sol_point = NlpPoint(*point)
    else:
        message = run.message.splitlines()[-1][:100] if run.message else run.outcome
        status = f"error: {message}" if run.outcome == "error" else f"fatrop {run.outcome}: " \
            f"{message}"
        success, iters, f, sol_point = False, 0, np.nan, _failed_point(nlp, w0, P)
    wall = time.perf_counter() - start
    return NlpSolution(success, status, f, sol_point, iters, wall, "fatrop", (status, iters, wall))


def _solve_ipopt(nlp: Nlp, w0, P, lbx, ubx, warm, lbg, ubg, near: bool = False
                 ) -> NlpSolution:
    import time

    start = time.perf_counter()
    args = dict(x0=np.clip(w0, lbx, ubx), p=P, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    solver = nlp.cold
    try:
        if warm is not None:
            args.update(x0=np.clip(warm.w, lbx, ubx), lam_x0=warm.lam_x, lam_g0=warm.lam_g)
            solver = warm_solver(nlp, args["x0"], P, lbg, ubg) if near else nlp.warm
        out = solver(**args)
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        success = bool(stats.get("success", False)) and bool(np.isfinite(float(out["f"])))
        point = NlpPoint(*(np.array(out[k]).ravel() for k in ("x", "lam_x", "lam_g", "lam_p")))
        iters = int(stats.get("iter_count", 0))
        f = float(out["f"])
    except RuntimeError as exc:  # evaluation errors (NaN in the model) end as a failed solve
        status, success, iters, f = f"error: {str(exc).splitlines()[-1][:100]}", False, 0, np.nan
        point = _failed_point(nlp, w0, P)
    return NlpSolution(success, status, f, point, iters, time.perf_counter() - start)


def start_violation(nlp: Nlp, w: np.ndarray, P: np.ndarray, lbg: np.ndarray, ubg: np.ndarray
                    ) -> float:
    """Largest constraint violation of ``w`` (inside its box) in the NLP's units: how far a
    warm start is from the optimum it comes from. One evaluation of g (IPOPT's own function)."""
    g = np.asarray(nlp.cold.get_function("nlp_g")(w, P), float).ravel()
    worst = float(np.max(np.maximum(lbg - g, 0.0) + np.maximum(g - ubg, 0.0), initial=0.0))
    return worst if np.isfinite(worst) else np.inf  # NaN (the model overflowed there): far


def warm_solver(nlp: Nlp, w: np.ndarray, P: np.ndarray, lbg: np.ndarray, ubg: np.ndarray
                ) -> ca.Function:
    """The IPOPT instance for a warm start at ``w``: ``near`` when its constraint violation is
    at most :data:`NEAR_VIOLATION`, else ``warm``."""
    if nlp.near is None or start_violation(nlp, w, P, lbg, ubg) > NEAR_VIOLATION:
        return nlp.warm
    return nlp.near
