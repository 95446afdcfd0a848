"""The limit lap on the real 16-state model, in the default run: one solve per session, checked for
what every correct minimum-time lap must show, by oracles that share no code with the solver.

The problem: SY250 from hover at 2 m, a 30 m straight then the paper track's 2.5 m curve leg
(1 m acceptance balls), 20 intervals per leg: one solve is seconds, so CI solves the real model on
every run (the paper track's laps stay in ``test_limitlap_slow.py``). What is checked:

- optimality that a test can see: on the straight the optimum saturates the rotors (the thrust
  reaches K, the actuator's limit, within 1 %) and the ESC commands are bang-bang (Pontryagin: a
  minimum-time problem whose dynamics are affine in the command has the command on its bounds
  except on singular arcs);
- the point-mass reference (the point-mass relaxation's best local optimum found: its global
  optimum would bound the lap from below) is below the lap and equals the relaxation solved here
  by an independent implementation (own rotation, drag, RK4, transcription and initial guess,
  CasADi's Opti), not the package's;
- the sensitivities dT/dθ and dT/dp equal central differences of warm re-solves;
- the commands flown open loop by an independent integrator (scipy's DOP853 on the model's
  explicit dynamics) follow the lap and pass every target, and the package's own re-simulation
  check passes.
"""

from __future__ import annotations

import math
from dataclasses import replace

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.track import TrackConfig
from casadrone.limit.lap import LapSeeds, LimitLapOptions, design_limit_lap
from casadrone.model import PARAM_NAMES, quadrotor_model

NAME = "SY250"
TRACK = TrackConfig(name="straight-and-curve", start_position_m=(0.0, 0.0, 2.0),
                    waypoints_m=[(30.0, 0.0, 2.0), (30.0, 2.5, 2.0)], straight=[True, False],
                    acceptance_radius_m=1.0)
OPTIONS = LimitLapOptions(intervals=20)
SUBSTEPS = OPTIONS.substeps  # the relaxation below is posed on the same grid: same problem


@pytest.fixture(scope="module")
def cfg():
    return load_airframe(NAME)


@pytest.fixture(scope="module")
def frame(cfg):
    return build_airframe(cfg)


@pytest.fixture(scope="module")
def lap(cfg):
    """The one cold solve of the module (every start, point-mass reference, re-simulation and
    sensitivities, as a user gets them)."""
    return design_limit_lap(cfg, TRACK, OPTIONS)


def straight_intervals(lap) -> np.ndarray:
    """Mask of the intervals on legs that end at a waypoint marked straight."""
    legs = [False] * TRACK.first_timed_segment + list(TRACK.straight)
    return np.asarray(legs)[lap.waypoint_index]


def test_lap_is_optimal_and_slower_than_the_point_mass_reference(lap):
    assert lap.completed, lap.reason
    assert lap.point_mass_reference_s < lap.lap_time_s


# --------------------------------------------------------------------------------------------
# Optimality on the straight: full thrust, bang-bang
# --------------------------------------------------------------------------------------------


def test_straight_saturates_every_rotor_at_its_maximum_thrust(lap, cfg):
    """Each rotor's thrust (the lagged thrust states) peaks at K on the straight within 1 % (the
    issue's criterion; observed: 9.030-9.052 N of K = 9.0519 N, within 0.25 %, on two local
    optima) and never exceeds it. K is read from the airframe file, not from the package's
    parameter vector."""
    K = float(cfg.thrust.gain_n)
    thrust = lap.x_euler[:, 12:16]
    on_straight = np.r_[straight_intervals(lap), False]  # nodes that start a straight interval
    peak = thrust[on_straight].max(axis=0)
    np.testing.assert_allclose(peak, K, rtol=0.01)
    assert thrust.max() <= K * (1 + 1e-6)


def test_straight_commands_are_bang_bang(lap):
    """On the straight the ESC commands sit on their bounds: off and full on the two sides to
    pitch over from hover, then full throttle, with brief trims of single rotors to hold the
    flight path. Observed on two local optima (3 per mille apart, from different starts): 65
    and 71 of the straight's 80 commands within 0.02 of 0 or 1 (the thrust at its bound K
    leaves a command free between 0.99 and 1), 63 and 70 at full throttle (≥ 0.98)."""
    u = lap.u[straight_intervals(lap)]
    assert np.mean((u <= 0.02) | (u >= 0.98)) >= 0.75
    assert np.mean(u >= 0.98) >= 0.7


# --------------------------------------------------------------------------------------------
# The point-mass reference: an independent implementation of the relaxation
# --------------------------------------------------------------------------------------------


def _euler_zyx(phi, theta, psi):
    """Body → world rotation of Z-Y-X Euler angles, the product of the elementary rotations."""
    def about(axis: int, a):
        c, s = ca.cos(a), ca.sin(a)
        i, j = [k for k in range(3) if k != axis]
        R = ca.SX.eye(3)
        R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
        return R if axis != 1 else R.T  # about y: z → x is the positive sense

    return about(2, psi) @ about(1, theta) @ about(0, phi)


