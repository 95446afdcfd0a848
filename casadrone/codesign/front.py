"""Design fronts by ε-continuation: the lap against one other measure, one NLP solve per point.

From the fastest frame (:func:`casadrone.codesign.design.codesign`), the measure m (mass, span,
or the limit lap's effort, :func:`casadrone.codesign.nlp.effort`) is bounded, m ≤ ε, and ε is
lowered step by step; each solve starts from the previous point's primal and dual values (a
primal-dual warm start, the previous ε-row multiplier included), so the front is followed as a
path of local optima rather than found again from scratch. The ε values are a geometric sweep
from the fastest frame's measure down to ``lowest`` of it; the sweep stops at the first ε the
NLP cannot meet (reported).

The front is written as a run directory (:func:`write_run`) with ``pareto.csv``,
``config.yaml`` and ``manifest.json`` as :mod:`casadrone.rundir.store` writes them.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from casadrone.codesign import events
from casadrone.codesign.certificate import active_constraints
from casadrone.codesign.driver import CodesignPoint, Prepared, constrained, solve_from
from casadrone.codesign.frontcert import certified_point
from casadrone.codesign.nlp import STEP_CPU_FACTOR, STEP_MIN_CPU_S, effort, epsilon_rows
from casadrone.config.problem import ProblemConfig
from casadrone.limit.starts import trajectory
from casadrone.progress import nested
from casadrone.results import Record
from casadrone.rundir.store import RunStore, atomic_write, now


@dataclass(frozen=True)
class FrontPoint:
    """One point of a front: the co-design point and the measure's value and bound."""

    point: CodesignPoint
    measure: float
    epsilon: float
    status: str
    success: bool
    #: its certificate (casadrone.codesign.certificate.Certificate; casadrone.codesign.frontcert
    #: issues it at every point), None where the front was not certified
    certificate: Any = None


@dataclass(frozen=True)
class Front:
    """A design front: lap against ``measure``, fastest first."""

    measure: str
    points: tuple[FrontPoint, ...]
    cpu_s: float
    stopped: str = ""  # why the sweep ended early ("" when every ε was met)
    prepared: Prepared | None = field(default=None, repr=False)  # the ε-constrained NLP's
    certificates_cpu_s: float = 0.0  # of cpu_s, the points' certificates


def measure_value(prep: Prepared, point: CodesignPoint, measure: str) -> float:
    """The measure at a point (mass kg, span m, effort N^1.5·s)."""
    if measure == "mass_kg":
        return point.mass_kg
    if measure == "span_m":
        return point.span_m
    return sum(track_efforts(prep, point).values())


def track_efforts(prep: Prepared, point: CodesignPoint) -> dict[str, float]:
    """Each track's limit-lap effort at a point (N^1.5·s), by track label."""
    import casadi as ca

    ws, s = prep.nlp.split(point.z)
    p = ca.DM(prep.nlp.frame.function(np.clip(s, 0.0, 1.0))[0])  # the airframe vector p(θ)
    return {label: float(ca.evalf(effort(part, ca.DM(w), p)))
            for label, part, w in zip(prep.labels, prep.nlp.parts, ws, strict=True)}


