"""Closed-loop lap: LQR-I + line-of-sight guidance at Ts, plant integrated between samples.

Integrators:
- ``rk4``: fixed-step RK4 with sub-steps; the controller, guidance and plant of one sample are one
  symbolic step, generated as C with a C loop around it that flies the whole lap in one call and
  checks after every sample how it ends (:mod:`casadrone.lapdriver`), compiled once and cached on
  disk (:mod:`casadrone.codegen`). The airframe, trim point, gain and track are inputs, so one
  compiled function serves every candidate. Without a C compiler the step is chained with
  ``mapaccum`` into chunks of samples evaluated by CasADi's virtual machine and checked between
  chunks in numpy (the chunked path, compiled, flies the whole-lap loop's lap to the bit; the
  virtual machine agrees with the compiled code to 1e-10: both tested).
- ``cvodes``: SUNDIALS CVODES on the explicit f, the same compiled-once controller per sample.
- ``idas``: SUNDIALS IDAS on the implicit residual F(ẋ, x, u, p) = 0 (ẋ as algebraic unknowns).

A lap that diverges (non-finite state, ground strike, attitude beyond the track's limit) or times
out is returned as a failed :class:`Trajectory` with a reason; it never raises.
"""

from __future__ import annotations

import math
import subprocess
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cached_property, lru_cache, partial
from typing import Any

import casadi as ca
import numpy as np

from casadrone.airframe import Airframe
from casadrone.codegen import ZeroCopyCall, compile_function
from casadrone.config.track import TrackConfig
from casadrone.control import LQRIDesign
from casadrone.guidance import GuidanceLayout, guidance, track_vector, wrap
from casadrone.lapdriver import LapDriver
from casadrone.model import NU, NX, n_params, quadrotor_model, rotation_matrix
from casadrone.results import Status

NC = 8  # controller state: ∫e (x, y, z, ψ) (4), active segment (1), shaped velocity ref (3)
NREF = 10  # logged per sample: p_ref (3), v_ref (3), ψ_ref (1), world acceleration (3)


@dataclass(frozen=True)
class SimOptions:
    """Numerical settings of the closed loop (the controller period comes from the design)."""

    substeps: int = 1  # RK4 steps per controller sample (rk4 vs cvodes: indices agree to 1e-6)
    chunk: int = 250  # samples per chunk of the SUNDIALS loops and the no-compiler rk4 path
    rtol: float = 1e-8  # SUNDIALS tolerances
    atol: float = 1e-8
    ground_margin_m: float = 0.1


