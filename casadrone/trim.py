"""Trim: the operating point (x0, u0) of a steady flight condition, by three solvers.

Conditions (one registry, :data:`CONDITION_REGISTRY`): ``hover``; ``forward``, level flight at
speed V along world +x; ``climb``, straight flight at speed V along a path inclined by the climb
angle γ (negative: descent); ``turn``, a coordinated level turn at speed V whose heading turns
at the rate Ω (positive: left, counter-clockwise seen from above), the nose along the velocity.
Each is a value of the operating-point vector (V, γ, Ω); hover is V = 0.

Formulation (the same for every solver and condition). With heading ψ = 0 at the instant
considered, world velocity V (cos γ, 0, sin γ) and body rates ω = W(φ, θ)⁻¹ (0, 0, Ω) (the heading
turns at Ω, roll and pitch stay put: p = −Ω sin θ, q = Ω sin φ cos θ, r = Ω cos φ cos θ), six
unknowns remain

    Z = (φ, θ, δ1, δ2, δ3, δ4)        (rad, rad, ESC commands)

from which the whole state follows: body velocity (u, v, w) = R(φ, θ, 0)ᵀ V (cos γ, 0, sin γ),
rotor thrusts T = K δ (the first-order thrust model at rest), position 0. The six residuals Q(Z)
are the body-velocity and body-rate rows of the explicit model f(x, u, p): v̇ = 0 (m/s²) and
ω̇ = 0 (rad/s²); in a turn the body velocity and rates are constant while the heading turns, so
these rows carry the centripetal and gyroscopic terms. The Euler-angle rows hold by the choice
of ω (φ̇ = θ̇ = 0, ψ̇ = Ω) and the thrust rows because T = K δ, so the system is square, 6 × 6.
Positive θ is nose-down: in forward flight θ > 0; a left turn banks left, φ < 0.

Every solver reports the same ``residual_norm``: the 2-norm of all 13 non-position rows of
f(x0, u0, p) minus their steady values (zero, except ψ̇ = Ω), evaluated by one compiled Function
after the solver has finished.

Solvers (all built once per process and option set, with p and (V, γ, Ω) as parameters):

* ``ipopt`` — CasADi ``nlpsol`` feasibility problem: objective 0, g(Z) = Q(Z) = 0.
* ``newton`` — CasADi ``rootfinder`` (Newton) on Q(Z) = 0.
* ``nelder-mead`` — the paper's method (Eq. 5–7): scipy Nelder–Mead on the penalised cost
  f(Z) + QᵀHQ with H = diag(weights). The operating-point constraints of Eq. 5 (level flight,
  zero rates, steady thrust) hold by construction of Z, so the objective f(Z) of Eq. 6 is
  eliminated and the cost is QᵀHQ alone. Adaptive simplex, restarted from the best point until
  ‖Q‖ reaches the tolerance or the iteration cap.

Commands outside [0, 1] are not a failure of the equations: the trim is reported (success) and
the message says the command saturates. A pitch or roll beyond ``max_tilt_deg`` is a failure,
and so, with ``propeller``, is a root with a negative rotor speed: the propeller would turn
backwards, which a racing ESC (no 3-D mode) cannot command and CT(J), CP(J) do not describe.
SY250-propeller at 40 m/s level has both roots: δ = 1.43 (saturating, reported) and δ = −0.44
with ω = −1945 rad/s, the one IPOPT's feasibility solve lands on (refused).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from casadrone.airframe import Airframe
from casadrone.codegen import ZeroCopyCall
from casadrone.conditions import CONDITION_REGISTRY, CONDITIONS, operating_vector
from casadrone.drag import DEFAULT_DRAG, drag_force
from casadrone.model import (
    EUL,
    INPUT_NAMES,
    NP,
    NX,
    RATE,
    STATE_NAMES,
    THR,
    VEL,
    n_params,
    named,
    propeller_outputs,
    quadrotor_model,
    rotation_matrix,
    state_names,
)
from casadrone.propulsion import hover_rotors, model_of_length, propulsion_model
from casadrone.results import AsDict

#: A trim condition's name: a key of :data:`casadrone.conditions.CONDITION_REGISTRY`.
Condition = str
UNKNOWN_NAMES = ("phi", "theta", "delta1", "delta2", "delta3", "delta4")
_PSI_ROW = STATE_NAMES.index("psi")
__all__ = ["CONDITION_REGISTRY", "CONDITIONS", "SOLVERS", "TRIM_SOLVERS", "TrimOptions",
           "TrimPoint", "initial_guess", "operating_vector", "residual_norm", "trim", "trim_all",
           "trim_residual"]


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
class TrimPoint(AsDict):
    """An operating point and how it was found.

    Attributes:
        solver, condition, speed_mps, climb_angle_deg, turn_rate_dps: what was asked (speed in
            m/s along the flight path, climb angle in deg, heading rate in deg/s).
        x0: state (16, STATE_NAMES order); u0: ESC commands (4); thrusts: rotor thrusts (N),
            equal to ``x0[12:16]``.
        residual_norm: 2-norm of the 13 non-position rows of f(x0, u0, p) minus their steady
            values (ψ̇ = Ω in a turn, zero otherwise).
        iterations: iterations reported by the solver (Nelder–Mead: summed over restarts).
        wall_time_s: wall time of the solve, residual evaluation included (s); the solver's
            one-off set-up (:data:`TRIM_SETUPS`) is not in it.
        cpu_time_s: CPU time of this process during the same solve (s): what the solve costs,
            undisturbed by other processes on the machine.
        setup_cpu_s: CPU time of the solver's one-off set-up before the solve (s): building its
            CasADi solver, importing scipy; about zero once done in the process.
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
    climb_angle_deg: float = 0.0
    turn_rate_dps: float = 0.0
    cpu_time_s: float = math.nan
    setup_cpu_s: float = 0.0
    state_names: tuple[str, ...] = field(default=STATE_NAMES)
    input_names: tuple[str, ...] = field(default=INPUT_NAMES)

    _omit = ("state_names", "input_names")
    _keys = {"thrusts": "thrusts_N"}

    def as_dict(self) -> dict[str, Any]:
        """The fields as plain data, the state ``x0`` by state name (``trim --json``)."""
        return super().as_dict() | {
            "x0": dict(zip(self.state_names, (float(v) for v in self.x0), strict=True))}

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
    state: ca.Function  # state(z, p, op) -> (x, u)
    residual: ca.Function  # residual(z, p, op) -> Q (6)
    cost: ZeroCopyCall  # cost(z, p, op, h) -> QᵀHQ
    qnorm: ZeroCopyCall  # qnorm(z, p, op) -> ‖Q‖₂
    point: ZeroCopyCall  # point(z, p, op) -> (x, u, residual norm) in one zero-copy call


