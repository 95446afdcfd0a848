"""``casadrone build`` against brute force: every combination of a catalogue co-designed and raced
alone (:func:`casadrone.build.solve.solve_combination` without seeds, one after another), against
the build (screen, bound, race best-first from the nearest raced neighbour at the box's dominant
frame or co-design where it has none, prune, co-design the ranked), serial and on two Dask
workers; the winner, the ranking (race times within 0.1 %), the CPU of each, every dominant-frame
race against the same combination co-designed alone, and the bound against every co-designed
race (bound over race time ≤ 1 where the bound holds).

Usage (from the checkout)::

    python benchmarks/bench_build.py                      # build-small (3 x 3 x 3)
    python benchmarks/bench_build.py --propellers 2 --motors 1 --packs 2 --short
    python benchmarks/bench_build.py --dask               # and the build on 2 Dask workers

Each side runs in a process of its own (spawned one after another), so none reuses what another
built (co-design NLPs, point-mass solves are cached per process). Brute force keeps each
combination's result as a JSON line in ``--state`` (default: a folder under the system's
temporary directory named after the catalogue) and resumes from it: an hour of CPU survives a
stop. ``--propellers/--motors/--packs N`` keep the first N of each kind of build-small;
``--short`` flies the co-design tests' short track (tests/data/codesign/short-track.yaml) on 16
intervals instead of the paper track. CPU is ``time.process_time`` of the process plus, for the
Dask build, every worker's co-design CPU (``Build.cpu_s``); wall time depends on what else the
machine runs. Writes ``benchmarks/RESULTS-build.md`` (dated summary first) and prints the same.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
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


def problem_of(args: argparse.Namespace, backend: str = "serial"):
    """build-small with the first N parts of each kind, on ``backend`` (serial, or dask with two
    local workers), uncertified."""
    full = load_build_problem("build-small")
    b = full.build
    pick = {"propellers": list(b.propellers)[:args.propellers],
            "motors": list(b.motors)[:args.motors], "packs": list(b.packs)[:args.packs]}
    over = [f"build.{k}=[{', '.join(v)}]" for k, v in pick.items()]
    over += ["build.certify=false", f"build.rank={args.rank}"]
    if args.short:  # the co-design tests' short track on their propeller grid
        over += [f"track={ROOT / 'tests/data/codesign/short-track.yaml'}",
                 "limit_lap.intervals=16",
                 "limit_lap.starts=[closed-loop, point-mass, coarse-grid]"]
    where = ["backend.name=serial"] if backend == "serial" else \
        ["backend.name=dask", "backend.workers=2"]
    return load_build_problem("build-small", over + where), over


def size_of(args: argparse.Namespace) -> str:
    return f"{args.propellers}x{args.motors}x{args.packs}" + ("-short" if args.short else "")


def state_file(args: argparse.Namespace) -> Path:
    folder = Path(args.state) if args.state else \
        Path(tempfile.gettempdir()) / "casadrone-bench-build"
    return folder / f"brute-{size_of(args)}-rank{args.rank}.jsonl"


def brute_force(args: argparse.Namespace) -> dict:
    """Every screened-in combination co-designed and raced alone, each result a JSON line of
    the state file as it is known; the ones already there are read back, not solved again."""
    problem, _ = problem_of(args)
    kept, _ = screened(problem)
    path = state_file(args)
    path.parent.mkdir(parents=True, exist_ok=True)
    held = {}
    if path.exists():
        held = {d["label"]: d for d in map(json.loads, path.read_text().splitlines())}
    for c in kept:
        if c.label in held:
            continue
        w0 = time.perf_counter()
        r = solve_combination(problem, c, None)
        d = jsonable(r.as_dict()) | {"wall_s": time.perf_counter() - w0}
        with path.open("a") as f:
            f.write(json.dumps(d) + "\n")
        held[c.label] = d
    results = [held[c.label] for c in kept]
    return {"cpu_s": sum(r["cpu_s"] for r in results),
            "wall_s": sum(r["wall_s"] for r in results), "results": results}


def part(args: argparse.Namespace) -> None:
    """One side in this (fresh) process: its results, CPU and wall as JSON on stdout."""
    if args.part == "brute":
        print(json.dumps(brute_force(args)))
        return
    problem, _ = problem_of(args, args.part)
    done = build(problem)
    print(json.dumps(jsonable({"cpu_s": done.cpu_s, "wall_s": done.wall_time_s,
                               "results": [r.as_dict() for r in done.results]})))


def run_part(name: str, args: argparse.Namespace) -> dict:
    """This script for one side, in a process of its own (no cache shared with another); its
    JSON kept beside the brute force state, and read back from there with ``--reuse``."""
    kept = state_file(args).with_name(f"{name}-{size_of(args)}-rank{args.rank}.json")
    if args.reuse and kept.exists() and name != "brute":
        return json.loads(kept.read_text())
    argv = [a for a in sys.argv[1:] if a != "--reuse"]
    out = subprocess.run([sys.executable, __file__, *argv, "--part", name],
                         stdout=subprocess.PIPE, text=True, check=True).stdout
    kept.parent.mkdir(parents=True, exist_ok=True)
    kept.write_text(out.splitlines()[-1])
    return json.loads(out.splitlines()[-1])


def ranked(side: dict, rank: int) -> list[dict]:
    return sorted((r for r in side["results"] if r["outcome"] == "raced" and r["feasible"]),
                  key=lambda r: (r["race_s"], r["label"]))[:rank]


def same_ranking(a: list[dict], b: list[dict]) -> bool:
    """The same labels in the same order, race times within 0.1 %."""
    return [r["label"] for r in a] == [r["label"] for r in b] and all(
        abs(x["race_s"] - y["race_s"]) <= 1e-3 * x["race_s"] for x, y in zip(a, b, strict=True))


def solved_by(side: dict, how: str) -> int:
    """How many combinations of a build (raced or failed) found their geometry ``how``:
    "co-design", "dominance" (raced at the box's dominant frame, without a co-design) or
    "descent" (that frame moved by its race's gradient)."""
    return sum(r["outcome"] in ("raced", "failed") and r.get("geometry_by", "co-design") == how
               for r in side["results"])


def codesigned(side: dict) -> int:
    return solved_by(side, "co-design")


def dominant(side: dict) -> int:
    return solved_by(side, "dominance")


def descended(side: dict) -> int:
    return solved_by(side, "descent")


def winner_alone(args: argparse.Namespace, side: dict
                 ) -> tuple[str, float, float, float, float]:
    """The build's winner flown again alone: its parts at its co-designed geometry, the race
    solved from the problem's own starts (no seed), in this process; (label, the build's race,
    this race, CPU s, the race of the same parts at the template's geometry: what the geometry
    still gives once the parts are chosen)."""
    from casadrone.airframe import with_theta
    from casadrone.build.solve import combination_start, lap_options, race_track
    from casadrone.limit.race import race

    problem, _ = problem_of(args)
    best = ranked(side, 1)[0]
    combo = next(c for c in screened(problem)[0] if c.label == best["label"])
    start = combination_start(problem, combo)
    c0 = time.process_time()
    alone = race(with_theta(start, best["theta"]), race_track(problem, None),
                 lap_options(problem, start))
    cpu = time.process_time() - c0
    template = race(start, race_track(problem, None), lap_options(problem, start))
    return best["label"], best["race_s"], alone.lap.lap_time_s, cpu, template.lap.lap_time_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    for kind, n in (("propellers", 3), ("motors", 3), ("packs", 3)):
        ap.add_argument(f"--{kind}", type=int, default=n)
    ap.add_argument("--rank", type=int, default=3)
    ap.add_argument("--short", action="store_true", help="the short test track instead of "
                    "build-small's paper track")
    ap.add_argument("--dask", action="store_true", help="also the build on two Dask workers")
    ap.add_argument("--state", help="folder of brute force's resumable results")
    ap.add_argument("--reuse", action="store_true", help="the builds' results kept by an earlier "
                    "run of this command (brute force always resumes from its state)")
    ap.add_argument("--part", choices=("brute", "serial", "dask"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.part:
        part(args)
        return
    _, over = problem_of(args)
    sides = ("brute", "serial", "dask") if args.dask else ("brute", "serial")
    got = {name: run_part(name, args) for name in sides}  # one after another
    brute, bb = got["brute"], got["serial"]
    want = ranked(brute, args.rank)
    same = same_ranking(want, ranked(bb, args.rank))
    by_label = {r["label"]: r for r in bb["results"]}
    ratios = [by_label[r["label"]]["bound_s"] / r["race_s"] for r in brute["results"]
              if r["label"] in by_label and r["race_s"] is not None
              and by_label[r["label"]]["bound_s"] is not None]
    co = codesigned(bb)
    dom = [(r, by_label[r["label"]]) for r in brute["results"] if r["race_s"] is not None
           and by_label.get(r["label"], {}).get("geometry_by") == "dominance"
           and by_label[r["label"]].get("race_s") is not None]
    dom_gap = max((abs(b["race_s"] - r["race_s"]) / r["race_s"] for r, b in dom),
                  default=math.nan)
    size = size_of(args)
    cmd = "python benchmarks/bench_build.py" + (
        "" if size == "3x3x3" else
        f" --propellers {args.propellers} --motors {args.motors} --packs {args.packs}") + (
        f" --rank {args.rank}" if args.rank != 3 else "") + (" --short" if args.short else "") + (
        " --dask" if args.dask else "")
    lines = [f"# casadrone build against brute force ({size} catalogue of build-small)", "",
             f"Problem: build-small with {' '.join(over)}. Each side in a process of its own "
             "(no in-process cache shared), one after another.", "",
             "| | CPU s | wall s | co-designed | raced at the dominant frame | moved from it by "
             "descent |", "|---|---|---|---|---|---|",
             f"| brute force (each alone, serial) | {brute['cpu_s']:.1f} | {brute['wall_s']:.1f} "
             f"| {len(brute['results'])} | 0 | 0 |",
             f"| build, serial | {bb['cpu_s']:.1f} | {bb['wall_s']:.1f} | {co} | "
             f"{dominant(bb)} | {descended(bb)} |"]
    if "dask" in got:
        dk = got["dask"]
        lines.append(f"| build, 2 Dask workers | {dk['cpu_s']:.1f} | {dk['wall_s']:.1f} | "
                     f"{codesigned(dk)} | {dominant(dk)} | {descended(dk)} |")
    order = [r["label"] for r in want] == [r["label"] for r in ranked(bb, args.rank)]
    gaps = ", ".join(f"{100 * (b['race_s'] - w['race_s']) / w['race_s']:+.3f} %"
                     for w, b in zip(want, ranked(bb, args.rank), strict=False))
    slower = all(b["race_s"] <= w["race_s"] * (1 + 1e-3)
                 for w, b in zip(want, ranked(bb, args.rank), strict=False))
    lines += ["", f"Same winner and ranking as brute force (race times within 0.1 %): {same}. "
              f"The same combinations in the same order: {order}; the build's ranked races "
              f"against brute force's: {gaps}; none more than 0.1 % slower: {slower}.",
              f"The {len(dom)} combinations raced at their box's dominant frame without a "
              f"co-design race within {100 * dom_gap:.3f} % of their co-designed race alone."]
    if "dask" in got:
        dsame = same_ranking(ranked(bb, args.rank), ranked(got["dask"], args.rank))
        lines.append(f"Two Dask workers rank as the serial build: {dsame}.")
    label, built, alone, alone_cpu, template = winner_alone(args, bb)
    lines += [f"The winner ({label}) raced again alone at its co-designed geometry, from the "
              f"problem's starts: {alone:.4f} s against the build's {built:.4f} s "
              f"({100 * (alone - built) / built:+.3f} %, {alone_cpu:.0f} s CPU). The same parts "
              f"at the template's geometry race {template:.4f} s: the geometry gives "
              f"{100 * (template - built) / template:.2f} % once the parts are chosen."]
    lines += ["", "| combination | brute force | build | build outcome | bound s |",
              "|---|---|---|---|---|"]
    for r in brute["results"]:
        b = by_label.get(r["label"], {})
        fig = (f"{r['race_s']:.4f} s" if r["race_s"] is not None
               else f"{r['outcome']}: {r['reason']}")
        bfig = f"{b['race_s']:.4f} s" if b.get("race_s") is not None else "-"
        bound = b.get("bound_s")
        how = "" if b.get("outcome") != "raced" else {
            "dominance": ", dominant frame", "descent": ", descent from the dominant frame"}.get(
            b.get("geometry_by", "co-design"), ", co-designed")
        lines.append(f"| {r['label']} | {fig} | {bfig} | {b.get('outcome', '-')}{how} | "
                     f"{'-' if bound is None else f'{bound:.4f}'} |")
    for r in bb["results"]:
        if r["outcome"] == "refused":
            lines.append(f"| {r['label']} | - | - | refused: {r['reason']} | - |")
    lines += ["", f"Bound over race time: largest {max(ratios, default=math.nan):.3f} "
              "(at most 1 where the bound holds).", "", "## Machine", "",
              "\n".join(f"- {k}: {v}" for k, v in describe().items())]
    fig = (f"{bb['cpu_s']:.0f} s CPU against {brute['cpu_s']:.0f} s "
           f"({bb['cpu_s'] / brute['cpu_s']:.2f}x); same order: {order}, races within 0.1 %: "
           f"{same} ({gaps}); dominant-frame "
           f"races within {100 * dom_gap:.3f} % of their co-design")
    if "dask" in got:
        fig += f"; 2 Dask workers rank as serial: {dsame}"
    rows = [(f"build of a {size} catalogue against brute force co-design", fig, f"`{cmd}`")]
    text = with_summary("\n".join(lines) + "\n", rows)
    RESULTS.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
