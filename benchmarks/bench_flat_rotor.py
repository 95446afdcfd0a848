"""Benchmark: the `propeller` limit lap with the rotor accelerations as its commands.

Why. Under ``propeller`` the limit lap's commands are the ESC commands δ, held over each
interval, and the rotor speeds ω follow them through the DC motor's ~20-28 ms lag: RK4 needs
80 intervals per leg to follow that lag (40 per leg with ``paper``), and each interval carries
the motor's electrics and the pack's sag coupling the four rotors. Both make a `propeller`
iteration 4-5 times as dear as a `paper` one (benchmarks/RESULTS-propulsion.md).

The motor and the pack are *invertible*: given the rotor speed ω_i and its rate ω̇_i, the motor
torque is J_r ω̇_i + Q_i (the propeller's shaft torque at its inflow), the current
I_i = I₀ + K_V (J_r ω̇_i + Q_i), the motor voltage e_i = R I_i + ω_i / K_V, the pack voltage
V = (V_oc + √(V_oc² − 4 R_b Σ e_i I_i)) / 2 and the command δ_i = e_i / V, all in closed form
(the module docstring of casadrone.propulsion; the hover commands use the same algebra,
``casadrone.propulsion.hover_commands``). So the same physics can be posed with the rotor
accelerations a_i = ω̇_i as the commands, held over each interval: the rotor speeds become
piecewise-linear states without a lag, the electrics leave the interval's dynamics, and the ESC
command becomes an output bounded by rows, 0 ≤ δ_i ≤ 1 at both ends of every interval (in
between δ varies smoothly with ω and the inflow). ``paper``'s 40 intervals per leg might then
suffice.

What this measures, on SY250-propeller and the paper track, every solve from the point-mass
reference lifted to the full model (the library's point-mass start):

- the default ``propeller`` NLP (δ commands) on 80 and 40 intervals per leg, and the
  accelerations NLP on 40: lap, iterations, CPU, ms per iteration;
- the accelerations lap flown by the *original* model (δ commands, DC motor and pack) with
  CVODES, δ linear over each interval between its two end values: the largest target miss, over
  the whole lap and leg by leg from the lap's own nodes (LimitLapOptions.resimulation);
- warm solves of ``--warm`` neighbours (±5 % of the Table 1 range around SY250, the draws of
  bench_propulsion.py --warm), each from the base lap's primal-dual point, both formulations.

Run: ``python benchmarks/bench_flat_rotor.py [--intervals 40] [--warm 2]`` (one JSON line per
measurement on stdout).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from functools import lru_cache  # noqa: E402
from pathlib import Path  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from casadrone.airframe import TABLE1_BOUNDS, build_airframe, with_theta  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import DEFAULT_TRACK, TrackConfig  # noqa: E402
from casadrone.limit.gates import TARGET_SIZE, target_miss  # noqa: E402
from casadrone.limit.nlp import OcpModel, build_nlp, solve  # noqa: E402
from casadrone.limit.problem import frame_clearance_m, row_bounds  # noqa: E402
from casadrone.limit.result import LimitLapOptions  # noqa: E402
from casadrone.limit.starts import prepare  # noqa: E402
from casadrone.model import (  # noqa: E402
    EUL,
    NU,
    NX,
    RATE,
    VEL,
    euler_rate_matrix,
    n_params,
    named,
    quadrotor_model,
    rotation_matrix,
    unpack_params,
)
from casadrone.propulsion import axial_inflow, rotor_loads  # noqa: E402

#: The unit of the accelerations command (rad/s²): a full-command spin-up of a 5-inch rotor is
#: ~10⁵ rad/s², so the commands are of order 1-10, like the states in the NLP's units.
ACCEL_UNIT = 1.0e4
#: Box on the accelerations command (ACCEL_UNIT): wider than any rotor reaches at δ ∈ [0, 1]
#: (the δ rows are what binds); it only keeps IPOPT's first steps finite.
ACCEL_BOX = 60.0
#: Smoothing (V²) of the pack's discriminant in the commands' closed form (flat_terms).
DISC_EPS = 1.0e-2


def flat_terms(x, a, p):
    """(ẋ (16), δ (4), the pack's discriminant V_oc² − 4 R_b Σ e I (V²): negative where no
    command gives these accelerations) of the ``propeller`` Euler model with rotor
    accelerations ``a`` (ACCEL_UNIT) as the input: the same forces and moments as
    casadrone.propulsion.propeller_terms, with the motor torque J_r ω̇ + Q (the rotor's own
    residual solved for it)."""
    g, J, r, s, cda = unpack_params(p)
    q = named(p)
    vel, omega, eul, w = x[VEL], x[RATE], x[EUL], x[12:16]
    wdot = ACCEL_UNIT * a
    ez = ca.DM([0, 0, 1])
    force, torque, qm = ca.DM.zeros(3), ca.DM.zeros(3), []
    for i in range(4):
        v_i = vel + ca.cross(omega, r[i])
        T, Q = rotor_loads(w[i], axial_inflow(v_i[2], q), q)
        f_i = T * ez - q["rotor_kd"] * w[i] * ca.vertcat(v_i[0], v_i[1], 0)
        qm.append(q["rotor_J"] * wdot[i] + Q)
        force = force + f_i
        torque = torque + ca.cross(r[i], f_i) + s[i] * qm[i] * ez
    qm = ca.vertcat(*qm)
    m = g["mass"]
    R = rotation_matrix(eul[0], eul[1], eul[2])
    drag = -0.5 * g["rho"] * cda * ca.fabs(vel) * vel
    acc = (force + drag + R.T @ ca.vertcat(0, 0, -m * g["g"])) / m - ca.cross(omega, vel)
    rate_dot = ca.solve(J, torque - ca.cross(omega, J @ omega))
    xdot = ca.vertcat(R @ vel, acc, rate_dot, euler_rate_matrix(eul[0], eul[1]) @ omega, wdot)
    # the commands that give these accelerations (closed form, see the module docstring)
    current = q["motor_I0"] + q["motor_kv"] * qm
    e = q["motor_R"] * current + w / q["motor_kv"]
    disc = q["batt_Voc"] ** 2 - 4 * q["batt_R"] * ca.dot(e, current)
    # √ of max(disc, 0) smoothed over DISC_EPS: finite where a guess asks more power than the
    # pack can give (disc < 0: no command reaches it; the δ rows then push back); 2.5e-7
    # relative on V at a full-throttle disc of ~100 V²
    V = 0.5 * (q["batt_Voc"] + ca.sqrt(0.5 * (disc + ca.sqrt(disc**2 + DISC_EPS**2))))
    dc = q["motor_dc"]
    delta = dc * e / V + (1 - dc) * (w + q["motor_tau"] * wdot) / (q["motor_kv"] * q["batt_Voc"])
    return xdot, delta, disc


@lru_cache(maxsize=1)
def flat_model() -> OcpModel:
    x, a = ca.SX.sym("x", NX), ca.SX.sym("a", NU)
    p = ca.SX.sym("p", n_params("propeller"))
    xdot, delta, _ = flat_terms(x, a, p)
    f = ca.Function("f_flat", [x, a, p], [xdot], ["x", "u", "p"], ["xdot"])
    commands = ca.Function("delta_flat", [x, a, p], [delta], ["x", "u", "p"], ["delta"])

    def rows(x0, x1, u, p_):
        return ca.vertcat(commands(x0, u, p_), commands(x1, u, p_))

    def vw(xx):
        return rotation_matrix(xx[9], xx[10], xx[11]) @ xx[3:6]

    scale = np.ones(NX)
    scale[12:16] = 1000.0  # krad/s, as the library's propeller model (ROTOR_SPEED_UNIT_RAD_S)
    return OcpModel("quadrotor-propeller-flat", f, vw, rates=slice(6, 9), rotor=slice(12, 16),
                    up_z=lambda xx: ca.cos(xx[9]) * ca.cos(xx[10]), attitude="euler",
                    scale=tuple(scale), velocity=slice(3, 6), propulsion="propeller",
                    interval_rows=(rows, 0.0, 1.0))


def inverse_check(p, n: int = 200, seed: int = 1) -> float:
    """Largest relative difference between the accelerations model and the original model fed
    the accelerations' commands, f(x, δ(x, a), p) against f_flat(x, a, p), over ``n`` random
    states and accelerations the pack can power (discriminant ≥ 1 V²; the rotor rows included:
    ω̇ must come back as a)."""
    x, a, pp = ca.SX.sym("x", NX), ca.SX.sym("a", NU), ca.SX.sym("p", len(p))
    xdot, delta, disc = flat_terms(x, a, pp)
    both = ca.Function("both", [x, a, pp],
                       [xdot, quadrotor_model("propeller").f(x, delta, pp), disc])
    rng = np.random.default_rng(seed)
    worst, used = 0.0, 0
    while used < n:
        xx = np.r_[rng.normal(size=3), rng.normal(scale=10, size=3), rng.normal(scale=3, size=3),
                   rng.uniform(-1, 1, 3), rng.uniform(800, 2800, 4)]
        flat, orig, d = (np.array(v).ravel() for v in both(xx, rng.uniform(-5, 5, 4), p))
        if d[0] < 1.0:
            continue
        used += 1
        worst = max(worst, float(np.max(np.abs(flat - orig) / (1 + np.abs(orig)))))
    return worst


def commands_of(X, A, p) -> tuple[np.ndarray, np.ndarray]:
    """δ at the start and at the end of every interval (M, 4) each."""
    x, a, pp = ca.SX.sym("x", NX), ca.SX.sym("a", NU), ca.SX.sym("p", len(p))
    d = ca.Function("d", [x, a, pp], [flat_terms(x, a, pp)[1]])  # δ
    M = len(A)
    d0 = np.array(d.map(M)(X[:-1].T, A.T, np.repeat(p[:, None], M, axis=1))).T
    d1 = np.array(d.map(M)(X[1:].T, A.T, np.repeat(p[:, None], M, axis=1))).T
    return d0, d1


@lru_cache(maxsize=1)
def foh_cvodes() -> ca.Function:
    """CVODES on the original propeller model over one interval (time scaled to [0, 1]) with δ
    linear from δ₀ to δ₁."""
    f = quadrotor_model("propeller").f
    x = ca.SX.sym("x", NX)
    tau = ca.SX.sym("tau")
    NP = n_params("propeller")
    par = ca.SX.sym("par", 2 * NU + NP + 1)
    d0, d1, p, h = par[:NU], par[NU:2 * NU], par[2 * NU:2 * NU + NP], par[-1]
    dae = {"x": x, "t": tau, "p": par, "ode": h * f(x, d0 + tau * (d1 - d0), p)}
    return ca.integrator("flat_resim", "cvodes", dae, 0.0, 1.0,
                         {"abstol": 1e-10, "reltol": 1e-10})


@lru_cache(maxsize=1)
def flat_cvodes() -> ca.Function:
    """CVODES on the accelerations model itself over one interval (time scaled to [0, 1])."""
    f = flat_model().f
    x = ca.SX.sym("x", NX)
    NP = n_params("propeller")
    par = ca.SX.sym("par", NU + NP + 1)
    dae = {"x": x, "p": par, "ode": par[-1] * f(x, par[:NU], par[NU:NU + NP])}
    return ca.integrator("flat_step", "cvodes", dae, 0.0, 1.0, {"abstol": 1e-10, "reltol": 1e-10})


def flat_defects(X, A, t, p) -> dict:
    """Largest local defect of the NLP's RK4 intervals against CVODES on the same model."""
    step = flat_cvodes()
    d = np.array([np.array(step(x0=X[i], p=np.concatenate([A[i], p, [t[i + 1] - t[i]]]))[
        "xf"]).ravel() - X[i + 1] for i in range(len(A))])
    return {"defect_position_m": float(np.abs(d[:, 0:3]).max()),
            "defect_velocity_m_s": float(np.abs(d[:, 3:6]).max()),
            "defect_rotor_rad_s": float(np.abs(d[:, 12:16]).max())}