def relaxation_time(mass, g, rho, drag_area, thrust_max, start, points, radius, tilt, intervals,
                    substeps, ground, time_limit, yaw_guess=0.0) -> float:
    """Minimum time of the point-mass relaxation: a body whose attitude (|φ|, |θ| ≤ tilt, ψ free)
    and total thrust (0 … thrust_max) change instantly, with the full model's body-axis quadratic
    drag, from rest at ``start`` through balls of ``radius`` around ``points``. Posed on the limit
    lap's grid (``intervals`` uniform intervals per leg, commands held, ``substeps`` RK4 steps)
    so that it is the same finite-dimensional problem; solved with CasADi's Opti from a
    constant-speed guess along the route."""
    x, u, h = ca.SX.sym("x", 6), ca.SX.sym("u", 4), ca.SX.sym("h")
    R = _euler_zyx(u[0], u[1], u[2])
    v_body = R.T @ x[3:6]
    drag = -0.5 * rho * ca.DM(drag_area) * ca.fabs(v_body) * v_body
    f = ca.Function("f", [x, u], [ca.vertcat(x[3:6], R @ (ca.vertcat(0, 0, u[3]) + drag) / mass
                                             - ca.DM([0, 0, g]))])
    xk = x
    for _ in range(substeps):
        k1 = f(xk, u)
        k2 = f(xk + h / 2 * k1, u)
        k3 = f(xk + h / 2 * k2, u)
        k4 = f(xk + h * k3, u)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    step = ca.Function("step", [x, u, h], [xk])

    route = np.vstack([start, points])
    L, N = len(points), intervals
    opti = ca.Opti()
    T, X, U = opti.variable(L), opti.variable(6, L * N + 1), opti.variable(4, L * N)
    opti.minimize(ca.sum1(T))
    opti.subject_to(X[:, 0] == ca.DM(np.r_[start, 0.0, 0.0, 0.0]))
    for k in range(L):
        for i in range(k * N, (k + 1) * N):
            opti.subject_to(X[:, i + 1] == step(X[:, i], U[:, i], T[k] / (N * substeps)))
        miss = X[0:3, (k + 1) * N] - route[k + 1]
        opti.subject_to(ca.dot(miss, miss) <= radius ** 2)
    opti.subject_to(opti.bounded(1e-3, T, time_limit))
    opti.subject_to(opti.bounded(-tilt, ca.vec(U[0:2, :]), tilt))
    opti.subject_to(opti.bounded(0.0, U[3, :], thrust_max))
    opti.subject_to(X[2, :] >= ground)
    legs = np.linalg.norm(np.diff(route, axis=0), axis=1)
    speed = 10.0
    opti.set_initial(T, legs / speed)
    guess = np.zeros((6, L * N + 1))
    guess[0:3, 0] = start
    for k in range(L):
        s = np.linspace(0.0, 1.0, N + 1)[1:]
        cols = slice(k * N + 1, (k + 1) * N + 1)
        guess[0:3, cols] = route[k][:, None] + s * (route[k + 1] - route[k])[:, None]
        guess[3:6, cols] = ((route[k + 1] - route[k]) / legs[k] * speed)[:, None]
    opti.set_initial(X, guess)
    opti.set_initial(U, np.tile([[0.0], [0.0], [yaw_guess], [mass * g]], L * N))
    opti.solver("ipopt", {"expand": True, "print_time": False},
                {"print_level": 0, "sb": "yes", "tol": 1e-9, "max_iter": 3000})
    return float(opti.solve().value(ca.sum1(T)))


def test_point_mass_reference_equals_an_independent_relaxation(lap, cfg):
    """The package's point-mass reference equals the same relaxation solved here from the
    airframe file's mass, thrust, drag and air density. Observed: 0.9353003 s (best of the
    package's three starts; 0.9353570 from its single start before) against 0.9353228 s here:
    2.4e-5 (3.7e-5) apart, IPOPT's local optima of the relaxation differing with the guess."""
    raw = cfg.model_dump()
    mass, K = float(raw["mass_kg"]), float(raw["thrust"]["gain_n"])
    independent = relaxation_time(
        mass=mass, g=raw["gravity_mps2"], rho=raw["air_density_kgm3"],
        drag_area=np.asarray(raw["drag_area_m2"], float),
        thrust_max=4 * K, start=np.asarray(TRACK.start_position_m), points=TRACK.waypoints_m,
        radius=TRACK.acceptance_radius_m, tilt=math.radians(TRACK.max_tilt_deg),
        intervals=OPTIONS.intervals, substeps=SUBSTEPS, ground=-0.1,
        time_limit=TRACK.time_limit_s)
    assert lap.point_mass_reference_s == pytest.approx(independent, rel=RELAXATION_RTOL)


RELAXATION_RTOL = 4e-4  # ~10x the observed 2.4e-5 to 3.7e-5


