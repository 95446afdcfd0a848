"""Optimisation throughput and ev-MOGA vs NSGA-II on paper run 1.

1. Evaluations per second for one generation of 850 drone evaluations (paper-run1's population,
   random θ inside paper Table 1) with the ``serial`` backend and with ``processes -j 2``, and the
   projected wall time of the paper-scale workload (850 + 350 × 850 evaluations).
   Target on 2 cores: ≥ 150 evaluations/s (≤ 35 min).
2. ev-MOGA vs NSGA-II on paper-run1's problem at an equal, reduced budget, several seeds:
   hypervolume of each final front in one shared normalised space (all fronts of all runs,
   each objective scaled to [0, 1] over their union, minimisation, reference point 1.1),
   median over seeds.

Run: ``python benchmarks/bench_optimise.py [--budget-generations 8] [--seeds 5]``
Writes ``benchmarks/RESULTS-optimise.md``.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from benchmarks.machine import markdown  # noqa: E402
from casadrone.config.problem import BackendConfig  # noqa: E402
from casadrone.optimise.backends import ProcessBackend, SerialBackend  # noqa: E402
from casadrone.optimise.checks import load_problem  # noqa: E402
from casadrone.optimise.problem import Study  # noqa: E402
from casadrone.optimise.runner import run  # noqa: E402

PAPER_EVALS = 850 + 350 * 850


def throughput(n: int, seed: int = 0) -> list[tuple[str, float, float]]:
    problem = load_problem(ROOT / "problems" / "paper-run1.yaml")
    study = Study(problem)
    lo, hi = study.bounds
    rng = np.random.default_rng(seed)
    X = lo + rng.random((n, len(lo))) * (hi - lo)
    rows = []
    for name, backend in (("serial", SerialBackend()), ("processes -j 2", ProcessBackend(2))):
        backend.evaluate(study, X[:8])  # warm-up: compiled lap loaded, workers started
        start = time.perf_counter()
        recs = backend.evaluate(study, X)
        wall = time.perf_counter() - start
        backend.close()
        feasible = np.mean([r.status == "completed" for r in recs])
        rows.append((name, n / wall, feasible))
    return rows


def compare(generations: int, seeds: int, population: int, children: int) -> dict:
    from pymoo.indicators.hv import HV

    fronts: dict[str, list[np.ndarray]] = {"evmoga": [], "nsga2": []}
    for algo in fronts:
        for seed in range(1, seeds + 1):
            over = [f"algorithm.name={algo}", f"algorithm.population={population}",
                    f"algorithm.generations={generations}", f"seed={seed}"]
            over += ([f"algorithm.settings.n_ind_ga={children}", "algorithm.settings.n_div=50"]
                     if algo == "evmoga" else ["algorithm.settings={}"])
            problem = load_problem(ROOT / "problems" / "paper-run1.yaml", over)
            with tempfile.TemporaryDirectory() as tmp:
                res = run(problem, Path(tmp) / "run", BackendConfig(name="processes", workers=2),
                          quiet=True)
            sign = np.array([-1.0 if s == "max" else 1.0 for s in Study(problem).senses])
            fronts[algo].append((res.F * sign, res.n_evaluations))
    allF = np.vstack([F for runs in fronts.values() for F, _ in runs])
    lo, hi = allF.min(axis=0), allF.max(axis=0)
    hv = HV(ref_point=np.full(allF.shape[1], 1.1))
    out = {}
    for algo, runs in fronts.items():
        vals = [float(hv((F - lo) / np.where(hi > lo, hi - lo, 1))) for F, _ in runs]
        out[algo] = (statistics.median(vals), vals, runs[0][1], [len(F) for F, _ in runs])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=850, help="evaluations in the timed generation")
    ap.add_argument("--budget-generations", type=int, default=8)
    ap.add_argument("--population", type=int, default=100)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "RESULTS-optimise.md"))
    args = ap.parse_args()

    lines = ["# Optimisation benchmark", "", markdown(), "",
             f"Command: `python benchmarks/bench_optimise.py --n {args.n} --budget-generations "
             f"{args.budget_generations} --population {args.population} --seeds {args.seeds}`", "",
             f"## Throughput: one generation of {args.n} drone evaluations (paper-run1, random θ "
             "in Table 1)", "",
             "| backend | evaluations/s | feasible | projected paper scale (850 + 350 × 850) |",
             "|---|---|---|---|"]
    for name, rate, feas in throughput(args.n):
        lines.append(f"| {name} | {rate:.0f} | {feas:.0%} | {PAPER_EVALS / rate / 60:.1f} min |")
        print(lines[-1], flush=True)
    lines += ["", "Target on 2 cores: ≥ 150 evaluations/s (≤ 35 min at paper scale).", ""]

    children = args.population
    budget = args.population + args.budget_generations * children
    cmp = compare(args.budget_generations, args.seeds, args.population, children)
    lines += [f"## ev-MOGA vs NSGA-II on paper-run1 (J1, J2, J3, J4, Jp), {budget} evaluations "
              f"each, {args.seeds} seeds", "",
              "Equal budget: population and children per generation "
              f"{args.population}, {args.budget_generations} generations (ev-MOGA n_div 50). "
              "Hypervolume of each final front in one normalised space (union of all fronts, "
              "each objective scaled to [0, 1], maximised indices negated, reference 1.1).", "",
              "| algorithm | median HV | HV per seed | front sizes |", "|---|---|---|---|"]
    for algo, (med, vals, _n, sizes) in cmp.items():
        lines.append(f"| {algo} | {med:.4f} | {', '.join(f'{v:.4f}' for v in vals)} | "
                     f"{', '.join(map(str, sizes))} |")
        print(lines[-1], flush=True)
    Path(args.out).write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
