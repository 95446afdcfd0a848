"""Benchmark: the co-design front (lap against effort) beside ev-MOGA's on the same objectives.

Phase 1 (``--front DIR``): ``casadrone codesign``'s front for ``--problem`` (default
``codesign-front``: the paper track, 40 intervals per leg, 15 points, effort ε from the fastest
frame's down to half of it) from the template's geometry alone (``codesign.starts=0``; the
template start reaches the best of six starts on this track, RESULTS-codesign.md), timed by
phase in CPU seconds of this one process (one core): the template's limit lap and the NLP's
build, the fastest frame, the ε-continuation. Writes the run directory to DIR and the timings
to DIR/timings.json at the end, and each point as it converges (lap, measure, ε, iterations,
CPU) to DIR.points.jsonl beside it, so a sweep stopped early keeps what it reached. Every
point is certified as it converges (:mod:`casadrone.codesign.frontcert`: the fastest frame
with its cold fixed-frame check, each ε-point by its warm fixed-θ re-solve, reduced gradient
and CVODES), each certificate written to DIR.certificates.jsonl as it is issued and timed apart
(``certificates_cpu_s``; ``--no-point-certificates`` leaves them out).

Phase 2 (``--ga RUN --ga-cpu S``): the comparison with a finished ``casadrone run`` of
``problems/limit-effort.yaml`` (ev-MOGA, the same airframe, track, box and objectives; its CPU
time S, user + system of the run and its worker processes, measured outside by
``/usr/bin/time``): which GA points some co-design point dominates or equals, and the
hypervolume of both fronts (pymoo's HV) from one reference point, the worst lap and effort over
both fronts plus 10 % of their ranges.

With ``--reevaluate``, phase 2 also evaluates each co-design frame as the GA evaluates a
candidate (:func:`reevaluate`) and compares those points too: the GA's objectives of a frame are
its minimum-time limit lap and that lap's effort, while a co-design ε-point's lap is the lap of
a trajectory held to the effort bound (slower than its frame's minimum-time lap, for less
effort).

Run: ``python benchmarks/bench_codesign_front.py --front /tmp/front``, then
``python benchmarks/bench_codesign_front.py --compare /tmp/front --ga runs/limit-effort
--ga-cpu 1234``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def run_front(problem: str, out: Path, overrides: list[str], certify: bool = False,
              point_certificates: bool = True) -> dict:
    """The co-design front, timed by phase (CPU s of this process). ``certify``: the fastest
    frame is certified first as ``casadrone codesign`` certifies it (restarted, or re-posed on
    a finer grid, while its certificate fails: :func:`casadrone.codesign.design.certified`),
    its certificate written to DIR.certificate.txt beside DIR, and the front follows from the
    certified point on its grid. ``point_certificates``: every point of the front is certified
    as it converges (:func:`casadrone.codesign.frontcert.certified_point`; the fastest frame by
    the certificate above, or by its own without ``certify``), each written to
    DIR.certificates.jsonl as it is issued; timed apart."""
    from casadrone.cli.codesign import text
    from casadrone.codesign.checks import load_codesign_problem
    from casadrone.codesign.design import certified
    from casadrone.codesign.driver import (
        CodesignResult,
        StartReport,
        initial_vector,
        prepare,
        solve_from,
        start_points,
    )
    from casadrone.codesign.front import design_front, write_run

    cfg = load_codesign_problem(problem, ["codesign.starts=0", *overrides])
    t = {"start": time.process_time()}
    wall0 = time.perf_counter()
    prep = prepare(cfg)
    t["prepared"] = time.process_time()
    (_, theta), = start_points(prep)
    z0 = initial_vector(prep, theta)
    assert z0 is not None, "the template has no limit lap"
    ok, status, best = solve_from(prep, z0)
    assert ok, status
    cert = None
    if certify:
        reports = [StartReport("template", theta, status, ok, best.objective, best.theta,
                               best.iterations, time.process_time() - t["prepared"])]
        prep, best, distinct, cert = certified(prep, [best], reports)
        result = CodesignResult("completed", "", cfg.name, prep.keys, prep.labels,
                                cfg.codesign.combine, best, tuple(reports), tuple(distinct),
                                cert, intervals=prep.options.intervals or 0,
                                cpu_s=time.process_time() - t["start"],
                                wall_time_s=time.perf_counter() - wall0,
                                build_cpu_s=t["prepared"] - t["start"])
        (out.parent / f"{out.name}.certificate.txt").write_text(text(result) + "\n")
    t["fastest"] = time.process_time()
    # each point as it converges, beside DIR (the run directory must start empty): a sweep
    # stopped early keeps its points
    progress = out.parent / f"{out.name}.points.jsonl"

    def keep(point, measure: float, epsilon: float) -> None:
        with open(progress, "a") as fh:
            fh.write(json.dumps({"lap_s": point.objective, "measure": measure,
                                 "epsilon": epsilon, "iterations": point.iterations,
                                 "solve_cpu_s": point.cpu_s, "theta": point.theta,
                                 "cpu_s": time.process_time() - t["start"]}) + "\n")

    issued = out.parent / f"{out.name}.certificates.jsonl"
    certificates: list[dict] = []

    def on_point(fp) -> None:
        keep(fp.point, math.nan if math.isinf(fp.epsilon) else fp.measure, fp.epsilon)
        c = fp.certificate
        if c is None:
            return
        row = {"point": len(certificates), "lap_s": fp.point.objective, "measure": fp.measure,
               "epsilon": fp.epsilon, "passed": c.passed, "reason": c.reason,
               "gap_pct": max((x.gap_pct for x in c.tracks), key=abs, default=math.nan),
               "miss_m": max((x.resimulation_miss_m for x in c.tracks), default=math.nan),
               "cpu_s": time.process_time() - t["start"], "summary": c.summary()}
        certificates.append(row)
        with open(issued, "a") as fh:
            fh.write(json.dumps(row) + "\n")

    front = design_front(prep, best, cfg.objectives[1].index, cfg.codesign.front.points,
                         cfg.codesign.front.lowest, on_point=on_point,
                         certify=point_certificates, first=cert)
    t["front"] = time.process_time()
    write_run(out, prep, front, len(front.points))
    timings = {"prepare_cpu_s": t["prepared"] - t["start"],
               "fastest_cpu_s": t["fastest"] - t["prepared"],
               "fastest_iterations": best.iterations,
               "intervals": prep.options.intervals,
               "continuation_cpu_s": t["front"] - t["fastest"] - front.certificates_cpu_s,
               "certificates_cpu_s": front.certificates_cpu_s,
               "certificates_passed": sum(c["passed"] for c in certificates),
               "certificates": certificates,
               "total_cpu_s": t["front"] - t["start"],
               "wall_s": time.perf_counter() - wall0,
               "points": len(front.points), "stopped": front.stopped,
               "iterations": [p.point.iterations for p in front.points],
               "load_average": os.getloadavg()}
    (out / "timings.json").write_text(json.dumps(timings, indent=1))
    return timings


def read_front(run: Path, names=("J3_limit", "effort")) -> np.ndarray:
    """A run's front: ``pareto.csv``, or for a run stopped early the non-dominated set of its
    completed evaluations in ``history.sqlite`` (as the report reads an unfinished run)."""
    if (run / "pareto.csv").is_file():
        with open(run / "pareto.csv", newline="") as fh:
            header, *rows = list(csv.reader(fh))
        return np.array([[float(r[header.index(n)]) for n in names] for r in rows])
    import sqlite3

    from casadrone.optimise.hypervolume import non_dominated

    with sqlite3.connect(run / "history.sqlite") as db:
        F = np.array(db.execute(f"SELECT {', '.join(names)} FROM evaluations WHERE status = "
                                "'completed'").fetchall(), float)
    return non_dominated(F)


def compare(codesign: np.ndarray, ga: np.ndarray) -> dict:
    """Dominance of the GA points by the co-design front, and both hypervolumes."""
    from pymoo.indicators.hv import HV

    both = np.vstack([codesign, ga])
    lo, hi = both.min(axis=0), both.max(axis=0)
    ref = hi + 0.1 * (hi - lo)
    covered = [bool(np.any(np.all(codesign <= g, axis=1))) for g in ga]
    hv = HV(ref_point=ref)
    return {"reference_point": ref.tolist(), "hv_codesign": float(hv(codesign)),
            "hv_ga": float(hv(ga)), "ga_points": len(ga), "codesign_points": len(codesign),
            "ga_points_dominated_or_equalled": int(sum(covered)),
            "ga_points_not_covered": ga[~np.array(covered)].tolist()}


def reevaluate(run: Path, ga: Path) -> dict:
    """The co-design front's frames evaluated as the GA evaluates a candidate (its problem, from
    a copy of its run directory): the frame's minimum-time limit lap (``J3_limit``) and that
    lap's effort. A co-design ε-point's own lap is the lap of a trajectory held to the effort
    bound, not its frame's minimum-time lap, so these are the GA's objectives of those frames."""
    import shutil
    import tempfile

    from casadrone.optimise.problem import Study, evaluate_rows
    from casadrone.rundir.store import RunStore

    with open(run / "pareto.csv", newline="") as fh:
        header, *rows = list(csv.reader(fh))
    with tempfile.TemporaryDirectory() as tmp:
        shutil.copytree(ga, Path(tmp) / "ga", ignore=shutil.ignore_patterns("run.lock"))
        study = Study(RunStore(Path(tmp) / "ga").problem())
        X = np.array([[float(r[header.index(k)]) for k in study.variable_names] for r in rows])
        c0 = time.process_time()
        records = evaluate_rows(study, X)
        cpu = time.process_time() - c0
    F = np.array([[r.indices.get(n, np.nan) if r.status == "completed" else np.nan
                   for n in ("J3_limit", "effort")] for r in records])
    return {"front": F.tolist(), "cpu_s": cpu,
            "failed": [f"{r.stage}: {r.reason}" for r in records if r.status != "completed"],
            "F": F[np.all(np.isfinite(F), axis=1)]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default="codesign-front")
    ap.add_argument("--front", type=Path, help="run the co-design front into this new folder")
    ap.add_argument("--compare", type=Path, help="a co-design front's run directory")
    ap.add_argument("--ga", type=Path, help="a finished ev-MOGA run of limit-effort.yaml")
    ap.add_argument("--ga-cpu", type=float, help="the GA run's CPU seconds (/usr/bin/time)")
    ap.add_argument("--reevaluate", action="store_true", help="also evaluate the co-design "
                    "frames as the GA does (their minimum-time limit lap and its effort)")
    ap.add_argument("--certify", action="store_true", help="certify the fastest frame first "
                    "(and re-pose it as casadrone codesign does while the certificate fails)")
    ap.add_argument("--no-point-certificates", dest="point_certificates",
                    action="store_false", help="leave the front's points uncertified (the "
                    "front alone, as measured before every point was certified)")
    ap.add_argument("overrides", nargs="*", help="co-design problem overrides (key=value)")
    args = ap.parse_args(argv)
    if args.front:
        print(json.dumps(run_front(args.problem, args.front, args.overrides, args.certify,
                                   args.point_certificates), indent=1))
    if args.compare and args.ga:
        result = compare(read_front(args.compare), read_front(args.ga))
        timings = json.loads((args.compare / "timings.json").read_text())
        if args.ga_cpu:
            result["ga_cpu_s"] = args.ga_cpu
            result["codesign_cpu_s"] = timings["total_cpu_s"]
            result["cpu_ratio"] = timings["total_cpu_s"] / args.ga_cpu
        if args.reevaluate:
            again = reevaluate(args.compare, args.ga)
            F = again.pop("F")
            result["reevaluated"] = {**again, **compare(F, read_front(args.ga))}
        print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
