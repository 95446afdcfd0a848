"""Benchmark: wall time of one complete candidate evaluation, and rotorpy on the same flight time.

casadrone side, on one core, after a warm-up (model build, compile of the RK4 lap kernel — cached
on disk — trim/Jacobian Functions, SUNDIALS integrators):

    evaluate(θ, setup)   θ → Airframe → hover trim (newton) → exact linearisation → discrete LQR-I
                         → closed-loop lap of the paper track → indices J1…Jp + Table 4 intervals

timed end to end with ``rk4`` (the compiled kernel) and with ``cvodes`` (SUNDIALS, the
high-fidelity reference), for SY250 (repeated) and for random θ inside paper Table 1
(overlapping-rotor draws resampled; evaluations that fail a stage are timed and counted apart).
A second pass times the stages separately on the same θ: build, trim, linearise, LQR-I, lap,
indices. Target: ≤ 10 ms median per complete rk4 evaluation.

rotorpy side (benchmark-only dependency: ``pip install rotorpy``; it is not a casadrone
dependency, and this part is skipped with a message when it is not importable): rotorpy's own
simulator (``Environment.run`` → ``Multirotor`` dynamics integrated by ``scipy.solve_ivp`` RK45,
``SE3Control``, trajectory evaluation, and its default IMU, motion-capture and null-estimator
models, which it runs every step) flies the same duration as casadrone's SY250 lap at the same
controller rate (``sim_rate`` = 1/Ts = 100 Hz), with an SY250-like vehicle (mass, inertia,
arm length and body drag of SY250; rotorpy's Hummingbird rotor/motor coefficients) and, for
reference, rotorpy's default Hummingbird. Flights:

    lap replay   the path casadrone's SY250 lap actually flew (position, world velocity,
                 acceleration, yaw vs time) as rotorpy flat outputs: same path, same duration
    circle       rotorpy's ThreeDCircularTraj, 10 m radius at the lap's mean speed
    hover        rotorpy's HoverTraj

Each is timed as the median of several runs in the same process as the casadrone timing, and the
ratio rotorpy / casadrone is reported.

Run: ``python benchmarks/bench_lap.py [--n 50] [--n-cvodes 10] [--n-rotorpy 9] [--seed 0]
[--no-write]``. Writes ``benchmarks/RESULTS-lap.md``.
"""

from __future__ import annotations

import os

# One core: pin BLAS/OpenMP thread pools before numpy, scipy or casadi are imported.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"
if hasattr(os, "sched_setaffinity"):
    _cpus = os.sched_getaffinity(0)
    os.sched_setaffinity(0, {0} if 0 in _cpus else {min(_cpus)})

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import datetime  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import casadi  # noqa: E402
import numpy as np  # noqa: E402
import scipy  # noqa: E402

from casadrone import airframe  # noqa: E402
from casadrone.airframe import build_airframe, with_theta  # noqa: E402
from casadrone.control import design_lqri  # noqa: E402
from casadrone.evaluate import default_setup, evaluate, theta_of  # noqa: E402
from casadrone.indices import compute_indices, interval_table  # noqa: E402
from casadrone.linearise import linearise  # noqa: E402
from casadrone.model import rotation_matrix  # noqa: E402
from casadrone.simulate import simulate  # noqa: E402
from casadrone.trim import trim  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "RESULTS-lap.md"
STAGES = ("build", "trim", "linearise", "lqri", "lap", "indices")
TARGET_MS = 10.0


# --------------------------------------------------------------------------------------------
# casadrone
# --------------------------------------------------------------------------------------------


def random_thetas(n: int, seed: int, template) -> tuple[list[dict[str, float]], int]:
    """``n`` decision vectors inside Table 1 with valid geometry, and the rejected draw count."""
    return airframe.random_thetas(template, n, seed)


def time_evaluations(thetas, setup) -> list[tuple[float, object]]:
    """(wall time s, Evaluation) of ``evaluate`` per θ, timed outside the call."""
    out = []
    for th in thetas:
        t = time.perf_counter()
        ev = evaluate(th, setup)
        out.append((time.perf_counter() - t, ev))
    return out


