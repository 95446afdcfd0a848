"""Design fronts by ε-continuation: the lap against one other measure, one NLP solve per point.

From the fastest frame (:func:`casadrone.codesign.design.codesign`), the measure m (mass, span,
or the limit lap's effort, :func:`casadrone.codesign.nlp.effort`) is bounded, m ≤ ε, and ε is
lowered step by step; each solve starts from the previous point's primal and dual values (a
primal-dual warm start, the previous ε-row multiplier included), so the front is followed as a
path of local optima rather than found again from scratch. The ε values are a geometric sweep
from the fastest frame's measure down to ``lowest`` of it; the sweep stops at the first ε the
NLP cannot meet (reported).

The front is written as a run directory (:func:`write_run`) with ``pareto.csv``,
``config.yaml`` and ``manifest.json`` as :mod:`casadrone.optimise.store` writes them.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from casadrone.codesign.driver import CodesignPoint, Prepared, prepare, solve_from


@dataclass(frozen=True)
class FrontPoint:
    """One point of a front: the co-design point and the measure's value and bound."""

    point: CodesignPoint
    measure: float
    epsilon: float
    status: str
    success: bool


@dataclass(frozen=True)
class Front:
    """A design front: lap against ``measure``, fastest first."""

    measure: str
    points: tuple[FrontPoint, ...]
    cpu_s: float
    stopped: str = ""  # why the sweep ended early ("" when every ε was met)


def measure_value(prep: Prepared, point: CodesignPoint, measure: str) -> float:
    """The measure at a point (mass kg, span m, effort N^1.5·s)."""
    if measure == "mass_kg":
        return point.mass_kg
    if measure == "span_m":
        return point.span_m
    import casadi as ca

    from casadrone.codesign.nlp import effort

    ws, _ = prep.nlp.split(point.z)
    return float(sum(float(ca.evalf(effort(part, ca.DM(w))))
                     for part, w in zip(prep.nlp.parts, ws, strict=True)))


def design_front(prep_free: Prepared, best: CodesignPoint, measure: str, points: int = 15,
                 lowest: float = 0.5) -> Front:
    """The front from ``best`` (the unconstrained optimum) down to ``lowest`` × its measure."""
    prep = prepare(prep_free.problem, epsilon=(measure,))
    c0 = time.process_time()
    top = measure_value(prep, best, measure)
    n_rows = 2 if measure == "span_m" else 1
    prev = replace(best, lam_g=np.concatenate([best.lam_g, np.zeros(n_rows)]))
    out = [FrontPoint(best, top, math.inf, "fastest frame", True)]
    stopped = ""
    for eps in top * lowest ** (np.arange(1, points) / (points - 1)):
        ok, status, pt = solve_from(prep, prev.z, {measure: float(eps)}, warm=prev)
        if not ok:
            stopped = f"ε = {eps:.6g}: {status}"
            break
        out.append(FrontPoint(pt, measure_value(prep, pt, measure), float(eps), status, ok))
        prev = pt
    return Front(measure, tuple(out), time.process_time() - c0, stopped)


def write_run(path, prep: Prepared, front: Front, n_solves: int):
    """The front as a run directory (``config.yaml`` a problem with the lap and the measure as
    objectives, ``pareto.csv`` variables then objectives, ``manifest.json``), so ``decide`` and
    the other run readers open it like an optimiser's run. Returns the RunStore."""
    from casadrone.config.problem import ProblemConfig
    from casadrone.optimise.store import RunStore, now

    data = prep.problem.model_dump(exclude={"codesign"})
    data["objectives"] = [{"index": "J3_limit", "sense": "min"},
                          {"index": front.measure, "sense": "min"}]
    if prep.problem.codesign.tracks:
        first = next(iter(prep.problem.codesign.tracks.values()))
        data["track"] = first.track
    problem = ProblemConfig.model_validate(data)
    names = [o["index"] for o in data["objectives"]]
    store = RunStore.create(path, problem, list(prep.keys), names, "codesign")
    try:
        X = [[p.point.theta[k] for k in prep.keys] for p in front.points]
        F = [[p.point.objective, p.measure] for p in front.points]
        store.write_pareto(list(prep.keys), names, X, F)
        store.update_manifest(finished=now(), status="completed", n_evaluations=n_solves,
                              cpu_s=front.cpu_s, front_stopped=front.stopped)
    finally:
        store.release()
    return store
