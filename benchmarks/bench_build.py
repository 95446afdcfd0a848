"""``casadrone build`` against brute force: every combination of a catalogue co-designed and raced
alone (:func:`casadrone.build.solve.solve_combination`, one after another in this process),
against the build's branch and bound (screen, bound, co-design best-first, prune) in this
process; the winner, the ranking (race times within 0.1 %), the CPU of each, and the bound
against every co-designed race (bound over race time ≤ 1 where the bound holds).

Usage (from the checkout)::

    python benchmarks/bench_build.py                      # build-small (3 x 3 x 3)
    python benchmarks/bench_build.py --propellers 2 --motors 1 --packs 2 --short

``--propellers/--motors/--packs N`` keep the first N of each kind of build-small; ``--short``
flies the co-design tests' short track (tests/data/codesign/short-track.yaml) on 16 intervals
instead of the paper track. CPU is
``time.process_time`` of this process (the co-design and race solves run in it: serial
backend), so the figures do not depend on what else the machine runs; wall time does. Writes
``benchmarks/RESULTS-build.md`` (dated summary first) and prints the same.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks.machine import describe, with_summary  # noqa: E402
from casadrone.build.checks import load_build_problem  # noqa: E402
from casadrone.build.search import build, ranking, screened  # noqa: E402
from casadrone.build.solve import solve_combination  # noqa: E402

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
                 "codesign.intervals=16",
                 "codesign.lap_starts=[closed-loop, point-mass, coarse-grid]"]
    return load_build_problem("build-small", over), over


def brute_force(problem) -> tuple[list, float]:
    """Every screened-in combination co-designed and raced alone; (results, CPU s)."""
    c0 = time.process_time()
    kept, _ = screened(problem)
    out = [solve_combination(problem, c, None) for c in kept]
    return out, time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for kind, n in (("propellers", 3), ("motors", 3), ("packs", 3)):
        ap.add_argument(f"--{kind}", type=int, default=n)
    ap.add_argument("--rank", type=int, default=3)
    ap.add_argument("--short", action="store_true", help="the short test track instead of "
                    "build-small's paper track")
    args = ap.parse_args()
    problem, over = problem_of(args)
    wall0 = time.perf_counter()
    brute, brute_cpu = brute_force(problem)
    brute_wall = time.perf_counter() - wall0
    wall0, c0 = time.perf_counter(), time.process_time()
    result = build(problem)
    bb_cpu, bb_wall = time.process_time() - c0, time.perf_counter() - wall0
    brute_rank = ranking(brute, args.rank)
    same = [a.label for a in brute_rank] == [b.label for b in result.ranking] and all(
        abs(a.race_s - b.race_s) <= 1e-3 * a.race_s
        for a, b in zip(brute_rank, result.ranking, strict=True))
    by_label = {r.label: r for r in result.results}
    ratios = [by_label[r.label].bound_s / r.race_s for r in brute
              if r.label in by_label and math.isfinite(r.race_s)]
    size = f"{args.propellers}x{args.motors}x{args.packs}"
    cmd = "python benchmarks/bench_build.py" + (
        "" if size == "3x3x3" else
        f" --propellers {args.propellers} --motors {args.motors} --packs {args.packs}") + (
        " --short" if args.short else "")
    lines = [f"# casadrone build against brute force ({size} catalogue of build-small)", "",
             f"Problem: build-small with {' '.join(over)}.", "",
             "| | CPU s | wall s | combinations co-designed |", "|---|---|---|---|",
             f"| brute force | {brute_cpu:.1f} | {brute_wall:.1f} | {len(brute)} |",
             f"| build (branch and bound) | {bb_cpu:.1f} | {bb_wall:.1f} | "
             f"{result.counts.get('raced', 0) + result.counts.get('failed', 0)} |", "",
             f"Same winner and ranking (race times within 0.1 %): {same}.", "",
             "| combination | brute-force race s | build outcome | bound s |", "|---|---|---|---|"]
    for r in sorted(brute, key=lambda r: (not math.isfinite(r.race_s), r.race_s)):
        b = by_label.get(r.label)
        lines.append(f"| {r.label} | {r.race_s:.4f} | {b.outcome if b else '-'} | "
                     f"{b.bound_s if b else math.nan:.4f} |")
    for r in result.results:
        if r.outcome == "refused":
            lines.append(f"| {r.label} | refused: {r.reason} | refused | - |")
    lines += ["", f"Bound over race time: largest {max(ratios, default=math.nan):.3f} "
              "(at most 1 where the bound holds).", "", "## Machine", "",
              "\n".join(f"- {k}: {v}" for k, v in describe().items())]
    rows = [(f"build of a {size} catalogue against brute force co-design, one process",
             f"{bb_cpu:.0f} s CPU against {brute_cpu:.0f} s ({bb_cpu / brute_cpu:.2f}x); same "
             f"ranking: {same}", cmd)]
    text = with_summary("\n".join(lines) + "\n", rows)
    RESULTS.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
