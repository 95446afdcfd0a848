"""Benchmark: is a limit-lap front's spread larger than the noise of its evaluations?

A run of ``problems/limit-lap.yaml`` scores each frame's J3_limit with the evaluation's own
starts (primal-dual warm starts from two per-study references, the closed-loop and point-mass
starts where those fail: :func:`casadrone.evaluate.evaluate_limit`). The limit-lap NLP has many
local optima, so a frame's J3_limit carries start noise. This script solves every front member
of a finished run again with the limit lap's default starts (``LimitLapOptions().starts``: the
best verified of closed-loop, point-mass, coarse-grid and fine-grid) and reports, per member,
the run's J3_limit, the re-solved best lap, their difference (positive: the run's evaluation
settled for a slower local optimum), the spread over the default starts, and, over the front,
the spread of J3_limit against the spread of that noise, and whether the front's order of
J3_limit survives (Spearman ρ).

Run: ``python benchmarks/bench_limitlap_front_noise.py RUN_DIR`` (a finished ``casadrone run
limit-lap --out RUN_DIR``); prints Markdown. One core; about 45 s of CPU per member.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import markdown  # noqa: E402
from casadrone.airframe import with_theta  # noqa: E402
from casadrone.limit.lap import LimitLapOptions, design_limit_lap  # noqa: E402
from casadrone.optimise.problem import Study, study_setup  # noqa: E402
from casadrone.rundir.store import RunStore  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir", type=Path)
    ap.add_argument("--index", default="J3_limit")
    ap.add_argument("--members", type=int, default=None, help="only the first N members")
    args = ap.parse_args()
    store = RunStore(args.run_dir)
    study = Study(store.problem())
    setup = study_setup(study)
    assert setup.limit is not None, f"{args.run_dir}: the run has no limit-lap index"
    header, rows = store.read_pareto()
    rows = rows[:args.members]
    n_var = len(header) - len(study.objective_names)
    col = header.index(args.index)
    options = replace(setup.limit, starts=LimitLapOptions().starts, sensitivities=False)
    lines = [f"Front of `{args.run_dir}` ({len(rows)} members), each re-solved with the default "
             f"starts {', '.join(options.starts)}; {options.intervals or 'default'} intervals "
             "per leg.", "",
             "| member | " + " | ".join(header[:n_var]) + f" | run's {args.index} (s) | "
             "default starts, best (s) | run − best (%) | certainty | spread over starts (%) | "
             "CPU (s) |", "|" + "---|" * (n_var + 7)]
    run_laps, best_laps = [], []
    for k, row in enumerate(rows):
        theta = {h: float(v) for h, v in zip(header[:n_var], row[:n_var], strict=True)}
        cfg = with_theta(setup.template, theta, base=setup.template_data)
        t0 = time.process_time()
        lap = design_limit_lap(cfg, setup.track, options)
        cpu = time.process_time() - t0
        ga = float(row[col])
        best = lap.lap_time_s if lap.completed else float("nan")
        run_laps.append(ga)
        best_laps.append(best)
        spread = 100 * lap.spread_s / best if np.isfinite(lap.spread_s) else float("nan")
        lines.append(f"| {k} | " + " | ".join(f"{theta[h]:.2f}" for h in header[:n_var])
                     + f" | {ga:.4f} | {best:.4f} | {100 * (ga - best) / best:+.2f} | "
                     f"{lap.certainty} | {spread:.2f} | {cpu:.0f} |")
        print(lines[-1], file=sys.stderr, flush=True)
    ga_arr, best_arr = np.array(run_laps), np.array(best_laps)
    ok = np.isfinite(best_arr)
    noise = 100 * (ga_arr[ok] - best_arr[ok]) / best_arr[ok]
    rho = spearmanr(ga_arr[ok], best_arr[ok]).statistic if ok.sum() > 2 else float("nan")
    lines += ["", f"- re-solved: {ok.sum()}/{len(rows)}",
              f"- front spread of the run's {args.index}: "
              f"{100 * (ga_arr.max() - ga_arr.min()) / ga_arr.min():.2f} % "
              f"({ga_arr.min():.4f}–{ga_arr.max():.4f} s)",
              f"- front spread of the re-solved laps: "
              f"{100 * (best_arr[ok].max() - best_arr[ok].min()) / best_arr[ok].min():.2f} %",
              f"- run − best: median {np.median(noise):+.2f} %, range {noise.min():+.2f} … "
              f"{noise.max():+.2f} %",
              f"- Spearman ρ between the run's and the re-solved laps: {rho:+.2f}", "",
              markdown()]
    print("\n".join(lines))


if __name__ == "__main__":
    main()
