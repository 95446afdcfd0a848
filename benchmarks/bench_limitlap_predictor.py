"""Benchmark: a tangent predictor before IPOPT's warm solve of the limit lap (not adopted).

Why. A warm solve starts from a neighbouring frame's optimum w*(P) at the new frame's
parameters P'. Between the two the optimum moves along the solution path; one Newton step on
the KKT conditions of the *new* problem from (w*, λ*), with the barrier terms of the old
solution's active bounds and rows (IPOPT's own primal-dual matrix at convergence, as in sIPOPT:
Pirnay, López-Negrete & Biegler 2012, Math. Prog. Comp. 4, 307), predicts w*(P') to second
order in |P' − P| while the active set does not change. IPOPT would then start from a point
whose constraint violation is O(|P' − P|²) instead of O(|P' − P|).

The step solves

    [ H + Σ_x    Jᵀ     ] [Δw]     [ ∇f + Jᵀλ_g + λ_x ]
    [ J         −Σ_g⁻¹  ] [Δλ] = − [ g(w*, P') − b     ]

with H the Lagrangian Hessian and J the row Jacobian of the new problem at w* (the NLP's own
compiled blocks), Σ = |λ| / gap for each bound and inequality row (gap floored at 1e-9 / |λ|:
IPOPT's final μ), b the active bound of each row (equality rows: their value; inactive rows
drop out with Σ_g ≈ 0). SuperLU factorises it once.

What this measures, for ``--n`` random Table 1 frames (the seeds of bench_limitlap.py, SY250
template, paper track, 40 intervals per leg): each frame's cold optimum (closed-loop guess) is
the warm start of the same frame moved by each of ``--moves`` (fractions of the Table 1 range in
every key, alternating signs), and of its nearest other frame. For each: the start's largest
constraint violation before and after the predictor, and IPOPT's iterations and lap from both
(``solve(..., near=True)``: the warm setting chosen by the violation).

Run: ``python benchmarks/bench_limitlap_predictor.py [--n 6] [--moves 1e-4,1e-3,1e-2]``
(a markdown table on stdout).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse as sps  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import markdown  # noqa: E402
from benchmarks.table1 import frame_problem, nearest, unit_positions  # noqa: E402
from casadrone.airframe import TABLE1_BOUNDS, random_thetas  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK  # noqa: E402
from casadrone.limit import lap as limit  # noqa: E402
from casadrone.limit.nlp import NlpPoint, solve, start_violation  # noqa: E402

#: IPOPT's barrier parameter at convergence (tol 1e-8): the floor of a bound's gap × |λ|.
MU_FINAL = 1e-9
#: Largest barrier weight Σ (an active bound: the variable stays on it).
SIGMA_CAP = 1e12


def _objective_gradient(nlp) -> np.ndarray:
    """∇f of the limit lap: f is the sum of the legs' durations, linear in w."""
    import casadi as ca

    x, p = nlp.problem["x"], nlp.problem["p"]
    grad = ca.Function("grad_f", [x, p], [ca.gradient(nlp.problem["f"], x)])
    return np.array(grad(np.zeros(x.numel()), np.zeros(p.numel()))).ravel()


def predict(nlp, point: NlpPoint, P: np.ndarray, lbx: np.ndarray, ubx: np.ndarray,
            lbg: np.ndarray, ubg: np.ndarray) -> NlpPoint:
    """One Newton step on the KKT conditions at ``P`` from ``point`` (module docstring)."""
    w, lam_x, lam_g = point.w, point.lam_x, point.lam_g
    g, J = nlp.derivatives["jac_g"](w, P)
    g = np.array(g).ravel()
    J = sps.csc_matrix(J.sparse())
    upper = sps.csc_matrix(nlp.derivatives["hess_lag"](w, P, 1.0, lam_g).sparse())
    H = upper + upper.T - sps.diags(upper.diagonal())

    def sigma(lam, gap):
        floor = MU_FINAL / np.maximum(np.abs(lam), 1e-300)
        return np.minimum(np.abs(lam) / np.maximum(gap, floor), SIGMA_CAP)

    s_x = sigma(lam_x, np.where(lam_x < 0, w - lbx, ubx - w))
    eq = lbg == ubg
    s_g = sigma(lam_g, np.where(lam_g < 0, g - lbg, ubg - g))
    d_g = np.where(eq, 0.0, 1.0 / np.maximum(s_g, 1.0 / SIGMA_CAP))
    active = np.where(lam_g < 0, lbg, ubg)
    r_g = np.where(eq, g - lbg, np.where(s_g > 1.0 / SIGMA_CAP, g - active, 0.0))
    r_w = J.T @ lam_g + lam_x + _objective_gradient(nlp)
    K = sps.bmat([[H + sps.diags(s_x + 1e-10), J.T], [J, -sps.diags(d_g + 1e-12)]],
                 format="csc")
    step = spla.splu(K).solve(-np.r_[r_w, r_g])
    return NlpPoint(np.clip(w + step[:len(w)], lbx, ubx), lam_x, lam_g + step[len(w):],
                    point.lam_p)


