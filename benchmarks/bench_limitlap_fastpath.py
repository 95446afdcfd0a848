"""Benchmark: the limit lap's fast path (the command's default) against ``--certify``.

Each case is ``casadrone limit-lap FRAME [--track T] --json`` run as a user runs it, in a fresh
process (imports, the NLP's build, the point-mass reference, the starts, re-simulation and
sensitivities included; the solver blocks already compiled), once on the fast path and once
with ``--certify``. Per call: the lap, the chosen start and how its solve ended, certainty, the
iterations (of the chosen solve and of every solve), the CPU time of the process and its
children (fatrop solves in a forked child: casadrone.limit.watchdog) and the wall time. CPU is
the figure to compare: the machine is shared, wall time is inflated by the load.

Run: ``python benchmarks/bench_limitlap_fastpath.py --cases paper gates --modes fast certify``
(appends one JSON line per call to ``benchmarks/limitlap-fastpath.jsonl``, ``--log``, and
rewrites ``benchmarks/RESULTS-limitlap-fastpath.md`` from every line of the log: the cases can
be run one at a time). ``--report`` only rewrites the file.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import describe, markdown, summary_section  # noqa: E402

HERE = Path(__file__).resolve().parent
#: The cases of issue 43's acceptance: (name, frame, track or None, lap target s, CPU target s)
CASES: dict[str, tuple[str, str | None, float, float]] = {
    "paper": ("SY250", None, 3.8839, 10.0),
    "hs210": ("HS210", None, 3.8346, 10.0),
    "gates": ("SY250", "multigp-cdra-gates", 2.1625, 10.0),
    "propeller": ("SY250-propeller", None, 4.3650, 30.0),
    "3laps": ("SY250", "uzh-waypoints-3laps", float("inf"), 60.0),
}
#: Figures measured before the fast path (issue 43: the command's defaults then, four starts
#: and grid rounds with IPOPT, the blocks compiled), for the table's "before" column.
BEFORE = {"paper": (3.8800, 106), "hs210": (3.8307, 115), "gates": (2.1603, 114),
          "propeller": (4.3606, 353), "3laps": (11.692, 628)}


def children_cpu() -> float:
    """CPU seconds (user + system) of every waited-for child process and its descendants."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def command(case: str, mode: str, extra: list[str]) -> list[str]:
    frame, track, _, _ = CASES[case]
    return (["casadrone", "limit-lap", frame, "--json"] + (["--track", track] if track else [])
            + (["--certify"] if mode == "certify" else []) + extra)


def run(case: str, mode: str, extra: list[str]) -> dict:
    """One call of the command: its JSON figures, CPU and wall time."""
    cmd = command(case, mode, extra)
    c0, w0 = children_cpu(), time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, check=False)
    cpu, wall = children_cpu() - c0, time.perf_counter() - w0
    row = {"case": case, "mode": mode, "command": " ".join(cmd), "cpu_s": cpu, "wall_s": wall,
           "exit": out.returncode, "date": describe()["date"], "git": describe()["git"],
           "load": describe()["load"]}
    if out.returncode != 0:
        return row | {"error": out.stderr.strip().splitlines()[-1:]}
    r = json.loads(out.stdout)
    return row | {"status": r["status"], "lap_time_s": r["lap_time_s"], "start": r["start"],
                  "ending": r.get("ending", ""), "return_status": r.get("return_status", ""),
                  "certainty": r["certainty"], "spread_s": r["spread_s"],
                  "iterations": r["iterations"],
                  "all_iterations": sum(s["iterations"] for s in r["starts"]),
                  "solves": len(r["starts"]), "miss_m": r["resimulation_miss_m"],
                  "starts": [(s["start"], s.get("ending", ""), s["lap_time_s"],
                              s["iterations"], s["solver"]) for s in r["starts"]]}


def fmt(v, spec: str) -> str:
    return "–" if v is None or v != v else format(v, spec)


