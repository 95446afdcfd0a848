"""The polish stage of a hybrid run (``algorithm.settings.polish``): ev-MOGA, then its front
members improved by the co-design NLP (:mod:`casadrone.codesign.polish`).

After the last generation, ``members`` members of the archive spread along the lap are polished
one after another in the coordinator (each is one co-design solve with the member's other
objectives as ε-constraints, proposing a frame θ_p). The proposals are then evaluated as one
more generation on the run's backend, exactly as children are (the problem's own objectives:
θ_p's minimum-time limit lap and its effort, the closed-loop lap, the constraints), stored in
``history.sqlite`` as that generation, and offered to the archive by its own rules
(:meth:`casadrone.optimise.evmoga.EvMOGA.offer_solutions`): a polished frame that dominates its
member replaces it, one that does not is kept only where the ε-box archive keeps any newcomer,
and the member stays otherwise. ``polish.json`` records every polish: the member, the co-design
point, the evaluation, whether it improves on the member, and the CPU time. Then the
checkpoint is written with the algorithm marked as polished.

Resuming: a run killed during the polish resumes from the last generation's checkpoint and
polishes again (IPOPT from the same points: the same proposals), so it ends as an uninterrupted
run; a run killed after the polish's checkpoint only writes ``pareto.csv``.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from casadrone.codesign.polish import improves, polish_member, polish_problem, prepared, spread
from casadrone.config.codesign import PolishSettings
from casadrone.optimise.problem import Study, objectives_and_constraints
from casadrone.results import Record
from casadrone.rundir.checkpoint import dumps
from casadrone.rundir.store import RunStore, atomic_write

if TYPE_CHECKING:
    from casadrone.config.codesign import PolishSettings

#: Beside ``history.sqlite`` in a polished run: every member's polish (JSON).
POLISH_FILE = "polish.json"


def polish_settings(study: Study) -> PolishSettings | None:
    """The problem's :class:`casadrone.config.codesign.PolishSettings`, or None."""
    raw = study.problem.algorithm.settings.get("polish")
    if raw is None or study.problem.test_problem is not None:
        return None

    return PolishSettings.model_validate(raw)


def needs_polish(algorithm: Any, study: Study) -> bool:
    """The problem asks for a polish and this run has not stored one yet."""
    return polish_settings(study) is not None and not getattr(algorithm, "polished", False)


def polish_front(algorithm: Any, study: Study, evaluate: Callable[..., Any],
                 front_of: Callable[..., Any], quiet: bool = False,
                 stream: TextIO | None = None) -> tuple[list[Record], list[dict]]:
    """Polish the archive's members and offer the evaluated proposals to it (see the module
    docstring): ``evaluate(study, X)`` evaluates the proposals (the run's backend),
    ``front_of(algorithm, study)`` gives the front (X, F in the objectives' own sense). Returns
    the evaluations (the polish's generation) and one report per member."""
    settings = polish_settings(study)
    assert settings is not None
    stream = stream or sys.stderr
    X, F = front_of(algorithm, study)
    names, keys = study.objective_names, study.variable_names
    prep = prepared(polish_problem(study.problem))
    outcomes = []
    for i in spread(F, settings.members):
        theta = dict(zip(keys, map(float, X[i]), strict=True))
        member = dict(zip(names, map(float, F[i]), strict=True))
        p = polish_member(prep, theta, member)
        outcomes.append(p)
        if not quiet:
            got = ", ".join(f"{n} {p.values[n]:.6g}" for n in names) if p.values else "-"
            print(f"polish {len(outcomes)}: {', '.join(f'{n} {member[n]:.6g}' for n in names)}"
                  f" -> {got}  {'converged' if p.accepted else p.reason}  {p.cpu_s:.1f} s CPU",
                  file=stream, flush=True)
    done = [p for p in outcomes if p.accepted]
    Xp = np.array([[p.theta[k] for k in keys] for p in done], float).reshape(len(done), len(keys))
    records = list(evaluate(study, Xp)) if done else []
    algorithm.evaluator.n_eval += len(records)
    Fm, G = objectives_and_constraints(study, records)
    if records:
        algorithm.offer_solutions(Xp, Fm, G)
    evaluated = iter(records)
    report = []
    for p in outcomes:
        r = next(evaluated) if p.accepted else None
        values = ({n: float(r.indices[n]) for n in names}
                  if r is not None and r.status == "completed" else {})
        report.append({**p.as_dict(), "evaluation": values,
                       "evaluation_status": None if r is None else
                       (r.status if r.status == "completed" else f"{r.stage}: {r.reason}"),
                       "improves": improves(p.member, values)})
        if not quiet:
            print(f"polish {len(report)}: evaluated {report[-1]['evaluation_status']}, "
                  f"improves on the member: {report[-1]['improves']} ({values or '-'})",
                  file=stream, flush=True)
    algorithm.polished = True
    return records, report


def polish_stage(store: RunStore, algorithm: Any, study: Study, front_of: Callable[..., Any],
                 quiet: bool = False, stream: TextIO | None = None) -> list[dict]:
    """:func:`polish_front` on the run's backend, stored as one more generation of the run
    (history, ``polish.json``, checkpoint). Returns the reports."""
    t0, c0 = time.perf_counter(), time.process_time()
    records, report = polish_front(algorithm, study, algorithm.problem.backend.evaluate,
                                   front_of, quiet, stream)
    generation = int(algorithm.n_gen) - 1  # one after the last stored generation
    previous = store.generations()
    elapsed = (previous[-1]["elapsed_s"] if previous else 0.0) + time.perf_counter() - t0
    kept = [r.status == "completed" for r in records]
    stats = {"n_evaluations": int(algorithm.evaluator.n_eval),
             "archive_size": int(algorithm.front_size()),
             "feasible_fraction": float(np.mean(kept)) if kept else 0.0,
             "hypervolume": None, "elapsed_s": elapsed}
    store.write_generation(generation, records, stats)
    atomic_write(store.path / POLISH_FILE, json.dumps(
        {"generation": generation, "coordinator_cpu_s": time.process_time() - c0,
         "members": report}, indent=1, default=float))
    store.write_checkpoint(dumps({"algorithm": algorithm, "elapsed_s": elapsed,
                                  "generation": generation, "hypervolume_state": None}))
    return report
