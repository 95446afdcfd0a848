"""Benchmark: where one co-design solve spends its CPU (template start, no certificate).

Prints the CPU seconds of ``prepare`` (the template's cold limit lap and the NLP's build), the
start's own limit lap, the co-design solve, and IPOPT's per-function times (Lagrangian Hessian,
constraint Jacobian, ...). Run: ``python benchmarks/bench_codesign_profile.py
tests/data/codesign/short-problem.yaml codesign.starts=0`` (or ``codesign-paper``).

With a second objective the NLP can hold (``tests/data/codesign/short-front.yaml``: effort), it
also prints the constraint Jacobian's colourings with and without that objective's ε row: the
number of forward (column) and adjoint (row) colours, and the CPU of one ``nlp_jac_g`` call. One
dense row (the effort sums every interval's thrusts and duration) needs a forward colour per
nonzero, which is why an ε-point's iteration costs several times a free one's.
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
    if len(cfg.objectives) > 1:
        colourings(prep, cfg.objectives[1].index, point.z)
    return 0 if ok else 1


def colourings(prep, measure: str, z) -> None:
    """The constraint Jacobian's colourings and its CPU per call, free and with the ε row."""
    import numpy as np

    from casadrone.codesign.driver import constrained

    for label, p in (("free", prep), (f"epsilon {measure}", constrained(prep, (measure,)))):
        jac = p.nlp.cold.get_function("nlp_jac_g")
        sp = jac.sparsity_out(1)
        eps = np.full(jac.size1_in(1), 1e3)
        c = time.process_time()
        for _ in range(5):
            jac(p.nlp.full(z), eps)
        print(f"{label}: Jacobian {sp.size1()}x{sp.size2()}, {sp.nnz()} nonzeros, "
              f"{sp.uni_coloring().size2()} forward colours, "
              f"{sp.T.uni_coloring().size2()} adjoint colours, "
              f"{(time.process_time() - c) / 5 * 1e3:.1f} ms CPU per nlp_jac_g call")


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
