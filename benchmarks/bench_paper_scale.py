"""Paper-scale runs, measured (issue 10, item 4): paper-run1 and paper-run2 to the end.

Each problem (850 + 350 × 850 = 298 350 evaluations) runs with ``casadrone run`` into
``RUN_ROOT/<problem>``; per generation the runner writes ``timings.csv`` in the run directory
(evaluation time, the coordinator's steps, archive size; see ``casadrone/rundir/timings.py``),
so a stopped run that is resumed keeps the record of its earlier generations. The script then
writes ``benchmarks/RESULTS-paper-scale.md`` from the run directories: per run the total wall
time, evaluation and coordinator time, the coordinator's share at the end of the run, and a
per-generation table (every 25th generation; the full record stays in each ``timings.csv``).

The full measurement, on a quiet machine, is one command (run it again after any stop: finished
runs are skipped, an interrupted one continues with ``casadrone resume``):

    python benchmarks/bench_paper_scale.py --run-root runs/paper-scale --workers 2

A short validation run (3 generations per problem):

    python benchmarks/bench_paper_scale.py --run-root /tmp/paper-short --generations 3

Options: ``--problems`` (default paper-run1 paper-run2), ``--generations`` (override
``algorithm.generations``; the report says so), ``--workers`` and ``--backend`` (default
processes; the evaluation backend), ``--report-only`` (only rebuild the results file from the
run directories), ``--reference DIR`` (compare each run's ``pareto.csv`` byte for byte with
``DIR/<problem>/pareto.csv``), ``--out``. Targets (issue 10) on 2 cores: ≤ 20 min per paper
run, coordinator ≤ 10 % of the wall time at the end of the run.

While a run goes, the machine's 1-minute load average is sampled every 10 s into
``RUN_DIR/load.csv`` (the coordinator shares its 2 cores with the workers and with anyone else:
a load above 2 means the measured times are inflated), and the report gives its range.
The history, checkpoint and timings row of each generation are written in the background behind
the next generation's evaluation (``casadrone/rundir/writer.py``): the coordinator's
"history" step is its wait for them, and the seconds the writes took are reported apart.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

CLI = [sys.executable, "-c", "from casadrone.cli import app; app()"]
COORDINATOR = ("ask_s", "advance_s", "statistics_s", "history_s", "checkpoint_s")


def run_or_resume(problem: str, run_dir: Path, generations: int | None, backend: str,
                  workers: int) -> float:
    """Run ``problem`` into ``run_dir`` to its end, resuming it if it was stopped (``casadrone
    resume`` also restarts a run stopped before its first checkpoint); return the wall time of
    this call (s)."""
    manifest = run_dir / "manifest.json"
    if manifest.exists() and json.loads(manifest.read_text()).get("status") == "completed":
        print(f"{run_dir}: already complete", file=sys.stderr)
        return 0.0
    backend_args = ["--backend", backend, "-j", str(workers)]
    if manifest.exists():
        cmd = [*CLI, "resume", str(run_dir), *backend_args]
    else:
        overrides = [] if generations is None else [f"algorithm.generations={generations}"]
        cmd = [*CLI, "run", problem, *overrides, "--out", str(run_dir), *backend_args]
    print(" ".join(cmd[3:]), file=sys.stderr, flush=True)
    start = time.perf_counter()
    done = threading.Event()
    sampler = threading.Thread(target=sample_load, args=(run_dir, done), daemon=True)
    sampler.start()
    try:
        subprocess.run(cmd, check=True)
    finally:
        done.set()
        sampler.join()
    return time.perf_counter() - start


def sample_load(run_dir: Path, done: threading.Event, every_s: float = 10.0) -> None:
    """Append the 1-minute load average to ``run_dir/load.csv`` every ``every_s`` until
    ``done``."""
    while not done.wait(every_s):
        if run_dir.is_dir():
            with open(run_dir / "load.csv", "a") as fh:
                fh.write(f"{time.strftime('%H:%M:%S', time.gmtime())},{os.getloadavg()[0]:.2f}\n")


def load_range(run_dir: Path) -> str:
    """The sampled load of the run's sessions: min, mean and max of the 1-minute average."""
    try:
        loads = [float(line.split(",")[1]) for line in
                 (run_dir / "load.csv").read_text().splitlines() if line]
    except (OSError, IndexError, ValueError):
        return "not sampled"
    if not loads:
        return "not sampled"
    return (f"1-minute load average during the run: min {min(loads):.2f}, mean "
            f"{sum(loads) / len(loads):.2f}, max {max(loads):.2f} ({len(loads)} samples, 2 cores)")


