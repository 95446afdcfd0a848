"""Benchmark: where one co-design solve spends its CPU (template start, no certificate).

Prints the CPU seconds of ``prepare`` (the template's cold limit lap and the NLP's build), the
start's own limit lap, the co-design solve, and IPOPT's per-function times (Lagrangian Hessian,
constraint Jacobian, ...). Run: ``python benchmarks/bench_codesign_profile.py
tests/data/codesign/short-problem.yaml codesign.starts=0`` (or ``codesign-paper``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main(argv: list[str]) -> int:
    from casadrone.codesign.checks import load_codesign_problem
    from casadrone.codesign.driver import initial_vector, prepare, solve_from, start_points

    cfg = load_codesign_problem(argv[0], argv[1:])
    c = time.process_time()
    prep = prepare(cfg)
    print(f"prepare {time.process_time() - c:.2f} s CPU")
    (_, theta), *_ = start_points(prep)
    c = time.process_time()
    z0 = initial_vector(prep, theta)
    print(f"start's own limit lap {time.process_time() - c:.2f} s CPU")
    assert z0 is not None
    c = time.process_time()
    ok, status, point = solve_from(prep, z0)
    print(f"solve {time.process_time() - c:.2f} s CPU: {status}, {point.iterations} iterations, "
          f"lap {point.objective:.4f} s")
    for key, value in sorted(prep.nlp.cold.stats().items()):
        if key.startswith(("t_proc_nlp", "n_call_nlp")):
            print(f"  {key} {value}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
