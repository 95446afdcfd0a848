"""Benchmark: warm starts of the limit lap that begin nearer the new frame's optimum (not adopted).

Why. A warm solve of the 50-frame benchmark (``bench_limitlap_solvers.py``, "warm" rows) starts
from the nearest other frame's optimum, primal-dual. It takes IPOPT about 43 iterations; issue
19 asks for 0.25 s, about 9 of them. Its start violates the new frame's dynamics by 4-5 (the
body rates' rows: the same rotor thrusts turn a frame of other inertias and arms at other
rates). Is it the violation that costs the iterations, or the commands' switching that must
move? This script removes most of the violation in two ways and counts the iterations:

- ``neighbour``: the neighbour's optimum as it is (the benchmark's warm start);
- ``remixed``: the neighbour's optimum with its rotor states and commands re-mixed for the new
  frame: at every node the four thrusts become those that give the new frame the neighbour's
  accelerations (collective thrust scaled by the mass ratio; body torque J'·ω̇ + ω × J'ω for the
  neighbour's angular acceleration ω̇ = J⁻¹(M − ω × Jω)), through the inverse of the new
  frame's 4 × 4 thrust-to-wrench map (the ``paper`` model's,
  :attr:`casadrone.airframe.Airframe.allocation_matrix`); the commands K·δ alike at their
  interval's first node; then the box;
- ``least-violation``: of the ``--k`` nearest neighbours, the one whose optimum violates the
  new frame's rows least (``k`` evaluations of g, counted in its CPU).

Each start is solved with ``solve(..., near=True)`` (IPOPT; the warm setting chosen by the
start's violation, as in the benchmark). The neighbour's start is also solved with two IPOPT
settings that cut work per iteration (``min_refinement_steps 0``: no iterative refinement of
the step unless its residual asks for it; ``max_soc 0``: no second-order corrections), on the
far warm setting, beside the far setting itself.

``--timing``: instead, where the far setting's time goes on the neighbour's start, by IPOPT's own
timers (``print_timing_statistics``, written to a scratch ``output_file``): function
evaluations, the primal-dual linear algebra (``PDSystemSolverTotal``: MUMPS's factorisations,
inertia corrections included, back-solves and iterative refinement) and the rest, per iteration.

For ``--n`` random Table 1 frames (the seeds of bench_limitlap.py; SY250 template, paper track,
40 intervals per leg, one core; CPU = process time), each frame's cold optimum from its
point-mass start. Run: ``python benchmarks/bench_limitlap_warmstart.py [--n 30] [--k 3] [--timing]``
(a markdown section on stdout).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import cpu_time, markdown  # noqa: E402
from benchmarks.table1 import cold_frames, nearest  # noqa: E402
from casadrone.airframe import Airframe  # noqa: E402
from casadrone.limit.nlp import NlpPoint, ipopt_solver, solve, start_violation  # noqa: E402

#: IPOPT settings measured on the neighbour's start, on top of the far warm setting.
SETTINGS: dict[str, dict] = {"far": {}, "far, min_refinement_steps 0":
                             {"min_refinement_steps": 0}, "far, max_soc 0": {"max_soc": 0}}


def remix(nlp, w: np.ndarray, old: Airframe, new: Airframe,
          box: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """The decision vector ``w`` of frame ``old`` with its rotor thrusts and commands re-mixed
    for frame ``new`` (the module docstring; the frames' :attr:`~casadrone.airframe.Airframe.
    allocation_matrix`, the ``paper`` model's thrust-to-wrench map), inside the box."""
    T, X, U = nlp.unpack(w)
    A0, A1 = old.allocation_matrix, new.allocation_matrix
    J0, J1 = old.inertia, new.inertia

    def moved(thrusts: np.ndarray, omega: np.ndarray) -> np.ndarray:
        W = A0 @ thrusts
        omega_dot = np.linalg.solve(J0, W[1:] - np.cross(omega, J0 @ omega))
        torque = J1 @ omega_dot + np.cross(omega, J1 @ omega)
        return np.linalg.solve(A1, np.concatenate([[W[0] * new.mass / old.mass], torque]))

    rotor, rates = nlp.model.rotor, nlp.model.rates
    X2, U2 = X.copy(), U.copy()
    for k in range(len(X)):
        X2[k, rotor] = moved(X[k, rotor], X[k, rates])
    for k in range(len(U)):
        U2[k] = moved(old.thrust_gain * U[k], X[k, rates]) / new.thrust_gain
    return np.clip(nlp.pack(T, X2, U2), *box)


#: IPOPT's timers read by ``--timing`` (the names it prints), in seconds over the solve.
TIMERS = ("OverallAlgorithm", "Function Evaluations", "Lagrangian Hessian",
          "PDSystemSolverTotal", "LinearSystemBackSolve")


def ipopt_timers(text: str) -> dict[str, float]:
    """CPU seconds of :data:`TIMERS` and the iteration count of the last solve in IPOPT's
    printed output (IPOPT appends each solve's summary to its ``output_file``)."""
    import re

    def last(pattern: str) -> float:
        found = re.findall(pattern, text, re.M)
        return float(found[-1]) if found else float("nan")

    return {name: last(rf"^\s*{re.escape(name)}\.*:\s+([0-9.]+)") for name in TIMERS} | {
        "iterations": last(r"^Number of Iterations\.*:\s+(\d+)")}


def timing_lines(problems: list, cold: list, pairs: list[tuple[int, int]]) -> list[str]:
    """Per-iteration CPU by IPOPT's timers of the far warm setting from each (frame, neighbour)."""
    import tempfile

    per: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        log = str(Path(tmp) / "ipopt.out")
        S = ipopt_solver(problems[0].full, "warm_timed", {
            "output_file": log, "file_print_level": 5, "print_timing_statistics": "yes"},
            warm=True)
        for i, j in pairs:
            pb, nb = problems[i], cold[j].point
            S(x0=np.clip(nb.w, *pb.box), lam_x0=nb.lam_x, lam_g0=nb.lam_g, p=pb.P,
              lbx=pb.box[0], ubx=pb.box[1], lbg=pb.rows[0], ubg=pb.rows[1])
            t = ipopt_timers(Path(log).read_text())
            n = max(t.pop("iterations"), 1.0)
            t["the rest"] = t["OverallAlgorithm"] - t["Function Evaluations"] \
                - t["PDSystemSolverTotal"]
            for k, v in t.items():
                per.setdefault(k, []).append(1e3 * v / n)
            per.setdefault("iterations", []).append(n)
    lines = [f"Where the far warm setting's time goes ({len(pairs)} frames from their nearest "
             "neighbour; IPOPT's timers, per iteration, median):", "",
             "| timer | ms per iteration (median) | range |", "|---|---|---|"]
    for k, v in per.items():
        unit = "" if k == "iterations" else " ms"
        lines.append(f"| {k} | {np.median(v):.1f}{unit} | {min(v):.1f}-{max(v):.1f} |")
    return lines


def _solve(pb, w0: np.ndarray, dual: NlpPoint) -> dict:
    c0 = cpu_time()
    s = solve(pb.full, w0, pb.P, *pb.box, warm=NlpPoint(w0, dual.lam_x, dual.lam_g, dual.lam_p),
              lbg=pb.rows[0], ubg=pb.rows[1], near=True)
    return {"ok": s.success, "it": s.iterations, "cpu": cpu_time() - c0, "f": s.objective}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=30)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--k", type=int, default=3, help="neighbours tried by least-violation")
    ap.add_argument("--timing", action="store_true",
                    help="IPOPT's own timers of the neighbour's warm solve instead")
    args = ap.parse_args()
    unit, problems, cold = cold_frames(args.n, args.seed)
    ok = [i for i in range(args.n) if cold[i].success]
    if args.timing:
        pairs = [(i, nearest(i, ok, unit)[0]) for i in ok]
        print("\n".join(timing_lines(problems, cold, pairs)))
        return
    settings = {name: ipopt_solver(problems[0].full, "warm_" + name.replace(" ", "_")
                                   .replace(",", ""), ov, warm=True)
                for name, ov in SETTINGS.items()}
    rows: dict[str, list[dict]] = {}
    for i in ok:
        pb = problems[i]
        near = nearest(i, ok, unit)
        j = near[0]
        nb = cold[j].point
        w_nb = np.clip(nb.w, *pb.box)
        starts = {"neighbour": (w_nb, nb, 0.0)}
        c0 = cpu_time()
        w_mix = remix(pb.full, nb.w, problems[j].frame, pb.frame, pb.box)
        starts["remixed"] = (w_mix, nb, cpu_time() - c0)
        c0 = cpu_time()
        viol = {m: start_violation(pb.full, np.clip(cold[m].point.w, *pb.box), pb.P, *pb.rows)
                for m in near[:args.k]}
        best = min(viol, key=lambda m: viol[m])
        starts["least-violation"] = (np.clip(cold[best].point.w, *pb.box), cold[best].point,
                                     cpu_time() - c0)
        for name, (w0, dual, extra) in starts.items():
            r = _solve(pb, w0, dual)
            r["cpu"] += extra
            r["viol"] = start_violation(pb.full, w0, pb.P, *pb.rows)
            rows.setdefault(name, []).append(r)
        for name, S in settings.items():
            c0 = cpu_time()
            out = S(x0=w_nb, lam_x0=nb.lam_x, lam_g0=nb.lam_g, p=pb.P, lbx=pb.box[0],
                    ubx=pb.box[1], lbg=pb.rows[0], ubg=pb.rows[1])
            st = S.stats()
            rows.setdefault(f"neighbour, {name}", []).append(
                {"ok": bool(st["success"]), "it": int(st["iter_count"]),
                 "cpu": cpu_time() - c0, "f": float(out["f"]), "viol": rows["neighbour"][-1]
                 ["viol"]})
        print(f"warm {i} from {j} (least violation: {best}): " + "; ".join(
            f"{k} {v[-1]['it']} it {v[-1]['cpu']:.2f} s {v[-1]['f']:.5f}"
            for k, v in rows.items()), file=sys.stderr, flush=True)
    base = rows["neighbour"]
    lines = ["## Warm starts that begin nearer (`bench_limitlap_warmstart.py`)", "", markdown(),
             "", f"Command: `python benchmarks/bench_limitlap_warmstart.py --n {args.n} --seed "
             f"{args.seed} --k {args.k}` ({len(ok)} frames with a cold optimum; laps compared "
             "with the neighbour's start's lap, frame by frame).", "",
             "| start, setting | converged | start violation (median) | iterations (median) | "
             "CPU median / max (s) | CPU against `neighbour`, median of the per-frame ratios | "
             "lap within 0.01 % of `neighbour`'s | faster / slower lap |",
             "|---|---|---|---|---|---|---|---|"]
    for name, rs in rows.items():
        ratio = np.median([r["cpu"] / b["cpu"] for r, b in zip(rs, base, strict=True)])
        rel = np.array([(r["f"] - b["f"]) / b["f"] for r, b in zip(rs, base, strict=True)])
        lines.append(
            f"| {name} | {sum(r['ok'] for r in rs)}/{len(rs)} | "
            f"{np.median([r['viol'] for r in rs]):.2f} | {np.median([r['it'] for r in rs]):g} | "
            f"{np.median([r['cpu'] for r in rs]):.2f} / {max(r['cpu'] for r in rs):.2f} | "
            f"{ratio:.2f} | {int(np.sum(np.abs(rel) <= 1e-4))}/{len(rs)} | "
            f"{int(np.sum(rel < -1e-4))} / {int(np.sum(rel > 1e-4))} |")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