def _state_expr(z, p, op, level: bool, propulsion: str = "paper"):
    """(x, u, steady ẋ) of the unknowns Z at the operating point op = (V, γ, Ω) (symbolic).
    ``level``: γ = Ω = 0 as constants, so level flight keeps the expression graph (and the
    results, bit for bit) of the level-only formulation this generalises."""
    phi, theta, delta = z[0], z[1], z[2:6]
    rotor = propulsion_model(propulsion).steady_rotors(delta, named(p, propulsion))
    if rotor is None:  # not explicit: unknowns of the trim (propeller: the rotor speeds)
        rotor = z[6:10]
    V, gamma, Omega = (op[0], 0, 0) if level else (op[0], op[1], op[2])
    R = rotation_matrix(phi, theta, 0)
    omega = Omega * ca.vertcat(-ca.sin(theta), ca.sin(phi) * ca.cos(theta),
                               ca.cos(phi) * ca.cos(theta))
    x = ca.vertcat(
        ca.SX.zeros(3), R.T @ ca.vertcat(V * ca.cos(gamma), 0, V * ca.sin(gamma)), omega, phi,
        theta, 0, rotor,
    )
    steady = ca.vertcat(ca.SX.zeros(_PSI_ROW), Omega, ca.SX.zeros(NX - _PSI_ROW - 1))
    return x, delta, steady


