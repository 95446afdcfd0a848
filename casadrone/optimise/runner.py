"""Run an optimisation problem into a run directory, and resume a killed run.

The loop is pymoo's own ``Algorithm.next()`` (ask → evaluate the whole generation on the backend
→ tell), one generation at a time; after each generation the coordinator pickles the algorithm
(random state included) and hands its evaluations and that checkpoint to a background writer,
which stores the evaluations and then the checkpoint while the next generation is evaluated
(:mod:`casadrone.rundir.writer`). Resuming loads the checkpoint, re-attaches a backend and
continues: the run ends exactly as an uninterrupted one would.

When no checkpoint is usable (killed before the first one, or both damaged), resuming rebuilds
the run from ``history.sqlite``: the algorithm starts again from its seed and each stored
generation is served from the history instead of being evaluated (a replay, checked row by row
against what the algorithm asks for), then the run continues live. SIGTERM (``timeout``, batch
schedulers, ``docker stop``) and SIGINT (Ctrl-C) stop a run the same way: the manifest records
``interrupted`` and :class:`Interrupted` carries the signal to the caller.
Each step is timed into the run's ``timings.csv`` (:mod:`casadrone.rundir.timings`); the
progress hypervolume stays cheap as the set grows (:mod:`casadrone.optimise.hypervolume`).
"""

from __future__ import annotations

import contextlib
import gc
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, replace
from pathlib import Path
from types import FrameType
from typing import Any, TextIO, TypeVar

import numpy as np

from casadrone.config.problem import BackendConfig, ProblemConfig
from casadrone.optimise.algorithms import (
    algorithm_settings,
    front_rows,
    front_size,
    make_algorithm,
    seeded_defaults,
)
from casadrone.optimise.backends import make_backend
from casadrone.optimise.hybrid import needs_polish, polish_stage
from casadrone.optimise.hypervolume import HypervolumeState, advance
from casadrone.optimise.mainguard import unguarded_main_call, unguarded_message
from casadrone.optimise.problem import CandidateProblem, Study, objectives_and_constraints
from casadrone.results import Record
from casadrone.rundir.checkpoint import dumps
from casadrone.rundir.store import RunDamaged, RunStore, now, record_of
from casadrone.rundir.writer import GenerationWriter

T = TypeVar("T")


