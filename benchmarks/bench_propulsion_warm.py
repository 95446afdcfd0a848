"""Benchmark: where a warm limit-lap solve's time goes, ``paper`` against ``propeller`` (issue 17).

For each variant (``--variants``, ``MODEL:INTERVALS`` per leg, e.g. ``paper:40,propeller:80``, or
``MODEL:INTERVALS:SUBSTEPS:ROTOR_STEP``, e.g. ``propeller:40:4:exponential``) it
solves SY250's lap on the paper track from the point-mass start, then ``--n`` neighbours (θ
within ±5 % of the Table 1 range, the same draws as ``bench_propulsion.py --warm``) each from
the primal-dual warm start of that lap, as ``limit_lap`` does (``Problem.solve``, the library's
IPOPT options), and reports for each warm solve:

- CPU of the whole ``limit_lap`` call (NLP solve + re-simulation check) and of the NLP solve
  alone, its iterations, and the NLP functions' share (IPOPT's ``t_proc_*`` statistics: the
  Hessian, the constraint Jacobian; the rest is MUMPS and IPOPT itself);
- from IPOPT's own iteration log (the same solve once more with ``file_print_level`` 5, written
  beside the results): restoration iterations, iterations with an inertia correction
  (``lg(rg)`` not ``-``), with a shortened step (α_pr < 1) and the line-search trials;
- how the warm point fits the neighbour: the constraint violation and the largest multiplier
  carried, split into the interval rows and the data-range rows (``advance_rows``);
- the base lap, its re-simulation miss and the grid (the time constant trade).

Run: ``python benchmarks/bench_propulsion_warm.py --n 2 --variants
paper:40,propeller:80,propeller:60,propeller:40``. Writes
``benchmarks/RESULTS-propulsion-warm-measured.md`` (``--out``) and the IPOPT logs under
``--logs``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import pickle  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.bench_propulsion import Report, cpu, frame_name  # noqa: E402
from benchmarks.machine import markdown  # noqa: E402
from casadrone.airframe import TABLE1_BOUNDS, build_airframe, with_theta  # noqa: E402
from casadrone.config import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK  # noqa: E402
from casadrone.limit.lap import LapSeeds, LimitLapOptions, frame_clearance_m, limit_lap  # noqa: E402
from casadrone.limit.nlp import ipopt_options  # noqa: E402
from casadrone.limit.starts import prepare  # noqa: E402

#: One IPOPT iteration line: iter (r: restoration), objective, inf_pr, inf_du, lg(mu), ||d||,
#: lg(rg), alpha_du, alpha_pr (with its letter), ls.
LINE = re.compile(r"^\s*(\d+)(r?)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+"
                  r"(\S+)\s+(\d+)\s*$")


def log_counts(path: Path) -> dict:
    """Counts from an IPOPT iteration log (print level 5)."""
    its = [m.groups() for m in map(LINE.match, path.read_text().splitlines()) if m]
    its = [g for g in its if g[0] != "0" or g[1]]  # iteration 0 is the start, not a step
    alpha = [float(re.sub(r"[a-zA-Z]+$", "", g[9])) for g in its]
    full = next((k + 1 for k, a in enumerate(alpha) if a >= 0.99), len(alpha))
    return {"iterations": len(its), "restoration": sum(g[1] == "r" for g in its),
            "first_full": full,
            "inertia": sum(g[7] != "-" for g in its),
            "short": sum(a < 1.0 for a in alpha),
            "ls_trials": sum(int(g[10]) for g in its),
            "mu_end": float(its[-1][5]) if its else np.nan,
            "mu_first": float(its[0][5]) if its else np.nan}


def neighbours(cfg, n: int, seed: int) -> list:
    """``n`` frames within ±5 % of the Table 1 range around ``cfg`` (bench_propulsion's draws)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        theta = {k: float(np.clip(getattr(cfg, k) + 0.05 * (hi - lo) * rng.uniform(-1, 1), lo,
                                  hi)) for k, (lo, hi) in TABLE1_BOUNDS.items()}
        out.append(with_theta(cfg, theta))
    return out


