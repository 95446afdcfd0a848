"""Benchmark: what a warm limit-lap solve costs at best, and why Newton-type active-set steps do
not lower it (none adopted).

Why. Issue 19 asks for a warm solve of ≤ 0.25 s (median, one core) from the nearest other
frame's optimum; IPOPT takes 1.2–1.5 s (43–48 iterations of ~25–30 ms). Earlier sections of
``RESULTS-limitlap-solvers.md`` tried other starts, settings, SQP with structure-exploiting QPs
and every NLP solver casadi 3.8 ships. This script measures the other side: the floor.

- **own**: each frame solved from its *own* primal-dual optimum, with the far warm setting (what
  every neighbour start gets) and the near one (:func:`casadrone.limit.nlp.warm_solver`); and
  IPOPT stopped after 0 and 1 iterations from there (the fixed cost of a solve: evaluations,
  MUMPS's analysis and first factorisation).
- **moved by r**: each frame moved by ± r of the Table 1 range in every key (seeded signs, as
  bench_limitlap_solvers.py's "near" rows; a move that makes an impossible frame, e.g. rotors
  that overlap, is drawn again) and solved from its own optimum (``solve(..., near=True)``): how
  close a start must be for the target.
- **neighbour**: from the nearest other frame's optimum (the benchmark's warm start), with its
  distance in the same measure (the largest key's move as a fraction of its range).
- ``--variants``: from the same neighbour, IPOPT with a limited-memory (L-BFGS) Hessian (no
  Hessian evaluations), and IPOPT on the NLP with ε Σ‖u_{i+1} − u_i‖² added to the lap (ε =
  1e-6 and 1e-4 s: a penalty on the commands' changes that gives the flat directions below a
  curvature of 2ε; the lap reported is the sum of the leg durations alone).
- **KKT at the optimum**: the reduced KKT matrix of each frame's own optimum on IPOPT's active
  set (a row or bound is active where its multiplier outweighs its distance, as a primal-dual
  active-set method would take it): its eigenvalues nearest zero (scipy's shift-invert Lanczos)
  against its largest, the share of their eigenvectors in the commands; and one full Newton step
  of the active-set method (KKT regularised by 1e-6 on the primal block) from the optimum: its
  largest move and the constraint violation after it. A local Newton/SQP method on the active
  set (semismooth Newton, primal-dual active set, SQP with an exact-Hessian QP) is well posed
  only if that matrix is far from singular.

For ``--n`` random Table 1 frames (SY250 template, paper track, 40 intervals per leg, one core,
CPU = process time; the seeds of bench_limitlap.py), each frame's cold optimum from its
point-mass start first. Run: ``python benchmarks/bench_limitlap_warmfloor.py [--n 10]
[--variants]`` (markdown on stdout).
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
import scipy.sparse.linalg as spla  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import cpu_time, markdown  # noqa: E402
from benchmarks.table1 import cold_frames, moved_problem, nearest  # noqa: E402
from casadrone.airframe import random_thetas  # noqa: E402
from casadrone.limit.nlp import (  # noqa: E402
    Nlp,
    NlpPoint,
    ipopt_options,
    ipopt_solver,
    solve,
    start_violation,
)

#: Regularisation of the KKT matrix's primal block in the Newton step (1/s² in the NLP's units)
NEWTON_DELTA = 1e-6
#: ... and of its dual block (−; the active rows need not be independent)
NEWTON_EPS = 1e-9
#: Shift of the shift-invert Lanczos iteration (the matrix itself may be singular)
SHIFT = 1e-9
#: Eigenvalues counted as "near zero", relative to the KKT matrix's largest
NEAR_ZERO = 1e-8


def _call(S: ca.Function, pb, start: NlpPoint) -> dict:
    """``S`` from the primal-dual ``start`` on ``pb``'s bounds: iterations, CPU, lap (the sum
    of the leg durations) and status."""
    lbx, ubx = pb.box
    c0 = cpu_time()
    out = S(x0=np.clip(start.w, lbx, ubx), lam_x0=start.lam_x, lam_g0=start.lam_g, p=pb.P,
            lbx=lbx, ubx=ubx, lbg=pb.rows[0], ubg=pb.rows[1])
    cpu = cpu_time() - c0
    st = S.stats()
    return {"it": int(st["iter_count"]), "cpu": cpu, "ok": bool(st["success"]),
            "status": str(st["return_status"]), "w": np.array(out["x"]).ravel()}


def lap_of(nlp: Nlp):
    """The lap (sum of the leg durations) of a decision vector: the objective is linear."""
    W, Pm = nlp.problem["x"], nlp.problem["p"]
    grad = ca.Function("lap_gradient", [W, Pm], [ca.gradient(nlp.problem["f"], W)])
    c = np.array(grad(np.zeros(W.numel()), np.zeros(Pm.numel()))).ravel()
    return lambda w: float(c @ w), c


def command_differences(nlp: Nlp) -> sps.csc_matrix:
    """D with D·w = the changes of each command from one interval to the next."""
    lay, nu, nx = nlp.layout, nlp.model.nu, nlp.model.nx
    per, M, nw = 1 + nu + nx, lay.n_intervals, nlp.problem["x"].numel()
    k, a = np.meshgrid(np.arange(M - 1), np.arange(nu), indexing="ij")
    r = np.arange(k.size)
    cols = np.r_[(k * per + 1 + a).ravel(), ((k + 1) * per + 1 + a).ravel()]
    return sps.csc_matrix((np.r_[-np.ones(r.size), np.ones(r.size)], (np.r_[r, r], cols)),
                          shape=(r.size, nw))


def regularised_solver(nlp: Nlp, eps: float) -> ca.Function:
    """IPOPT (far warm setting) on ``nlp`` with ε‖D w‖² added to the objective
    (:func:`command_differences`), its Hessian 2εDᵀD added to the library's."""
    D = command_differences(nlp)
    R = sps.triu(D.T @ D).tocsc()
    nw = R.shape[0]
    W, Pm = nlp.oracle["x"], nlp.oracle["p"]
    Dm = ca.DM(ca.Sparsity(D.shape[0], nw, D.indptr.tolist(), D.indices.tolist()),
               D.data.tolist())
    oracle = dict(nlp.oracle) | {"f": nlp.oracle["f"] + eps * ca.sumsqr(ca.mtimes(Dm, W))}
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", len(nlp.lbg))
    Rm = ca.DM(ca.Sparsity(nw, nw, R.indptr.tolist(), R.indices.tolist()),
               (2 * eps * R.data).tolist())
    H = nlp.derivatives["hess_lag"](W, Pm, lam_f, lam_g) + lam_f * Rm
    hess = ca.Function("nlp_hess_l", [W, Pm, lam_f, lam_g], [ca.triu(H)],
                       ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    opts = ipopt_options(nlp.tol, nlp.max_iter, True) | {
        "jac_g": nlp.derivatives["jac_g"], "hess_lag": hess}
    return ca.nlpsol(f"limit_regularised_{int(round(-np.log10(eps)))}", "ipopt",
                     oracle, opts)


def active_kkt(nlp: Nlp, pb, point: NlpPoint, c_lap: np.ndarray
               ) -> tuple[sps.csc_matrix, np.ndarray, np.ndarray, dict]:
    """The reduced KKT matrix at ``point`` on its active set (free variables; active rows that
    touch them; active bounds of free variables), the right-hand side of the primal-dual
    active-set Newton step (multipliers of the inactive constraints dropped), and the indices of
    the free variables; with the active set's sizes."""
    lbx, ubx = pb.box
    lbg, ubg = pb.rows
    w = np.clip(point.w, lbx, ubx)
    lg, lx = point.lam_g, point.lam_x
    g, J = nlp.derivatives["jac_g"](w, pb.P)
    g, J = np.array(g).ravel(), J.sparse().tocsr()
    Hu = nlp.derivatives["hess_lag"](w, pb.P, 1.0, lg).sparse()
    H = (Hu + Hu.T - sps.diags(Hu.diagonal())).tocsc()
    free = lbx < ubx
    eq = lbg == ubg
    up_g, lo_g = ~eq & (lg + g - ubg > 0), ~eq & (lg + g - lbg < 0)
    up_x, lo_x = free & (lx + w - ubx > 0), free & (lx + w - lbx < 0)
    fx = np.flatnonzero(free)
    Jf = J[:, free]
    rows = np.flatnonzero((eq | up_g | lo_g) & (np.diff(Jf.indptr) > 0))
    ax = np.flatnonzero((up_x | lo_x)[free])
    E = sps.csr_matrix((np.ones(len(ax)), (np.arange(len(ax)), ax)), shape=(len(ax), len(fx)))
    K = sps.bmat([[H[free][:, free], Jf[rows].T, E.T], [Jf[rows], None, None],
                  [E, None, None]], format="csc")
    b_g = np.where(up_g, ubg, lbg)[rows]
    b_x = np.where(up_x, ubx, lbx)[fx[ax]]
    r_l = c_lap[free] + Jf[rows].T @ lg[rows] + E.T @ lx[fx[ax]]
    rhs = -np.r_[r_l, g[rows] - b_g, w[fx[ax]] - b_x]
    sizes = {"rows": int(eq.sum()), "rows at a bound": int((up_g | lo_g).sum()),
             "bounds": int(len(ax)), "free": int(len(fx))}
    return K, rhs, fx, sizes


def kkt_at_optimum(nlp: Nlp, pb, point: NlpPoint, c_lap: np.ndarray, k: int = 60) -> dict:
    """Eigenvalues of the active-set KKT matrix nearest zero, the commands' share of their
    eigenvectors, and one full regularised Newton step of the active-set method from ``point``:
    its largest move and the violation after it."""
    K, rhs, fx, sizes = active_kkt(nlp, pb, point, c_lap)
    nf = len(fx)
    near, vecs = spla.eigsh(K, k=k, sigma=SHIFT, which="LM")
    top = float(np.abs(spla.eigsh(K, k=1, which="LM", return_eigenvectors=False))[0])
    per = 1 + nlp.model.nu + nlp.model.nx
    command = (fx % per >= 1) & (fx % per <= nlp.model.nu)
    small = np.abs(near) < NEAR_ZERO * top
    share = float(np.mean([np.sum(vecs[:nf, t][command] ** 2) / np.sum(vecs[:nf, t] ** 2)
                           for t in np.flatnonzero(small)])) if small.any() else np.nan
    reg = K + sps.block_diag([NEWTON_DELTA * sps.identity(nf),
                              -NEWTON_EPS * sps.identity(K.shape[0] - nf)]).tocsc()
    step = spla.splu(reg).solve(rhs)
    lbx, ubx = pb.box
    w = np.clip(point.w, lbx, ubx)
    w_new = w.copy()
    w_new[fx] += step[:nf]
    return {"n": K.shape[0], "smallest": float(np.min(np.abs(near))), "largest": top,
            "near_zero": int(small.sum()), "k": k, "command_share": share,
            "residual": float(np.max(np.abs(rhs))), "move": float(np.max(np.abs(step[:nf]))),
            "violation_before": start_violation(nlp, w, pb.P, *pb.rows),
            "violation_after": start_violation(nlp, w_new, pb.P, *pb.rows)} | sizes


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--radii", default="0.001,0.003,0.01,0.03",
                    help="moves of every key, as fractions of its Table 1 range")
    ap.add_argument("--variants", action="store_true",
                    help="L-BFGS and the regularised NLP from the neighbour's start")
    ap.add_argument("--kkt", type=int, default=3, help="frames whose KKT matrix is analysed")
    args = ap.parse_args(argv)
    radii = [float(r) for r in args.radii.split(",")]

    from casadrone.config.airframe import load_airframe
    from casadrone.config.io import load
    from casadrone.config.track import TrackConfig
    from casadrone.evaluate import DEFAULT_TRACK
    from casadrone.limit import lap as limit

    unit, problems, cold = cold_frames(args.n, args.seed)
    template = load_airframe("SY250")
    track = load(TrackConfig, DEFAULT_TRACK)
    options = limit.LimitLapOptions(intervals=limit.DEFAULT_INTERVALS["paper"])
    thetas, _ = random_thetas(template, args.n, args.seed)
    nlp = problems[0].full
    lap, c_lap = lap_of(nlp)
    stop0 = ipopt_solver(nlp, "limit_stop_0", {"max_iter": 0}, warm=True)
    stop1 = ipopt_solver(nlp, "limit_stop_1", {"max_iter": 1}, warm=True)
    variants = {"L-BFGS Hessian": ipopt_solver(
        nlp, "limit_lbfgs", {"hessian_approximation": "limited-memory"}, warm=True),
        **{f"ε = {e:g} s on the commands' changes": regularised_solver(nlp, e)
           for e in (1e-6, 1e-4)}} if args.variants else {}
    rng = np.random.default_rng(args.seed + 1)
    ok = [i for i, s in enumerate(cold) if s.success]
    rows: dict[str, list[dict]] = {}
    kkt: list[dict] = []

    def record(label: str, run: dict) -> None:
        rows.setdefault(label, []).append(run)

    for i in ok:
        pb, own = problems[i], cold[i].point
        ref = cold[i].objective
        for label, S in (("own optimum, stopped after 0 iterations", stop0),
                         ("own optimum, stopped after 1 iteration", stop1),
                         ("own optimum, far setting", nlp.warm),
                         ("own optimum, near setting", nlp.near)):
            r = _call(S, pb, own)
            record(label, r | {"rel": abs(lap(r["w"]) - ref) / ref})
        for r_ in radii:
            made = moved_problem(template, thetas[i], r_, rng, f"moved{i}", track, options)
            if made is None:
                continue
            moved = made[1]
            c0 = cpu_time()
            s = solve(moved.full, own.w, moved.P, *moved.box, warm=own, lbg=moved.rows[0],
                      ubg=moved.rows[1], near=True)
            record(f"own optimum, frame moved by {100 * r_:g} % of the range in every key",
                   {"it": s.iterations, "cpu": cpu_time() - c0, "ok": s.success,
                    "status": s.return_status, "rel": np.nan})
        j = nearest(i, ok, unit)[0]
        start = cold[j].point
        dist = float(np.max(np.abs(unit[i] - unit[j])))
        c0 = cpu_time()
        s = solve(pb.full, start.w, pb.P, *pb.box, warm=start, lbg=pb.rows[0], ubg=pb.rows[1],
                  near=True)
        base = s.objective
        record("nearest neighbour's optimum (the benchmark's warm start)",
               {"it": s.iterations, "cpu": cpu_time() - c0, "ok": s.success,
                "status": s.return_status, "rel": 0.0, "dist": dist})
        for label, S in variants.items():
            r = _call(S, pb, start)
            record(f"nearest neighbour's optimum, {label}",
                   r | {"rel": (lap(r["w"]) - base) / base, "dist": dist})
        if len(kkt) < args.kkt:
            kkt.append(kkt_at_optimum(nlp, pb, own, c_lap) | {"frame": i})
        print(f"frame {i}: " + "; ".join(f"{k[:40]} {v[-1]['it']} it {v[-1]['cpu']:.2f} s"
                                         for k, v in rows.items()), file=sys.stderr, flush=True)
    print("\n".join(report(args, rows, kkt, len(ok))))
    return 0


