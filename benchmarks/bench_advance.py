"""CPU time of one ev-MOGA ``_advance`` (archive each child, then update P) at paper scale.

Two states, each advanced ``--repeats`` times from a pickled copy (minimum and median CPU time,
``time.process_time``, one thread), with a SHA-256 of P, the archive, the grid and the random
generator state afterwards (equal hashes: bit-identical results, e.g. across revisions run with
``PYTHONPATH=<checkout>``):

- late: the final checkpoint of a finished paper-scale run (``--run``; P 850, archive ~7 700,
  5 objectives), offered 850 children whose X come from its ``_infill`` and whose objectives and
  constraints are those recorded for generation ``--generation`` in its history;
- growth: ev-MOGA with paper-run1's settings (P 850, 850 children, n_div 200, G 350, seed 1) on
  DTLZ2 with 7 variables and 5 objectives, advanced until the archive holds ``--archive`` members
  (many grid moves per generation).

Run: ``python benchmarks/bench_advance.py [--run runs/paper-scale/paper-run1]``
Writes ``benchmarks/RESULTS-advance.md``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import hashlib  # noqa: E402
import pickle  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))


def late_state(run: Path, generation: int) -> bytes:
    from casadrone.optimise.problem import Study, objectives_and_constraints
    from casadrone.rundir.store import RunStore, record_of

    store = RunStore(run)
    alg = store.load_checkpoint()["algorithm"]
    man = store.manifest
    records = [record_of(r, man) for r in store.history(generation)]
    F, G = objectives_and_constraints(Study(store.problem()), records)
    alg.termination = None
    off = alg._infill()
    if len(F) < len(off):
        raise SystemExit(f"{run}: generation {generation} has {len(F)} rows, need {len(off)}")
    off.set("F", F[:len(off)], "G", G[:len(off)])
    off.set("CV", np.maximum(off.get("G"), 0).sum(axis=1, keepdims=True))
    return pickle.dumps((alg, off))


def growth_state(archive: int) -> bytes:
    from pymoo.core.evaluator import Evaluator
    from pymoo.problems import get_problem

    from casadrone.optimise.evmoga import EvMOGA

    problem = get_problem("dtlz2", n_var=7, n_obj=5)
    alg = EvMOGA(n_ind_p=850, n_ind_ga=850, n_div=200, generations=350)
    alg.setup(problem, seed=1)
    while len(alg.box_archive) < archive:
        alg.next()
    off = alg.infill()
    Evaluator().eval(problem, off)
    return pickle.dumps((alg, off))


def advance(blob: bytes, repeats: int) -> tuple[list[float], str, int, int]:
    times = []
    for _ in range(repeats):
        alg, off = pickle.loads(blob)
        n_before = len(alg.box_archive)
        start = time.process_time()
        alg._advance(infills=off)
        times.append(time.process_time() - start)
    h = hashlib.sha256()
    b = alg.box_archive
    for arr in (alg.pop_F, alg.pop_cv, alg.pop.get("X"), *[b.rows[k] for k in sorted(b.rows)],
                b.box, b.grid_min, b.grid_max, b.eps):
        h.update(np.ascontiguousarray(arr).tobytes())
    h.update(repr(alg.random_state.bit_generator.state).encode())
    return times, h.hexdigest()[:16], n_before, len(b)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--run", type=Path, default=HERE.parent / "runs/paper-scale/paper-run1")
    parser.add_argument("--generation", type=int, default=300)
    parser.add_argument("--archive", type=int, default=4800)
    parser.add_argument("--repeats", type=int, default=9)
    parser.add_argument("--out", type=Path, default=HERE / "RESULTS-advance.md")
    args = parser.parse_args()
    import machine

    states = []
    if (args.run / "checkpoint.pkl").exists():
        states.append((f"late: {args.run.name} checkpoint, children of generation "
                       f"{args.generation}", late_state(args.run, args.generation)))
    else:
        print(f"{args.run}: no checkpoint, late state skipped", file=sys.stderr)
    states.append((f"growth: DTLZ2 5 objectives at archive >= {args.archive}",
                   growth_state(args.archive)))
    lines = [
        "# ev-MOGA `_advance` CPU per paper-scale generation (850 children, 5 objectives)", "",
        f"`python benchmarks/bench_advance.py --run {args.run} --repeats {args.repeats}` — "
        "CPU time (`time.process_time`) of one `_advance` from a pickled state, repeated; the "
        "hash covers P, the archive, the grid and the random generator state afterwards.", "",
        machine.markdown(), "",
        "| state | archive before → after | CPU min (ms) | CPU median (ms) | hash |",
        "|---|---|---:|---:|---|",
    ]
    for name, blob in states:
        times, digest, n0, n1 = advance(blob, args.repeats)
        lines.append(f"| {name} | {n0} → {n1} | {1e3 * min(times):.1f} "
                     f"| {1e3 * float(np.median(times)):.1f} | `{digest}` |")
        print(lines[-1], flush=True)
    args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