def design_front(prep_free: Prepared, best: CodesignPoint, measure: str, points: int = 15,
                 lowest: float = 0.5, on_point=None, certify: bool = False,
                 first=None) -> Front:
    """The front from ``best`` (the unconstrained optimum) down to ``lowest`` × its measure;
    ``on_point(FrontPoint)``, if given, is called as each point converges (a long sweep's
    progress, kept by the caller). ``certify``: each point is certified as it converges, before
    ``on_point`` sees it (:func:`casadrone.codesign.frontcert.certified_point`; ``first``, the
    fastest frame's certificate where already issued)."""
    prep = constrained(prep_free, (measure,))
    c0 = time.process_time()
    cert_cpu = 0.0

    def certified(fp: FrontPoint) -> FrontPoint:
        nonlocal cert_cpu
        if not certify:
            return fp
        t0 = time.process_time()
        with nested():
            fp = certified_point(prep, fp, first)
        cert_cpu += time.process_time() - t0
        return fp

    def reached(fp: FrontPoint) -> None:
        events.front_point(len(out), points, fp, measure)
        if on_point is not None:
            on_point(fp)

    top = measure_value(prep, best, measure)
    prev = replace(best, lam_g=np.concatenate([best.lam_g, np.zeros(epsilon_rows(measure))]))
    out = [certified(FrontPoint(prev, top, math.inf, "fastest frame", True))]
    reached(out[-1])
    stopped = ""
    last = top
    step_cpu = [best.cpu_s]  # the CPU of each converged solve: the fastest frame's, each step's
    for eps in top * lowest ** (np.arange(1, points) / (points - 1)):
        ok, status, pt = continued(prep, prev, measure, last, float(eps),
                                   budget_s=step_budget(step_cpu))
        if not ok:
            stopped = f"ε = {eps:.6g}: {status}"
            events.front_stopped(stopped)
            break
        out.append(certified(FrontPoint(pt, measure_value(prep, pt, measure), float(eps),
                                        status, ok)))
        reached(out[-1])
        prev, last = pt, float(eps)
        step_cpu.append(pt.cpu_s)
    return Front(measure, tuple(out), time.process_time() - c0, stopped, prep, cert_cpu)


#: How many times one continuation step may be halved (each half again) before the sweep stops.
MAX_SPLITS = 2


def continued(prep: Prepared, prev: CodesignPoint, measure: str, last: float, eps: float,
              splits: int = MAX_SPLITS, budget_s: float | None = None
              ) -> tuple[bool, str, CodesignPoint]:
    """The ε-point ``eps`` from ``prev`` (the point at ``last``): one warm solve capped at
    :data:`casadrone.codesign.nlp.STEP_MAX_ITER` iterations and ``budget_s`` CPU seconds; if
    it fails, the step is halved (geometric mean of ``last`` and ``eps``: the sweep's own
    spacing) and both halves are solved in turn, each from the one before and with the same
    budget, at most ``splits`` levels deep. Step-length control of a continuation (Allgower &
    Georg, *Introduction to Numerical Continuation Methods*, 2003, ch. 6): a shorter step
    starts closer to the next optimum."""
    ok, status, pt = solve_from(prep, prev.z, {measure: eps}, warm=prev, step=True,
                                budget_s=budget_s)
    if ok or splits == 0:
        return ok, status, pt
    mid = math.sqrt(last * eps)
    ok_mid, status_mid, half = continued(prep, prev, measure, last, mid, splits - 1, budget_s)
    if not ok_mid:
        return False, f"{status}; halved at ε = {mid:.6g}: {status_mid}", pt
    ok, status2, pt = continued(prep, half, measure, mid, eps, splits - 1, budget_s)
    return ok, status2 if ok else f"{status}; from ε = {mid:.6g}: {status2}", pt


def step_budget(converged_cpu_s: list[float]) -> float | None:
    """A continuation step's CPU budget from the solves converged so far (their CPU seconds:
    the fastest frame's, then each step's): :data:`~casadrone.codesign.nlp.STEP_CPU_FACTOR` ×
    the slowest, at least :data:`~casadrone.codesign.nlp.STEP_MIN_CPU_S`; ``None`` with no
    history (the solver's own guard, :data:`~casadrone.codesign.nlp.STEP_MAX_CPU_S`, holds).
    A step that needs many times what its neighbours needed has lost its way; halving it is
    cheaper. A multiple, not a fixed cap, because a step's cost depends on the model, the grid
    and the machine (paper 2–10 s, `propeller` on 120 intervals 33–109 s on the same VM)."""
    if not converged_cpu_s:
        return None
    return max(STEP_MIN_CPU_S, STEP_CPU_FACTOR * max(converged_cpu_s))