def report(args, rows: dict[str, list[dict]], kkt: list[dict], n_ok: int) -> list[str]:
    """The markdown tables: solves by start, then the KKT matrices."""
    cmd = f"python benchmarks/bench_limitlap_warmfloor.py --n {args.n} --seed {args.seed} " \
          f"--radii {args.radii} --kkt {args.kkt}" + (" --variants" if args.variants else "")
    lines = [markdown(), "", f"Command: `{cmd}` ({n_ok} frames whose cold solve converged; "
             "paper track, 40 intervals per leg, one core).", "",
             "| start | solved | iterations median (range) | CPU median / max (s) | "
             "frames ≤ 0.25 s | lap against the reference |", "|---|---|---|---|---|---|"]
    for label, runs in rows.items():
        it = np.array([r["it"] for r in runs])
        cpu = np.array([r["cpu"] for r in runs])
        rel = np.array([r["rel"] for r in runs], float)
        if "neighbour's optimum," in label:
            against = f"{100 * np.median(rel):+.4f} % median, {100 * rel.min():+.4f} to " \
                      f"{100 * rel.max():+.4f} % (against the library's solve from the same start)"
        elif np.isfinite(rel).any():
            against = f"≤ {100 * np.nanmax(rel):.4f} % (against the frame's cold optimum)"
        else:
            against = "–"
        dists = [r["dist"] for r in runs if "dist" in r]
        if dists and "(the benchmark" in label:
            against = "reference; the neighbour's largest key moved by " \
                      f"{100 * np.median(dists):.0f} % of its range (median; " \
                      f"{100 * min(dists):.0f}–{100 * max(dists):.0f} %)"
        solved = "stopped" if "stopped" in label else f"{sum(r['ok'] for r in runs)}/{len(runs)}"
        lines.append(f"| {label} | {solved} | "
                     f"{np.median(it):g} ({it.min()}–{it.max()}) | {np.median(cpu):.2f} / "
                     f"{cpu.max():.2f} | {int(np.sum(cpu <= 0.25))}/{len(runs)} | {against} |")
    if kkt:
        lines += ["", "The reduced KKT matrix of the frame's own optimum on its active set, and "
                  "one Newton step of the active-set method from there:", "",
                  "| frame | size (free variables; equality rows, rows at a bound, bounds) | "
                  f"eigenvalues below {NEAR_ZERO:g} × the largest, of the {kkt[0]['k']} "
                  "nearest zero | smallest / largest \\|eigenvalue\\| | commands' share of "
                  "those eigenvectors | KKT residual at the optimum | Newton step: largest move "
                  "| violation before → after |", "|---|---|---|---|---|---|---|---|"]
        for d in kkt:
            lines.append(
                f"| {d['frame']} | {d['n']} ({d['free']}; {d['rows']}, {d['rows at a bound']}, "
                f"{d['bounds']}) | {d['near_zero']} | {d['smallest']:.1e} / {d['largest']:.1e} "
                f"| {100 * d['command_share']:.0f} % | {d['residual']:.1e} | {d['move']:.3g} | "
                f"{d['violation_before']:.1e} → {d['violation_after']:.2g} |")
    return lines


if __name__ == "__main__":
    raise SystemExit(main())
