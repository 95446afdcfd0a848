"""Benchmark: casadi 3.8's other NLP solvers on the limit lap's warm solve (none adopted).

Why. Issue 19 asks for a warm limit-lap solve of ≤ 0.25 s (median, one core) from the nearest
other frame's optimum; IPOPT takes 43 iterations of ~30 ms. The measured reason
(``RESULTS-limitlap-solvers.md``, "SQP with HPIPM" and "Warm starts that begin nearer the new
frame") is that the iterations move the switching of bang-bang commands, so what would be needed
is a method that changes many active bounds per iteration and warm-starts its working set from
the neighbour's. casadi 3.8 ships, beside IPOPT and fatrop (measured in
``bench_limitlap_solvers.py``), four more NLP plugins. This script tries each on the same warm
solves:

- ``blocksqp``: blockSQP (Janka, Kirches, Sager, Wächter, "An SR1/BFGS SQP algorithm for
  nonconvex nonlinear programs with block-diagonal Hessian matrix", Math. Prog. Comp. 2016), an
  SQP for multiple shooting: block-wise SR1/BFGS or exact Hessian blocks, convexified, and the
  active-set QP solver qpOASES warm-started from the previous working set. Its sparse mode
  (qpOASES' Schur-complement method, ``schur`` true, the default) factorises the working set's
  KKT matrix with the linear solver ``linsol``, which must report the inertia: casadi's
  default, ``ma27``, needs HSL's ``libhsl.so`` (not redistributable, so not in casadi's wheel);
  ``ldl``, casadi's own sparse LDLᵀ, has no pivoting. ``blocksqp-dense`` is qpOASES' dense mode
  (``schur`` false).
- ``sleqp``: SLEQP (Hübner, Sequential linear/equality-constrained QP: an LP estimates the
  active set, an equality-constrained QP takes the step), with its defaults.
- ``alpaqa``: alpaqa's augmented-Lagrangian PANOC (Pas, Patrinos et al.), a first-order method,
  with its defaults.
- ``madnlp``: listed as unavailable when its plugin cannot load (it needs MadNLP's ``libMad.so``,
  a Julia build that casadi's wheel does not carry).

All get the same NLP with its fixed variables (``lbx == ubx``: the start state) substituted as
parameters and the rows that then involve no free variable (16: the start's own rows) dropped:
with them the working set's KKT matrix is singular by construction, which no QP solver should
have to survive. The symbolic NLP (:attr:`casadrone.limit.nlp.Nlp.problem`) is given, with the
solvers' own derivatives (these plugins do not take IPOPT's ``jac_g``/``hess_lag`` options), so
their time per iteration is not comparable with IPOPT's; the iterations, the status and the lap
are. Each solve runs in a forked child given up after ``--cap`` seconds of wall time
(:func:`casadrone.limit.watchdog.run_guarded`).

For ``--n`` random Table 1 frames (the seeds of bench_limitlap.py; SY250 template, paper track,
40 intervals per leg, one core; CPU = process time), each frame's cold optimum from its
point-mass start, then each frame from its nearest neighbour's primal-dual optimum: IPOPT (the
library's far warm setting, the reference) and every ``--solvers`` entry.
Run: ``python benchmarks/bench_limitlap_nlpsols.py [--n 3] [--cap 300]`` (markdown on stdout).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402
import scipy.sparse as sps  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import cpu_time, markdown  # noqa: E402
from benchmarks.table1 import cold_frames, nearest  # noqa: E402
from casadrone.limit.nlp import solve  # noqa: E402
from casadrone.limit.watchdog import run_guarded  # noqa: E402

TOL = 1e-6
#: plugin, options (beside the tolerances) of each solver this script knows
SOLVERS: dict[str, tuple[str, dict]] = {
    "blocksqp": ("blocksqp", {"linsol": "ldl", "warmstart": True, "print_header": False,
                              "print_iteration": False, "opttol": TOL, "nlinfeastol": TOL,
                              "max_iter": 200}),
    "blocksqp-dense": ("blocksqp", {"schur": False, "warmstart": True, "print_header": False,
                                    "print_iteration": False, "opttol": TOL,
                                    "nlinfeastol": TOL, "max_iter": 200}),
    "sleqp": ("sleqp", {}),
    "alpaqa": ("alpaqa", {}),
    "madnlp": ("madnlp", {}),
}


def reduced_nlp(problem: dict, fixed: np.ndarray, jac_sparsity: ca.Sparsity
                ) -> tuple[dict, np.ndarray]:
    """``problem`` with the variables ``fixed`` made parameters (appended to p) and the rows
    that involve no free variable dropped; and the mask of the rows kept."""
    free = ~fixed
    n, nf, nc = len(fixed), int(free.sum()), int(fixed.sum())
    xf, xc = ca.MX.sym("xf", nf), ca.MX.sym("xc", nc)
    scatter_f = sps.csc_matrix((np.ones(nf), (np.flatnonzero(free), np.arange(nf))), (n, nf))
    scatter_c = sps.csc_matrix((np.ones(nc), (np.flatnonzero(fixed), np.arange(nc))), (n, nc))
    x = ca.mtimes(ca.DM(scatter_f), xf) + ca.mtimes(ca.DM(scatter_c), xc)
    fg = ca.Function("fg", [problem["x"], problem["p"]], [problem["f"], problem["g"]])
    f, g = fg(x, problem["p"])
    sp = jac_sparsity
    J = sps.csc_matrix((np.ones(sp.nnz()), sp.row(), sp.colind()), (sp.size1(), sp.size2()))
    keep = np.asarray(abs(J.tocsr()[:, free]).sum(axis=1)).ravel() > 0
    return {"x": xf, "p": ca.vertcat(problem["p"], xc), "f": f,
            "g": g[np.flatnonzero(keep).tolist()]}, keep


def capped(build, args: dict, cap: float) -> dict:
    """``build()(**args)`` in a forked child given up after ``cap`` s of wall time: the library's
    :func:`casadrone.limit.watchdog.run_guarded`, whose stall limit is a wall-clock limit here
    (these solvers never call its ``beat``)."""
    def run() -> dict:
        S = build()
        out = S(**args)
        st = S.stats()
        return {"status": str(st.get("return_status", st.get("unified_return_status", "?"))),
                "success": bool(st.get("success", False)), "f": float(out["f"]),
                "it": st.get("iter_count"),
                "moved": float(np.abs(np.array(out["x"]).ravel() - args["x0"]).max())}

    g = run_guarded(run, stall_s=cap)
    if g.outcome == "ok":
        return g.value | {"cpu": g.cpu_s}
    status = f"given up after {cap:.0f} s" if g.outcome == "stalled" else \
        f"{g.outcome}: {' '.join(g.message.split())[-160:]}"
    return {"status": status, "success": False, "f": np.nan, "it": None,
            "cpu": g.cpu_s if g.outcome == "error" else np.nan, "moved": np.nan}


def available(name: str) -> str | None:
    """None when the solver ``name`` (its plugin and options) loads and solves a small NLP,
    else why not (one line)."""
    plugin, opts = SOLVERS[name]
    x = ca.MX.sym("x", 2)
    try:
        ca.nlpsol("probe", plugin, {"x": x, "f": ca.sumsqr(x - 1), "g": x[0] + x[1]},
                  opts)(x0=0, lbg=0, ubg=1)
    except RuntimeError as exc:
        lines = [ln.strip() for ln in str(exc).splitlines() if "Error code" in ln]
        return lines[0] if lines else " ".join(str(exc).split())[-160:]
    return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--solvers", default=",".join(SOLVERS))
    ap.add_argument("--cap", type=float, default=300.0, help="wall seconds per solve")
    args = ap.parse_args(argv)
    names = args.solvers.split(",")
    unit, problems, cold = cold_frames(args.n, args.seed)
    nlp = problems[0].full
    fixed = problems[0].box[0] == problems[0].box[1]
    red, keep = reduced_nlp(nlp.problem, fixed, ca.jacobian_sparsity(nlp.problem["g"],
                                                                      nlp.problem["x"]))
    free = ~fixed
    why = {name: available(name) for name in names}
    ok = [i for i, s in enumerate(cold) if s.success]
    rows: dict[str, list[dict]] = {"ipopt": [], **{k: [] for k in names if why[k] is None}}
    for i in ok:
        j = nearest(i, ok, unit)[0]
        pb, start = problems[i], cold[j].point
        c0 = cpu_time()
        ref = solve(pb.full, start.w, pb.P, *pb.box, warm=start, lbg=pb.rows[0], ubg=pb.rows[1])
        rows["ipopt"].append({"status": ref.return_status, "success": ref.success,
                              "f": ref.objective, "it": ref.iterations, "cpu": cpu_time() - c0})
        lbx, ubx = pb.box
        call = {"x0": np.clip(start.w, lbx, ubx)[free], "lam_x0": start.lam_x[free],
                "lam_g0": start.lam_g[keep], "p": np.r_[pb.P, lbx[fixed]],
                "lbx": lbx[free], "ubx": ubx[free], "lbg": pb.rows[0][keep],
                "ubg": pb.rows[1][keep]}
        line = [f"frame {i} from {j}: ipopt {ref.objective:.6f} {ref.iterations} it"]
        for name in rows:
            if name == "ipopt":
                continue
            plugin, opts = SOLVERS[name]
            r = capped(lambda p=plugin, o=opts: ca.nlpsol(f"nlp_{p}", p, red, o), call, args.cap)
            r["rel"] = abs(r["f"] - ref.objective) / ref.objective
            rows[name].append(r)
            line.append(f"{name}: {r['status']} {r['f']:.6f} it {r['it']} cpu {r['cpu']:.1f} s "
                        f"moved {r['moved']:.3g}")
        print(" | ".join(line), flush=True)
    print("\n".join(report(args, names, why, rows, int(fixed.sum()), int((~keep).sum()))))
    return 0


def report(args, names: list[str], why: dict, rows: dict, n_fixed: int, n_dropped: int
           ) -> list[str]:
    """The markdown section: a row per solver and frame."""
    lines = [markdown(), "",
             f"Command: `python benchmarks/bench_limitlap_nlpsols.py --n {args.n} --seed "
             f"{args.seed} --solvers {args.solvers} --cap {args.cap:g}` (paper track, 40 "
             f"intervals per leg, one core; warm from the nearest neighbour's primal-dual "
             f"optimum; {n_fixed} fixed variables substituted, {n_dropped} rows dropped).", "",
             "| solver | frame | status | iterations | CPU (s) | lap (s) | "
             "\\|lap − IPOPT\\| / IPOPT | largest move from the start |",
             "|---|---|---|---|---|---|---|---|"]
    for k, r in enumerate(rows["ipopt"]):
        lines.append(f"| IPOPT (far warm setting) | {k} | {r['status']} | {r['it']} | "
                     f"{r['cpu']:.2f} | {r['f']:.6f} | reference | – |")
    for name in names:
        if why[name] is not None:
            lines.append(f"| {name} | – | unavailable: {why[name]} | – | – | – | – | – |")
            continue
        for k, r in enumerate(rows[name]):
            rel = "–" if not np.isfinite(r["rel"]) else f"{100 * r['rel']:.4f} %"
            lap = "–" if not np.isfinite(r["f"]) else f"{r['f']:.6f}"
            cpu = "–" if not np.isfinite(r["cpu"]) else f"{r['cpu']:.2f}"
            status = r["status"].replace("|", "/")
            moved = "–" if not np.isfinite(r["moved"]) else f"{r['moved']:.3g}"
            lines.append(f"| {name} | {k} | {status} | {r['it'] if r['it'] is not None else '–'}"
                         f" | {cpu} | {lap} | {rel} | {moved} |")
    return lines


if __name__ == "__main__":
    raise SystemExit(main())
