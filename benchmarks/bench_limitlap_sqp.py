"""Limit-lap warm solves: IPOPT against an SQP whose QPs exploit the stage structure (HPIPM).

An experiment for issue 19, item 5 (warm ≤ 0.25 s median on one core). ``n`` random Table 1
frames around the template are solved cold by IPOPT from their closed-loop guesses; each is then
solved warm from its nearest neighbour's primal-dual optimum (the search's case, as in
``bench_limitlap_solvers.py``) by IPOPT (the far warm setting, the reference) and by the SQP of
this script in each ``--variants`` setting. Same NLP, same compiled interval blocks: the SQP works
on the stage-ordered permutation of :mod:`casadrone.limit.stagewise`.

The SQP (kept here, not in the package: it does not beat IPOPT, see
``RESULTS-limitlap-solvers.md``, "SQP with HPIPM"):

- QP: HPIPM (Frison & Diehl, IFAC 2020; casadi's ``hpipm`` conic plugin), a Riccati-based
  interior-point QP solver, given the stage sizes of :class:`~casadrone.limit.stagewise.StageOrder`
  (``N``, ``nx``, ``nu``, ``ng``); ``mode`` robust, ``iter_max`` ``--qp-iter`` (HPIPM's default
  of 15 stops most of these QPs early), residual tolerances ``--qp-tol``.
- Hessian: the exact Lagrangian Hessian, indefinite, convexified per stage block
  (``clip``: eigenvalues below δ raised to δ; ``mirror``: |λ|, at least δ; acados'
  ``PROJECT``/``MIRROR``), or along the backward Riccati recursion (``riccati``: the reduced
  matrix H_k + [A B]ᵀP[A B] clipped, as acados' ``PROJECT_REDUC_HESS``, Verschueren et al.,
  "A sparsity preserving convexification procedure for indefinite quadratic programs arising
  in direct optimal control", SIAM J. Optim. 2017); ``exact-ipopt`` hands the exact Hessian to
  IPOPT as the QP solver (a diagnostic: slow).
- Globalisation: ℓ1 merit f + ν‖c‖₁ with ν ≥ 1.5 × the largest QP multiplier, Armijo
  backtracking (Nocedal & Wright, Numerical Optimization, 2nd ed., §18.3).
- Stop: largest violation (rows and box, the NLP's units) ≤ 1e-6 and stationarity
  ‖∇f + Jᵀλ_g + λ_x‖∞ ≤ 1e-6; or ``--max-iter``.

Per solve: iterations, CPU (process time), lap, |lap − IPOPT| / IPOPT lap from the same start,
final violation, and the first iteration (and its CPU) at which the lap is within 0.01 % of
IPOPT's with violation ≤ 1e-6.

Run: ``python benchmarks/bench_limitlap_sqp.py [--n 10] [--seed 0] [--variants clip,mirror]``.
Prints a markdown section.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import contextlib  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import casadi as ca  # noqa: E402
import numpy as np  # noqa: E402
import scipy.sparse as sps  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import markdown  # noqa: E402
from benchmarks.table1 import frame_problem, nearest, unit_positions  # noqa: E402
from casadrone.airframe import build_airframe, random_thetas  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK  # noqa: E402
from casadrone.limit import lap as limit  # noqa: E402
from casadrone.limit.nlp import solve, start_violation  # noqa: E402
from casadrone.limit.stagewise import fatrop_solver, stagewise_functions  # noqa: E402

TOL = 1e-6
SAME = 1e-4  # 0.01 % of the lap


@dataclass(frozen=True)
class Variant:
    """One SQP setting: the convexification and its δ, the QP solver."""

    convexify: str  # clip | mirror | riccati | exact
    delta: float = 1e-4
    qp: str = "hpipm"  # hpipm | ipopt

    @staticmethod
    def parse(text: str) -> Variant:
        """``clip``, ``clip:1e-2``, ``mirror``, ``riccati``, ``exact-ipopt``."""
        if text == "exact-ipopt":
            return Variant("exact", 0.0, "ipopt")
        name, _, delta = text.partition(":")
        if name not in ("clip", "mirror", "riccati"):
            raise SystemExit(f"bench_limitlap_sqp: unknown variant {text!r}")
        return Variant(name, float(delta) if delta else 1e-4)

    @property
    def label(self) -> str:
        return "exact Hessian, IPOPT as QP solver" if self.qp == "ipopt" else \
            f"{self.convexify} δ={self.delta:g}, HPIPM"


@contextlib.contextmanager
def quiet_stdout():
    """casadi's HPIPM interface prints its return flag on the C stdout at every QP."""
    sys.stdout.flush()
    saved = os.dup(1)
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    try:
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)