def fly_foh(X, d0, d1, t, p, first, last) -> np.ndarray:
    step = foh_cvodes()
    out = [X[first]]
    for i in range(first, last):
        par = np.concatenate([d0[i], d1[i], p, [t[i + 1] - t[i]]])
        out.append(np.array(step(x0=out[-1], p=par)["xf"]).ravel())
    return np.array(out)


def misses(X, d0, d1, t, p, targets, kinds, N) -> dict:
    whole = fly_foh(X, d0, d1, t, p, 0, len(X) - 1)
    legs, lap = [], []
    for k, kind in enumerate(kinds):
        tgt = targets[TARGET_SIZE * k:TARGET_SIZE * (k + 1)]
        own = fly_foh(X, d0, d1, t, p, k * N, (k + 1) * N)[-1]
        legs.append(float(target_miss(own[:3], tgt, kind)))
        lap.append(float(target_miss(whole[(k + 1) * N, :3], tgt, kind)))
    return {"miss_lap_m": max(lap), "miss_legs_m": max(legs),
            "drift_at_leg_ends_m": [float(np.linalg.norm(whole[(k + 1) * N, :3]
                                                         - X[(k + 1) * N, :3]))
                                    for k in range(len(kinds))]}


def flat_guess(nlp, pb_nlp, w) -> np.ndarray:
    """The accelerations NLP's vector of a δ-NLP vector: same durations and nodes, each
    interval's acceleration the rotor speeds' difference over it."""
    T, X, _ = pb_nlp.unpack(w)
    N = nlp.layout.intervals
    h = np.repeat(T, N) / N
    A = np.diff(X[:, 12:16], axis=0) / h[:, None] / ACCEL_UNIT
    return nlp.pack(T, X, np.clip(A, -ACCEL_BOX, ACCEL_BOX))


