"""Run an optimisation problem into a run directory, and resume a killed run.

The loop is pymoo's own ``Algorithm.next()`` (ask → evaluate the whole generation on the backend
→ tell), one generation at a time; after each generation the coordinator stores its evaluations
and then checkpoints the algorithm (random state included). Resuming loads the checkpoint,
re-attaches a backend and continues: the run ends exactly as an uninterrupted one would.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from casadrone.optimise.backends import make_backend
from casadrone.optimise.hypervolume import HypervolumeState, advance
from casadrone.optimise.mainguard import unguarded_main_call, unguarded_message
from casadrone.optimise.problem import CandidateProblem, Study, objectives_and_constraints
from casadrone.optimise.store import RunStore, now
from casadrone.problemconfig import BackendConfig, ProblemConfig


@dataclass(frozen=True)
class RunResult:
    """A finished run: its directory, Pareto set (variables) and front (objective values in their
    own units and sense)."""

    path: Path
    variable_names: list[str]
    objective_names: list[str]
    X: np.ndarray
    F: np.ndarray
    n_evaluations: int
    generations: int


def build_algorithm(problem: ProblemConfig, n_obj: int):
    """The problem's algorithm and its pymoo termination (G generations after initialisation)."""
    from casadrone.optimise.algorithms import make_algorithm

    a = problem.algorithm
    settings = dict(a.settings)
    if a.name.strip().lower() == "evmoga":
        settings["generations"] = a.generations  # ev-MOGA's dd and σ schedules need G
    algorithm = make_algorithm(a.name, settings, pop_size=a.population, n_obj=n_obj)
    return algorithm, ("n_gen", a.generations + 1)


def front(algorithm, study: Study) -> tuple[np.ndarray, np.ndarray]:
    """Feasible non-dominated set of the algorithm's result (objectives back in their sense)."""
    opt = algorithm.opt
    if opt is None or len(opt) == 0:
        return np.empty((0, len(study.variable_names))), np.empty((0, len(study.objective_names)))
    feas = np.asarray(opt.get("CV")).ravel() <= 0
    X, F = opt.get("X")[feas], opt.get("F")[feas]
    sign = np.array([-1.0 if s == "max" else 1.0 for s in study.senses])
    order = np.lexsort(F.T[::-1])
    return X[order], F[order] * sign


def generation_hypervolume(study: Study, records, state: HypervolumeState | None
                          ) -> tuple[HypervolumeState, float]:
    """The hypervolume shown after a generation (:mod:`casadrone.optimise.hypervolume`): its
    feasible evaluations join the non-dominated set so far, measured in the run's fixed space."""
    F, G = objectives_and_constraints(study, records)
    feasible = F[np.all(G <= 0, axis=1)] if len(records) else np.empty((0, F.shape[1]))
    return advance(state, feasible, raw=study.problem.test_problem is not None)


class Progress:
    """One line per generation (and a bar on a terminal) unless quiet."""

    def __init__(self, total_generations: int, quiet: bool = False, stream=None):
        self.total, self.quiet = total_generations, quiet
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def __call__(self, gen: int, stats: dict) -> None:
        if self.quiet:
            return
        done = (gen + 1) / (self.total + 1)
        eta = stats["elapsed_s"] * (1 - done) / done
        line = (f"gen {gen:>4}/{self.total}  evals {stats['n_evaluations']:>7}  "
                f"archive {stats['archive_size']:>4}  feasible {stats['feasible_fraction']:6.1%}  "
                f"HV {stats['hypervolume']:.5f}  elapsed {stats['elapsed_s']:7.1f} s  "
                f"remaining {eta:7.1f} s")
        if self.tty:
            width = 24
            bar = "#" * int(width * done) + "-" * (width - int(width * done))
            line = f"[{bar}] {line}"
        print(line, file=self.stream, flush=True)


def _loop(store: RunStore, algorithm, study: Study, backend, elapsed0: float,
          progress: Callable[[int, dict], None] | None, stop_after: int | None = None,
          hv: HypervolumeState | None = None) -> RunResult:
    problem = algorithm.problem
    problem.backend = backend
    store.acquire()
    try:
        return _generations(store, algorithm, study, problem, elapsed0, progress, stop_after, hv)
    finally:
        store.release()