class StageSqp:
    """The stage-ordered functions of one NLP and its QP solver (built once per variant)."""

    def __init__(self, nlp, variant: Variant, qp_iter: int, qp_tol: float):
        self.variant = variant
        self.order = fatrop_solver(nlp, nlp.tol, nlp.max_iter).order
        fn = stagewise_functions(nlp.problem, nlp.derivatives["jac_g"],
                                 nlp.derivatives["hess_lag"], self.order)
        self.jac, self.g, self.hess = fn["nlp_jac_g"], fn["nlp_g"], fn["hess_only"]
        self.grad_f = fn["nlp_grad_f"]
        o = self.order
        self.sizes = [int(a + b) for a, b in zip(o.nx, o.nu, strict=True)]
        self.starts = np.r_[0, np.cumsum(self.sizes)[:-1]]
        # the QP's Hessian: dense stage blocks (a convexified block is dense)
        self.Hsp = ca.diagcat(*[ca.DM.ones(s, s) for s in self.sizes]).sparsity()
        assert (self.hess.sparsity_out(0) + self.Hsp).nnz() == self.Hsp.nnz()
        Asp = self.jac.sparsity_out(1)
        if variant.qp == "ipopt":
            opts = {"nlpsol": "ipopt", "error_on_fail": False, "print_time": False,
                    "nlpsol_options": {"ipopt.print_level": 0, "print_time": False,
                                       "ipopt.sb": "yes", "ipopt.tol": qp_tol,
                                       "ipopt.mu_strategy": "adaptive"}}
            self.qp = ca.conic("sqp_qp", "nlpsol", {"h": self.Hsp, "a": Asp}, opts)
        else:
            opts = {"N": len(o.nx) - 1, "nx": list(o.nx), "nu": list(o.nu), "ng": list(o.ng),
                    "print_time": False, "error_on_fail": False,
                    "hpipm": {"mode": "robust", "iter_max": qp_iter, "res_g_max": qp_tol,
                              "res_b_max": qp_tol, "res_d_max": qp_tol, "res_m_max": qp_tol}}
            self.qp = ca.conic("sqp_qp", "hpipm", {"h": self.Hsp, "a": Asp}, opts)
        # the gap rows of stage k start at row0[k] (stage order: gap_k, then path_k)
        self.row0 = np.r_[0, np.cumsum([o.nx[k + 1] + o.ng[k] for k in range(len(o.nx) - 1)])]

    def _block(self, H: sps.csr_matrix, k: int) -> np.ndarray:
        a, s = self.starts[k], self.sizes[k]
        return H[a:a + s, a:a + s].toarray()

    def _clip(self, M: np.ndarray) -> np.ndarray:
        ev, V = np.linalg.eigh(M)
        delta = self.variant.delta
        ev = np.maximum(np.abs(ev), delta) if self.variant.convexify == "mirror" else \
            np.maximum(ev, delta)
        return (V * ev) @ V.T

    def qp_hessian(self, H: sps.csc_matrix, J: sps.csc_matrix) -> np.ndarray:
        """Nonzeros (in Hsp's column-major order) of the QP's stage-block Hessian."""
        Hr = H.tocsr()
        n, kind = len(self.sizes), self.variant.convexify
        if kind == "exact":
            blocks = [self._block(Hr, k) for k in range(n)]
        elif kind in ("clip", "mirror"):
            blocks = [self._clip(self._block(Hr, k)) for k in range(n)]
        else:  # riccati: clip the reduced matrix of the backward recursion
            Jr, o = J.tocsr(), self.order
            blocks = [np.zeros(0)] * n
            P = None
            for k in range(n - 1, -1, -1):
                a, s, nxk = self.starts[k], self.sizes[k], o.nx[k]
                C = np.zeros((s, s))
                if P is not None:  # x_{k+1} = A x_k + B u_k: the gap rows carry −[A B]
                    AB = -Jr[self.row0[k]:self.row0[k] + o.nx[k + 1], a:a + s].toarray()
                    C = AB.T @ P @ AB
                M = self._clip(self._block(Hr, k) + C)
                blocks[k] = M - C
                P = M[:nxk, :nxk] - (M[:nxk, nxk:] @ np.linalg.solve(M[nxk:, nxk:], M[nxk:, :nxk])
                                     if s > nxk else 0.0)
                P = 0.5 * (P + P.T)
        return np.concatenate([b.ravel(order="F") for b in blocks])