def n_unknowns(propulsion: str = "paper") -> int:
    """Unknowns of a trim: Z = (φ, θ, δ1…δ4) with ``paper`` (T = K δ at rest), with the four
    rotor speeds appended for ``propeller`` (their steady state is not explicit); the residual
    then gains the four rotor rows, so the system stays square."""
    return propulsion_model(propulsion).trim_unknowns


def _kind(p) -> str:
    """The propulsion kind of a parameter vector (its length tells)."""
    return model_of_length(len(p) - NP)


@lru_cache(maxsize=4)
def _functions(level: bool, propulsion: str = "paper") -> _TrimFunctions:
    """The compiled trim Functions; ``level``: for conditions without climb or turn."""
    f = quadrotor_model(propulsion).f
    nz = n_unknowns(propulsion)
    z, p, op = ca.SX.sym("z", nz), ca.SX.sym("p", n_params(propulsion)), ca.SX.sym("op", 3)
    h = ca.SX.sym("h", nz)
    x, u, steady = _state_expr(z, p, op, level, propulsion)
    xdot = f(x, u, p)
    Q = ca.vertcat(xdot[VEL], xdot[RATE])
    if nz > 6:  # the rotor states are unknowns: their steady rows too
        Q = ca.vertcat(Q, xdot[THR])
    names = ["z", "p", "op"]
    return _TrimFunctions(
        state=ca.Function("trim_state", [z, p, op], [x, u], names, ["x", "u"]),
        residual=ca.Function("trim_residual", [z, p, op], [Q], names, ["Q"]),
        cost=ZeroCopyCall(ca.Function(
            "trim_cost", [z, p, op, h], [ca.dot(Q, h * Q)], [*names, "h"], ["cost"])),
        qnorm=ZeroCopyCall(ca.Function("trim_qnorm", [z, p, op], [ca.norm_2(Q)], names, ["q"])),
        point=ZeroCopyCall(ca.Function(
            "trim_point", [z, p, op], [x, u, ca.norm_2((xdot - steady)[3:])], names,
            ["x", "u", "norm"],
        )),
    )


@lru_cache(maxsize=16)
def _ipopt(tol: float, max_iter: int, level: bool, propulsion: str = "paper") -> ca.Function:
    fn = _functions(level, propulsion)
    NP = n_params(propulsion)
    z, pv = ca.SX.sym("z", n_unknowns(propulsion)), ca.SX.sym("pv", NP + 3)
    g = fn.residual(z, pv[:NP], pv[NP:])
    opts: dict[str, Any] = {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": min(tol * 1e-3, 1e-12),
        "ipopt.constr_viol_tol": min(tol * 1e-3, 1e-12),
        "ipopt.max_iter": max_iter,
        "ipopt.nlp_scaling_method": "none",
    }
    return ca.nlpsol("trim_ipopt", "ipopt", {"x": z, "p": pv, "f": 0, "g": g}, opts)


@lru_cache(maxsize=16)
def _newton(tol: float, max_iter: int, level: bool, propulsion: str = "paper") -> ca.Function:
    fn = _functions(level, propulsion)
    NP = n_params(propulsion)
    z, pv = ca.SX.sym("z", n_unknowns(propulsion)), ca.SX.sym("pv", NP + 3)
    g = ca.Function("trim_g", [z, pv], [fn.residual(z, pv[:NP], pv[NP:])])
    opts = {
        "abstol": min(tol * 1e-3, 1e-12),
        "abstolStep": 1e-14,
        "max_iter": max_iter,
        "error_on_fail": False,
    }
    return ca.rootfinder("trim_newton", "newton", g, opts)


# ---------------------------------------------------------------------------------------------
# Solvers: each maps (Z0, p, op, options) -> (Z, iterations, solver message)
# ---------------------------------------------------------------------------------------------


def _level(op: np.ndarray) -> bool:
    """Whether the operating point has no climb and no turn (the level Functions serve it)."""
    return bool(op[1] == 0 and op[2] == 0)