def time_stages(theta, setup) -> dict[str, float] | None:
    """The chain of :func:`evaluate`, each stage timed separately (None if a stage fails)."""
    out = {}
    t = time.perf_counter()
    frame = build_airframe(with_theta(setup.template, theta))
    out["build"] = time.perf_counter() - t
    t = time.perf_counter()
    tp = trim(frame, "hover", 0.0, solver=setup.trim_solver)
    out["trim"] = time.perf_counter() - t
    if not tp.success or np.any(tp.u0 > 1.0):
        return None
    t = time.perf_counter()
    lin = linearise(frame, tp)  # gain_policy "redesign": design_for = design_lqri(linearise(…))
    out["linearise"] = time.perf_counter() - t
    t = time.perf_counter()
    design = design_lqri(lin, setup.controller, certificate=False)  # as evaluate() does
    out["lqri"] = time.perf_counter() - t
    if not design.stable:
        return None
    t = time.perf_counter()
    traj = simulate(frame, design, setup.track, setup.integrator, setup.sim_options)
    out["lap"] = time.perf_counter() - t
    if not traj.completed:
        return None
    t = time.perf_counter()
    compute_indices(traj)
    interval_table(traj)
    out["indices"] = time.perf_counter() - t
    return out


def summary(seconds) -> dict[str, float]:
    ms = 1e3 * np.asarray(seconds, float)
    if ms.size == 0:
        return {
            "n": 0,
            "median": np.nan,
            "p10": np.nan,
            "p90": np.nan,
            "min": np.nan,
            "max": np.nan,
        }
    return {
        "n": int(ms.size),
        "median": float(np.median(ms)),
        "p10": float(np.percentile(ms, 10)),
        "p90": float(np.percentile(ms, 90)),
        "min": float(ms.min()),
        "max": float(ms.max()),
    }


def run_casadrone(n: int, n_cvodes: int, seed: int) -> dict:
    setup = default_setup()
    sy250 = theta_of(setup.template)
    thetas, rejected = random_thetas(n, seed, setup.template)
    cv_setup = dataclasses.replace(setup, integrator="cvodes")

    # Warm-up: compile/load the lap kernel, build model, trim, Jacobian and SUNDIALS Functions.
    t = time.perf_counter()
    first = evaluate(sy250, setup, keep_trajectory=True)
    first_call = time.perf_counter() - t
    if not first.completed:
        raise SystemExit(
            f"SY250 does not complete the lap ({first.stage}: {first.reason}): nothing to benchmark"
        )
    for th in (sy250, *thetas[:5]):
        evaluate(th, setup)
    evaluate(sy250, cv_setup)

    r: dict = {
        "n": n,
        "n_cvodes": n_cvodes,
        "seed": seed,
        "rejected": rejected,
        "first_call_s": first_call,
        "sy250_traj": first.trajectory,
        "sy250_indices": first.indices,
    }
    for label, setup_i, ths in (
        ("rk4 SY250", setup, [sy250] * n),
        ("rk4 random", setup, thetas),
        ("cvodes SY250", cv_setup, [sy250] * n_cvodes),
        ("cvodes random", cv_setup, thetas[:n_cvodes]),
    ):
        res = time_evaluations(ths, setup_i)
        ok = [dt for dt, ev in res if ev.completed]
        bad = [dt for dt, ev in res if not ev.completed]
        reasons: dict[str, int] = {}
        for _, ev in res:
            if not ev.completed:
                reasons[ev.stage] = reasons.get(ev.stage, 0) + 1
        laps = [ev.indices["J3"] for _, ev in res if ev.completed]
        r[label] = {
            "ok": summary(ok),
            "failed": summary(bad),
            "fail_stages": reasons,
            "mean_lap_s": float(np.mean(laps)) if laps else np.nan,
            "evals": [ev for _, ev in res],
        }
        print(
            f"  {label}: median {r[label]['ok']['median']:.2f} ms "
            f"({len(ok)} completed, {len(bad)} failed)",
            flush=True,
        )

    # Agreement rk4 vs cvodes on the random θ both integrators evaluated.
    diffs = []
    for a, b in zip(r["rk4 random"]["evals"][:n_cvodes], r["cvodes random"]["evals"], strict=True):
        if a.completed and b.completed:
            diffs.append(
                max(
                    abs(a.indices[k] - b.indices[k]) / max(abs(b.indices[k]), 1e-12)
                    for k in a.indices
                )
            )
        elif a.completed != b.completed:
            diffs.append(np.inf)
    r["rk4_vs_cvodes_max_rel"] = float(max(diffs)) if diffs else np.nan

    # Stage breakdown (rk4), second pass over the same θ.
    for label, ths in (("SY250", [sy250] * n), ("random", thetas)):
        rows = [s for s in (time_stages(th, setup) for th in ths) if s is not None]
        r[f"stages {label}"] = {k: summary([s[k] for s in rows]) for k in STAGES}
        r[f"stages {label}"]["sum"] = summary([sum(s.values()) for s in rows])
    return r


