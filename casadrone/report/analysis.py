"""Reading a run directory for the report, and what the report computes from it: the A/B/C
candidates, the convergence history (hypervolume in one fixed normalised space) and the failures
grouped by reason."""

from __future__ import annotations

import math
import re
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from casadrone.compare import CANDIDATE_LABELS, DECISION_TEXT, Candidate
from casadrone.decide import decide
from casadrone.indices import INDICES
from casadrone.optimise.hypervolume import HypervolumeSpace, non_dominated
from casadrone.optimise.problem import FAILURE_CV, Study, objectives_and_constraints
from casadrone.results import Record
from casadrone.rundir.store import PARETO, RunStore

#: Decision methods in label order (paper: A utopian, B trade-off, C extreme).
LABELS = tuple((CANDIDATE_LABELS[m], m, text) for m, text in DECISION_TEXT.items())
STAGES = tuple(FAILURE_CV)  # geometry, trim, control, lap, limit


# ---------------------------------------------------------------------------------------------
# Reading the run
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Run:
    """What the report reads from a run directory."""

    store: RunStore
    study: Study
    manifest: dict
    history: list[dict]
    generations: list[dict]
    X: np.ndarray  # Pareto set (n, variables)
    F: np.ndarray  # Pareto front (n, objectives), own units and sense
    front_source: str

    @property
    def test_problem(self) -> bool:
        return self.study.problem.test_problem is not None

    def unit(self, objective: str) -> str:
        return "–" if self.test_problem or objective not in INDICES else INDICES[objective].unit


def _records(study: Study, history: list[dict]) -> list[Record]:
    names = study.variable_names
    index_names = study.objective_names if study.problem.test_problem else list(INDICES)
    return [Record(theta={n: h[n] for n in names}, status=h["status"], stage=h["stage"] or "",
                   reason=h["reason"] or "",
                   indices={n: h[n] for n in index_names if h.get(n) is not None})
            for h in history]