def warm_fit(pb, point) -> str:
    """How the warm point fits this problem: max |g − clip(g)| and max |λ| over the interval
    (dynamics) rows and over the data-range rows."""
    g = np.asarray(ca.Function("g", [pb.full.problem["x"], pb.full.problem["p"]],
                               [pb.full.problem["g"]])(point.w, pb.P)).ravel()
    viol = np.abs(g - np.clip(g, pb.rows[0], pb.rows[1]))
    n_dyn = pb.full.model.nx * pb.layout.n_intervals
    dyn = f"{viol[:n_dyn].max():.1e}, |λ| ≤ {np.abs(point.lam_g[:n_dyn]).max():.2g}"
    if pb.layout.max_advance_ratio is None:
        return dyn + "; no data-range rows"
    nM = 4 * pb.layout.n_intervals
    at = n_dyn + (pb.layout.n_intervals - pb.layout.n_legs) + pb.full.model.nx
    lam = point.lam_g[at:at + nM]
    return (dyn + f"; data-range rows {viol[at:at + nM].max():.1e}, |λ| ≤ "
            f"{np.abs(lam).max():.2g}, active {int(np.sum(np.abs(lam) > 1e-6))}/{nM}")


def logged_solve(pb, warm, log: Path, overrides: dict):
    """The warm solve of ``pb`` once more with IPOPT's iteration log in ``log`` (the library's
    warm options, plus the log and ``overrides``: a diagnosis, not the library's solve)."""
    opts = ipopt_options(pb.full.tol, pb.full.max_iter, True,
                         propulsion=pb.full.model.propulsion) | pb.full.derivatives
    opts["ipopt"] = dict(opts["ipopt"], output_file=str(log), file_print_level=5) | overrides
    solver = ca.nlpsol("logged", "ipopt", pb.full.problem, opts)
    out, t = cpu(lambda: solver(x0=np.clip(warm.w, *pb.box), lam_x0=warm.lam_x,
                                lam_g0=warm.lam_g, p=pb.P, lbx=pb.box[0], ubx=pb.box[1],
                                lbg=pb.rows[0], ubg=pb.rows[1]))
    return solver.stats(), t, float(out["f"])


