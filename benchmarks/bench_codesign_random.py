"""Benchmark: the limit laps of random feasible Table 1 frames, the baseline co-design must beat.

For ``--n`` random frames of the template's decision variables inside paper Table 1 (default
SY250-components: the four geometry keys, mass and inertia from the parts; overlapping rotors
redrawn), on one core, the limit lap on the paper track:

- every frame primal-dual warm-started from the template's own limit lap (cold starts only if
  that fails: :func:`casadrone.limit.lap.limit_lap`'s fallback);
- the ``--top`` fastest frames then re-solved with the full cold starts (closed-loop and
  point-mass guesses, best of all), so that the best random frame is not a warm start's local
  optimum.

Writes a CSV of every frame (θ, lap, status, CPU) to ``--csv`` as it goes and prints the best.
Run: ``python benchmarks/bench_codesign_random.py --n 200 --csv benchmarks/codesign-random.csv``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import csv  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from casadrone.airframe import random_thetas, with_theta  # noqa: E402
from casadrone.config import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import DEFAULT_TRACK, TrackConfig  # noqa: E402
from casadrone.limit.lap import LapSeeds, LimitLapOptions, design_limit_lap  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--top", type=int, default=10)
    ap.add_argument("--intervals", type=int, default=LimitLapOptions().intervals)
    ap.add_argument("--template", default="SY250-components")
    ap.add_argument("--track", default=str(DEFAULT_TRACK))
    ap.add_argument("--csv", type=Path, default=Path("codesign-random.csv"))
    args = ap.parse_args(argv)
    template = load_airframe(args.template)
    track = load(TrackConfig, args.track)
    options = LimitLapOptions(intervals=args.intervals, sensitivities=False,
                              point_mass_reference=False)
    ref = design_limit_lap(template, track, options)
    print(f"reference {template.name}: {ref.status} {ref.lap_time_s:.4f} s", flush=True)
    warm, from_ref = replace(options, starts=()), LapSeeds(warm_starts=(ref,))
    thetas, rejected = random_thetas(template, args.n, args.seed)
    keys = list(thetas[0])
    rows = []
    with args.csv.open("w", newline="") as fh:
        out = csv.writer(fh)
        out.writerow(["frame", *keys, "status", "lap_time_s", "start", "cpu_s", "pass"])
        for i, theta in enumerate(thetas):
            cfg = with_theta(template, theta, name=f"frame{i}")
            c0 = time.process_time()
            lap = design_limit_lap(cfg, track, warm, from_ref)
            rows.append([i, *theta.values(), lap.status, lap.lap_time_s, lap.start,
                         time.process_time() - c0, "warm"])
            out.writerow(rows[-1])
            fh.flush()
            print(*rows[-1], flush=True)
        ok = sorted((r for r in rows if r[len(keys) + 1] == "completed"),
                    key=lambda r: r[len(keys) + 2])
        for r in ok[:args.top]:
            cfg = with_theta(template, thetas[r[0]], name=f"frame{r[0]}")
            c0 = time.process_time()
            lap = design_limit_lap(cfg, track, options, from_ref)
            row = [r[0], *thetas[r[0]].values(), lap.status, lap.lap_time_s, lap.start,
                   time.process_time() - c0, "cold"]
            out.writerow(row)
            fh.flush()
            print(*row, flush=True)
    print(f"{len(ok)}/{args.n} completed ({rejected} draws rejected as infeasible)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