def _violation(g, lbg, ubg, w, lbx, ubx) -> tuple[float, float]:
    """(largest, sum of) the row and box violations."""
    vg = np.maximum(lbg - g, 0) + np.maximum(g - ubg, 0)
    vx = np.maximum(lbx - w, 0) + np.maximum(w - ubx, 0)
    return float(max(vg.max(initial=0), vx.max(initial=0))), float(vg.sum() + vx.sum())


def solve_sqp(sq: StageSqp, point, P, lbx, ubx, lbg, ubg, max_iter: int) -> dict:
    """SQP from a primal-dual point (NLP order); the per-iteration history (lap, violation,
    stationarity, step, cumulative CPU) and the CPU split."""
    c0 = time.process_time()
    o = sq.order
    lg, ug = o.to_stage(lbg, rows=True), o.to_stage(ubg, rows=True)
    lx, ux = o.free_box(o.to_stage(lbx), o.to_stage(ubx), lg, ug)
    w = np.clip(o.to_stage(point.w), lx, ux)
    lam_g, lam_x = o.to_stage(point.lam_g, rows=True), o.to_stage(point.lam_x)
    grad_f = np.array(sq.grad_f(w, P)).ravel()  # f is a sum of leg durations: linear
    cpu = dict.fromkeys(("jac", "hess", "convexify", "qp", "line search"), 0.0)
    hist: list[dict] = []
    status, nu_pen, qp_fail = "max_iter", 1.0, 0
    for it in range(max_iter + 1):
        t = time.process_time()
        gk, Jk = sq.jac(w, P)
        g, J = np.array(gk).ravel(), Jk.sparse()
        cpu["jac"] += time.process_time() - t
        pr, pr1 = _violation(g, lg, ug, w, lx, ux)
        du = float(np.abs(grad_f + J.T @ lam_g + lam_x).max())
        hist.append({"f": float(grad_f @ w), "pr": pr, "du": du,
                     "cpu": time.process_time() - c0})
        if pr <= TOL and du <= TOL:
            status = "converged"
            break
        if it == max_iter or not np.all(np.isfinite(g)):
            status = status if np.all(np.isfinite(g)) else "NaN in g"
            break
        t = time.process_time()
        H = sq.hess(w, P, 1.0, lam_g).sparse()
        cpu["hess"] += time.process_time() - t
        t = time.process_time()
        hnz = sq.qp_hessian(H, J)
        cpu["convexify"] += time.process_time() - t
        t = time.process_time()
        with quiet_stdout():
            out = sq.qp(h=ca.DM(sq.Hsp, hnz), g=grad_f, a=Jk, lba=lg - g, uba=ug - g,
                        lbx=lx - w, ubx=ux - w, x0=np.zeros(len(w)))
        qp_fail += not sq.qp.stats().get("success", False)
        cpu["qp"] += time.process_time() - t
        d = np.array(out["x"]).ravel()
        lam_g_qp, lam_x_qp = np.array(out["lam_a"]).ravel(), np.array(out["lam_x"]).ravel()
        if not np.all(np.isfinite(d)):
            status = "QP step not finite"
            break
        t = time.process_time()
        nu_pen = max(nu_pen, 1.5 * float(max(np.abs(lam_g_qp).max(), np.abs(lam_x_qp).max())))
        phi0, dphi = hist[-1]["f"] + nu_pen * pr1, float(grad_f @ d) - nu_pen * pr1
        alpha = 1.0
        for _ in range(20):
            gt = np.array(sq.g(w + alpha * d, P)).ravel()
            if np.all(np.isfinite(gt)):
                phi = float(grad_f @ (w + alpha * d)) + nu_pen * _violation(
                    gt, lg, ug, w + alpha * d, lx, ux)[1]
                if phi <= phi0 + 1e-4 * alpha * min(dphi, 0.0):
                    break
            alpha *= 0.5
        cpu["line search"] += time.process_time() - t
        w = np.clip(w + alpha * d, lx, ux)
        lam_g += alpha * (lam_g_qp - lam_g)
        lam_x += alpha * (lam_x_qp - lam_x)
        hist[-1] |= {"alpha": alpha, "step": float(np.abs(d).max()),
                     "qp_it": int(sq.qp.stats().get("iter_count", 0))}
    return {"status": status, "f": hist[-1]["f"], "it": len(hist) - 1, "pr": hist[-1]["pr"],
            "cpu": time.process_time() - c0, "hist": hist, "split": cpu, "qp_fail": qp_fail}


