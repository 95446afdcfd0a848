"""The coordinator of a finished paper-scale run, alone: the run replayed from its history.

A finished run directory (``--run``, e.g. ``runs/paper-scale/paper-run1``) is run again into a new
directory with the real runner (ask → evaluate → advance → statistics → checkpoint, background
writes), but each generation's evaluations are read back from the finished run's
``history.sqlite`` instead of being computed (one generation at a time, by the runner's own
``ReplayBackend``, which checks them candidate by candidate against what the algorithm asks for,
as a resume from history does). The evaluation step is then only the read; everything else is
the coordinator's real work on the run's real stream of children: archive growth, grid moves, P
updates, hypervolume, checkpoints. The result must be the finished run's ``pareto.csv`` byte for
byte.

Reported: the coordinator's wall and CPU time per generation (``timings.csv`` of the replay), by
step, over the whole run and over its last 10 generations, and the time spent in the garbage
collector (``gc.callbacks``). The share of a live run follows from these and the evaluation time
of the live run: ``coordinator / (coordinator + evaluate)``.

Run: ``python benchmarks/bench_replay.py --run runs/paper-scale/paper-run1 --out /tmp/replay1``
(``--profile N``: cProfile over the last N generations, top functions printed; ``--results F``:
the markdown file the summary is written to, ``benchmarks/RESULTS-replay.md`` by default; a
second run with ``--append`` adds its section, e.g. for paper-run2 or another revision).
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import filecmp  # noqa: E402
import gc  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))


class StoredGenerations:
    """A finished run's generations as ``runner.ReplayBackend`` serves them, read from its
    ``history.sqlite`` one generation at a time when asked (holding all ~300 000 records at
    once would give the garbage collector work a live run does not have); ``on_read(g)`` is
    called before generation ``g`` is read."""

    def __init__(self, run: Path, on_read=None):
        from casadrone.rundir.store import RunStore

        self.store = RunStore(run)
        self.manifest = self.store.manifest
        self.n = len(self.store.generations())
        self.on_read = on_read

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, generation: int) -> list:
        from casadrone.rundir.store import record_of

        if self.on_read is not None:
            self.on_read(generation)
        return [record_of(r, self.manifest) for r in self.store.history(generation)]


class NoLiveEvaluation:
    """The backend behind the replay: a finished run has nothing left to evaluate."""

    def evaluate(self, study, X):
        raise SystemExit("the replay asked for a generation the finished run does not have")

    def close(self) -> None:
        pass

    terminate = close


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--run", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True, help="new run directory of the replay")
    ap.add_argument("--profile", type=int, default=0, help="cProfile the last N generations")
    ap.add_argument("--sort", default="tottime", help="pstats sort key of --profile's table")
    ap.add_argument("--results", type=Path, default=HERE / "RESULTS-replay.md")
    ap.add_argument("--append", action="store_true", help="add to --results, do not replace it")
    args = ap.parse_args()

    from casadrone.optimise import runner
    from casadrone.rundir.store import RunStore

    problem = RunStore(args.run).problem()
    stored = StoredGenerations(args.run)
    runner.make_backend = lambda cfg, without_main=False: runner.ReplayBackend(
        stored, NoLiveEvaluation(), why=f"replaying {args.run}")

    gc_time = [0.0, 0]
    gc_start = [0.0]

    def on_gc(phase, info):
        if phase == "start":
            gc_start[0] = time.perf_counter()
        else:
            gc_time[0] += time.perf_counter() - gc_start[0]
            gc_time[1] += info["generation"] == 2

    gc.callbacks.append(on_gc)
    profiler = None
    if args.profile:
        import cProfile

        profiler = cProfile.Profile()
        first = problem.algorithm.generations + 1 - args.profile

        def switch(g):
            if g == first:
                profiler.enable()
        stored.on_read = switch

    t0, c0 = time.perf_counter(), time.process_time()
    runner.run(problem, args.out, quiet=True)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if profiler is not None:
        import pstats

        profiler.disable()
        pstats.Stats(profiler).sort_stats(args.sort).print_stats(25)

    with open(args.out / "timings.csv") as f:
        rows = list(csv.DictReader(f))
    last = rows[-10:]
    same = filecmp.cmp(args.out / "pareto.csv", args.run / "pareto.csv", shallow=False)

    def mean_ms(rs, key):
        return 1e3 * np.mean([float(r[key]) for r in rs])

    steps = ("ask_s", "advance_s", "statistics_s", "history_s", "checkpoint_s")
    lines = [
        f"- replay of `{args.run}`: {len(rows)} generations, wall {wall:.1f} s, CPU {cpu:.1f} s, "
        f"garbage collection {gc_time[0]:.1f} s ({gc_time[1]} full collections)",
        "- whole run, coordinator (s): "
        f"{sum(float(r['coordinator_s']) for r in rows):.1f} wall, "
        f"{sum(float(r['coordinator_cpu_s']) for r in rows):.1f} CPU; by step: "
        + ", ".join(f"{k[:-2]} {sum(float(r[k]) for r in rows):.1f}" for k in steps),
        "- last 10 generations, mean per generation (ms): "
        f"coordinator {mean_ms(last, 'coordinator_s'):.1f} wall, "
        f"{mean_ms(last, 'coordinator_cpu_s'):.1f} CPU; "
        + ", ".join(f"{k[:-2]} {mean_ms(last, k):.1f}" for k in steps)
        + f"; archive {last[-1]['archive_size']}",
        f"- pareto.csv equal to the finished run's: {same}",
    ]
    print("\n".join(lines))
    import machine

    section = "\n".join([f"## {args.run.name}", "", machine.markdown(), *lines, ""])
    head = ("# The coordinator alone: finished paper-scale runs replayed from their history\n\n"
            "`python benchmarks/bench_replay.py --run RUN --out NEW_DIR` (method in its "
            "docstring).\n\n")
    if args.append and args.results.exists():
        args.results.write_text(args.results.read_text() + "\n" + section)
    else:
        args.results.write_text(head + section)


if __name__ == "__main__":
    main()
