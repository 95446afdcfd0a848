"""Benchmark: the hybrid (ev-MOGA, then ``algorithm.settings.polish``) against plain ev-MOGA at
equal CPU time, from one finished plain run of ``problems/limit-effort.yaml``.

The hybrid is the plain run stopped at generation K and polished: its archive at K is rebuilt
from the run's ``history.sqlite`` (the run's own replay, :class:`casadrone.optimise.runner.
ReplayBackend`: the same algorithm from the same seed, served the stored evaluations, so no
evaluation is repeated), then :func:`casadrone.optimise.hybrid.polish_front` polishes
``--members`` members and evaluates the proposals in this process (timed: CPU s of this process,
co-design solves and evaluations together). The hybrid's CPU is the plain run's CPU up to K plus
the polish's. The plain run's CPU up to a generation is estimated from its measured total
(``--ga-cpu``, user + system of the run and its workers by ``/usr/bin/time``) in proportion to
the evaluations' own times stored in the history (wall seconds of each evaluation in its worker:
the evaluations are nearly all of the run's CPU). Plain ev-MOGA at equal CPU is the same run's
archive at the first generation whose estimated CPU reaches the hybrid's (rebuilt the same
way), and its final front is reported beside. Hypervolumes by pymoo's HV from one reference
point: the worst lap and effort over every front compared plus 10 % of their ranges.

The run directory is copied first (nothing is written into it). Run:
``python benchmarks/bench_codesign_hybrid.py --ga runs/limit-effort --ga-cpu 3600 --at 5
--members 4``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


class _NoLive:
    """The replay's live backend: the replay never goes past the stored generations."""

    def evaluate(self, study, X):
        raise RuntimeError("the replay asked for an evaluation the history does not hold")

    def close(self) -> None:
        pass


def archive_at(store, generation: int, polish: dict | None = None):
    """(algorithm, study): the run's algorithm after ``generation``, rebuilt from its history;
    ``polish`` set as the study's ``algorithm.settings.polish``."""
    from casadrone.optimise.algorithms import seeded_defaults
    from casadrone.optimise.problem import CandidateProblem, Study
    from casadrone.optimise.runner import ReplayBackend, build_algorithm, stored_generations

    problem = store.problem()
    if polish is not None:
        settings = {**problem.algorithm.settings, "polish": polish}
        problem = problem.model_copy(update={"algorithm": problem.algorithm.model_copy(
            update={"settings": settings})})
    study = Study(problem)
    algorithm, termination = build_algorithm(problem, len(study.objective_names))
    algorithm.setup(CandidateProblem(study), termination=termination, seed=problem.seed,
                    verbose=False)
    algorithm.problem.backend = ReplayBackend(stored_generations(store)[:generation + 1],
                                              _NoLive(), "benchmark")
    for _ in range(generation + 1):
        with seeded_defaults(algorithm):
            infills = algorithm.infill()
            algorithm.evaluator.eval(algorithm.problem, infills, algorithm=algorithm)
            algorithm.advance(infills=infills)
    return algorithm, study


def cpu_by_generation(store, total_cpu: float) -> np.ndarray:
    """The plain run's estimated CPU (s) at the end of each generation (see the docstring)."""
    rows = store.history()
    last = max(r["generation"] for r in rows)
    per = np.zeros(last + 1)
    for r in rows:
        per[r["generation"]] += r["wall_time_s"] or 0.0
    return total_cpu * np.cumsum(per) / per.sum()


def hypervolumes(fronts: dict[str, np.ndarray]) -> dict:
    from pymoo.indicators.hv import HV

    both = np.vstack(list(fronts.values()))
    lo, hi = both.min(axis=0), both.max(axis=0)
    ref = hi + 0.1 * (hi - lo)
    hv = HV(ref_point=ref)
    return {"reference_point": ref.tolist(), **{k: float(hv(F)) for k, F in fronts.items()}}


def main(argv: list[str] | None = None) -> int:
    from casadrone.optimise.hybrid import polish_front
    from casadrone.optimise.problem import evaluate_rows
    from casadrone.optimise.runner import front
    from casadrone.rundir.store import RunStore

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ga", type=Path, required=True, help="a finished plain ev-MOGA run")
    ap.add_argument("--ga-cpu", type=float, required=True, help="its CPU s (/usr/bin/time)")
    ap.add_argument("--at", type=int, required=True, help="the generation K polished")
    ap.add_argument("--members", type=int, default=4, help="members polished")
    ap.add_argument("--json", type=Path, help="write the result here too")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        copy = Path(tmp) / "run"
        shutil.copytree(args.ga, copy, ignore=shutil.ignore_patterns("run.lock"))
        store = RunStore(copy)
        cpu = cpu_by_generation(store, args.ga_cpu)
        algorithm, study = archive_at(store, args.at, {"members": args.members})
        _, F_before = front(algorithm, study)
        c0, w0 = time.process_time(), time.perf_counter()
        _, report = polish_front(algorithm, study, evaluate_rows, front)
        polish_cpu, polish_wall = time.process_time() - c0, time.perf_counter() - w0
        _, F_hybrid = front(algorithm, study)
        hybrid_cpu = float(cpu[args.at] + polish_cpu)
        equal = int(np.searchsorted(cpu, hybrid_cpu))
        equal = min(equal, len(cpu) - 1)
        plain, pstudy = archive_at(store, equal)
        _, F_plain = front(plain, pstudy)
        final, fstudy = archive_at(store, len(cpu) - 1)
        _, F_final = front(final, fstudy)
    result = {
        "generation_polished": args.at, "members": args.members,
        "plain_cpu_at_K_s": float(cpu[args.at]), "polish_cpu_s": polish_cpu,
        "polish_wall_s": polish_wall, "hybrid_cpu_s": hybrid_cpu,
        "plain_generation_at_equal_cpu": equal, "plain_cpu_at_that_generation_s": float(cpu[equal]),
        "plain_total_cpu_s": args.ga_cpu, "load_average": os.getloadavg(),
        "front_at_K": F_before.tolist(), "front_hybrid": F_hybrid.tolist(),
        "front_plain_equal_cpu": F_plain.tolist(), "front_plain_final": F_final.tolist(),
        "hypervolume": hypervolumes({"at_K": F_before, "hybrid": F_hybrid,
                                     "plain_equal_cpu": F_plain, "plain_final": F_final}),
        "polish": report,
    }
    text = json.dumps(result, indent=1, default=float)
    print(text)
    if args.json:
        args.json.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
