"""Benchmark: the trim-solver study, its cost and what it finds across airframes.

1. Timing target: one airframe (HS210, asymmetric), the default envelope (hover, level flight
   5…40 m/s, climb and descent at ±30°, two turns: 13 points), 100 random starts plus the
   analytic guess per point and solver, on one core. Target: under a minute. Wall time and the
   process's CPU time are both recorded (the machine may be shared; CPU time is what one core
   spends).
2. What the study finds: the five reference airframes and N random paper Table 1 frames, the
   same envelope and spreads with fewer starts; per frame and solver the success rate over the
   envelope, the outcomes, median iterations and the point where the solver did worst.

Writes ``benchmarks/RESULTS-trimstudy.md`` (machine, load, the command, tables).

Run: ``python benchmarks/bench_trimstudy.py [--starts 100] [--frame-starts 20] [--random 5]
[--seed 0] [--no-write]``; ``--propeller SY250-propeller`` studies that airframe alone (any
propulsion kind) and writes ``RESULTS-trimstudy-propeller.md``.
"""

from __future__ import annotations

import os

# One core: pin BLAS/OpenMP thread pools before numpy, scipy or casadi are imported.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"
if hasattr(os, "sched_setaffinity"):
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks.machine import markdown, with_summary  # noqa: E402
from casadrone.airframe import build_airframe, random_thetas, with_theta  # noqa: E402
from casadrone.config import load_airframe  # noqa: E402
from casadrone.trimstudy import StudyOptions, TrimStudy, trim_study  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "RESULTS-trimstudy.md"
REFERENCE = ("SY250", "SY220", "HS200", "HS210", "NSY200")
ENVELOPE = "hover,forward,climb,turn"


def timed_study(frame, options: StudyOptions) -> tuple[TrimStudy, float, float]:
    """The study, its wall time and CPU time (s)."""
    wall, cpu = time.perf_counter(), time.process_time()
    study = trim_study(frame, ENVELOPE, options)
    return study, time.perf_counter() - wall, time.process_time() - cpu