def flat_problem(pb):
    nlp = build_nlp(flat_model(), pb.layout, pb.options.tol, pb.options.max_iter)
    lo, hi = pb.box
    T0, X0, _ = pb.full.unpack(lo)
    T1, X1, _ = pb.full.unpack(hi)
    M = pb.layout.n_intervals
    box = (nlp.pack(T0, X0, np.full((M, NU), -ACCEL_BOX)),
           nlp.pack(T1, X1, np.full((M, NU), ACCEL_BOX)))
    rows = row_bounds(nlp, pb.track, pb.options)
    return nlp, box, rows


def split(nlp, iterations: int) -> dict:
    """CPU per iteration (ms) of the last warm solve's parts (CasADi's solver stats)."""
    st = nlp.warm.stats()
    return {k[7:]: round(1e3 * st[k] / max(iterations, 1), 1) for k in st
            if k.startswith("t_proc_") and st[k] > 1e-3}


def cpu(fn):
    c0 = time.process_time()
    out = fn()
    return out, time.process_time() - c0


def neighbours(cfg, n: int, seed: int) -> list:
    """``n`` frames within ±5 % of the Table 1 range around ``cfg`` (bench_propulsion's draws)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        theta = {k: float(np.clip(getattr(cfg, k) + 0.05 * (hi - lo) * rng.uniform(-1, 1),
                                  lo, hi)) for k, (lo, hi) in TABLE1_BOUNDS.items()}
        out.append(build_airframe(with_theta(cfg, theta)))
    return out


def lbfgs_solver(nlp) -> ca.Function:
    """IPOPT on the same NLP (its compiled rows and constraint Jacobian), warm settings, with a
    limited-memory quasi-Newton Hessian instead of the compiled exact one."""
    from casadrone.limit.nlp import ipopt_solver

    return ipopt_solver(nlp, "limit_lbfgs", {"hessian_approximation": "limited-memory",
                                             "max_iter": 3000}, warm=True)


def warm_delta(args, cfg, base, problem) -> int:
    for j, near in enumerate(neighbours(cfg, args.warm, args.seed)):
        for n in args.default_intervals:
            _, sol0 = base[("delta", n)]
            pbn = problem(near, n)
            s, t = cpu(lambda pbn=pbn, sol0=sol0: pbn.solve(sol0.point.w, warm=sol0.point))
            print(json.dumps({"warm": j, "nlp": "delta", "intervals": n, "status":
                              s.return_status, "lap_s": s.objective, "iterations":
                              s.iterations, "cpu_s": t,
                              "ms_per_iteration": split(pbn.full, s.iterations)}), flush=True)
            if args.lbfgs:
                lb = lbfgs_solver(pbn.full)
                pt = sol0.point
                out, t = cpu(lambda lb=lb, pbn=pbn, pt=pt: lb(
                    x0=pt.w, lam_x0=pt.lam_x, lam_g0=pt.lam_g, p=pbn.P, lbx=pbn.box[0],
                    ubx=pbn.box[1], lbg=pbn.rows[0], ubg=pbn.rows[1]))
                st = lb.stats()
                print(json.dumps({"warm": j, "nlp": "delta, limited-memory Hessian",
                                  "intervals": n, "status": st["return_status"],
                                  "lap_s": float(out["f"]), "iterations": st["iter_count"],
                                  "cpu_s": t}), flush=True)
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--template", default="SY250-propeller")
    ap.add_argument("--intervals", type=int, default=40)
    ap.add_argument("--default-intervals", type=int, nargs="*", default=[80])
    ap.add_argument("--warm", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--lbfgs", action="store_true",
                    help="also solve each δ-NLP warm start with IPOPT's limited-memory "
                         "quasi-Newton Hessian instead of the exact one (the same warm point)")
    ap.add_argument("--no-flat", action="store_true",
                    help="only the δ NLP (the paper model's side of the comparison: --template "
                         "SY250 --default-intervals 40 --no-flat)")
    args = ap.parse_args(argv)
    cfg = load_airframe(args.template)
    frame = build_airframe(cfg)
    track = load(TrackConfig, DEFAULT_TRACK)
    clearance = frame_clearance_m(frame, cfg.prop_diameter_mm / 1000)

    def problem(frame_, n):
        opts = LimitLapOptions(intervals=n, sensitivities=False, starts=("point-mass",))
        return prepare(frame_, track, opts, clearance)

    base = {}
    for n in args.default_intervals:
        pb = problem(frame, n)
        w_start = pb.lifted  # the point-mass reference, solved outside the timed solve
        sol, t = cpu(lambda pb=pb, w_start=w_start: pb.solve(w_start))
        base[("delta", n)] = (pb, sol)
        print(json.dumps({"nlp": "delta", "intervals": n, "status": sol.return_status,
                          "lap_s": sol.objective, "iterations": sol.iterations, "cpu_s": t,
                          "ms_per_iteration": 1e3 * t / max(sol.iterations, 1)}), flush=True)
    if args.no_flat:
        return warm_delta(args, cfg, base, problem)
    print(json.dumps({"inverse_check_max_rel_diff": inverse_check(frame.p)}), flush=True)
    pb = problem(frame, args.intervals)
    nlp, box, rows = flat_problem(pb)
    w0 = flat_guess(nlp, pb.full, pb.lifted)
    sol, t = cpu(lambda: solve(nlp, w0, pb.P, *box, lbg=rows[0], ubg=rows[1]))
    row = {"nlp": "accelerations", "intervals": args.intervals, "status": sol.return_status,
           "lap_s": sol.objective, "iterations": sol.iterations, "cpu_s": t,
           "ms_per_iteration": 1e3 * t / max(sol.iterations, 1)}
    if sol.success:
        T, X, A = nlp.unpack(sol.point.w)
        tn = np.concatenate([[0.0], np.cumsum(np.repeat(T, args.intervals) / args.intervals)])
        d0, d1 = commands_of(X, A, frame.p)
        row |= {"delta_range": [float(min(d0.min(), d1.min())), float(max(d0.max(), d1.max()))],
                "top_speed_m_s": float(np.linalg.norm(X[:, 3:6], axis=1).max())}
        row |= flat_defects(X, A, tn, frame.p)
        row |= misses(X, d0, d1, tn, frame.p, pb.targets.vector, pb.layout.kinds,
                      args.intervals)
    print(json.dumps(row), flush=True)
    if not sol.success or not args.warm:
        return 0
    warm_delta(args, cfg, base, problem)
    for j, near in enumerate(neighbours(cfg, args.warm, args.seed)):
        pbn = problem(near, args.intervals)
        nlpn, boxn, rowsn = flat_problem(pbn)
        s, t = cpu(lambda nlpn=nlpn, pbn=pbn, boxn=boxn, rowsn=rowsn: solve(
            nlpn, sol.point.w, pbn.P, *boxn, warm=sol.point, lbg=rowsn[0], ubg=rowsn[1]))
        print(json.dumps({"warm": j, "nlp": "accelerations", "intervals": args.intervals,
                          "status": s.return_status, "lap_s": s.objective,
                          "iterations": s.iterations, "cpu_s": t,
                          "ms_per_iteration": split(nlpn, s.iterations)}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