def _solve_ipopt(z0, p, op, o: TrimOptions):
    solver = _ipopt(o.tolerance, o.max_iterations, _level(op), _kind(p))
    sol = solver(x0=z0, p=np.append(p, op), lbg=0, ubg=0)
    st = solver.stats()
    return np.asarray(sol["x"]).ravel(), int(st.get("iter_count", 0)), str(st["return_status"])


@lru_cache(maxsize=16)
def _newton_call(tol: float, max_iter: int, level: bool, propulsion: str = "paper"
                 ) -> ZeroCopyCall:
    return ZeroCopyCall(_newton(tol, max_iter, level, propulsion))


def _solve_newton(z0, p, op, o: TrimOptions):
    rf = _newton_call(o.tolerance, o.max_iterations, _level(op), _kind(p))
    (z,) = rf(z0, np.append(p, op))
    st = rf.stats()
    return z.ravel().copy(), int(st.get("iter_count", 0)), str(st["return_status"])


def _solve_nelder_mead(z0, p, op, o: TrimOptions):
    from scipy.optimize import minimize  # here: scipy.optimize costs ~0.3 s to import

    fn = _functions(_level(op), _kind(p))
    nz = n_unknowns(_kind(p))
    # propeller: the rotor rows (rad/s²) weighted to the scale of the rigid-body rows, and the
    # simplex a thousand times wider along the rotor speeds (rad/s) than along δ
    h = np.concatenate([np.asarray(o.nelder_mead_weights, dtype=float), [1e-6] * (nz - 6)])
    scale = np.concatenate([np.ones(6), [1e3] * (nz - 6)])

    def cost(z):  # zero-copy: a few µs a call, where a DM call costs tens
        return float(fn.cost(z, p, op, h)[0][0, 0])

    def qnorm(z):
        return float(fn.qnorm(z, p, op)[0][0, 0])

    # Aim below the acceptance tolerance so the reported 13-row norm passes with margin.
    target = 0.1 * o.nelder_mead_tolerance
    z, step, nit, runs = np.asarray(z0, dtype=float), o.nelder_mead_step, 0, 0
    status = "iteration cap reached"
    q0 = qnorm(z)
    if q0 <= target:
        return z, 0, "initial guess already within tolerance"
    if not math.isfinite(q0):  # a simplex of non-finite costs cannot move
        return z, 0, "non-finite residual at the initial guess"
    while nit < o.nelder_mead_max_iterations:
        simplex = z + np.vstack([np.zeros(nz), step * np.diag(scale)])
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


#: The trim solvers, by the name the API and the CLI use: each maps (Z0, p, operating vector,
#: options) to (Z, iterations, solver message). A new solver is one entry here and its function.
TRIM_SOLVERS: dict[str, Callable[[np.ndarray, np.ndarray, np.ndarray, TrimOptions],
                                 tuple[np.ndarray, int, str]]] = {
    "ipopt": _solve_ipopt, "nelder-mead": _solve_nelder_mead, "newton": _solve_newton}


def _setup_ipopt(p, op, o: TrimOptions) -> None:
    _ipopt(o.tolerance, o.max_iterations, _level(op), _kind(p))


def _setup_newton(p, op, o: TrimOptions) -> None:
    _newton_call(o.tolerance, o.max_iterations, _level(op), _kind(p))


def _setup_nelder_mead(p, op, o: TrimOptions) -> None:
    import scipy.optimize  # noqa: F401 (the import is the set-up: ~0.4 s of CPU once)


def _no_setup(p, op, o: TrimOptions) -> None:
    """A solver without a set-up entry: everything it does is its solve."""


#: The one-off set-up of a solver of :data:`TRIM_SOLVERS` (its CasADi solver built, scipy
#: imported), run and timed apart before its solve (``TrimPoint.setup_cpu_s``), so that the
#: solve's time is the solve's: Nelder–Mead's first trim in a process spent ~0.44 s of its
#: 0.46 s CPU importing scipy. Optional: a solver without an entry has none.
TRIM_SETUPS: dict[str, Callable[[np.ndarray, np.ndarray, TrimOptions], None]] = {
    "ipopt": _setup_ipopt, "nelder-mead": _setup_nelder_mead, "newton": _setup_newton}