def _generations(store, algorithm, study, problem, elapsed0, progress, stop_after,
                 hv) -> RunResult:
    start = time.perf_counter()
    steps = 0
    while algorithm.has_next():
        algorithm.next()
        # pymoo's n_gen is 2 after the initial population (generation 0 here), 3 after the next…
        gen = int(algorithm.n_gen) - 2
        records = problem.last_records
        X_f, _ = front(algorithm, study)
        had_space = hv is not None and hv.space is not None
        hv, hv_value = generation_hypervolume(study, records, hv)
        if hv.space is not None and not had_space:  # the report measures in the same space
            store.update_manifest(hypervolume_space={"ideal": hv.space.ideal.tolist(),
                                                     "nadir": hv.space.nadir.tolist()})
        stats = {
            "n_evaluations": int(algorithm.evaluator.n_eval),
            "archive_size": len(X_f),
            "feasible_fraction": float(np.mean([r.status == "completed" for r in records]))
            if records else 0.0,
            "hypervolume": hv_value,
            "elapsed_s": elapsed0 + time.perf_counter() - start,
        }
        store.write_generation(gen, records, stats)
        problem.last_records = []
        store.save_checkpoint({"algorithm": algorithm, "elapsed_s": stats["elapsed_s"],
                               "generation": gen, "hypervolume_state": hv})
        if progress:
            progress(gen, stats)
        steps += 1
        if stop_after is not None and steps >= stop_after:
            break
    X, F = front(algorithm, study)
    if not algorithm.has_next():
        store.write_pareto(study.variable_names, study.objective_names, X, F)
        store.update_manifest(finished=now(), status="completed",
                              n_evaluations=int(algorithm.evaluator.n_eval))
    return RunResult(path=store.path, variable_names=study.variable_names,
                     objective_names=study.objective_names, X=X, F=F,
                     n_evaluations=int(algorithm.evaluator.n_eval),
                     generations=int(algorithm.n_gen or 0))


def _check_main_guard(backend: BackendConfig, what: str) -> bool:
    """True when called from a script's unguarded top level (its workers must not import it);
    RuntimeError (one line) when the backend cannot start workers that way (Dask LocalCluster)."""
    where = unguarded_main_call()
    if where and backend.name == "dask" and not backend.scheduler:
        raise RuntimeError(unguarded_message(where, what))
    return where is not None


def run(problem: ProblemConfig, out: str | Path, backend: BackendConfig | None = None,
        quiet: bool = False, progress: Callable | None = None,
        stop_after: int | None = None) -> RunResult:
    """Run ``problem`` into the new run directory ``out``.

    ``backend`` overrides the problem's own; ``stop_after`` stops after that many generations
    (as if killed; resume continues it). Safe from a script's top level without
    ``if __name__ == "__main__":`` (:mod:`casadrone.optimise.mainguard`), except on a Dask
    LocalCluster, where such a call raises RuntimeError before anything is created.
    """
    from casadrone.indices import INDICES

    backend_cfg = backend or problem.backend
    unguarded = _check_main_guard(backend_cfg, "casadrone.run()")
    problem = problem.model_copy(update={"backend": backend_cfg})
    study = Study(problem)
    index_names = (study.objective_names if problem.test_problem is not None
                   else list(INDICES))
    store = RunStore.create(out, problem, study.variable_names, index_names, backend_cfg.name)
    study = Study(store.problem())  # the run's own copies of its input files
    algorithm, termination = build_algorithm(problem, len(study.objective_names))
    algorithm.setup(CandidateProblem(study), termination=termination, seed=problem.seed,
                    verbose=False)
    be = make_backend(backend_cfg, without_main=unguarded)
    try:
        prog = progress or Progress(problem.algorithm.generations, quiet)
        return _loop(store, algorithm, study, be, 0.0, prog, stop_after)
    finally:
        be.close()


def resume(out: str | Path, backend: BackendConfig | None = None, quiet: bool = False,
           progress: Callable | None = None, stop_after: int | None = None) -> RunResult:
    """Continue the run in ``out`` from its last checkpoint."""
    store = RunStore(Path(out))
    if not (store.path / "checkpoint.pkl").exists():
        raise FileNotFoundError(f"{out}: no checkpoint.pkl: not a run directory, or killed "
                                "before its first generation was stored (start it again)")
    problem = store.problem()
    backend_cfg = backend or problem.backend
    unguarded = _check_main_guard(backend_cfg, "casadrone.resume()")
    state = store.load_checkpoint()
    algorithm = state["algorithm"]
    be = make_backend(backend_cfg, without_main=unguarded)
    store.update_manifest(status="running", resumed=now())
    try:
        prog = progress or Progress(problem.algorithm.generations, quiet)
        return _loop(store, algorithm, algorithm.problem.study, be, state["elapsed_s"], prog,
                     stop_after, state.get("hypervolume_state"))
    finally:
        be.close()
