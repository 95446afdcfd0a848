"""ev-MOGA vs NSGA-II on pymoo's ZDT1, ZDT2 (4 variables) and DTLZ2 (3 objectives, 5 variables).

Both algorithms get the same budget of 20 000 evaluations; each runs with 10 seeds and the table
reports medians (docs/concepts/evmoga.md: "judge it on the median of at least 10 seeds").

Settings and why:

- ev-MOGA: ``n_ind_p = 800``, ``n_ind_ga = 8`` (MATLAB default), ``G = 2400`` generations, so
  ``n_ind_p + G * n_ind_ga = 800 + 19 200 = 20 000``; termination ``("n_gen", G + 1)``. P is close
  to the paper's 850 (850 does not divide the budget into whole generations of 8), and a large P
  is what keeps ev-MOGA's search diverse once σ has shrunk (σ falls below 1 % of the range within
  the first ~1 % of the generations). ``n_div = 200`` for two objectives (the paper's value; at
  most 201 archive members). For DTLZ2 ``n_div = 20``: with three objectives the archive can hold
  O(n_div²) members and insertion is O(|A|) per child, so 200 would be slow and far denser than
  NSGA-II's 100 points. Everything else at docs/concepts/evmoga.md defaults (p_m 0.2, dd 0.25→0.1,
  σ 20→0.1 %).
- NSGA-II: pymoo defaults (pop 100, SBX η 15, PM η 20), termination ``("n_eval", 20 000)``
  = 200 generations.

Indicators: pymoo ``IGD`` against pymoo's reference front (``pareto_front()``; DTLZ2 on 91
Das-Dennis directions) and pymoo ``HV`` with reference point 1.1 per objective; exact
hypervolumes ZDT1 1.21 − 1/3 = 0.87667, ZDT2 1.21 − 2/3 = 0.54333, DTLZ2 1.1³ − π/6 = 0.80740.
A finite front loses some HV to discretisation (≈ 1/(2n) for n evenly spread points on ZDT1),
so neither algorithm reaches the exact value.

Run: ``python benchmarks/bench_evmoga_zdt.py [--seeds 10] [--jobs 2]``
Writes ``benchmarks/RESULTS-evmoga.md``.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

BUDGET = 20_000
EXACT_HV = {"zdt1": 1.21 - 1.0 / 3.0, "zdt2": 1.21 - 2.0 / 3.0, "dtlz2": 1.1**3 - np.pi / 6.0}
PROBLEMS = {  # name -> (pymoo get_problem kwargs, ev-MOGA n_div)
    "zdt1": ({"n_var": 4}, 200),
    "zdt2": ({"n_var": 4}, 200),
    "dtlz2": ({"n_var": 5, "n_obj": 3}, 20),
}
N_IND_P, N_IND_GA = 800, 8
GENERATIONS = (BUDGET - N_IND_P) // N_IND_GA  # 2400
assert N_IND_P + GENERATIONS * N_IND_GA == BUDGET


def reference_front(name: str, problem) -> np.ndarray:
    if name == "dtlz2":
        from pymoo.util.ref_dirs import get_reference_directions

        return problem.pareto_front(get_reference_directions("das-dennis", 3, n_partitions=12))
    return problem.pareto_front()


def one_run(job: tuple[str, str, int]) -> dict:
    """One (problem, algorithm, seed): final front's IGD, HV, size, evaluations, wall time."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.indicators.hv import HV
    from pymoo.indicators.igd import IGD
    from pymoo.optimize import minimize
    from pymoo.problems import get_problem

    from casadrone.optimise.evmoga import EvMOGA

    name, algo, seed = job
    kwargs, n_div = PROBLEMS[name]
    problem = get_problem(name, **kwargs)
    if algo == "ev-MOGA":
        algorithm = EvMOGA(n_ind_p=N_IND_P, n_ind_ga=N_IND_GA, n_div=n_div, generations=GENERATIONS)
        termination = ("n_gen", GENERATIONS + 1)
    else:
        algorithm, termination = NSGA2(pop_size=100), ("n_eval", BUDGET)
    start = time.perf_counter()
    res = minimize(problem, algorithm, termination, seed=seed)
    wall = time.perf_counter() - start
    F = res.F
    ref = np.full(problem.n_obj, 1.1)
    return {
        "problem": name,
        "algorithm": algo,
        "seed": seed,
        "igd": float(IGD(reference_front(name, problem)).do(F)),
        "hv": float(HV(ref_point=ref).do(F)),
        "size": len(F),
        "evals": int(res.algorithm.evaluator.n_eval),
        "wall_s": wall,
    }