def _first_same(hist: list[dict], f_ref: float) -> tuple[int | None, float | None]:
    """First iteration (and its CPU) with the lap within 0.01 % of f_ref and violation ≤ tol."""
    for k, h in enumerate(hist):
        if abs(h["f"] - f_ref) / f_ref <= SAME and h["pr"] <= TOL:
            return k, h["cpu"]
    return None, None


def spectrum(sq: StageSqp, pb, point) -> list[str]:
    """Eigenvalues of the exact Hessian's stage blocks at a primal-dual point, and of the
    reduced Hessian on the active set estimated by distance to the bounds (IPOPT's interior
    point sits near its active bounds, not on them), exact and as the QP sees it."""
    import scipy.linalg as sla

    o, (lbx, ubx) = sq.order, pb.box
    w = o.to_stage(point.w)
    H = sq.hess(w, pb.P, 1.0, o.to_stage(point.lam_g, rows=True)).sparse()
    eig = [np.linalg.eigvalsh(sq._block(H.tocsr(), k)) for k in range(len(sq.sizes))]
    neg = [int(np.sum(e < -1e-8)) for e in eig]
    out = [f"{len(eig)} stage blocks of {min(sq.sizes)}–{max(sq.sizes)} variables; negative "
           f"eigenvalues per block median {np.median(neg):.0f} (max {max(neg)}, blocks with "
           f"any {sum(n > 0 for n in neg)}); smallest eigenvalue per block median "
           f"{np.median([e.min() for e in eig]):.3g} (min {min(e.min() for e in eig):.3g}), "
           f"largest median {np.median([e.max() for e in eig]):.3g}; {len(w)} variables "
           f"({int(np.sum(lbx == ubx))} fixed), {int(np.sum(pb.rows[0] == pb.rows[1]))} "
           "equality rows."]
    g = np.asarray(sq.g(w, pb.P)).ravel()
    J = sq.jac(w, pb.P)[1]
    Hc = ca.DM(sq.Hsp, sq.qp_hessian(H, J.sparse())).full()  # the QP's Hessian
    lg, ug = o.to_stage(pb.rows[0], rows=True), o.to_stage(pb.rows[1], rows=True)
    slack = np.minimum(w - o.to_stage(lbx), o.to_stage(ubx) - w)
    for tol in (1e-6, 1e-5, 1e-4):
        rows = (lg == ug) | (g - lg < tol) | (ug - g < tol)
        Z = sla.null_space(np.vstack([J.full()[rows], np.eye(len(w))[slack < tol]]))
        red = np.linalg.eigvalsh(Z.T @ H.toarray() @ Z) if Z.shape[1] else np.zeros(1)
        red_qp = np.linalg.eigvalsh(Z.T @ Hc @ Z) if Z.shape[1] else np.zeros(1)
        out.append(f"active = within {tol:g} of a bound: {int(np.sum(slack < tol))} variables, "
                   f"{int(np.sum(rows & (lg < ug)))} inequality rows; reduced Hessian on "
                   f"{Z.shape[1]} directions: eigenvalues {red.min():.3g} to {red.max():.3g} "
                   f"({int(np.sum(red < 1e-6))} below 1e-6); with the QP's Hessian "
                   f"({sq.variant.label}) {red_qp.min():.3g} to {red_qp.max():.3g}.")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=10)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--template", default="SY250")
    ap.add_argument("--variants", default="clip,mirror,clip:1e-2",
                    help="comma-separated: clip[:δ], mirror[:δ], riccati[:δ], exact-ipopt")
    ap.add_argument("--max-iter", type=int, default=40)
    ap.add_argument("--qp-iter", type=int, default=100, help="HPIPM's iter_max")
    ap.add_argument("--qp-tol", type=float, default=1e-6, help="HPIPM's residual tolerances")
    ap.add_argument("--trace", action="store_true",
                    help="print every SQP iteration (lap, violation, stationarity, step)")
    ap.add_argument("--spectrum", action="store_true",
                    help="only the exact Hessian's stage-block eigenvalues at the cold optimum "
                    "of the first frame whose solve succeeded (not 'acceptable')")
    args = ap.parse_args(argv)
    variants = [Variant.parse(v) for v in args.variants.split(",")]
    template = load_airframe(args.template)
    track = load(TrackConfig, DEFAULT_TRACK)
    kind = build_airframe(template).propulsion
    options = limit.LimitLapOptions(intervals=limit.DEFAULT_INTERVALS.get(kind, 40))
    thetas, _ = random_thetas(template, args.n, args.seed)
    unit = unit_positions(thetas)
    problems, cold = [], []
    for i, theta in enumerate(thetas):
        frame, pb = frame_problem(template, theta, f"frame{i}", track, options)
        traj = limit.closed_loop_lap(frame, track, None)  # the default controller
        w0 = limit.guess_from_trajectory(pb.full, traj, pb.x0) if traj is not None else \
            limit.straight_guess(pb.full, pb.targets.route, pb.x0)
        problems.append(pb)
        s = solve(pb.full, w0, pb.P, *pb.box, lbg=pb.rows[0], ubg=pb.rows[1])
        cold.append(s)
        print(f"cold {i}: {s.return_status} {s.objective:.6f} {s.iterations} it", flush=True)
        if args.spectrum and s.return_status == "Solve_Succeeded":
            print("\n".join(spectrum(StageSqp(pb.full, variants[0], args.qp_iter,
                                                args.qp_tol), pb, s.point)))
            return 0
    ok = [i for i, s in enumerate(cold) if s.success]
    solvers = {v: StageSqp(problems[0].full, v, args.qp_iter, args.qp_tol) for v in variants}
    rows: dict[str, list[dict]] = {"ipopt": [], **{v.label: [] for v in variants}}
    for i in ok:
        j = nearest(i, ok, unit)[0]
        pb, start = problems[i], cold[j].point
        v0 = start_violation(pb.full, np.clip(start.w, *pb.box), pb.P, *pb.rows)
        c = time.process_time()
        ref = solve(pb.full, start.w, pb.P, *pb.box, warm=start, lbg=pb.rows[0],
                    ubg=pb.rows[1])
        rows["ipopt"].append({"frame": i, "ok": ref.success, "f": ref.objective,
                              "it": ref.iterations, "cpu": time.process_time() - c,
                              "start_violation": v0})
        line = [f"warm {i} from {j} (violation {v0:.2f}): ipopt {ref.objective:.6f} "
                f"{ref.iterations} it {rows['ipopt'][-1]['cpu']:.2f} s"]
        for v, sq in solvers.items():
            r = solve_sqp(sq, start, pb.P, *pb.box, *pb.rows, args.max_iter)
            if args.trace:
                print(f"frame {i}, {v.label}: iteration lap violation stationarity step "
                      "alpha HPIPM-iterations")
                for k, h in enumerate(r["hist"]):
                    print(f"  {k} {h['f']:.6f} {h['pr']:.2e} {h['du']:.2e} "
                          f"{h.get('step', 0):.3g} {h.get('alpha', 0):.3g} {h.get('qp_it', 0)}")
            k, ck = _first_same(r["hist"], ref.objective)
            rows[v.label].append(r | {"frame": i, "ok": r["status"] == "converged",
                                      "rel": abs(r["f"] - ref.objective) / ref.objective,
                                      "same_it": k, "same_cpu": ck})
            line.append(f"{v.label}: {r['status']} {r['f']:.6f} {r['it']} it "
                        f"{r['cpu']:.2f} s, rel {100 * rows[v.label][-1]['rel']:.4f} %, "
                        f"0.01 % at {k}")
        print(" | ".join(line), flush=True)
    print("\n".join(report(args, variants, rows)))
    return 0