# --------------------------------------------------------------------------------------------
# rotorpy
# --------------------------------------------------------------------------------------------


class LapReplay:
    """A rotorpy trajectory (``update(t)`` → flat outputs) replaying a casadrone trajectory:
    position, world velocity, world acceleration and yaw, linearly interpolated (jerk, snap and
    yaw rates zero). Precomputed arrays, one ``np.interp`` per channel per call."""

    def __init__(self, traj):
        self.t = traj.t
        x = traj.x
        R = np.array([np.array(rotation_matrix(*xi[9:12])) for xi in x])
        self.cols = np.hstack(
            [
                x[:, 0:3],
                np.einsum("kij,kj->ki", R, x[:, 3:6]),
                traj.acceleration,
                np.unwrap(x[:, 11])[:, None],
            ]
        )
        self.zero = np.zeros(3)

    def update(self, t):
        v = [np.interp(t, self.t, self.cols[:, j]) for j in range(10)]
        return {
            "x": np.array(v[0:3]),
            "x_dot": np.array(v[3:6]),
            "x_ddot": np.array(v[6:9]),
            "x_dddot": self.zero,
            "x_ddddot": self.zero,
            "yaw": v[9],
            "yaw_dot": 0.0,
            "yaw_ddot": 0.0,
        }


def rotorpy_params(airframe, base: dict) -> dict:
    """rotorpy quad_params with SY250's mass, inertia, arm length and body drag."""
    qp = dict(base)
    J = airframe.inertia
    qp.update(
        mass=airframe.mass,
        Ixx=J[0, 0],
        Iyy=J[1, 1],
        Izz=J[2, 2],
        Ixy=J[0, 1],
        Ixz=J[0, 2],
        Iyz=J[1, 2],
    )
    arm = float(np.mean(np.linalg.norm(airframe.rotor_positions[:, :2], axis=1)))
    qp["rotor_pos"] = {
        k: arm * np.asarray(v) / np.linalg.norm(v) for k, v in base["rotor_pos"].items()
    }
    for k, cda in zip(("c_Dx", "c_Dy", "c_Dz"), airframe.drag_area, strict=True):
        qp[k] = 0.5 * airframe.air_density * float(cda)  # F = c_D |v| v, N/(m/s)²
    return qp