class _Iterates(ca.Callback):
    """IPOPT's iterates x, kept (nlpsol's ``iteration_callback``)."""

    def __init__(self, sizes: dict[str, int]):
        ca.Callback.__init__(self)
        self.sizes = sizes
        self.xs: list[np.ndarray] = []
        self.construct("iterates", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(self.sizes[ca.nlpsol_out(i)], 1)

    def eval(self, arg):
        self.xs.append(np.array(arg[0]).ravel())
        return [0]


def blocking_bounds(pb, warm, until: int) -> str:
    """Which box bounds cut IPOPT's steps short (fraction to the boundary) in the first
    ``until`` iterations: the components that moved ≥ 94 % of the way to a bound they were
    within 1e-2 of, counted by kind (commands, rotor states, Euler roll/pitch: the tilt bounds,
    other states, leg durations). Bounds of rows (their slacks) are not seen."""
    pr = pb.full.problem
    nw, ng, n_p = pr["x"].numel(), pr["g"].numel(), pr["p"].numel()
    rec = _Iterates({"x": nw, "f": 1, "g": ng, "lam_x": nw, "lam_g": ng, "lam_p": n_p})
    opts = ipopt_options(pb.full.tol, pb.full.max_iter, True,
                         propulsion=pb.full.model.propulsion) | pb.full.derivatives
    ca.nlpsol("iterates", "ipopt", pr, opts | {"iteration_callback": rec})(
        x0=np.clip(warm.w, *pb.box), lam_x0=warm.lam_x, lam_g0=warm.lam_g, p=pb.P,
        lbx=pb.box[0], ubx=pb.box[1], lbg=pb.rows[0], ubg=pb.rows[1])
    nx, nu, M = pb.full.model.nx, pb.full.model.nu, pb.layout.n_intervals
    per, idx = 1 + nu + nx, np.arange(nw)
    state = np.where(idx >= M * per, idx - M * per, idx % per - 1 - nu)  # < 0: not a state
    rotor = pb.full.model.rotor
    kinds = np.select([idx % per == 0, state < 0, (state >= rotor.start) & (state < rotor.stop),
                       (state == 9) | (state == 10)],
                      ["duration", "command", "rotor", "roll/pitch"], "other state")
    kinds[idx >= M * per] = np.where((state[idx >= M * per] == 9) | (state[idx >= M * per] == 10),
                                     "roll/pitch", "other state")
    count: dict[str, int] = {}
    for a, b in zip(rec.xs[:until], rec.xs[1:until + 1], strict=False):
        for bound, sign in ((pb.box[0], 1), (pb.box[1], -1)):
            d0, d1 = sign * (a - bound), sign * (b - bound)
            hit = np.isfinite(bound) & (d0 > 0) & (d0 < 1e-2) & (d1 < 0.06 * d0)
            for k in kinds[hit]:
                count[k] = count.get(k, 0) + 1
    return ", ".join(f"{k} {v}" for k, v in sorted(count.items(), key=lambda kv: -kv[1])) or "—"


def variant(rep: Report, model: str, intervals: int, n: int, seed: int, logs: Path,
            overrides: dict, itself: bool, blockers: bool = False,
            nlp_only: bool = False, substeps: int = 3, rotor_step: str = "rk4") -> None:
    """``model``: paper, propeller, or propeller-norows (the propeller frames without the
    data-range rows: ``max_advance_ratio`` None)."""
    track = load(TrackConfig, DEFAULT_TRACK)
    cfg = load_airframe(frame_name("SY250", model.removesuffix("-norows")))
    rows = not model.endswith("-norows")

    def frame_of(c):
        f = build_airframe(c)
        return f if rows else replace(f, max_advance_ratio=None)

    grid = dict(intervals=intervals, substeps=substeps, rotor_step=rotor_step)
    base_opts = LimitLapOptions(starts=("point-mass",), sensitivities=False,
                                **grid)  # type: ignore[arg-type]
    label = f"{intervals}" if (substeps, rotor_step) == (3, "rk4") else \
        f"{intervals}x{substeps}-{rotor_step}"
    cached = logs / f"base-{model}-{label}.pickle"  # the base lap of an earlier run
    if cached.exists():
        (lap0, t0) = pickle.loads(cached.read_bytes())
    else:
        lap0, t0 = cpu(lambda: limit_lap(frame_of(cfg), track, base_opts))
        cached.write_bytes(pickle.dumps((lap0, t0)))
    if not lap0.completed:
        rep.add(f"| {model} | {label} | base lap failed: {lap0.reason[:80]} | {t0:.0f} s |"
                + " |" * 9)
        return
    base = (f"{lap0.lap_time_s:.4f} s, miss {100 * lap0.resimulation_miss_m:.2f} cm, "
            f"{lap0.iterations} it, {t0:.0f} s")
    frames = ([cfg] if itself else []) + neighbours(cfg, n, seed)
    for i, near in enumerate(frames):
        seeds = LapSeeds(warm_starts=(lap0,))
        opts = LimitLapOptions(starts=(), point_mass_reference=False,
                               sensitivities=False, fallback_reference=None,
                               **grid)  # type: ignore[arg-type]
        frame = frame_of(near)
        if overrides or nlp_only:  # a diagnosis of the NLP solve only: limit_lap not repeated
            lap, t_lap = None, np.nan
        else:
            lap, t_lap = cpu(lambda f=frame, o=opts, s=seeds: limit_lap(f, track, o, s))
        pb = prepare(frame, track, opts,
                     frame_clearance_m(frame, near.prop_diameter_mm / 1000), seeds)
        fit = warm_fit(pb, lap0.solution)
        tag = "-".join(f"{k}={v}" for k, v in overrides.items())
        log = logs / f"warm-{model}-{label}-{i + 1 - itself}{'-' + tag if tag else ''}.log"
        stats, t_nlp, f = logged_solve(pb, lap0.solution, log, overrides)
        c = log_counts(log)
        its = int(stats["iter_count"])
        blocked = blocking_bounds(pb, lap0.solution, c["first_full"]) if blockers else ""
        hess, jac = stats["t_proc_nlp_hess_l"], stats["t_proc_nlp_jac_g"]
        status = "—" if lap is None else f"{lap.lap_time_s:.4f}" if lap.completed \
            else lap.reason[:40]
        rep.add(f"| {model} | {label} | {base} | {i + 1 - itself or 'itself'}: {status} "
                f"({stats['return_status']}, {f:.4f}) | {t_lap:.2f} | {t_nlp:.2f} | {its} | "
                f"{1000 * t_nlp / max(its, 1):.0f} | {100 * hess / t_nlp:.0f} % / "
                f"{100 * jac / t_nlp:.0f} % | {c['restoration']} | {c['inertia']} | "
                f"{c['short']} ({c['ls_trials']}) | {c['mu_end']:.1f} | {fit} | "
                f"{c['first_full']}; {c['mu_first']:.1f} | {blocked} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--variants", default="paper:40,propeller:80")
    ap.add_argument("--out", default=str(Path(__file__).with_name(
        "RESULTS-propulsion-warm-measured.md")))
    ap.add_argument("--logs", default="/tmp/casadrone-warm-logs")
    ap.add_argument("--self", action="store_true",
                    help="also warm-start SY250 from its own lap (the same problem)")
    ap.add_argument("--blockers", action="store_true",
                    help="a third solve per neighbour recording IPOPT's iterates: which box "
                         "bounds cut the steps short")
    ap.add_argument("--nlp-only", action="store_true", help="skip the limit_lap call")
    ap.add_argument("--ipopt", default="",
                    help="IPOPT options for the logged solve only (diagnosis), e.g. "
                         "mu_strategy=monotone,mu_init=1e-3")
    a = ap.parse_args()
    logs = Path(a.logs)
    logs.mkdir(parents=True, exist_ok=True)
    rep = Report(a.out, ["# Warm limit-lap solves: where the time goes", "",
                         f"`python benchmarks/bench_propulsion_warm.py {' '.join(sys.argv[1:])}`",
                         "", markdown(), "",
                         f"Started {time.strftime('%H:%M UTC', time.gmtime())}.",
                         "", "| model | intervals per leg | base lap (point-mass start) | warm "
                         "solve: lap (IPOPT status, objective) | CPU limit_lap (s) | CPU NLP (s) | "
                         "iterations | ms per iteration | Hessian / Jacobian share | "
                         "restoration iterations | inertia corrections | α_pr < 1 (line-search "
                         "trials) | lg(μ) at the end | warm point on the neighbour: violation "
                         "and multipliers | first full step; lg(μ) at iteration 1 | box bounds "
                         "that cut the steps before it (`--blockers`) |", "|" + "---|" * 16])
    overrides = {k: _value(v) for k, v in (kv.split("=") for kv in a.ipopt.split(",") if kv)}
    if overrides:
        rep.add("", f"IPOPT overrides of the logged solve (CPU NLP and the columns after it): "
                f"{overrides}; the CPU of limit_lap is the library's own solve.", "")
    for v in a.variants.split(","):
        model, intervals, *rest = v.split(":")
        variant(rep, model, int(intervals), a.n, a.seed, logs, overrides, a.self,
                a.blockers, a.nlp_only, int(rest[0]) if rest else 3,
                rest[1] if len(rest) > 1 else "rk4")


def _value(text: str):
    try:
        return int(text)
    except ValueError:
        try:
            return float(text)
        except ValueError:
            return text


if __name__ == "__main__":
    main()