#: The solver names, in registry order (``trim_all`` runs them in this order).
SOLVERS: tuple[str, ...] = tuple(TRIM_SOLVERS)
#: A trim solver's name: a key of :data:`TRIM_SOLVERS`.
Solver = str


# ---------------------------------------------------------------------------------------------
# Public API
# ---------------------------------------------------------------------------------------------


#: Damped fixed-point steps of :func:`_attitude_balance` (the attitude settles in ~10 at 35 m/s).
ATTITUDE_BALANCE_STEPS = 40


def _attitude_balance(a: Airframe, v_world: np.ndarray, fy: float, theta: float, phi: float
                      ) -> tuple[float, float, float]:
    """(θ, φ, F_z) of the point-mass balance F = m g e_z + m a_c − D(attitude) with the airframe's
    own body-drag form evaluated at the attitude the thrust tilts to (world velocity ``v_world``,
    m/s; ``fy`` the centripetal force, N), by damped fixed-point steps from (θ, φ). A form whose
    drag depends on the attitude (``isotropic``: more drag pitched into the flow than nose-on)
    otherwise starts the trim so far below its pitch that it lands on a backward-turning root."""
    weight = a.mass * a.gravity
    fz = weight
    for _ in range(ATTITUDE_BALANCE_STEPS):
        R = np.asarray(rotation_matrix(phi, theta, 0.0), float)
        d = R @ np.array(drag_force(tuple(R.T @ v_world), a.air_density, tuple(a.drag_area),
                                    a.drag_model))
        fx, fz = -d[0], weight - d[2]
        theta = 0.5 * theta + 0.5 * math.atan2(fx, fz)
        phi = 0.5 * phi + 0.5 * (0.0 - math.atan2(fy, math.hypot(fx, fz)))
    return theta, phi, fz


def initial_guess(
    airframe: Airframe, speed_mps: float = 0.0, *, climb_angle_deg: float = 0.0,
    turn_rate_dps: float = 0.0,
) -> np.ndarray:
    """Analytic guess of Z = (φ, θ, δ1…δ4) from a point-mass force balance.

    The thrust must supply F = m g e_z + m a_c + D v̂ (world frame): weight, the centripetal
    acceleration of a turn a_c = V Ω e_y, and a drag D = ½ ρ CdA_x V² along the flight path v̂
    (the nose-on drag area for every direction, small-angle). Its direction gives θ = atan2(F_x,
    F_z) and φ = −atan2(F_y, √(F_x² + F_z²)); its size, |F| = F_z / (cos θ cos φ), scales the hover
    thrusts (which balance the moments). In level forward flight this is θ = atan(D / (m g)).
    """
    a = airframe
    V, gamma, Omega = operating_vector(
        "climb" if turn_rate_dps == 0 else "turn", abs(speed_mps), climb_angle_deg, turn_rate_dps
    )
    drag = 0.5 * a.air_density * a.drag_area[0] * speed_mps * abs(speed_mps)
    weight = a.mass * a.gravity
    fx, fy = drag * math.cos(gamma), a.mass * V * Omega
    fz = weight + drag * math.sin(gamma)
    theta = math.atan2(fx, fz)
    phi = 0.0 - math.atan2(fy, math.hypot(fx, fz))  # 0.0 - : no negative zero in level flight
    if a.drag_model != DEFAULT_DRAG:  # the form's own drag at the attitude it pitches to
        theta, phi, fz = _attitude_balance(a, V * np.array([math.cos(gamma), 0.0,
                                                             math.sin(gamma)]), fy, theta, phi)
    delta = a.hover_thrusts() / (math.cos(theta) * math.cos(phi)) * (fz / weight)
    rotors, commands = hover_rotors(a, delta)  # the static rotor states and commands
    if n_unknowns(a.propulsion) > 6:  # the rotor states are unknowns too
        return np.concatenate([[phi, theta], commands, rotors])
    return np.concatenate([[phi, theta], commands])