def run_rotorpy(r: dict, n_runs: int, n_interleave: int = 10) -> dict | None:
    """Time rotorpy's flights; before each timed run, ``n_interleave`` casadrone rk4
    evaluations of SY250 are timed too, so both sides see the same machine load."""
    try:
        import rotorpy
        from rotorpy.controllers.quadrotor_control import SE3Control
        from rotorpy.environments import Environment
        from rotorpy.trajectories.circular_traj import ThreeDCircularTraj
        from rotorpy.trajectories.hover_traj import HoverTraj
        from rotorpy.vehicles import multirotor as mr
        from rotorpy.vehicles.hummingbird_params import quad_params
    except ImportError as exc:
        print(
            f"rotorpy not importable ({exc}); skipping the rotorpy comparison. "
            "It is a benchmark-only dependency: pip install rotorpy",
            file=sys.stderr,
        )
        return None
    from importlib.metadata import version

    traj = r["sy250_traj"]
    T = float(traj.t[-1])  # the lap's simulated duration (last sample), s
    Ts = traj.t[1] - traj.t[0]
    rate = round(1.0 / Ts)
    frame = build_airframe(default_setup().template)
    sy = rotorpy_params(frame, quad_params)
    V = float(np.sum(np.linalg.norm(np.diff(traj.x[:, 0:3], axis=0), axis=1)) / T)  # mean speed
    rad = 10.0
    flights = {
        "lap replay": (LapReplay(traj), traj.x[0, 0:3], np.zeros(3)),
        "circle": (
            ThreeDCircularTraj(
                center=np.array([0.0, -rad, 20.0]),
                radius=np.array([rad, rad, 0.0]),
                freq=np.full(3, V / (2 * np.pi * rad)),
            ),
            np.array([rad, -rad, 20.0]),
            np.array([0.0, V, 0.0]),
        ),
        "hover": (HoverTraj(np.zeros(3)), np.zeros(3), np.zeros(3)),
    }
    cases = [("SY250-like", sy, f) for f in flights] + [("Hummingbird", quad_params, "lap replay")]

    # The first run of each case is a warm-up (not timed) that also counts the solve_ivp calls
    # and right-hand-side evaluations, through a stand-in for multirotor's module-level `scipy`.
    import types

    counter = {"calls": 0, "nfev": 0}
    real_scipy = mr.scipy

    def counting_solve_ivp(*a, **k):
        sol = real_scipy.integrate.solve_ivp(*a, **k)
        counter["calls"] += 1
        counter["nfev"] += sol.nfev
        return sol

    counting = types.SimpleNamespace(integrate=types.SimpleNamespace(solve_ivp=counting_solve_ivp))
    out = {
        "version": version("rotorpy"),
        "duration_s": T,
        "rate_hz": rate,
        "mean_speed": V,
        "cases": {},
    }
    setup = default_setup()
    sy250 = theta_of(setup.template)
    interleaved: list[float] = []
    for vehicle, qp, flight in cases:
        trajectory, x0, v0 = flights[flight]
        w_hover = float(np.sqrt(qp["mass"] * 9.81 / (qp["num_rotors"] * qp["k_eta"])))
        times, info = [], None
        for i in range(n_runs + 1):
            veh = mr.Multirotor(
                qp,
                initial_state={
                    "x": np.array(x0, float),
                    "v": np.array(v0, float),
                    "q": np.array([0.0, 0.0, 0.0, 1.0]),
                    "w": np.zeros(3),
                    "wind": np.zeros(3),
                    "rotor_speeds": np.full(4, w_hover),
                },
            )
            env = Environment(
                vehicle=veh, controller=SE3Control(qp), trajectory=trajectory, sim_rate=rate
            )
            if i:
                interleaved += [dt for dt, _ in time_evaluations([sy250] * n_interleave, setup)]
            mr.scipy = counting if i == 0 else real_scipy
            counter.update(calls=0, nfev=0)
            try:
                t = time.perf_counter()
                res = env.run(t_final=T, terminate=False)
                dt = time.perf_counter() - t
            finally:
                mr.scipy = real_scipy
            if i == 0:
                info = {
                    "exit": res["exit"].name,
                    "steps": counter["calls"],
                    "nfev_per_step": counter["nfev"] / max(counter["calls"], 1),
                    "sim_time": float(res["time"][-1]),
                    "max_pos_err": float(
                        np.max(np.linalg.norm(res["state"]["x"] - res["flat"]["x"], axis=1))
                    ),
                }
            else:
                times.append(dt)
        t = time.perf_counter()
        for tk in np.arange(0.0, T, Ts):
            trajectory.update(tk)
        info["traj_update_s"] = time.perf_counter() - t
        key = f"{vehicle}, {flight}"
        out["cases"][key] = {"time": summary(times), **info}
        print(
            f"  rotorpy {key}: median {np.median(times):.3f} s, exit {info['exit']}, "
            f"{info['nfev_per_step']:.1f} f-evals/step",
            flush=True,
        )
    out["casadrone_interleaved"] = summary(interleaved)
    out["n_interleave"] = n_interleave
    out["rotorpy_module"] = rotorpy.__file__
    return out


# --------------------------------------------------------------------------------------------
# Report
# --------------------------------------------------------------------------------------------