def machine() -> list[str]:
    uname = " ".join(platform.uname())
    try:
        uname = subprocess.run(["uname", "-a"], capture_output=True, text=True).stdout.strip()
        nproc = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
        rev = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        ).stdout.strip()
    except OSError:
        nproc, rev = str(os.cpu_count()), "?"
    import pymoo

    return [
        f"- date: {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC",
        f"- machine: `{uname}`; nproc {nproc}; load average {os.getloadavg()[0]:.2f} at start",
        f"- Python {platform.python_version()}; pymoo {pymoo.__version__}; numpy {np.__version__};"
        f" casadrone git {rev}",
    ]


def table(results: list[dict], seeds: int) -> list[str]:
    lines = [
        "| problem | algorithm | evaluations | median IGD | IGD min–max | median HV | exact HV "
        "| HV gap (median) | HV min–max | median front size | median wall time / run |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name in PROBLEMS:
        for algo in ("ev-MOGA", "NSGA-II"):
            rows = [r for r in results if r["problem"] == name and r["algorithm"] == algo]
            if not rows:
                continue
            igd = np.array([r["igd"] for r in rows])
            hv = np.array([r["hv"] for r in rows])
            evals = sorted({r["evals"] for r in rows})
            lines.append(
                f"| {name.upper()} | {algo} | {'/'.join(map(str, evals))} "
                f"| {np.median(igd):.5f} | {igd.min():.5f}–{igd.max():.5f} "
                f"| {np.median(hv):.5f} | {EXACT_HV[name]:.5f} "
                f"| {EXACT_HV[name] - np.median(hv):.5f} | {hv.min():.5f}–{hv.max():.5f} "
                f"| {int(np.median([r['size'] for r in rows]))} "
                f"| {np.median([r['wall_s'] for r in rows]):.1f} s |"
            )
    lines.append("")
    lines.append(f"Medians over {seeds} seeds (0–{seeds - 1}) per row.")
    return lines


def summary_rows(results: list[dict], seeds: int) -> list[tuple[str, str, str]]:
    """The performance page's row: ev-MOGA's medians on ZDT1 (none when ZDT1 was not run)."""
    rows = [r for r in results if r["problem"] == "zdt1" and r["algorithm"] == "ev-MOGA"]
    if not rows:
        return []
    igd = np.median([r["igd"] for r in rows])
    hv = np.median([r["hv"] for r in rows])
    budget = f"{BUDGET:,}".replace(",", " ")
    return [(f"ev-MOGA on ZDT1 (4 variables, {budget} evaluations, {seeds} seeds)",
             f"median IGD {igd:.4f}, HV {hv:.4f} (exact {EXACT_HV['zdt1']:.5f})",
             "`python benchmarks/bench_evmoga_zdt.py`")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--problems", nargs="*", default=list(PROBLEMS))
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "RESULTS-evmoga.md")
    args = parser.parse_args()

    header = machine()
    jobs = [
        (name, algo, seed)
        for name in args.problems
        for algo in ("ev-MOGA", "NSGA-II")
        for seed in range(args.seeds)
    ]
    start = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(one_run, jobs))
    total = time.perf_counter() - start

    lines = [
        "# ev-MOGA vs NSGA-II on ZDT1, ZDT2 and DTLZ2",
        "",
        "`python benchmarks/bench_evmoga_zdt.py` — same budget of "
        f"{BUDGET} evaluations for both; settings and their reasons in the script's docstring.",
        "",
        *header,
        f"- wall time of the whole benchmark: {total:.0f} s with {args.jobs} worker processes",
        "",
        f"ev-MOGA: n_ind_p {N_IND_P}, n_ind_ga {N_IND_GA}, G {GENERATIONS} "
        f"(termination n_gen {GENERATIONS + 1}), n_div 200 (ZDT) / 20 (DTLZ2), p_m 0.2, "
        "dd 0.25→0.1, σ 20→0.1 %. NSGA-II: pymoo defaults, pop 100, 200 generations. "
        "ZDT1/ZDT2 with 4 variables, DTLZ2 with 3 objectives and 5 variables. "
        "IGD: pymoo, against pymoo's Pareto front (DTLZ2: 91 Das-Dennis points). "
        "HV: pymoo, reference point 1.1 per objective.",
        "",
        *table(results, args.seeds),
        "",
    ]
    summary = summary_rows(results, args.seeds)
    text = "\n".join(lines)
    if summary:
        from benchmarks.machine import with_summary

        text = with_summary(text, summary)
    print(text)
    args.out.write_text(text)


if __name__ == "__main__":
    main()