def trim(
    airframe: Airframe,
    condition: Condition = "hover",
    speed_mps: float = 0.0,
    solver: Solver = "ipopt",
    options: TrimOptions | None = None,
    *,
    climb_angle_deg: float = 0.0,
    turn_rate_dps: float = 0.0,
) -> TrimPoint:
    """Trim ``airframe`` in a condition of :data:`CONDITION_REGISTRY` at ``speed_mps`` (m/s along
    the flight path), ``climb_angle_deg`` (climb) and ``turn_rate_dps`` (turn).

    Never raises for a case the solver cannot solve: the TrimPoint then has ``success=False``
    and a message. An unknown ``condition`` or ``solver``, or a parameter the condition does not
    take (hover with a speed), raise ValueError.
    """
    if solver not in TRIM_SOLVERS:
        raise ValueError(f"unknown trim solver '{solver}'; choose one of "
                         f"{', '.join(TRIM_SOLVERS)}")
    op = operating_vector(condition, speed_mps, climb_angle_deg, turn_rate_dps)
    o = options or TrimOptions()
    fn = _functions(_level(op), airframe.propulsion)
    p = airframe.p
    guess = initial_guess(airframe, speed_mps, climb_angle_deg=climb_angle_deg,
                          turn_rate_dps=turn_rate_dps)
    z0 = np.asarray(o.initial_guess if o.initial_guess is not None else guess)
    if z0.size < guess.size:  # propeller, six values given: the guess's rotor speeds
        z0 = np.concatenate([z0, guess[z0.size:]])

    setup = time.process_time()
    TRIM_SETUPS.get(solver, _no_setup)(p, op, o)
    setup_cpu = time.process_time() - setup
    start, cpu = time.perf_counter(), time.process_time()
    try:
        z, iterations, status = TRIM_SOLVERS[solver](z0, p, op, o)
        error = None
    except Exception as exc:  # a solver crash is a failed trim, never an exception
        z, iterations, status, error = z0, 0, "", f"{type(exc).__name__}: {exc}"
    z = _wrap_angles(z)
    x, u, norm = fn.point(z, p, op)
    x0, u0, residual = x.ravel().copy(), u.ravel().copy(), float(norm[0, 0])
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    rotor_speeds = None if propulsion_model(airframe.propulsion).thrust_is_state else x0[THR]
    success, message = _verdict(solver, o, z, u0, residual, status, error, rotor_speeds)
    if success:
        message += beyond_data_note(airframe, x0, u0)
    return TrimPoint(
        solver=solver,
        condition=condition,
        speed_mps=float(speed_mps),
        x0=x0,
        u0=u0,
        thrusts=rotor_thrusts(airframe, x0, u0),
        residual_norm=residual,
        iterations=int(iterations),
        wall_time_s=wall,
        success=success,
        message=message,
        airframe=airframe.name,
        climb_angle_deg=float(climb_angle_deg),
        turn_rate_dps=float(turn_rate_dps),
        cpu_time_s=cpu,
        setup_cpu_s=setup_cpu,
        state_names=state_names(airframe.propulsion),
    )


def beyond_data_note(airframe: Airframe, x0: np.ndarray, u0: np.ndarray) -> str:
    """A note for the trim's message when a rotor's advance ratio is beyond the propeller
    data's largest (``Airframe.max_advance_ratio``): the trim then rests on CT(J), CP(J)
    extrapolated. Empty with ``paper``, without a range, or inside it. The trim solves the
    model as it is (docs/concepts/propulsion.md, "Beyond the data"): it says so, it does not
    refuse."""
    if airframe.max_advance_ratio is None:  # paper: none
        return ""

    J = float(np.max(np.asarray(propeller_outputs()(x0, u0, airframe.p)[2])))
    if not J > airframe.max_advance_ratio:
        return ""
    return (f"; advance ratio {J:.3g} beyond the propeller data's {airframe.max_advance_ratio:.3g}"
            " (CT, CP extrapolated)")