def machine() -> dict[str, str]:
    cpu = "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass

    import casadrone

    def sh(*cmd):
        try:
            where = Path(casadrone.__file__).parent  # the code measured, not this script's tree
            out = subprocess.run(cmd, capture_output=True, text=True, cwd=where)
            return out.stdout.strip()
        except OSError:
            return ""

    return {
        "uname": sh("uname", "-a") or " ".join(platform.uname()),
        "nproc": sh("nproc", "--all") or str(os.cpu_count()),
        "cpu": cpu,
        "pinned": ",".join(map(str, sorted(os.sched_getaffinity(0))))
        if hasattr(os, "sched_getaffinity")
        else "n/a",
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "python": platform.python_version(),
        "versions": f"casadi {casadi.__version__}, numpy {np.__version__}, "
        f"scipy {scipy.__version__}",
        "git": (sh("git", "rev-parse", "--short", "HEAD") or "unknown")
        + (" + uncommitted changes" if sh("git", "status", "--porcelain", "--", ".") else ""),
        "uptime": sh("uptime"),
    }


def _row(label, s, extra=""):
    if s["n"] == 0:
        return f"| {label} | 0 | – | – | – | – |{extra}"
    return (
        f"| {label} | {s['n']} | {s['median']:.2f} | {s['p10']:.2f} | {s['p90']:.2f} "
        f"| {s['max']:.2f} |{extra}"
    )


def tables(r: dict, rp: dict | None) -> str:
    lines = [
        "### Complete evaluation (`evaluate(θ, setup)`: build + trim + linearise + LQR-I + lap "
        "+ indices)",
        "",
        "| integrator, θ | n | median (ms) | p10 (ms) | p90 (ms) | max (ms) "
        f"| ≤ {TARGET_MS:g} ms |",
        "|---|---:|---:|---:|---:|---:|:-:|",
    ]
    for label in ("rk4 SY250", "rk4 random", "cvodes SY250", "cvodes random"):
        s = r[label]["ok"]
        mark = (
            (" yes |" if s["median"] <= TARGET_MS else " no |")
            if label.startswith("rk4")
            else " – |"
        )
        lines.append(_row(f"{label} (completed)", s, mark))
        f = r[label]["failed"]
        if f["n"]:
            stages = ", ".join(f"{k} {v}" for k, v in sorted(r[label]["fail_stages"].items()))
            lines.append(_row(f"{label} (failed: {stages})", f, " – |"))
    lines += [
        "",
        "### Stage breakdown, rk4 (same θ, stages timed one by one, completed only)",
        "",
        "| stage | SY250 median (ms) | SY250 p90 (ms) | random median (ms) | random p90 (ms) |",
        "|---|---:|---:|---:|---:|",
    ]
    for k in (*STAGES, "sum"):
        a, b = r["stages SY250"][k], r["stages random"][k]
        lines.append(
            f"| {k} | {a['median']:.3f} | {a['p90']:.3f} | {b['median']:.3f} | {b['p90']:.3f} |"
        )
    if rp is None:
        lines += ["", "rotorpy: not importable, comparison skipped (`pip install rotorpy`)."]
        return "\n".join(lines)
    ci = rp["casadrone_interleaved"]
    cas, cas_min = ci["median"] / 1e3, ci["min"] / 1e3
    cas_lap = r["stages SY250"]["lap"]["median"] / 1e3
    cv = r["cvodes SY250"]["ok"]["median"] / 1e3
    lines += [
        "",
        f"### rotorpy {rp['version']}: {rp['duration_s']:.2f} s of closed-loop flight at "
        f"{rp['rate_hz']} Hz (the SY250 lap's duration and controller rate)",
        "",
        f"casadrone rk4 evaluation of SY250 timed interleaved with these runs "
        f"({ci['n']} evaluations, {rp['n_interleave']} before each timed rotorpy run): median "
        f"{ci['median']:.2f} ms, min {ci['min']:.2f} ms, p90 {ci['p90']:.2f} ms.",
        "",
        "| vehicle, flight | runs | median (s) | min (s) | p90 (s) | RK45 f-evals / step "
        "| max \\|x − x_ref\\| (m) | exit | ÷ casadrone rk4 evaluation: median (min) "
        "| ÷ casadrone rk4 lap only | ÷ casadrone cvodes evaluation |",
        "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|",
    ]
    for key, c in rp["cases"].items():
        s = c["time"]
        m = s["median"] / 1e3
        lines.append(
            f"| {key} | {s['n']} | {m:.3f} | {s['min'] / 1e3:.3f} | {s['p90'] / 1e3:.3f} "
            f"| {c['nfev_per_step']:.1f} | {c['max_pos_err']:.2f} | {c['exit']} "
            f"| {m / cas:.0f}× ({s['min'] / 1e3 / cas_min:.0f}×) | {m / cas_lap:.0f}× "
            f"| {m / cv:.1f}× |"
        )
    return "\n".join(lines)