def _measure(pb, start: NlpPoint) -> dict:
    lbx, ubx = pb.box
    before = start_violation(pb.full, np.clip(start.w, lbx, ubx), pb.P, *pb.rows)
    plain = solve(pb.full, start.w, pb.P, lbx, ubx, warm=start, lbg=pb.rows[0],
                  ubg=pb.rows[1], near=True)
    c0 = time.process_time()
    try:
        predicted = predict(pb.full, start, pb.P, lbx, ubx, *pb.rows)
    except RuntimeError:  # SuperLU: singular
        return {"before": before, "after": np.inf, "plain": plain, "pred": None, "cpu": 0.0}
    cpu = time.process_time() - c0
    after = start_violation(pb.full, predicted.w, pb.P, *pb.rows)
    pred = solve(pb.full, predicted.w, pb.P, lbx, ubx, warm=predicted, lbg=pb.rows[0],
                 ubg=pb.rows[1], near=True)
    return {"before": before, "after": after, "plain": plain, "pred": pred, "cpu": cpu}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=6)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--moves", default="1e-4,1e-3,1e-2")
    args = ap.parse_args(argv)
    template = load_airframe("SY250")
    track = load(TrackConfig, DEFAULT_TRACK)
    options = limit.LimitLapOptions(intervals=limit.DEFAULT_INTERVALS["paper"])
    thetas, _ = random_thetas(template, args.n, args.seed)
    keys = list(thetas[0])
    span = np.array([TABLE1_BOUNDS[k][1] - TABLE1_BOUNDS[k][0] for k in keys])
    unit = unit_positions(thetas)
    problems, optima = [], []
    for i, theta in enumerate(thetas):
        _, pb = frame_problem(template, theta, f"frame{i}", track, options)
        traj = limit.closed_loop_lap(pb.frame, track, None)  # the default controller
        w0 = limit.guess_from_trajectory(pb.full, traj, pb.x0) if traj is not None else \
            limit.straight_guess(pb.full, pb.targets.route, pb.x0)
        problems.append(pb)
        optima.append(solve(pb.full, w0, pb.P, *pb.box, lbg=pb.rows[0], ubg=pb.rows[1]))
    lines = ["| start | violation before → after the predictor (median; max) | predictor CPU "
             "(s) | IPOPT iterations without / with (median) | same lap (≤ 0.01 %) | "
             "with the predictor faster |", "|---|---|---|---|---|---|"]
    moves = [float(m) for m in args.moves.split(",")]
    for label in [*(f"own optimum, moved {m:g} of the range" for m in moves),
                  "nearest other frame's optimum"]:
        runs = []
        for i, theta in enumerate(thetas):
            if label.startswith("own"):
                m = moves[[f"own optimum, moved {x:g} of the range" for x in moves].index(label)]
                sign = np.where(np.arange(len(keys)) % 2, -1.0, 1.0)
                moved = {k: float(np.clip(theta[k] + sign[j] * m * span[j], *TABLE1_BOUNDS[k]))
                         for j, k in enumerate(keys)}
                _, pb = frame_problem(template, moved, f"moved{i}", track, options)
                start = optima[i]
            else:
                j = nearest(i, range(args.n), unit)[0]
                pb, start = problems[i], optima[j]
            if not start.success:
                continue
            runs.append(_measure(pb, start.point))
            r = runs[-1]
            print(label, i, f"{r['before']:.3g} -> {r['after']:.3g}", r["plain"].iterations,
                  None if r["pred"] is None else r["pred"].iterations, flush=True)
        ok = [r for r in runs if r["pred"] is not None and r["pred"].success and r["plain"].success]
        same = sum(abs(r["pred"].objective - r["plain"].objective) <= 1e-4 * r["plain"].objective
                   for r in ok)
        faster = sum(r["pred"].iterations < r["plain"].iterations for r in ok)
        med = np.median
        lines.append(
            f"| {label} | {med([r['before'] for r in runs]):.2g} → "
            f"{med([r['after'] for r in runs]):.2g}; {max(r['before'] for r in runs):.2g} → "
            f"{max(r['after'] for r in runs):.2g} | {med([r['cpu'] for r in runs]):.3f} | "
            f"{med([r['plain'].iterations for r in ok]):.0f} / "
            f"{med([r['pred'].iterations for r in ok]):.0f} | {same}/{len(ok)} | "
            f"{faster}/{len(ok)} |")
    print("\n".join(["", markdown(), "", f"`python benchmarks/bench_limitlap_predictor.py --n "
                     f"{args.n} --seed {args.seed} --moves {args.moves}`", "", *lines]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