def report(args, variants: list[Variant], rows: dict[str, list[dict]]) -> list[str]:
    """The markdown section: one row per solver, then the CPU split of the SQP."""
    med = np.median
    lines = [markdown(), "",
             f"Command: `python benchmarks/bench_limitlap_sqp.py --n {args.n} --seed {args.seed} "
             f"--template {args.template} --variants {args.variants} --max-iter {args.max_iter} "
             f"--qp-iter {args.qp_iter} --qp-tol {args.qp_tol:g}` (paper track, one core, "
             "CPU = process time; warm from the nearest neighbour's primal-dual optimum).", "",
             "| solver | converged (tol 1e-6) | iterations, median | CPU median / max (s) | "
             "CPU per iteration (ms) | \\|lap − IPOPT\\| / IPOPT, median / max | within 0.01 % "
             "and violation ≤ 1e-6 by the end | iterations (CPU) to get there, median |",
             "|---|---|---|---|---|---|---|---|"]
    ref = rows["ipopt"]
    lines.append(f"| IPOPT (far warm setting) | {sum(r['ok'] for r in ref)}/{len(ref)} | "
                 f"{med([r['it'] for r in ref]):.0f} | {med([r['cpu'] for r in ref]):.2f} / "
                 f"{max(r['cpu'] for r in ref):.2f} | "
                 f"{1e3 * med([r['cpu'] / max(r['it'], 1) for r in ref]):.1f} | reference | "
                 "– | – |")
    for v in variants:
        rs = rows[v.label]
        rel = np.array([r["rel"] for r in rs])
        reached = [r for r in rs if r["same_it"] is not None]
        to = "–"
        if reached:
            to = (f"{med([r['same_it'] for r in reached]):.0f} "
                  f"({med([r['same_cpu'] for r in reached]):.2f} s)")
        lines.append(f"| SQP, {v.label} | {sum(r['ok'] for r in rs)}/{len(rs)} | "
                     f"{med([r['it'] for r in rs]):.0f} | {med([r['cpu'] for r in rs]):.2f} / "
                     f"{max(r['cpu'] for r in rs):.2f} | "
                     f"{1e3 * med([r['cpu'] / max(r['it'], 1) for r in rs]):.1f} | "
                     f"{100 * med(rel):.4f} % / {100 * rel.max():.4f} % | "
                     f"{len(reached)}/{len(rs)} | {to} |")
    lines += ["", "SQP CPU per iteration by part (ms, median over the frames): "]
    for v in variants:
        rs = rows[v.label]
        parts = ", ".join(f"{k} {1e3 * med([r['split'][k] / max(r['it'], 1) for r in rs]):.1f}"
                          for k in rs[0]["split"])
        qp_it = med([med([h.get("qp_it", 0) for h in r["hist"][:-1]] or [0]) for r in rs])
        fails = sum(r["qp_fail"] for r in rs)
        lines.append(f"- {v.label}: {parts}; HPIPM iterations per QP {qp_it:.0f} (median), "
                     f"QPs not converged {fails} of {sum(r['it'] for r in rs)}.")
    return lines


if __name__ == "__main__":
    raise SystemExit(main())