def write(r: dict, rp: dict | None, m: dict, cmd: str, path: Path) -> None:
    rk = r["rk4 SY250"]["ok"]["median"]
    if rp is not None:
        head = rp["cases"]["SY250-like, lap replay"]
        ci = rp["casadrone_interleaved"]
        ratio = head["time"]["median"] / ci["median"]
        rp_line = (
            f"rotorpy (SY250-like vehicle, SE3Control, replaying the same lap) takes "
            f"**{head['time']['median'] / 1e3:.2f} s** for the same {rp['duration_s']:.2f} s "
            f"of flight: **{ratio:.0f}×** the casadrone rk4 evaluation timed interleaved with it "
            f"({ci['median']:.2f} ms), in the same run."
        )
        traj_cost = head["traj_update_s"] * 1e3
        per_step = head["time"]["median"] / head["steps"]  # ms
        per_fev = per_step / head["nfev_per_step"]  # ms
        rp_notes = f"""- rotorpy computes, per 10 ms step: `Multirotor.step` (scipy `solve_ivp`,
  RK45, rotorpy's default `integrator_kwargs`, scipy's default rtol 1e-3 / atol 1e-6, on its
  20-state model (quaternion attitude, wind state, rotor speeds) with rotor aerodynamics
  (rotor drag, induced inflow, translational lift) and a first-order motor with
  τ = 5 ms), `SE3Control.update`, the trajectory's `update`, plus its default IMU (with noise),
  motion-capture (with noise) and null-estimator models, the safety checks, and the stored
  histories. No plotting, no animation (`plot=False`), `terminate=False`, `t_final` = the lap's
  duration, so it always simulates the full {rp["duration_s"]:.2f} s
  ({head["steps"]} steps; exit `TIMEOUT` is rotorpy's status for reaching `t_final`: no run
  stopped early). Each case's first run is an untimed warm-up that also counts the RK45
  right-hand-side evaluations. rotorpy {rp["version"]} from PyPI, installed in the benchmark
  environment only.
- casadrone computes the whole candidate evaluation: airframe build and validation, hover trim,
  exact linearisation (CasADi AD), discrete LQR-I (ZOH + 20-state DARE + closed-loop
  eigenvalues; `evaluate` skips the Lyapunov certificate),
  the lap (line-of-sight guidance, reference shaping, LQR-I with saturation and anti-windup, RK4
  plant with one sub-step per 10 ms sample, generated C compiled once and cached, run in chunks
  of 250 samples, so up to 249 samples past the lap's end are computed and dropped), then the
  six indices and the Table 4 interval table. Its plant is the 16-state Euler-angle model with a
  first-order thrust lag (τ = 60.5 ms) and quadratic body drag: a simpler model than rotorpy's,
  integrated at a fixed step instead of adaptively. The lap-only column compares rotorpy with
  `simulate` alone.
- The flights: "lap replay" feeds rotorpy the path casadrone's SY250 lap flew (position, world
  velocity, world acceleration, yaw; linear interpolation in a 15-line trajectory object of this
  script; its `update` costs {traj_cost:.1f} ms over the whole flight, included in rotorpy's time).
  rotorpy flies it with its SE3 controller, not casadrone's LQR-I, so its flight is close to,
  not identical with, casadrone's (max position error from the replayed path in the table).
  "circle" is rotorpy's built-in `ThreeDCircularTraj` (10 m radius, the lap's mean
  speed {rp["mean_speed"]:.1f} m/s, started on the circle at speed); "hover" its `HoverTraj`.
  "SY250-like": SY250's mass, inertia, arm length and body drag (½ρC_dA) on rotorpy's
  Hummingbird rotor/motor coefficients; "Hummingbird": rotorpy's default parameters unchanged.
- rotorpy's cost depends on the flight through RK45's adaptive step count (f-evals per step in
  the table). Lap replay: {per_step:.2f} ms per 10 ms step, {per_fev * 1e3:.0f} µs per
  f-eval including the step's share of controller, sensors and bookkeeping. The ratio is a
  cost-per-simulated-second comparison of two different tools, not a like-for-like model
  comparison."""
    else:
        rp_line = "rotorpy was not importable: comparison skipped (`pip install rotorpy`)."
        rp_notes = ""
    tr = r["sy250_traj"]
    st = r["stages SY250"]
    share = 100 * (st["lqri"]["median"] + st["lap"]["median"]) / st["sum"]["median"]
    text = f"""# Lap benchmark (complete evaluation: trim → linearisation → LQR-I → lap → indices)

`{cmd}`

- One complete casadrone evaluation of SY250 with `rk4`: **{rk:.2f} ms** (median, one core;
  target ≤ {TARGET_MS:g} ms: {"met" if rk <= TARGET_MS else "NOT met"}).
  Random Table 1 θ: {r["rk4 random"]["ok"]["median"]:.2f} ms.
  With `cvodes`: {r["cvodes SY250"]["ok"]["median"]:.0f} ms.
- {rp_line}

- date: {m["date"]}
- machine: `{m["uname"]}`
- CPU: {m["cpu"]} (nproc {m["nproc"]}; benchmark pinned to CPU {m["pinned"]}, BLAS/OpenMP threads 1)
- load: `{m["uptime"]}` at the end; 1-min load average at start / end:
  {r["load"][0]:.2f} / {r["load"][1]:.2f}. The machine is shared with other jobs running now, so
  p90 and max include interference; quote the medians.
- Python {m["python"]}; {m["versions"]}; casadrone git {m["git"]}

Setup: `default_setup()` (SY250 template, default controller: LQR-I at Ts = 0.01 s, gain policy
`redesign`; paper rectangle track; newton hover trim). SY250's lap: J3 =
{r["sy250_indices"]["J3"]:.3f} s, {len(tr.t)} samples of 10 ms. Warm-up (excluded): the first
call in the process took {r["first_call_s"] * 1e3:.0f} ms (loading the compiled lap kernel
from the disk cache, building the model, trim and Jacobian Functions), then six rk4 and one
cvodes evaluations. Random θ:
{r["n"]} draws inside paper Table 1 (seed {r["seed"]}; {r["rejected"]} overlapping-rotor draws
rejected and redrawn before timing); cvodes runs the first {r["n_cvodes"]} of them. rk4 vs cvodes
on those: largest relative index difference {r["rk4_vs_cvodes_max_rel"]:.1e}.
Times are wall clock per evaluation, measured around the call.

{tables(r, rp)}

Notes:
- "completed" rows are evaluations that flew the lap; failed ones (a stage failed: trim, unstable
  LQR-I, or a lap that diverged, hit the ground or timed out) are timed apart: a lap that fails
  early is cheap, a time-out flies the full 60 s limit.
- The stage rows are a second pass, each stage timed on its own (LQR-I without the Lyapunov
  certificate, as `evaluate` runs it: ZOH + the 20-state DARE of scipy + eigenvalues); their sum
  is close to the end-to-end median (the difference is call overhead and load noise). LQR-I and
  the lap are {share:.0f} % of it; inside LQR-I, scipy's `solve_discrete_are` (QZ on the 40 × 40
  pencil) takes most of the time.
{rp_notes}
"""
    path.write_text(text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50, help="rk4 evaluations per θ set")
    ap.add_argument("--n-cvodes", type=int, default=10, help="cvodes evaluations per θ set")
    ap.add_argument("--n-rotorpy", type=int, default=9, help="rotorpy runs per flight")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-write", action="store_true", help="print only, do not write RESULTS")
    args = ap.parse_args()
    cmd = "python benchmarks/bench_lap.py " + " ".join(sys.argv[1:])
    load0 = os.getloadavg()[0]
    print("casadrone …", flush=True)
    r = run_casadrone(args.n, args.n_cvodes, args.seed)
    print("rotorpy …", flush=True)
    rp = run_rotorpy(r, args.n_rotorpy)
    r["load"] = (load0, os.getloadavg()[0])
    m = machine()
    print(f"{m['cpu']} ({m['uname']}), {m['date']}, {m['uptime']}")
    print(tables(r, rp))
    if not args.no_write:
        write(r, rp, m, cmd.strip(), RESULTS)
        print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