class Interrupted(KeyboardInterrupt):
    """The run was stopped by a signal (SIGINT or SIGTERM); its state is recorded."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.run_dir: Path | None = None  # the run to resume, once it has a directory


#: Signals taken while a :func:`_signals_interrupt` block runs. CasADi calls Python's signal
#: handlers from inside a solve and turns the exception they raise into a warning
#: ("KeyboardInterruptException") and a normal return, so an :class:`Interrupted` raised during
#: an evaluation's solve never reaches the run; :func:`raise_swallowed_signal` raises it after.
_TAKEN: list[int] = []
_DEPTH = [0]  # nested blocks (a run inside its setup's block): only the outermost resets _TAKEN


def raise_swallowed_signal() -> None:
    """Raise :class:`Interrupted` for a signal whose exception a C extension swallowed."""
    if _TAKEN:
        raise Interrupted(_TAKEN[-1])


@contextlib.contextmanager
def _signals_interrupt() -> Iterator[None]:
    """SIGTERM and SIGINT raise :class:`Interrupted` in the coordinator while the block runs
    (only the main thread can take signals; elsewhere nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        _TAKEN.append(signum)
        raise Interrupted(signum)

    if _DEPTH[0] == 0:  # a signal swallowed in the setup's solves still counts in the loop
        _TAKEN.clear()
    _DEPTH[0] += 1
    old = {s: signal.signal(s, handler) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        yield
    finally:
        _DEPTH[0] -= 1
        for s, h in old.items():
            signal.signal(s, h)


class ReplayBackend:
    """Serves a run's stored generations (``history.sqlite``) in order, then evaluates live."""

    name = "replay"

    def __init__(self, stored: list[list[Record]], live: Any, why: str = "") -> None:
        self.stored, self.live, self.generation = stored, live, 0
        self.why = why  # why the run is being rebuilt, for the message if it cannot be

    def evaluate(self, study: Study, X: np.ndarray) -> list[Record]:
        if self.generation >= len(self.stored):
            return self.live.evaluate(study, X)
        records = self.stored[self.generation]
        names = study.variable_names
        X_stored = np.array([[r.theta[n] for n in names] for r in records], dtype=float)
        if X_stored.shape != np.shape(X) or not np.array_equal(X_stored, X):
            raise RunDamaged(f"{self.why}; and history.sqlite cannot rebuild the run: it does "
                             f"not match a replay at generation {self.generation} (different "
                             "candidates)")
        self.generation += 1
        return records

    def close(self) -> None:
        self.live.close()

    def terminate(self) -> None:
        getattr(self.live, "terminate", self.live.close)()


def _check_history(store: RunStore, generation: int) -> None:
    """The history holds every generation up to the checkpoint's (else the run lost data)."""
    done = {g["generation"] for g in store.generations()}
    with store.database("read the evaluations") as db:
        db.execute("SELECT generation, idx FROM evaluations LIMIT 1").fetchall()
    missing = sorted(set(range(generation + 1)) - done)
    if missing:
        raise RunDamaged(f"{store.path / 'history.sqlite'}: generation {missing[0]} is missing "
                         f"though the checkpoint is at generation {generation}")


def stored_generations(store: RunStore) -> list[list[Record]]:
    """The complete generations of ``history.sqlite`` (0, 1, … without a gap) as records."""
    m = store.manifest
    done = [g["generation"] for g in store.generations()]
    rows = store.history()
    n = next((i for i, g in enumerate(done) if g != i), len(done))
    out: list[list[Record]] = [[] for _ in range(n)]
    for r in rows:
        if r["generation"] < n:
            out[r["generation"]].append(record_of(r, m))
    return out


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


def build_algorithm(problem: ProblemConfig, n_obj: int) -> tuple[Any, Any]:
    """The problem's algorithm and its pymoo termination (G generations after initialisation)."""
    a = problem.algorithm
    algorithm = make_algorithm(a.name, algorithm_settings(a.settings), pop_size=a.population,
                               n_obj=n_obj,
                               generations=a.generations)
    return algorithm, ("n_gen", a.generations + 1)


def front(algorithm: Any, study: Study) -> tuple[np.ndarray, np.ndarray]:
    """Feasible non-dominated set of the algorithm's result (objectives back in their sense)."""
    rows = front_rows(algorithm)
    if rows is None:
        return (np.empty((0, len(study.variable_names))),
                np.empty((0, len(study.objective_names))))
    X, F, CV = rows
    feas = np.asarray(CV).ravel() <= 0
    X, F = X[feas], F[feas]
    sign = np.array([-1.0 if s == "max" else 1.0 for s in study.senses])
    order = np.lexsort(F.T[::-1])
    return X[order], F[order] * sign


def archive_count(algorithm: Any, study: Study) -> int:
    """Size of the feasible non-dominated set :func:`front` returns, without building it where
    the algorithm keeps it as arrays (ev-MOGA's archive holds feasible solutions only; a pymoo
    population of a 7 000-member archive costs ~35 ms a generation)."""
    size = front_size(algorithm)
    return size if size is not None else len(front(algorithm, study)[0])


def generation_hypervolume(study: Study, records: list[Record], state: HypervolumeState | None
                          ) -> tuple[HypervolumeState, float]:
    """The hypervolume shown after a generation (:mod:`casadrone.optimise.hypervolume`): its
    feasible evaluations join the set so far, measured in the run's fixed space."""
    F, G = objectives_and_constraints(study, records)
    m = len(study.objective_names)
    feasible = F[np.all(G <= 0, axis=1)] if len(records) else np.empty((0, m))
    return advance(state, feasible, raw=study.problem.test_problem is not None)


class Progress:
    """One line per generation (and a bar on a terminal) unless quiet."""

    def __init__(self, total_generations: int, quiet: bool = False,
                 stream: TextIO | None = None) -> None:
        self.total, self.quiet = total_generations, quiet
        self.stream = stream or sys.stderr
        self.tty = hasattr(self.stream, "isatty") and self.stream.isatty()

    def __call__(self, gen: int, stats: dict) -> None:
        if self.quiet:
            return
        done = (gen + 1) / (self.total + 1)
        eta = stats["elapsed_s"] * (1 - done) / done
        hv = stats["hypervolume"]
        line = (f"gen {gen:>4}/{self.total}  evals {stats['n_evaluations']:>7}  "
                f"archive {stats['archive_size']:>4}  feasible {stats['feasible_fraction']:6.1%}  "
                f"HV {'      -' if hv is None else format(hv, '.5f')}  "
                f"elapsed {stats['elapsed_s']:7.1f} s  "
                f"remaining {eta:7.1f} s")
        if self.tty:
            width = 24
            bar = "#" * int(width * done) + "-" * (width - int(width * done))
            line = f"[{bar}] {line}"
        print(line, file=self.stream, flush=True)


def _loop(store: RunStore, algorithm: Any, study: Study, backend: Any, elapsed0: float,
          progress: Callable[[int, dict], None] | None, stop_after: int | None = None,
          hv: HypervolumeState | None = None) -> RunResult:
    problem = algorithm.problem
    problem.backend = backend
    store.acquire()
    try:
        with _signals_interrupt():
            return _generations(store, algorithm, study, problem, elapsed0, progress, stop_after,
                                hv)
    except Interrupted as exc:
        exc.run_dir = store.path
        with contextlib.suppress(Exception):
            store.update_manifest(status="interrupted", interrupted=now(), signal=str(exc))
        raise
    except Exception as exc:
        with contextlib.suppress(Exception):
            store.update_manifest(status="stopped", stopped=now(),
                                  error=f"{type(exc).__name__}: {exc}"[:300])
        if isinstance(exc, OSError) and exc.strerror:  # the same error, saying what to do
            raise OSError(exc.errno, storage_failure(exc.strerror, store.path),
                          exc.filename) from None
        if isinstance(exc, RunDamaged):
            raise RunDamaged(storage_failure(str(exc), store.path)) from None
        raise
    finally:
        store.release()


def storage_failure(text: str, run_dir: Path) -> str:
    """A failed write of a run's files (``text``: the cause), with what to do: every generation
    stored before it is kept (each is written whole or not at all), and ``casadrone resume``
    continues."""
    if "disk I/O error" in text or "disk is full" in text or "No space left" in text:
        text += " (the disk is full, or the folder was removed or made read-only)"
    return (f"{text}; every generation stored before it is kept: free space or fix the folder, "
            f"then continue with: casadrone resume {run_dir}")


def _marker(t: list[float], cpu: list[float]) -> Callable[[], None]:
    """A function appending the wall-clock and CPU time to ``t`` and ``cpu``."""
    def mark() -> None:
        t.append(time.perf_counter())
        cpu.append(time.process_time())
    return mark


#: Write each generation's history, checkpoint and timings row in the background, behind the next
#: generation's evaluation (:mod:`casadrone.rundir.writer`); False writes them in turn.
BACKGROUND_WRITES = True


@contextlib.contextmanager
def _long_lived_objects_frozen() -> Iterator[None]:
    """While the block runs, the garbage collector leaves alone the objects alive when it
    starts (``gc.freeze``): imported modules, the study, the backend. They live as long as the
    run anyway, and at paper scale they are ~80 000 of the ~100 000 objects that each full
    collection walked (~40 of them per run, 0.1–0.4 s each, in the coordinator's time). Only
    the cyclic collector is affected: reference counting frees as before. Unfrozen afterwards.
    Freezing again after each generation was tried and reverted (it kept the garbage of every
    generation alive; ``benchmarks/RESULTS-paper-scale.md``)."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()


def _generations(store: RunStore, algorithm: Any, study: Study, problem: CandidateProblem,
                 elapsed0: float, progress: Callable[[int, dict], None] | None,
                 stop_after: int | None, hv: HypervolumeState | None) -> RunResult:
    writer = GenerationWriter(store, background=BACKGROUND_WRITES)
    try:
        with _long_lived_objects_frozen():
            result = _generation_loop(store, writer, algorithm, study, problem, elapsed0,
                                      progress, stop_after, hv)
    except BaseException:
        writer.close(raise_errors=False)  # the lock is released after the writes in flight
        raise
    writer.close()
    if not algorithm.has_next():  # every generation is stored: the run is complete
        if needs_polish(algorithm, study):  # algorithm.settings.polish: the hybrid's last step
            quiet = getattr(progress, "quiet", progress is None)
            polish_stage(store, algorithm, study, front, quiet=quiet)
            X, F = front(algorithm, study)
            result = replace(result, X=X, F=F)
        store.write_pareto(study.variable_names, study.objective_names, result.X, result.F)
        store.update_manifest(finished=now(), status="completed",
                              n_evaluations=int(algorithm.evaluator.n_eval))
    return result


def _generation_loop(store: RunStore, writer: GenerationWriter, algorithm: Any, study: Study,
                     problem: CandidateProblem, elapsed0: float,
                     progress: Callable[[int, dict], None] | None, stop_after: int | None,
                     hv: HypervolumeState | None) -> RunResult:
    start = time.perf_counter()
    steps = 0
    while algorithm.has_next():
        t, cpu = [time.perf_counter()], [time.process_time()]
        mark = _marker(t, cpu)
        with seeded_defaults(algorithm):  # Algorithm.next(), one step at a time
            infills = algorithm.infill()
            mark()
            if infills is not None:
                algorithm.evaluator.eval(algorithm.problem, infills, algorithm=algorithm)
                raise_swallowed_signal()  # before the generation is stored: resume redoes it
            mark()
            algorithm.advance(infills=infills)
            mark()
        # pymoo's n_gen is 2 after the initial population (generation 0 here), 3 after the next…
        gen = int(algorithm.n_gen) - 2
        records = problem.last_records
        archive_size = archive_count(algorithm, study)
        had_space = hv is not None and hv.space is not None
        hv, hv_value = generation_hypervolume(study, records, hv)
        if hv.space is not None and not had_space:  # the report measures in the same space
            store.update_manifest(hypervolume_space={"ideal": hv.space.ideal.tolist(),
                                                     "nadir": hv.space.nadir.tolist()})
        stats = {
            "n_evaluations": int(algorithm.evaluator.n_eval),
            "archive_size": archive_size,
            "feasible_fraction": float(np.mean([r.status == "completed" for r in records]))
            if records else 0.0,
            "hypervolume": hv_value,
            "elapsed_s": elapsed0 + time.perf_counter() - start,
        }
        mark()
        writer.wait()  # the previous generation's writes (usually long done)
        problem.last_records = []
        mark()
        checkpoint = dumps({"algorithm": algorithm, "elapsed_s": stats["elapsed_s"],
                            "generation": gen, "hypervolume_state": hv})
        mark()
        step = dict(zip(("ask_s", "evaluate_s", "advance_s", "statistics_s", "history_s",
                         "checkpoint_s"), np.diff(t).tolist(), strict=True))
        writer.submit(gen, records, dict(stats), checkpoint, {
            "generation": gen, "n_evaluations": stats["n_evaluations"],
            "archive_size": stats["archive_size"], **step, "wall_s": t[-1] - t[0],
            "cpu_s": cpu[-1] - cpu[0], "coordinator_s": t[-1] - t[0] - step["evaluate_s"],
            "coordinator_cpu_s": cpu[-1] - cpu[0] - (cpu[2] - cpu[1]), "finished": now()})
        if progress:
            progress(gen, stats)
        steps += 1
        if stop_after is not None and steps >= stop_after:
            break
    X, F = front(algorithm, study)
    return RunResult(path=store.path, variable_names=study.variable_names,
                     objective_names=study.objective_names, X=X, F=F,
                     n_evaluations=int(algorithm.evaluator.n_eval),
                     generations=int(algorithm.n_gen or 0))


@contextlib.contextmanager
def _released_on_error(store: RunStore) -> Iterator[None]:
    """Setting up a run or resume: on any failure or signal, release its lock (and tell an
    :class:`Interrupted` which run it stopped) before passing the exception on."""
    try:
        yield
    except BaseException as exc:
        if isinstance(exc, Interrupted):
            exc.run_dir = store.path
        store.release()
        raise


def _close(be: Any, failed: bool) -> None:
    """Close a backend; after a failure or a signal, kill its workers rather than wait."""
    if failed and hasattr(be, "terminate"):
        be.terminate()
    else:
        be.close()


def _interruptible(fn: Callable[..., T]) -> Callable[..., T]:
    """Signals interrupt ``fn`` (a run or resume) anywhere, not only inside the loop."""
    import functools

    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> T:
        with _signals_interrupt():
            return fn(*args, **kwargs)

    return wrapper


@_interruptible
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
    """Run ``problem`` into the new run directory ``out`` (a new or empty folder; anything else
    is refused untouched).

    ``backend`` overrides the problem's own; ``stop_after`` stops after that many generations
    (as if killed; resume continues it).
    """
    from casadrone.indices import INDICES

    backend_cfg = backend or problem.backend
    unguarded = _check_main_guard(backend_cfg, "casadrone.run()")
    problem = problem.model_copy(update={"backend": backend_cfg})
    study = Study(problem)
    index_names = (study.objective_names if problem.test_problem is not None
                   else list(INDICES))
    build_algorithm(problem, len(study.objective_names))  # refused here, before any file
    store = RunStore.create(out, problem, study.variable_names, index_names, backend_cfg.name)
    with _released_on_error(store):
        study = Study(store.problem())  # the run's own copies of its input files
        algorithm, termination = build_algorithm(problem, len(study.objective_names))
        algorithm.setup(CandidateProblem(study), termination=termination, seed=problem.seed,
                        verbose=False)
        be = make_backend(backend_cfg, without_main=unguarded)
    failed = True
    try:
        prog = progress or Progress(problem.algorithm.generations, quiet)
        result = _loop(store, algorithm, study, be, 0.0, prog, stop_after)
        failed = False
        return result
    finally:
        _close(be, failed)


@_interruptible
def resume(out: str | Path, backend: BackendConfig | None = None, quiet: bool = False,
           progress: Callable | None = None, stop_after: int | None = None) -> RunResult:
    """Continue the run in ``out`` from its last checkpoint (the previous one if the last is
    damaged; with neither, rebuilt from ``history.sqlite``, which also restarts a run killed
    before its first checkpoint). The lock is taken before anything is read or written."""
    store = RunStore(Path(out))
    store.acquire()
    with _released_on_error(store):
        store.manifest  # noqa: B018 -- a run killed while being created: says so, not "missing"
        problem = store.problem()  # from the run's own config.yaml and inputs/, wherever it is
        study = Study(problem)
        replay: list[list[Record]] | None = None
        reason = ""
        try:
            state = store.load_checkpoint()
            algorithm, elapsed0 = state["algorithm"], float(state["elapsed_s"])
            _check_history(store, int(state["generation"]))
        except (FileNotFoundError, RunDamaged) as why:
            reason = str(why)
            try:
                replay = stored_generations(store)
            except RunDamaged as exc:
                raise RunDamaged(f"{why}; and the history cannot rebuild it: {exc}") from None
            algorithm, termination = build_algorithm(problem, len(study.objective_names))
            algorithm.setup(CandidateProblem(study), termination=termination,
                            seed=problem.seed, verbose=False)
            elapsed0 = 0.0
            if not quiet:
                print(f"{out}: no usable checkpoint ({str(why).removeprefix(f'{out}: ')}); "
                      f"rebuilding from history.sqlite ({len(replay)} stored generation(s))",
                      file=sys.stderr, flush=True)
        algorithm.problem.study = study  # never the original directory's inputs
        backend_cfg = backend or problem.backend
        be = make_backend(backend_cfg,
                          without_main=_check_main_guard(backend_cfg, "casadrone.resume()"))
        if replay is not None:
            be = ReplayBackend(replay, be, reason)
    failed = True
    try:
        store.update_manifest(status="running", resumed=now())
        prog = progress or Progress(problem.algorithm.generations, quiet)
        result = _loop(store, algorithm, study, be, elapsed0, prog, stop_after,
                       None if replay is not None else state.get("hypervolume_state"))
        failed = False
        return result
    finally:
        _close(be, failed)
