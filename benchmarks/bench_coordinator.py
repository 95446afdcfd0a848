"""The coordinator alone: seconds per generation against archive size (issue 10, item 5).

ev-MOGA with paper-run1's algorithm settings (P 850, 850 children per generation, 200 divisions,
G = 350 for the dd/σ schedule) on pymoo's DTLZ2 with 7 variables and 5 objectives, whose
evaluation is nearly free, run by casadrone's own runner (serial backend) into a run directory.
The runner's ``timings.csv`` gives, per generation, the wall-clock time of each coordinator step:
``ask`` (children), ``advance`` (ev-MOGA's archive and P update), ``statistics`` (archive size
and the progress hypervolume, every generation), ``history`` (writing ``history.sqlite`` and the
checkpoint file, fsyncs included), ``checkpoint`` (pickling the algorithm), and the
coordinator's CPU time. The process is pinned to one core (``--core``) with one BLAS thread, and
the runner writes each generation's files in turn (``runner.BACKGROUND_WRITES = False``): on one
core the background writes of a real run would only move into the evaluation step, so here they
are counted where they happen.

The archive reaches 10 000 members near generation 28 (seed 1); the run stops after the first
generation that ends with at least ``--archive`` members.

Acceptance target (issue 10): coordinator <= 0.5 s per generation of 850 children at an archive of
5 000 with 5 objectives on one core.

Run: ``python benchmarks/bench_coordinator.py [--archive 10000] [--core 0]``
Writes ``benchmarks/RESULTS-coordinator.md``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

STEPS = ("ask_s", "advance_s", "statistics_s", "history_s", "checkpoint_s")


class Enough(Exception):
    """Raised by the progress callback once the archive is large enough."""


def problem(generations: int):
    from casadrone.config.problem import ProblemConfig

    return ProblemConfig.model_validate({
        "name": "coordinator-dtlz2-5",
        "description": "DTLZ2, 7 variables, 5 objectives, paper-run1's ev-MOGA settings",
        "test_problem": {"name": "dtlz2", "n_var": 7, "n_obj": 5},
        "algorithm": {"name": "evmoga", "population": 850, "generations": generations,
                      "settings": {"n_ind_ga": 850, "n_div": 200}},
        "seed": 1,
    })


def measure(run_dir: Path, archive: int, generations: int) -> tuple[list[dict], float]:
    import casadrone.optimise.runner as runner
    from casadrone.optimise.runner import run
    from casadrone.rundir.timings import read_timings

    runner.BACKGROUND_WRITES = False  # see the module docstring
    from casadrone.config.problem import BackendConfig

    def progress(gen: int, stats: dict) -> None:
        print(f"gen {gen:>3}  archive {stats['archive_size']:>6}", file=sys.stderr, flush=True)
        if stats["archive_size"] >= archive:
            raise Enough

    start = time.perf_counter()
    try:
        run(problem(generations), run_dir, BackendConfig(name="serial"), progress=progress)
    except Enough:
        pass
    return read_timings(run_dir), time.perf_counter() - start


def table(rows: list[dict]) -> list[str]:
    head = ("| generation | archive | ask | advance (archive + P) | statistics | history "
            "| checkpoint | coordinator (wall) | coordinator (CPU) | evaluate (free) |")
    lines = [head, "|" + "---:|" * 10]
    for r in rows:
        lines.append(
            f"| {r['generation']} | {r['archive_size']} | "
            + " | ".join(f"{r[k]:.3f}" for k in STEPS)
            + f" | {r['coordinator_s']:.3f} | {r['coordinator_cpu_s']:.3f} "
              f"| {r['evaluate_s']:.3f} |")
    return lines


def at_size(rows: list[dict], size: int) -> str:
    """Coordinator time around an archive size: the generation that first reaches it, and the
    mean over it and its neighbours."""
    hit = next((i for i, r in enumerate(rows) if r["archive_size"] >= size), None)
    if hit is None:
        return f"- archive {size}: not reached"
    near = rows[max(0, hit - 2):hit + 3]
    mean = {k: sum(r[k] for r in near) / len(near) for k in ("coordinator_s", "coordinator_cpu_s")}
    r = rows[hit]
    return (f"- archive {size}: generation {r['generation']} ({r['archive_size']} members): "
            f"coordinator {r['coordinator_s']:.3f} s wall, {r['coordinator_cpu_s']:.3f} s CPU; "
            f"mean of generations {near[0]['generation']}–{near[-1]['generation']}: "
            f"{mean['coordinator_s']:.3f} s wall, {mean['coordinator_cpu_s']:.3f} s CPU")


def summary_row(rows: list[dict]) -> tuple[str, str, str]:
    """The performance page's row: the coordinator's wall time at the generation that first
    reaches an archive of 5 000 and of 10 000 members."""

    def at(size: int) -> str:
        hit = next((r for r in rows if r["archive_size"] >= size), None)
        return f"{hit['coordinator_s']:.2f} s" if hit else "not reached"

    return ("ev-MOGA coordinator alone, 850 children, 5 objectives, archive 5 000 / 10 000, "
            "one core", f"{at(5000)} / {at(10_000)} per generation",
            "`python benchmarks/bench_coordinator.py`")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--archive", type=int, default=10_000,
                        help="stop after the first generation ending with this many members")
    parser.add_argument("--generations", type=int, default=350,
                        help="G of the dd/sigma schedule (paper: 350)")
    parser.add_argument("--core", type=int, default=0, help="CPU core to pin to (-1: no pin)")
    parser.add_argument("--run-dir", type=Path, default=None,
                        help="run directory (default: a temporary one, removed afterwards)")
    parser.add_argument("--out", type=Path, default=HERE / "RESULTS-coordinator.md")
    args = parser.parse_args()

    import machine

    if args.core >= 0 and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {args.core})
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = args.run_dir or Path(tmp) / "run"
        rows, wall = measure(run_dir, args.archive, args.generations)
    load_after = os.getloadavg()
    lines = [
        "# The coordinator alone: seconds per generation against archive size",
        "",
        "`python benchmarks/bench_coordinator.py` — ev-MOGA with paper-run1's settings (P 850, "
        "850 children per generation, n_div 200, G 350, seed 1) on DTLZ2 with 7 variables and 5 "
        "objectives (evaluation nearly free), serial backend, one process pinned to core "
        f"{args.core}, one BLAS thread; per-generation times from the runner's `timings.csv` "
        "(seconds). Settings and method in the script's docstring.",
        "",
        machine.markdown(),
        f"- load average before {load_before[0]:.2f}, after {load_after[0]:.2f} "
        "(the machine's other users share its 2 cores: wall-clock times are inflated by up to "
        "the load; CPU times much less)",
        f"- wall time of the benchmark: {wall:.0f} s, {len(rows)} generations",
        "",
        "Target (issue 10): coordinator <= 0.5 s per generation of 850 children at an archive of "
        "5 000 with 5 objectives on one core.",
        "",
        *[at_size(rows, s) for s in (1000, 2000, 5000, 7500, 10000)],
        "",
        "Statistics: the progress hypervolume (`casadrone.optimise.hypervolume`: of every "
        "feasible evaluation so far in the run's fixed space; from 4 objectives a fixed-sample "
        "estimate kept incrementally, so each generation tests only its own new points) and "
        "the archive size, every generation. "
        "Coordinator = ask + advance + statistics + history + checkpoint (history: writing the "
        "history and the checkpoint file, in turn here; checkpoint: pickling); CPU = the "
        "coordinating process's CPU time over those steps.",
        "",
        *table(rows),
    ]
    text = machine.with_summary("\n".join(lines), [summary_row(rows)])
    args.out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