def table(rows: list[dict]) -> list[str]:
    out = ["| case | command | lap (s) | target lap (s) | chosen start, ending | certainty | "
           "iterations (chosen / all solves) | CPU (s) | target CPU (s) | wall (s) | before: "
           "lap / CPU (s) |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        _, _, lap_target, cpu_target = CASES[r["case"]]
        b_lap, b_cpu = BEFORE[r["case"]]
        if "lap_time_s" not in r:
            out.append(f"| {r['case']} | `{r['command']}` | error {r.get('error')} | | | | | "
                       f"{r['cpu_s']:.1f} | | {r['wall_s']:.0f} | |")
            continue
        out.append(
            f"| {r['case']} | `{r['command'].replace(' --json', '')}` | {r['lap_time_s']:.4f} | "
            f"{fmt(lap_target, '.4f') if lap_target != float('inf') else '–'} | "
            f"{r['start']}, {r['ending']} | {r['certainty']} | {r['iterations']} / "
            f"{r['all_iterations']} ({r['solves']} solves) | {r['cpu_s']:.1f} | "
            f"{cpu_target if r['mode'] == 'fast' else '–'} | {r['wall_s']:.0f} | "
            f"{b_lap:.4f} / {b_cpu} |")
    return out


def starts_table(rows: list[dict]) -> list[str]:
    out = ["| case | mode | every solve: start, ending, lap (s), iterations, solver |",
           "|---|---|---|"]
    for r in rows:
        if "starts" in r:
            per = "; ".join(f"{s[0]} {s[1]} {fmt(s[2], '.4f')} {s[3]} {s[4]}"
                            for s in r["starts"])
            out.append(f"| {r['case']} | {r['mode']} | {per} |")
    return out


def latest(rows: list[dict]) -> list[dict]:
    """The last row of each (case, mode), in CASES order then fast before certify."""
    last = {(r["case"], r["mode"]): r for r in rows}
    return [last[k] for k in sorted(last, key=lambda k: (list(CASES).index(k[0]),
                                                         k[1] != "fast"))]


def summary(rows: list[dict]) -> str:
    fast = {r["case"]: r for r in rows if r["mode"] == "fast" and "lap_time_s" in r}
    figure = "; ".join(f"{c} {r['lap_time_s']:.4f} s in {r['cpu_s']:.1f} s CPU"
                       for c, r in fast.items())
    return summary_section([("limit lap, the command's fast path (one start, fatrop) at the "
                             "defaults, blocks compiled, CPU of the process and children",
                             figure, "`python benchmarks/bench_limitlap_fastpath.py --cases "
                             + " ".join(fast) + " --modes fast certify`")])


def report(log: Path, out: Path) -> None:
    rows = latest([json.loads(line) for line in log.read_text().splitlines() if line.strip()])
    dates = sorted({r["date"][:10] for r in rows})
    fast = [r for r in rows if r["mode"] == "fast" and "lap_time_s" in r]
    lines = [
        "# Limit lap: the fast path against --certify", "",
        f"## Summary of {', '.join(dates)}", "",
        "What was measured: `casadrone limit-lap` as a user runs it (a fresh process, solver "
        "blocks compiled), on the fast path (the default: one start, fine-grid, with fatrop) "
        "and with `--certify` (four cold starts and grid rounds with IPOPT, the default "
        "before); CPU of the process and its children (one core's worth; the machine's 2 "
        "cores were shared with other jobs, so wall times are inflated).", "",
        *[f"- **{r['case']}**: {r['lap_time_s']:.4f} s in {r['cpu_s']:.1f} s CPU "
          f"(`{r['command'].replace(' --json', '')}`)" for r in fast], "",
        "Command: `python benchmarks/bench_limitlap_fastpath.py --cases "
        + " ".join(dict.fromkeys(r["case"] for r in rows)) + " --modes fast certify`", "",
        "Machine (at the report; each row's own date, revision and load are in "
        "`benchmarks/limitlap-fastpath.jsonl`):", "", markdown(), "",
        "## Laps, CPU and iterations", "", *table(rows), "",
        "## Every solve", "", *starts_table(rows), "", summary(rows)]
    out.write_text("\n".join(lines), encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["paper", "hs210", "gates"],
                    choices=list(CASES))
    ap.add_argument("--modes", nargs="+", default=["fast"], choices=["fast", "certify"])
    ap.add_argument("--extra", nargs="*", default=[], help="more options for the command")
    ap.add_argument("--log", type=Path, default=HERE / "limitlap-fastpath.jsonl")
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-limitlap-fastpath.md")
    ap.add_argument("--report", action="store_true", help="only rewrite --out from --log")
    args = ap.parse_args(argv)
    if not args.report:
        for case in args.cases:
            for mode in args.modes:
                row = run(case, mode, args.extra)
                print(json.dumps(row), flush=True)
                with args.log.open("a", encoding="utf-8") as f:
                    f.write(json.dumps(row) + "\n")
    report(args.log, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