def feasible_front(study: Study, history: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per evaluation: generation, minimised objectives F and feasibility (completed and within
    every constraint), with the run's own definition (:func:`objectives_and_constraints`)."""
    if not history:
        m = len(study.objective_names)
        return np.empty(0, int), np.empty((0, m)), np.empty(0, bool)
    F, G = objectives_and_constraints(study, _records(study, history))
    return np.array([h["generation"] for h in history]), F, np.all(G <= 0, axis=1)


def read_run(run_dir: str | Path) -> Run:
    """Read a run directory; without ``pareto.csv`` (an unfinished run) the front is the
    non-dominated feasible set of every evaluation stored so far."""
    store = RunStore(Path(run_dir))
    study = Study(store.problem())
    history = store.history()
    nv = len(study.variable_names)
    if (store.path / PARETO).exists():
        _, rows = store.read_pareto()
        A = np.asarray(rows, float).reshape(len(rows), nv + len(study.objective_names))
        X, F, source = A[:, :nv], A[:, nv:], PARETO
    else:
        _, Fmin, ok = feasible_front(study, history)
        best = non_dominated(Fmin[ok]) if ok.any() else Fmin[:0]
        keep = [i for i in np.flatnonzero(ok) if (best == Fmin[i]).all(axis=1).any()]
        keep = list({tuple(Fmin[i]): i for i in keep}.values())  # one design per point
        X = np.array([[history[i][n] for n in study.variable_names] for i in keep]).reshape(-1, nv)
        F = np.array([[history[i][n] for n in study.objective_names] for i in keep]).reshape(
            len(keep), -1)
        source = f"history.sqlite (no {PARETO}: the run has not finished)"
    return Run(store, study, store.manifest, history, store.generations(), X, F, source)


# ---------------------------------------------------------------------------------------------
# Analysis
# ---------------------------------------------------------------------------------------------


def choose_candidates(run: Run) -> list[Candidate]:
    """A (utopian), B (compromise) and C (extreme on the first objective) on the run's front, as
    :func:`casadrone.compare.run_candidates` chooses them (which needs ``pareto.csv``; this
    also works on the front of an unfinished run), one entry per distinct design. Empty for an
    empty front."""
    if len(run.F) == 0:
        return []
    names = run.study.objective_names
    senses = dict(zip(names, run.study.senses, strict=True))
    rows: dict[int, list] = {}
    for label, method, _ in LABELS:
        d = decide(run.F, senses, method, names[0] if method == "extreme" else None)
        rows.setdefault(d.index, []).append((label, method, d.distance))
    return sorted((Candidate(
        label="=".join(x[0] for x in picks), methods=tuple(x[1] for x in picks), row=row,
        distance=picks[0][2],
        theta=dict(zip(run.study.variable_names, map(float, run.X[row]), strict=True)),
        objectives=dict(zip(names, map(float, run.F[row]), strict=True)))
        for row, picks in rows.items()), key=lambda c: c.label)


@dataclass(frozen=True)
class ConvergenceHistory:
    """Per generation: hypervolume of the non-dominated feasible set of all evaluations so far,
    in one normalised space fixed for the whole run (ideal and nadir of the first feasible
    generation's non-dominated set, objectives minimised, scaled to [0, 1], reference point 1.1
    per objective; :mod:`casadrone.optimise.hypervolume`)."""

    generations: np.ndarray
    hypervolume: np.ndarray
    n_non_dominated: np.ndarray
    ideal: np.ndarray
    nadir: np.ndarray


def convergence_history(run: Run, max_points: int = 60) -> ConvergenceHistory:
    """Recompute the hypervolume per generation from the history (see ConvergenceHistory): the
    value the run showed on the console and logged, in the same fixed space
    (:mod:`casadrone.optimise.hypervolume`; the space stored in the manifest, else the one the
    first feasible generation fixes).

    The archive is updated every generation; the hypervolume (whose cost grows fast with the
    archive in five objectives) is computed at no more than ``max_points`` evenly spaced
    generations, the last always included, and is NaN at the others.
    """
    gen, F, ok = feasible_front(run.study, run.history)
    gens = np.array(sorted({g["generation"] for g in run.generations} | set(gen.tolist())), int)
    m = F.shape[1]
    stored = run.manifest.get("hypervolume_space")
    space = (HypervolumeSpace(np.array(stored["ideal"]), np.array(stored["nadir"]))
             if stored else None)
    every = max(1, math.ceil(len(gens) / max_points))
    archive, hv, size = np.empty((0, m)), [], []
    for k, g in enumerate(gens):
        new = F[ok & (gen == g)]
        if len(new):
            space = space or HypervolumeSpace.of(new, raw=run.test_problem)
            archive = non_dominated(np.vstack([archive, new]))
        due = k % every == 0 or k == len(gens) - 1
        hv.append(space.hypervolume(archive) if due and space is not None else
                  0.0 if due else math.nan)
        size.append(len(archive))
    nan = np.full(m, np.nan)
    return ConvergenceHistory(gens, np.array(hv), np.array(size, int),
                              space.ideal if space else nan, space.nadir if space else nan)


_NUMBER = re.compile(r"(?<![A-Za-z_\d.])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def reason_group(reason: str) -> str:
    """A failure reason without its time (text before `` at t =``) and with numbers as ``#``,
    so that the same failure at different times or values is one group."""
    return _NUMBER.sub("#", reason.split(" at t =")[0]).strip()


def failure_groups(history: list[dict]) -> list[tuple[str, str, int, str]]:
    """(stage, reason group, count, first reason seen) of the failed evaluations, most frequent
    first within each stage (stages in chain order)."""
    counts: Counter = Counter()
    example: dict[tuple[str, str], str] = {}
    for h in history:
        if h["status"] != "completed":
            key = (h["stage"] or "?", reason_group(h["reason"] or ""))
            counts[key] += 1
            example.setdefault(key, h["reason"] or "")
    order = {s: i for i, s in enumerate(STAGES)}
    return [(s, r, n, example[(s, r)]) for (s, r), n in
            sorted(counts.items(), key=lambda kv: (order.get(kv[0][0], 99), -kv[1], kv[0][1]))]
