"""``casadrone build`` against brute force: every combination of a catalogue co-designed and raced
alone (:func:`casadrone.build.solve.solve_combination`, one after another in this process),
against the build's branch and bound (screen, bound, co-design best-first, prune) in this
process; the winner, the ranking (race times within 0.1 %), the CPU of each, and the bound
against every co-designed race (bound over race time ≤ 1 where the bound holds).

Usage (from the checkout)::

    python benchmarks/bench_build.py                      # build-small (3 x 3 x 3)
    python benchmarks/bench_build.py --propellers 2 --motors 1 --packs 2 --short

Brute force and the build each run in a process of their own (spawned side by side), so neither
reuses what the other built (co-design NLPs, point-mass solves are cached per process).
``--propellers/--motors/--packs N`` keep the first N of each kind of build-small; ``--short``
flies the co-design tests' short track (tests/data/codesign/short-track.yaml) on 16 intervals
instead of the paper track. CPU is
``time.process_time`` of this process (the co-design and race solves run in it: serial
backend), so the figures do not depend on what else the machine runs; wall time does. Writes
``benchmarks/RESULTS-build.md`` (dated summary first) and prints the same.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks.machine import describe, with_summary  # noqa: E402
from casadrone.build.checks import load_build_problem  # noqa: E402
from casadrone.build.search import build, screened  # noqa: E402
from casadrone.build.solve import solve_combination  # noqa: E402
from casadrone.cli.common import jsonable  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "RESULTS-build.md"
ROOT = Path(__file__).resolve().parent.parent


def problem_of(args: argparse.Namespace):
    """build-small with the first N parts of each kind, serial, uncertified."""
    full = load_build_problem("build-small")
    b = full.build
    pick = {"propellers": list(b.propellers)[:args.propellers],
            "motors": list(b.motors)[:args.motors], "packs": list(b.packs)[:args.packs]}
    over = [f"build.{k}=[{', '.join(v)}]" for k, v in pick.items()]
    over += ["backend.name=serial", "build.certify=false", f"build.rank={args.rank}"]
    if args.short:  # the co-design tests' short track on their propeller grid
        over += [f"track={ROOT / 'tests/data/codesign/short-track.yaml'}",
                 "limit_lap.intervals=16",
                 "limit_lap.starts=[closed-loop, point-mass, coarse-grid]"]
    return load_build_problem("build-small", over), over


def brute_force(problem) -> list:
    """Every screened-in combination co-designed and raced alone."""
    kept, _ = screened(problem)
    return [solve_combination(problem, c, None) for c in kept]


def part(args: argparse.Namespace) -> None:
    """One side in this (fresh) process: its results, CPU and wall as JSON on stdout."""
    problem, _ = problem_of(args)
    wall0, c0 = time.perf_counter(), time.process_time()
    if args.part == "brute":
        results = brute_force(problem)
    else:
        done = build(problem)
        results = list(done.results)
    cpu, wall = time.process_time() - c0, time.perf_counter() - wall0
    print(json.dumps(jsonable({"cpu_s": cpu, "wall_s": wall,
                               "results": [r.as_dict() for r in results]})))


def run_part(name: str) -> subprocess.Popen:
    """This script for one side, in a process of its own (no cache shared with the other)."""
    argv = [a for a in sys.argv[1:]]
    return subprocess.Popen([sys.executable, __file__, *argv, "--part", name],
                            stdout=subprocess.PIPE, text=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for kind, n in (("propellers", 3), ("motors", 3), ("packs", 3)):
        ap.add_argument(f"--{kind}", type=int, default=n)
    ap.add_argument("--rank", type=int, default=3)
    ap.add_argument("--short", action="store_true", help="the short test track instead of "
                    "build-small's paper track")
    ap.add_argument("--part", choices=("brute", "build"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.part:
        part(args)
        return
    _, over = problem_of(args)
    procs = {name: run_part(name) for name in ("brute", "build")}  # side by side
    got = {name: json.loads(p.communicate()[0]) for name, p in procs.items()}
    brute, bb = got["brute"], got["build"]
    brute_rank = sorted((r for r in brute["results"] if r["feasible"]),
                        key=lambda r: (r["race_s"], r["label"]))[:args.rank]
    bb_rank = sorted((r for r in bb["results"] if r["outcome"] == "raced" and r["feasible"]),
                     key=lambda r: (r["race_s"], r["label"]))[:args.rank]
    same = [a["label"] for a in brute_rank] == [b["label"] for b in bb_rank] and all(
        abs(a["race_s"] - b["race_s"]) <= 1e-3 * a["race_s"]
        for a, b in zip(brute_rank, bb_rank, strict=True))
    by_label = {r["label"]: r for r in bb["results"]}
    ratios = [by_label[r["label"]]["bound_s"] / r["race_s"] for r in brute["results"]
              if r["label"] in by_label and r["race_s"] is not None
              and by_label[r["label"]]["bound_s"] is not None]
    co = sum(r["outcome"] in ("raced", "failed") for r in bb["results"])
    size = f"{args.propellers}x{args.motors}x{args.packs}"
    cmd = "python benchmarks/bench_build.py" + (
        "" if size == "3x3x3" else
        f" --propellers {args.propellers} --motors {args.motors} --packs {args.packs}") + (
        f" --rank {args.rank}" if args.rank != 3 else "") + (" --short" if args.short else "")
    lines = [f"# casadrone build against brute force ({size} catalogue of build-small)", "",
             f"Problem: build-small with {' '.join(over)}. Each side in a process of its own "
             "(no in-process cache shared), both at once.", "",
             "| | CPU s | wall s | combinations co-designed |", "|---|---|---|---|",
             f"| brute force | {brute['cpu_s']:.1f} | {brute['wall_s']:.1f} | "
             f"{len(brute['results'])} |",
             f"| build (branch and bound) | {bb['cpu_s']:.1f} | {bb['wall_s']:.1f} | {co} |", "",
             f"Same winner and ranking (race times within 0.1 %): {same}.", "",
             "| combination | brute force | build outcome | bound s |", "|---|---|---|---|"]
    for r in brute["results"]:
        b = by_label.get(r["label"], {})
        fig = (f"{r['race_s']:.4f} s" if r["race_s"] is not None
               else f"{r['outcome']}: {r['reason']}")
        bound = b.get("bound_s")
        lines.append(f"| {r['label']} | {fig} | {b.get('outcome', '-')} | "
                     f"{'-' if bound is None else f'{bound:.4f}'} |")
    for r in bb["results"]:
        if r["outcome"] == "refused":
            lines.append(f"| {r['label']} | - | refused: {r['reason']} | - |")
    lines += ["", f"Bound over race time: largest {max(ratios, default=math.nan):.3f} "
              "(at most 1 where the bound holds).", "", "## Machine", "",
              "\n".join(f"- {k}: {v}" for k, v in describe().items())]
    rows = [(f"build of a {size} catalogue against brute force co-design, one process each",
             f"{bb['cpu_s']:.0f} s CPU against {brute['cpu_s']:.0f} s "
             f"({bb['cpu_s'] / brute['cpu_s']:.2f}x); same ranking: {same}", f"`{cmd}`")]
    text = with_summary("\n".join(lines) + "\n", rows)
    RESULTS.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