def row_norm(a: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of an (N, 3) array, √((a₀² + a₁²) + a₂²): the value (to the
    bit) of ``np.linalg.norm(a, axis=1)``, in a fifth of its time."""
    return np.sqrt(a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1] + a[:, 2] * a[:, 2])


@dataclass(frozen=True)
class Trajectory:
    """A closed-loop flight, sampled at the controller period.

    Row k holds the state at t[k] and the command applied on [t[k], t[k+1]).
    """

    status: Status
    reason: str
    integrator: str
    t: np.ndarray  # (N,) s
    x: np.ndarray  # (N, 16) state
    u: np.ndarray  # (N, 4) ESC commands δ ∈ [0, 1]
    p_ref: np.ndarray  # (N, 3) position reference, m
    v_ref: np.ndarray  # (N, 3) shaped velocity reference, m/s (world)
    psi_ref: np.ndarray  # (N,) yaw reference, rad
    acceleration: np.ndarray  # (N, 3) world kinematic acceleration, m/s²
    segment: np.ndarray  # (N,) active route segment after switching at t[k]
    u0: np.ndarray  # (4,) trim commands
    battery_voltage: float  # V
    waypoints: np.ndarray  # (W, 3) timed waypoints, m
    straight: tuple[bool, ...]  # leg ending at each waypoint is straight
    split_times: np.ndarray  # (W,) time each waypoint was reached (NaN if not), s
    first_timed_segment: int = 0  # route segment ending at the first waypoint (after a climb)
    wall_time_s: float = 0.0

    @property
    def completed(self) -> bool:
        return self.status == "completed"

    @property
    def voltage(self) -> np.ndarray:
        """ESC voltage commands V_i = δ_i V_batt (N, 4), V."""
        return self.u * self.battery_voltage

    @property
    def thrust(self) -> np.ndarray:
        """Rotor thrusts (N, 4), N."""
        return self.x[:, 12:16]

    @cached_property
    def speed(self) -> np.ndarray:
        """Airspeed |v| (N,), m/s (computed once)."""
        return row_norm(self.x[:, 3:6])

    @property
    def lap_time(self) -> float:
        """Time at the last waypoint (s), NaN if not reached."""
        return float(self.split_times[-1])

    @cached_property
    def waypoint_index(self) -> np.ndarray:
        """Index (0-based) of the waypoint being flown to at each sample; W once done."""
        first = self.first_timed_segment
        return np.clip(self.segment - first, 0, len(self.waypoints)).astype(int)


# --------------------------------------------------------------------------------------------
# Symbolic closed loop
# --------------------------------------------------------------------------------------------


def _controller_expr(x, c, p, x0, u0, K, g, Ts: float, layout: GuidanceLayout):
    """Guidance + reference shaping + LQR-I + saturation + anti-windup for one sample."""
    xi, seg, vf = c[0:4], c[4], c[5:8]
    p_ref, v_ref, psi_ref, seg_next = guidance(x[0:3], seg, g, layout)
    a_max, max_pos, max_yaw = g[layout.size - 1], g[layout.size - 2], g[layout.size - 3]

    dv = v_ref - vf
    step = ca.fmin(1, a_max * Ts / ca.fmax(ca.norm_2(dv), 1e-9))
    vf_next = vf + step * dv

    phi, theta, psi = x[9], x[10], x[11]
    cps, sps = ca.cos(psi), ca.sin(psi)
    world_to_heading = ca.vertcat(
        ca.horzcat(cps, sps, 0), ca.horzcat(-sps, cps, 0), ca.horzcat(0, 0, 1)
    )
    e_pos = ca.fmin(ca.fmax(world_to_heading @ (x[0:3] - p_ref), -max_pos), max_pos)
    R = rotation_matrix(phi, theta, psi)
    e_vel = x[3:6] - R.T @ vf_next
    e_psi = ca.fmin(ca.fmax(wrap(psi - psi_ref), -max_yaw), max_yaw)
    dx = ca.vertcat(e_pos, e_vel, x[6:9], phi - x0[9], theta - x0[10], e_psi, x[12:16] - x0[12:16])
    u_raw = u0 - K @ ca.vertcat(dx, xi)
    u = ca.fmin(ca.fmax(u_raw, 0), 1)
    saturated = ca.sum1(ca.fabs(u_raw - u)) > 0
    xi_next = ca.if_else(saturated, xi, xi + Ts * ca.vertcat(e_pos, e_psi))
    return u, ca.vertcat(xi_next, seg_next, vf_next), ca.vertcat(p_ref, vf_next, psi_ref)


def _world_acceleration(x, u, p, propulsion: str = "paper"):
    """World-frame kinematic acceleration R (v̇ + ω × v) (m/s²)."""
    xdot = quadrotor_model(propulsion).f(x, u, p)
    R = rotation_matrix(x[9], x[10], x[11])
    return R @ (xdot[3:6] + ca.cross(x[6:9], x[3:6]))


def _symbols(layout: GuidanceLayout, propulsion: str = "paper"):
    return dict(
        x=ca.SX.sym("x", NX),
        c=ca.SX.sym("c", NC),
        p=ca.SX.sym("p", n_params(propulsion)),
        x0=ca.SX.sym("x0", NX),
        u0=ca.SX.sym("u0", NU),
        K=ca.SX.sym("K", NU, NX + 4),
        g=ca.SX.sym("g", layout.size),
    )


@lru_cache(maxsize=8)
def controller_function(Ts: float, n_route: int, propulsion: str = "paper") -> ca.Function:
    """``controller(x, c, p, x0, u0, K, g) -> (u, c_next, ref)`` for the SUNDIALS loops."""
    layout = GuidanceLayout(n_route)
    s = _symbols(layout, propulsion)
    u, c_next, ref = _controller_expr(
        s["x"], s["c"], s["p"], s["x0"], s["u0"], s["K"], s["g"], Ts, layout
    )
    acc = _world_acceleration(s["x"], u, s["p"], propulsion)
    names = ["x", "c", "p", "x0", "u0", "K", "g"]
    return ca.Function("controller", [s[n] for n in names], [u, c_next, ca.vertcat(ref, acc)],
                       names, ["u", "c_next", "ref"])


@lru_cache(maxsize=8)
def step_function(Ts: float, substeps: int, n_route: int, propulsion: str = "paper"
                  ) -> ca.Function:
    """One sample of the closed loop with an RK4 plant: ``(x, c, …) -> (x_next, c_next, u, …)``.

    Common subexpressions are merged (``cse``): the logged acceleration reuses the first RK4
    stage, for instance. Merging reuses values, it does not reorder arithmetic."""
    layout = GuidanceLayout(n_route)
    s = _symbols(layout, propulsion)
    x, p = s["x"], s["p"]
    u, c_next, ref = _controller_expr(x, s["c"], p, s["x0"], s["u0"], s["K"], s["g"], Ts, layout)
    f = quadrotor_model(propulsion).f
    h = Ts / substeps
    xk = x
    for _ in range(substeps):
        k1 = f(xk, u, p)
        k2 = f(xk + h / 2 * k1, u, p)
        k3 = f(xk + h / 2 * k2, u, p)
        k4 = f(xk + h * k3, u, p)
        xk = xk + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    acc = _world_acceleration(x, u, p, propulsion)
    names = ["x", "c", "p", "x0", "u0", "K", "g"]
    return ca.Function("lap_step", [s[n] for n in names], [xk, c_next, u, ca.vertcat(ref, acc)],
                       names, ["x_next", "c_next", "u", "ref"], {"cse": True})


@lru_cache(maxsize=8)
def lap_kernel(Ts: float, substeps: int, n_route: int, chunk: int, propulsion: str = "paper"
               ) -> ZeroCopyCall:
    """The chunk of :func:`chunk_function` behind a zero-copy caller (outputs: one row per
    sample)."""
    return ZeroCopyCall(chunk_function(Ts, substeps, n_route, chunk, propulsion))


@lru_cache(maxsize=8)
def chunk_function(Ts: float, substeps: int, n_route: int, chunk: int,
                   propulsion: str = "paper") -> ca.Function:
    """``chunk`` samples of the RK4 closed loop, compiled once (see :func:`compile_function`)."""
    step = step_function(Ts, substeps, n_route, propulsion)
    mapped = step.mapaccum(f"lap_rk4_{chunk}_map", chunk, 2)
    # the parameters enter once (mapaccum alone would take one copy per sample)
    ins = [ca.MX.sym(step.name_in(i), step.sparsity_in(i)) for i in range(step.n_in())]
    acc = ca.Function(f"lap_rk4_{chunk}", ins, mapped.call(ins),
                      step.name_in(), step.name_out())
    try:
        return compile_function(acc)
    except (OSError, subprocess.CalledProcessError):  # no C compiler: CasADi's virtual machine
        return acc


@lru_cache(maxsize=8)
def lap_driver(Ts: float, substeps: int, n_route: int, propulsion: str = "paper"
               ) -> LapDriver | None:
    """The whole-lap C loop of :func:`step_function` (None without a working C compiler: the
    chunked path on CasADi's virtual machine then flies the lap)."""
    try:
        return LapDriver(step_function(Ts, substeps, n_route, propulsion))
    except (OSError, subprocess.CalledProcessError):
        return None


def _cvodes_plant(model: Any, x: ca.SX, u: ca.SX, p: ca.SX) -> dict[str, ca.SX]:
    """CVODES's problem: the explicit ODE ẋ = f(x, u, p)."""
    return {"x": x, "ode": model.f(x, u, p)}


def _idas_plant(model: Any, x: ca.SX, u: ca.SX, p: ca.SX) -> dict[str, ca.SX]:
    """IDAS's problem: the implicit residual 0 = F(z, x, u, p) with ẋ = z algebraic."""
    z = ca.SX.sym("z", NX)
    return {"x": x, "z": z, "ode": z, "alg": model.F(z, x, u, p)}


#: The SUNDIALS plants: the DAE each integrator is given over one controller period.
SUNDIALS_PLANTS = {"cvodes": _cvodes_plant, "idas": _idas_plant}


@lru_cache(maxsize=8)
def sundials_integrator(kind: str, Ts: float, rtol: float, atol: float,
                        propulsion: str = "paper") -> ca.Function:
    """CVODES on ẋ = f(x, u, p) or IDAS on 0 = F(z, x, u, p), ẋ = z, over one period Ts."""
    x = ca.SX.sym("x", NX)
    up = ca.SX.sym("up", NU + n_params(propulsion))
    dae = {**SUNDIALS_PLANTS[kind](quadrotor_model(propulsion), x, up[:NU], up[NU:]), "p": up}
    return ca.integrator(f"plant_{kind}", kind, dae, 0.0, Ts, {"abstol": atol, "reltol": rtol})


# --------------------------------------------------------------------------------------------
# Simulation
# --------------------------------------------------------------------------------------------


def initial_state(airframe: Airframe, design: LQRIDesign, track: TrackConfig):
    """On the ground at the start, at rest, rotors at trim thrust; controller state zero."""
    x = np.zeros(NX)
    x[0:3] = track.start_position_m
    x[11] = np.radians(track.start_yaw_deg)
    x[12:16] = design.x0[12:16]
    return x, np.zeros(NC)


_FAILURES = ("non-finite", "attitude", "ground")


def _failure_reason(why: str, xk: np.ndarray, tk: float, track: TrackConfig) -> str:
    """The reason text of a lap that failed at the sample with state ``xk`` at time ``tk``."""
    if why == "attitude":
        return (f"attitude beyond {track.max_tilt_deg:g} deg (roll {np.degrees(xk[9]):.0f}, "
                f"pitch {np.degrees(xk[10]):.0f} deg) at t = {tk:.2f} s")
    text = "non-finite state (diverged)" if why == "non-finite" else "ground strike"
    return f"{text} at t = {tk:.2f} s"


def _check(x: np.ndarray, t: np.ndarray, track: TrackConfig, margin: float,
           airborne: bool) -> tuple[int, str, bool]:
    """First sample of a chunk at which the flight fails and why (−1, "" when none), and whether
    the vehicle has been airborne (more than 1 m up) by the chunk's end. At one sample a
    non-finite state comes before an attitude beyond the limit, which comes before a ground
    strike (the order of the compiled lap loop, :mod:`casadrone.lapdriver`)."""
    bad = ~np.all(np.isfinite(x), axis=1)
    tilt = np.radians(track.max_tilt_deg)
    over = (np.abs(x[:, 9]) > tilt) | (np.abs(x[:, 10]) > tilt)
    z0 = track.start_position_m[2]
    up = np.logical_or.accumulate(x[:, 2] - z0 > 1.0) | airborne
    ground = (x[:, 2] < z0 - margin) | (up & (x[:, 2] < z0))
    first = [int(np.argmax(m)) if m.any() else len(x) for m in (bad, over, ground)]
    k = min(first)
    if k == len(x):
        return -1, "", bool(up[-1])
    why = _FAILURES[first.index(k)]
    return k, _failure_reason(why, x[k], t[k], track), bool(up[-1])


#: One chunk of a flight: states, controller states, commands, logged references (one row per
#: sample) and the integrator's error message ("" when none).
Chunk = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, str]


def _rk4_chunks(airframe: Airframe, x: np.ndarray, c: np.ndarray, args: list, Ts: float,
                n_route: int, options: SimOptions) -> Iterator[Chunk]:
    """Chunks of the compiled RK4 closed loop, without end (the path without a C compiler; with
    one, the whole-lap loop of :func:`lap_driver` flies the lap)."""
    kernel = lap_kernel(Ts, options.substeps, n_route, options.chunk, airframe.propulsion)
    while True:
        xs, cs, us, refs = kernel(x, c, *args)
        X = np.vstack([x[None, :], xs[:-1]])
        x, c = xs[-1].copy(), cs[-1].copy()
        yield X, cs.copy(), us.copy(), refs.copy(), ""


def _sundials_chunks(kind: str, airframe: Airframe, x: np.ndarray, c: np.ndarray, args: list,
                     Ts: float, n_route: int, options: SimOptions) -> Iterator[Chunk]:
    """Chunks of the closed loop with a SUNDIALS plant, one controller sample at a time; a
    solver error ends the flight with a non-finite state and its message."""
    kind_p = airframe.propulsion
    ctrl = controller_function(Ts, n_route, kind_p)
    plant = sundials_integrator(kind, Ts, options.rtol, options.atol, kind_p)
    f = quadrotor_model(kind_p).f
    while True:
        X, C, U, R = (np.empty((options.chunk, n)) for n in (NX, NC, NU, NREF))
        error = ""
        for k in range(options.chunk):
            X[k] = x
            u, c, ref = (np.array(a).ravel() for a in ctrl(x, c, *args))
            C[k], U[k], R[k] = c, u, ref
            up = np.concatenate([u, airframe.p])
            start = {"z0": np.array(f(x, u, airframe.p)).ravel()} if kind == "idas" else {}
            try:
                x = np.array(plant(x0=x, p=up, **start)["xf"]).ravel()
            except RuntimeError as exc:
                x = np.full(NX, np.nan)
                error = f"{kind} failed: {str(exc).splitlines()[-1][:120]}"
            if not np.all(np.isfinite(x)):
                X[k + 1 :] = np.nan
                break
        yield X[: k + 1] if error else X, C, U, R, error
        if error:
            return


#: The plant integrators, by the name a config, the API and the CLI use: each flies the closed
#: loop in chunks of samples (``rk4`` also has the compiled whole-lap loop, :func:`lap_driver`).
#: A new integrator is one entry here and its chunk function.
INTEGRATORS: dict[str, Callable[..., Iterator[Chunk]]] = {
    "rk4": _rk4_chunks,
    "cvodes": partial(_sundials_chunks, "cvodes"),
    "idas": partial(_sundials_chunks, "idas"),
}
#: An integrator's name: a key of :data:`INTEGRATORS`.
Integrator = str


def simulate(
    airframe: Airframe,
    design: LQRIDesign,
    track: TrackConfig,
    integrator: Integrator = "rk4",
    options: SimOptions = SimOptions(),
) -> Trajectory:
    """Fly one lap of ``track`` under the LQR-I ``design``; failures come back as a result."""
    start = time.perf_counter()
    if integrator not in INTEGRATORS:
        raise ValueError(f"unknown integrator {integrator!r}; choose from {', '.join(INTEGRATORS)}")
    Ts = design.sample_time_s
    route = track.route
    n_route, n_seg = len(route), len(route) - 1
    args = [airframe.p, design.x0, design.u0, design.K, track_vector(track)]
    x, c = initial_state(airframe, design, track)
    n_max = int(np.ceil(track.time_limit_s / Ts))
    kind_p = airframe.propulsion
    driver = lap_driver(Ts, options.substeps, n_route, kind_p) if integrator == "rk4" else None
    if driver is not None:
        lap = driver.run([x, c, *args], n_seg, track.start_position_m[2],
                         np.radians(track.max_tilt_deg), options.ground_margin_m, n_max)
        return _trajectory(lap.X, lap.C, lap.U, lap.R, *_lap_status(lap, Ts, track), airframe,
                           design, track, integrator, start)
    chunks = INTEGRATORS[integrator](airframe, x, c, args, Ts, n_route, options)

    parts: list[tuple[np.ndarray, ...]] = []
    n_done, airborne = 0, False
    status, reason = "failed", f"time-out: lap not finished in {track.time_limit_s:g} s"
    for X, C, U, R, error in chunks:
        t = (n_done + np.arange(len(X))) * Ts
        k_fail, why, airborne = _check(X, t, track, options.ground_margin_m, airborne)
        done = np.flatnonzero(C[: len(X), 4] > n_seg - 0.5)
        k_done = int(done[0]) if done.size else -1
        left = n_max - n_done  # samples before the time limit: nothing after it counts
        k_fail, k_done = (k if k < left else -1 for k in (k_fail, k_done))
        if k_fail >= 0 and (k_done < 0 or k_fail <= k_done):
            status, reason, n = "failed", error or why, k_fail + 1
        elif k_done >= 0:
            status, reason, n = "completed", "", k_done + 1
        else:
            n = min(len(X), n_max - n_done)
        parts.append((X[:n], C[:n], U[:n], R[:n]))
        n_done += n
        if k_fail >= 0 or k_done >= 0 or n_done >= n_max:
            break

    X_all, C_all, U_all, R_all = (np.vstack(p) for p in zip(*parts, strict=True))
    return _trajectory(X_all, C_all, U_all, R_all, status, reason, airframe, design, track,
                       integrator, start)


def _lap_status(lap, Ts: float, track: TrackConfig) -> tuple[str, str]:
    """Status and reason of a lap flown by the compiled lap loop."""
    if lap.outcome == "completed":
        return "completed", ""
    if lap.outcome == "time-out":
        return "failed", f"time-out: lap not finished in {track.time_limit_s:g} s"
    if lap.outcome == "error":
        return "failed", "the compiled lap reported an evaluation error"
    return "failed", _failure_reason(lap.outcome, lap.X[-1], (lap.n - 1) * Ts, track)


def _trajectory(X, C, U, R, status, reason, airframe, design, track, integrator,
                start) -> Trajectory:
    Ts = design.sample_time_s
    t = np.arange(len(X)) * Ts
    seg = np.rint(C[:, 4]).astype(int)
    splits = split_times(t, X, seg, track.route, track)
    return Trajectory(
        status=status, reason=reason, integrator=integrator, t=t, x=X, u=U,
        p_ref=R[:, 0:3], v_ref=R[:, 3:6], psi_ref=R[:, 6], acceleration=R[:, 7:10],
        segment=seg, u0=np.asarray(design.u0), battery_voltage=airframe.battery_voltage,
        waypoints=np.array(track.waypoints_m, float), straight=tuple(track.straight),
        split_times=splits, first_timed_segment=track.first_timed_segment,
        wall_time_s=time.perf_counter() - start,
    )


def _norm(v: np.ndarray) -> float:
    """|v| of a vector: √(v·v), what ``np.linalg.norm`` computes, without its overhead."""
    return math.sqrt(v.dot(v))


def split_times(t, x, seg, route, track: TrackConfig) -> np.ndarray:
    """Time each waypoint was reached, interpolated inside the sample where the segment switched.

    The switch condition is g ≤ 0 with g = min(|p − b| − r_acc, L − s); between the last sample
    with g > 0 and the first with g ≤ 0, g is interpolated linearly.
    """
    first = track.first_timed_segment
    out = np.full(len(track.waypoints_m), np.nan)
    for j in range(len(track.waypoints_m)):
        k_seg = first + j
        hit = np.flatnonzero(seg > k_seg)
        if not hit.size:
            continue
        k = int(hit[0])
        a, b = route[k_seg], route[k_seg + 1]
        L = _norm(b - a)

        def g(i, a=a, b=b, L=L):
            s = np.dot(x[i, :3] - a, (b - a) / L)
            return min(_norm(x[i, :3] - b) - track.acceptance_radius_m, L - s)

        if k == 0:
            out[j] = t[0]
            continue
        g0, g1 = g(k - 1), g(k)
        frac = g0 / (g0 - g1) if g0 > 0 and g1 <= 0 and g0 != g1 else 1.0
        out[j] = t[k - 1] + frac * (t[k] - t[k - 1])
    return out