# --------------------------------------------------------------------------------------------
# Sensitivities: finite differences of warm re-solves
# --------------------------------------------------------------------------------------------


#: IPOPT's tolerance of the finite differences' re-solves (the lap's own: LimitLapOptions.tol).
RESOLVE_TOL = 1e-10


def _resolved(lap, name_overrides: list[str]):
    """The lap of SY250 with ``overrides``, warm-started from ``lap`` (the same local optimum),
    solved to RESOLVE_TOL: a central difference over a step of 1 % divides the laps' own error
    by the step, so the re-solves must be far more accurate than the slope compared (at the
    default tol, 1e-6, the difference of dT/dK moved by 8e-4 of itself with the last bits of
    the derivative blocks)."""
    opts = replace(OPTIONS, starts=(), point_mass_reference=False, resimulate=False,
                   sensitivities=False, tol=RESOLVE_TOL)
    out = design_limit_lap(load_airframe(NAME, name_overrides), TRACK, opts,
                           LapSeeds(warm_starts=(lap,)))
    assert out.completed, out.reason
    return out.lap_time_s


@pytest.mark.parametrize("key, step", [("iyy_kgm2", 2e-5)])
def test_theta_sensitivity_equals_finite_differences_of_warm_resolves(lap, cfg, key, step):
    """dT/dθ (envelope theorem, chained through the config → airframe build) against central
    differences of two warm re-solves. Observed for Iyy (the pitch axis: the lap's largest θ
    sensitivity, 11.5-12.2 s per kg·m²): 0.12 % and 0.17 % apart on two local optima. (The
    arm geometry is not used: SY250 is symmetric and the lap is at a local minimum over λ and
    α, so central differences over
    2 mm / 2° are dominated by curvature: λb's were -4.8e-4, -3.2e-4, -1.5e-4 s/mm at steps 2,
    0.5, 0.1, tending to the envelope's -1.44e-4.)"""
    v = float(getattr(cfg, key))
    lo, hi = (_resolved(lap, [f"{key}={v + s}"]) for s in (-step, step))
    fd = (hi - lo) / (2 * step)
    assert lap.sensitivities[key] == pytest.approx(fd, rel=THETA_RTOL), (key, fd)


THETA_RTOL = 0.015  # ~10x the observed 0.12-0.17 %


def test_thrust_gain_sensitivity_equals_finite_differences_of_warm_resolves(lap, cfg):
    """dT/dK from the NLP's parameter multipliers against central differences of warm re-solves
    with the airframe file's ``thrust.gain_n`` changed. The thrust saturates on the straight, so
    the bounds T_i ≤ K are active and count. Observed: -0.0527122 against -0.0527117 s/N, 1e-5
    apart (without the bounds' share, -0.0509: 3.4 % short); on the reworked starts' optimum
    -0.0524629 against -0.0524634, 9e-6 apart."""
    K, step = float(cfg.thrust.gain_n), 0.01
    lo, hi = (_resolved(lap, [f"thrust.gain_n={K + s}"]) for s in (-step, step))
    fd = (hi - lo) / (2 * step)
    assert lap.param_sensitivity[PARAM_NAMES.index("K")] == pytest.approx(fd, rel=K_RTOL)
    assert fd < 0  # more thrust, a faster lap


K_RTOL = 1e-4  # ~10x the observed 1e-5


# --------------------------------------------------------------------------------------------
# Re-simulation
# --------------------------------------------------------------------------------------------


def test_commands_flown_open_loop_follow_the_lap_and_pass_every_target(lap, frame):
    """The optimal commands, held on each interval, integrated by scipy's DOP853 (rtol 1e-10) on
    the model's explicit dynamics from the start state: every node within RESIM_M of the lap's,
    every leg's end inside its ball (+ RESIM_M), and the package's own CVODES check passed."""
    f = quadrotor_model().f
    p = frame.p
    x = lap.x_euler[0].copy()
    nodes = [x]
    for i, u in enumerate(lap.u):
        sol = solve_ivp(lambda _t, s, u=u: np.asarray(f(s, u, p)).ravel(),
                        (lap.t[i], lap.t[i + 1]), x, method="DOP853", rtol=1e-10, atol=1e-10)
        x = sol.y[:, -1]
        nodes.append(x)
    nodes = np.array(nodes)
    drift = np.linalg.norm(nodes[:, 0:3] - lap.x_euler[:, 0:3], axis=1)
    assert drift.max() <= RESIM_M, drift.max()
    N = lap.layout.intervals
    for k, wp in enumerate(TRACK.waypoints_m):
        miss = np.linalg.norm(nodes[(k + 1) * N, 0:3] - np.asarray(wp))
        assert miss <= TRACK.acceptance_radius_m + RESIM_M, (k, miss)
    assert lap.resimulation_miss_m <= RESIM_M


RESIM_M = 0.02  # ~10x the observed: nodes within 2.3 mm, CVODES miss 1.1-1.8 mm