#: Beside ``pareto.csv`` in a front's run directory: per point, its laps, measures and active
#: constraints (JSON), and its limit laps' nodes (numpy ``.npz``), read by the report.
POINTS_FILE = "codesign.json"
LAPS_FILE = "codesign-laps.npz"


def point_laps(prep: Prepared, point: CodesignPoint) -> dict[str, dict[str, np.ndarray]]:
    """Each track's limit lap of a co-design point: node times (s), node states with Euler
    angles (16 columns), commands held on each interval, and the split times (s)."""
    ws, _ = prep.nlp.split(point.z)
    out = {}
    for label, part, w in zip(prep.labels, prep.nlp.parts, ws, strict=True):
        lap = trajectory(part.nlp, w, part.nlp.layout)
        T, _, _ = part.nlp.unpack(w)
        out[label] = {"t": lap.t, "x": lap.x_euler, "u": lap.u,
                      "splits": np.cumsum(T)[part.first_timed:]}
    return out


def point_record(prep: Prepared, fp: FrontPoint, measure: str) -> dict:
    """One front point as plain data for :data:`POINTS_FILE`."""
    p = fp.point
    efforts = track_efforts(prep, p)
    return {"theta": p.theta, "objective_s": p.objective, "laps_s": p.laps_s,
            "measure": measure, "value": fp.measure,
            "epsilon": None if math.isinf(fp.epsilon) else fp.epsilon, "status": fp.status,
            "mass_kg": p.mass_kg, "span_m": p.span_m, "effort": efforts,
            "iterations": p.iterations, "cpu_s": p.cpu_s,
            "active_constraints": active_constraints(prep, p),
            "certificate": None if fp.certificate is None else fp.certificate.as_dict()}


def write_run(path, prep: Prepared, front: Front, n_solves: int):
    """The front as a run directory (``config.yaml`` a problem with the lap and the measure as
    objectives, ``pareto.csv`` variables then objectives, ``manifest.json``, each solve in
    ``history.sqlite``, and :data:`POINTS_FILE` and :data:`LAPS_FILE` for the report), so
    ``decide``, ``report``, ``compare`` and ``export`` open it like an optimiser's run. The
    manifest's backend is ``codesign`` and records the limit lap's posing (intervals, gate
    clearance) so a reader re-solves the same lap. Returns the RunStore."""
    import json

    prep = front.prepared or prep  # the ε-constrained NLP the points were solved in

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
        records = [Record(theta=p.point.theta, status="completed",
                          indices=dict(zip(names, f, strict=True)), wall_time_s=p.point.cpu_s)
                   for p, f in zip(front.points, F, strict=True)]
        store.write_generation(0, records, {
            "n_evaluations": len(records), "archive_size": len(records),
            "feasible_fraction": 1.0, "hypervolume": None, "elapsed_s": front.cpu_s})
        points = [point_record(prep, p, front.measure) for p in front.points]
        atomic_write(store.path / POINTS_FILE, json.dumps(
            {"measure": front.measure, "tracks": list(prep.labels),
             "intervals": prep.options.intervals,
             "gate_clearance_m": prep.options.gate_clearance_m, "points": points},
            indent=1, default=float))
        laps = [point_laps(prep, p.point) for p in front.points]
        arrays = {f"{i}/{label}/{k}": v for i, lap in enumerate(laps)
                  for label, parts in lap.items() for k, v in parts.items()}
        with open(store.path / LAPS_FILE, "wb") as fh:
            np.savez_compressed(fh, **arrays)  # type: ignore[arg-type]  # names → arrays
        store.write_pareto(list(prep.keys), names, X, F)
        store.update_manifest(finished=now(), status="completed", n_evaluations=n_solves,
                              cpu_s=front.cpu_s, front_stopped=front.stopped,
                              codesign={"intervals": prep.options.intervals,
                                        "gate_clearance_m": prep.options.gate_clearance_m,
                                        "tracks": list(prep.labels)})
    finally:
        store.release()
    return store