def solver_totals(study: TrimStudy) -> list[str]:
    """Per solver over the envelope: starts, success, outcomes, iterations, time spent."""
    rows = ["| solver | starts | success | converged | other trim | out-of-domain | failed | "
            "diverged | iterations median (q25–q75) | time per start median (ms) | time spent (s) "
            "|", "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for solver in study.options.solvers:
        res = [r for p in study.points for r in p.results if r.solver == solver]
        its = [r.iterations for r in res if r.success]
        t = np.array([r.wall_time_s for r in res])
        n = {o: sum(r.outcome == o for r in res) for o in
             ("converged", "other-trim", "out-of-domain", "failed", "diverged")}
        q = np.percentile(its, [25, 50, 75]) if its else [np.nan] * 3
        rows.append(f"| {solver} | {len(res)} | {100 * np.mean([r.success for r in res]):.1f} % "
                    f"| {n['converged']} | {n['other-trim']} | {n['out-of-domain']} | "
                    f"{n['failed']} | {n['diverged']} | {q[1]:.0f} ({q[0]:.0f}–{q[2]:.0f}) | "
                    f"{1e3 * np.median(t):.2f} | {t.sum():.1f} |")
    return rows


def point_table(study: TrimStudy) -> list[str]:
    """Success rate (%) per point and solver, and the distinct roots found."""
    solvers = study.options.solvers
    rows = ["| point | " + " | ".join(f"{s} success" for s in solvers)
            + " | " + " | ".join(f"{s} iterations" for s in solvers) + " | roots (in domain) |",
            "|---|" + "---:|" * (2 * len(solvers) + 1)]
    for p in study.points:
        s = [p.summary(x) for x in solvers]
        rows.append(f"| {p.point.label} | "
                    + " | ".join(f"{100 * x.success_rate:.0f}" for x in s) + " | "
                    + " | ".join(f"{x.iterations_median:.0f}" for x in s)
                    + f" | {len(p.solutions)} ({sum(x.in_domain for x in p.solutions)}) |")
    return rows


def frames(n_random: int, seed: int):
    out = [build_airframe(load_airframe(name)) for name in REFERENCE]
    base = load_airframe("SY250")
    thetas, _ = random_thetas(base, n_random, seed)
    out += [build_airframe(with_theta(base, th, name=f"table1-{i}"))
            for i, th in enumerate(thetas)]
    return out


def frame_rows(study: TrimStudy, wall: float) -> list[str]:
    rows = []
    for solver in study.options.solvers:
        s = [p.summary(solver) for p in study.points]
        rate = np.mean([x.success_rate for x in s])
        worst = min(study.points, key=lambda p: p.summary(solver).success_rate)
        n = {o: sum(x.outcomes[o] for x in s)
             for o in ("other-trim", "out-of-domain", "failed", "diverged")}
        guess = sum(x.from_guess == "converged" for x in s)
        rows.append(f"| {study.airframe} | {solver} | {100 * rate:.1f} % | {guess}/{len(s)} | "
                    f"{n['other-trim']} | {n['out-of-domain']} | {n['failed']} | {n['diverged']} | "
                    f"{np.median([x.iterations_median for x in s]):.0f} | "
                    f"{worst.point.label} ({100 * worst.summary(solver).success_rate:.0f} %) | "
                    f"{wall:.1f} |")
    return rows


def propeller_study(name: str, options: StudyOptions, command: str, no_write: bool) -> None:
    """One airframe of any propulsion kind over the envelope: totals, per point, the failures'
    messages (the first three per point and solver)."""
    frame = build_airframe(load_airframe(name))
    trim_study(frame, "forward:10", StudyOptions(starts=1))  # warm-up
    study, wall, cpu = timed_study(frame, options)
    notes = []
    for p in study.points:
        for solver in options.solvers:
            bad = [r for r in p.results if r.solver == solver and r.outcome != "converged"][:3]
            notes += [f"- {p.point.label}, {solver}, start {r.start}: {r.outcome}: {r.message}"
                      for r in bad]
    text = "\n".join([
        f"# Trim-solver study, {name} (propulsion: {getattr(frame, 'propulsion', 'paper')})", "",
        f"Command: `{command}`", "", markdown(), "",
        f"{len(study.points)} operating points × {len(options.solvers)} solvers × "
        f"{options.starts + 1} starts (seed {options.seed}; roll, pitch "
        f"±{options.angle_spread_deg:g}°, commands ±{100 * options.command_spread:g} %; rotor "
        "states from the trim's analytic guess).", "",
        f"**Wall time {wall:.1f} s, CPU time {cpu:.1f} s.**", "",
        *solver_totals(study), "", *point_table(study), "",
        "Starts that did not reach the reference (first three per point and solver):", "",
        *notes, ""])
    print(text)
    if not no_write:
        out = RESULTS.with_name("RESULTS-trimstudy-propeller.md")
        out.write_text(text)
        print(f"wrote {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=100)
    ap.add_argument("--frame-starts", type=int, default=20)
    ap.add_argument("--random", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--propeller", metavar="AIRFRAME", default=None,
                    help="also study this airframe (e.g. SY250-propeller) over the envelope with "
                    "--starts starts; writes RESULTS-trimstudy-propeller.md instead")
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args()
    command = "python benchmarks/bench_trimstudy.py " + " ".join(sys.argv[1:])

    if args.propeller:
        propeller_study(args.propeller, StudyOptions(starts=args.starts, seed=args.seed), command,
                        args.no_write)
        return
    hs210 = build_airframe(load_airframe("HS210"))
    trim_study(hs210, "forward:10", StudyOptions(starts=1))  # warm-up: build every solver once
    target = StudyOptions(starts=args.starts, seed=args.seed)
    study, wall, cpu = timed_study(hs210, target)
    o = target
    part1 = [
        f"## 1. One airframe, the whole envelope, {o.starts} starts per point and solver",
        "",
        f"HS210, {len(study.points)} operating points × {len(o.solvers)} solvers × "
        f"{o.starts + 1} starts (the analytic guess and {o.starts} draws, seed {o.seed}: roll, "
        f"pitch ±{o.angle_spread_deg:g}°, commands ±{100 * o.command_spread:g} %), one core.",
        "",
        f"**Wall time {wall:.1f} s, CPU time {cpu:.1f} s** (target: under 60 s).",
        "",
        *solver_totals(study),
        "",
        *point_table(study),
    ]
    per_solver = ["", "Each solver alone over the same starts (three more studies, one solver "
                  "each), to split the time:", "",
                  "| solver | wall time (s) | CPU time (s) | CPU per solve (ms) |",
                  "|---|---:|---:|---:|"]
    alone = {}
    for solver in o.solvers:
        _, w, c = timed_study(hs210, replace(target, solvers=(solver,)))
        n = len(study.points) * (o.starts + 1)
        per_solver.append(f"| {solver} | {w:.1f} | {c:.1f} | {1e3 * c / n:.2f} |")
        alone[solver] = c
    summary = summary_row(len(study.points), o.starts, wall, cpu, os.getloadavg()[0], alone)
    part1 += per_solver
    print("\n".join(part1), flush=True)

    part2 = [
        f"## 2. Reference and random Table 1 frames, {args.frame_starts} starts per point",
        "",
        "Success: trims (at the reference or another trim) per start, averaged over the "
        "envelope's points; analytic guess: points where the solver, started from it, reached "
        "the reference; the outcome columns count starts over the envelope; worst point: where "
        "the solver's success rate was lowest.",
        "",
        "| frame | solver | success | analytic guess converged (points) | other trim | "
        "out-of-domain | failed | diverged | iterations (median of point medians) | worst point "
        "| study wall time (s) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---:|",
    ]
    for frame in frames(args.random, args.seed):
        st, w, _ = timed_study(frame, StudyOptions(starts=args.frame_starts, seed=args.seed))
        rows = frame_rows(st, w)
        part2 += rows
        print("\n".join(rows), flush=True)

    text = with_summary("\n".join(["# Trim-solver study", "", f"Command: `{command}`", "",
                                   markdown(), "", *part1, "", *part2, ""]), [summary])
    if not args.no_write:
        RESULTS.write_text(text)
        print(f"wrote {RESULTS}")


def summary_row(n_points: int, starts: int, wall: float, cpu: float, load: float,
                alone: dict[str, float]) -> tuple[str, str, str]:
    """The performance page's row: the whole study's CPU time, and each solver's alone."""
    each = ", ".join(f"{solver} {c:.1f} s" for solver, c in alone.items())
    return (f"trim study: one airframe (HS210), {n_points} operating points, {len(alone)} solvers "
            f"× {starts + 1} starts, one core",
            f"{cpu:.1f} s CPU time (target < 1 min; {wall:.0f} s wall at load average "
            f"{load:.0f}); each solver alone: {each}", "`python benchmarks/bench_trimstudy.py`")


if __name__ == "__main__":
    main()