def _wrap_angles(z: np.ndarray) -> np.ndarray:
    """Z with φ and θ beyond ±π brought back by whole turns (the same attitude: a solver may end
    a turn away from its start); angles within ±π are left untouched, bit for bit."""
    z = np.array(z, dtype=float)
    for i in (0, 1):
        if np.isfinite(z[i]) and abs(z[i]) > math.pi:
            z[i] -= 2 * math.pi * round(z[i] / (2 * math.pi))
    return z


def _verdict(solver: str, o: TrimOptions, z, u0, residual: float, status: str,
             error: str | None, rotor_speeds: np.ndarray | None = None) -> tuple[bool, str]:
    """Whether a solve is a usable trim, and the message saying why (not); ``rotor_speeds``
    (rad/s) of a ``propeller`` frame, none of which may be negative."""
    tol = o.nelder_mead_tolerance if solver == "nelder-mead" else o.tolerance
    finite = bool(np.all(np.isfinite(z))) and math.isfinite(residual)
    if error is not None:
        return False, f"{solver} failed: {error}"
    if not finite:
        return False, f"{solver} returned non-finite values ({status})"
    if residual > tol:
        return False, f"residual {residual:.3g} above tolerance {tol:.3g} ({status})"
    tilt = math.degrees(max(abs(z[0]), abs(z[1])))
    if tilt > o.max_tilt_deg:
        return False, f"tilt {tilt:.1f} deg beyond max_tilt_deg {o.max_tilt_deg:g}"
    if rotor_speeds is not None and np.any(rotor_speeds < 0):
        return False, (f"rotor speed {float(np.min(rotor_speeds)):.4g} rad/s below 0: a root "
                       f"with the propellers turning backwards is no physical trim ({status})")
    message = f"converged ({status})"
    if np.any(u0 < 0) or np.any(u0 > 1):
        message += f"; commands outside [0, 1] (max {u0.max():.3f}): they saturate in flight"
    return True, message


def residual_norm(
    airframe: Airframe, z: np.ndarray, condition: Condition = "hover", speed_mps: float = 0.0,
    *, climb_angle_deg: float = 0.0, turn_rate_dps: float = 0.0,
) -> float:
    """The ``residual_norm`` a TrimPoint would report at unknowns ``z`` (an unsolved start, for
    instance): the 13 non-position rows of f minus their steady values, 2-norm (SI)."""
    op = operating_vector(condition, speed_mps, climb_angle_deg, turn_rate_dps)
    fn = _functions(_level(op), airframe.propulsion)
    return float(fn.point(_wrap_angles(z), airframe.p, op)[2][0, 0])


def trim_residual(p: np.ndarray, op: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """Q(Z): the rows a trim zeroes (the velocity and body-rate derivatives, and with the
    propeller model the rotor rows) as a function of the unknowns Z, at the airframe's parameter
    vector ``p`` and operating vector ``op`` (:func:`operating_vector`): what a solver of
    :data:`TRIM_SOLVERS` written outside this module solves."""
    fn = _functions(_level(op), _kind(p))
    return lambda z: np.asarray(fn.residual(z, p, op)).ravel()


def trim_all(
    airframe: Airframe,
    condition: Condition = "hover",
    speed_mps: float = 0.0,
    solvers: tuple[str, ...] | None = None,
    options: TrimOptions | None = None,
    **operating_point: float,
) -> list[TrimPoint]:
    """Trim with each of ``solvers`` (default: every registered one, in registry order; same
    airframe, condition and options), for comparison; ``operating_point``: ``climb_angle_deg`` or
    ``turn_rate_dps`` as in :func:`trim`."""
    return [trim(airframe, condition, speed_mps, s, options, **operating_point)
            for s in solvers or tuple(TRIM_SOLVERS)]


def rotor_thrusts(airframe: Airframe, x, u) -> np.ndarray:
    """Each rotor's thrust (N) in state x under commands u: the rotor states with ``paper``, the
    propeller model's thrust at the rotor's own inflow with ``propeller``."""
    if propulsion_model(airframe.propulsion).thrust_is_state:
        return np.asarray(x, float)[THR].copy()
    return np.asarray(propeller_outputs()(x, u, airframe.p)[0], float).ravel()