def summary(run_dir: Path) -> list[str]:
    """The results section of one run directory."""
    from casadrone.rundir.store import RunStore
    from casadrone.rundir.timings import read_timings

    store = RunStore(run_dir)
    m, problem = store.manifest, store.problem()
    rows = read_timings(run_dir)
    if not rows:
        return [f"## {problem.name}", "", f"`{run_dir}`: no generation stored yet.", ""]
    total = {k: sum(r[k] for r in rows) for k in ("wall_s", "evaluate_s", "coordinator_s",
                                                   "coordinator_cpu_s", *COORDINATOR)}
    writes = [r["write_s"] for r in rows if r.get("write_s") is not None]
    tail = rows[-10:]
    end_share = sum(r["coordinator_s"] for r in tail) / sum(r["wall_s"] for r in tail)
    mean = {k: sum(r[k] for r in tail) / len(tail)
            for k in ("evaluate_s", "wall_s", "coordinator_s", *COORDINATOR)}
    evals = rows[-1]["n_evaluations"]
    a = problem.algorithm
    lines = [
        f"## {problem.name}",
        "",
        f"- run directory `{run_dir}`; status {m.get('status')}; started {m.get('started')}, "
        f"finished {m.get('finished')}; resumed: {m.get('resumed') or 'never'}; backend "
        f"{m.get('backend')} (that of the run's last start: see the command above)",
        f"- {a.name}, population {a.population}, {a.generations} generations, "
        f"n_ind_ga {a.settings.get('n_ind_ga')}, n_div {a.settings.get('n_div')}; "
        f"{len(rows)} generations recorded, {evals} evaluations",
        f"- total wall time (sum over generations) {total['wall_s']:.0f} s = "
        f"{total['wall_s'] / 60:.1f} min (target ≤ 20 min); evaluation "
        f"{total['evaluate_s']:.0f} s ({evals / total['evaluate_s']:.0f} evaluations/s); "
        f"coordinator {total['coordinator_s']:.1f} s wall, {total['coordinator_cpu_s']:.1f} s CPU "
        "(coordinating process)",
        f"- coordinator share of the wall time: {total['coordinator_s'] / total['wall_s']:.1%} "
        f"over the run, {end_share:.1%} over its last {len(tail)} generations (target ≤ 10 % "
        "at the end)",
        "- coordinator time by step (s, summed): "
        + ", ".join(f"{k[:-2]} {total[k]:.1f}" for k in COORDINATOR),
        f"- last {len(tail)} generations, mean per generation (ms): evaluate "
        f"{1e3 * mean['evaluate_s']:.0f}, coordinator {1e3 * mean['coordinator_s']:.1f} ("
        + ", ".join(f"{k[:-2]} {1e3 * mean[k]:.1f}" for k in COORDINATOR)
        + f"), wall {1e3 * mean['wall_s']:.0f}",
        (f"- background writes (history, checkpoint; behind the next evaluation): "
         f"{sum(writes):.1f} s over {len(writes)} generations, mean "
         f"{1e3 * sum(writes) / len(writes):.1f} ms, max {1e3 * max(writes):.1f} ms"
         if writes else "- background writes: none recorded (a run before they existed)"),
        f"- {load_range(run_dir)}",
        f"- archive at the end: {rows[-1]['archive_size']} members",
        "",
        "| generation | archive | evaluate (s) | coordinator (s) | of which advance | statistics "
        "| history | checkpoint | wall (s) | coordinator share |",
        "|" + "---:|" * 10,
    ]
    for r in rows:
        if r["generation"] % 25 and r is not rows[-1]:
            continue
        lines.append(
            f"| {r['generation']} | {r['archive_size']} | {r['evaluate_s']:.2f} "
            f"| {r['coordinator_s']:.3f} | {r['advance_s']:.3f} | {r['statistics_s']:.3f} "
            f"| {r['history_s']:.3f} | {r['checkpoint_s']:.3f} | {r['wall_s']:.2f} "
            f"| {r['coordinator_s'] / r['wall_s']:.1%} |")
    lines.append("")
    return lines


def same_front(run_dir: Path, reference: Path) -> str:
    """Whether the run's pareto.csv equals the reference run's, byte for byte."""
    try:
        same = (run_dir / "pareto.csv").read_bytes() == (reference / "pareto.csv").read_bytes()
    except OSError as exc:
        return f"- pareto.csv against `{reference}`: not compared ({exc.strerror})"
    return (f"- pareto.csv against `{reference / 'pareto.csv'}`: "
            + ("identical, byte for byte" if same else "**DIFFERENT**"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run-root", type=Path, default=Path("runs/paper-scale"))
    parser.add_argument("--problems", nargs="*", default=["paper-run1", "paper-run2"])
    parser.add_argument("--generations", type=int, default=None,
                        help="override algorithm.generations (validation runs)")
    parser.add_argument("--backend", default="processes", choices=["serial", "processes", "dask"])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--report-only", action="store_true")
    parser.add_argument("--reference", type=Path, default=None,
                        help="compare each pareto.csv with REFERENCE/<problem>/pareto.csv")
    parser.add_argument("--out", type=Path, default=HERE / "RESULTS-paper-scale.md")
    args = parser.parse_args()

    import machine

    command = " ".join(["python benchmarks/bench_paper_scale.py", "--run-root",
                        str(args.run_root), "--workers", str(args.workers), "--backend",
                        args.backend] + ([] if args.generations is None
                                         else ["--generations", str(args.generations)])
                       + ([] if args.reference is None else ["--reference", str(args.reference)]))
    sessions = []
    for problem in args.problems:
        run_dir = args.run_root / problem
        if not args.report_only:
            wall = run_or_resume(problem, run_dir, args.generations, args.backend, args.workers)
            sessions.append(f"- {problem}: {wall:.0f} s of wall time under the command above")
    lines = [
        "# Paper-scale runs: paper-run1 and paper-run2, measured",
        "",
        f"`{command}` — settings and method in the script's docstring. Per-generation times "
        "come from each run directory's `timings.csv` (written by the runner, kept across "
        "resumes).",
        "",
        machine.markdown(),
        *sessions,
        "",
    ]
    if args.generations is not None:
        lines += [f"**Shortened validation run: algorithm.generations={args.generations}, not "
                  "the paper's 350.**", ""]
    for problem in args.problems:
        run_dir = args.run_root / problem
        if (run_dir / "manifest.json").exists():
            lines += summary(run_dir)
            if args.reference is not None:
                lines[-1:-1] = ["", same_front(run_dir, args.reference / problem)]
        else:
            lines += [f"## {problem}", "", f"`{run_dir}`: not run yet.", ""]
    text = "\n".join(lines)
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
