"""The pymoo problem over the evaluation chain (or over a pymoo test problem).

A :class:`Study` is the picklable description shared by the coordinator and the workers: the
resolved :class:`~casadrone.config.problem.ProblemConfig`. Workers turn it into an evaluation setup
once per process (:func:`study_setup`, cached), then evaluate rows of decision vectors into
:class:`Record` objects. :class:`CandidateProblem` maps records to pymoo's F (minimised) and G
(≤ 0 feasible): a failed candidate is infeasible with its reason kept, never NaN in F.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from pymoo.core.problem import Problem

from casadrone.config.airframe import load_airframe
from casadrone.config.controller import load_controller
from casadrone.config.io import load
from casadrone.config.problem import ProblemConfig
from casadrone.config.track import TrackConfig
from casadrone.limit.search import lap_options
from casadrone.results import Record
from casadrone.rundir.plugins import import_plugin

if TYPE_CHECKING:  # the chain is imported when a setup is built
    from casadrone.config.airframe import AirframeConfig
    from casadrone.evaluate import EvaluationSetup

#: Constraint violation of a failed candidate, by the stage where it failed: earlier failures are
#: worse, so feasibility-first selection moves the search towards candidates that fly.
FAILURE_CV = {"geometry": 4.0, "trim": 3.0, "control": 2.0, "lap": 1.0, "limit": 0.5}
#: Objective value stored for failed candidates (pymoo needs finite F; feasibility decides first).
FAILED_F = 1e9


@dataclass(frozen=True)
class Study:
    """What every worker needs to evaluate candidates of one problem."""

    problem: ProblemConfig

    @property
    def key(self) -> str:
        """Hash of the resolved problem (cache key of the per-process setup)."""
        return hashlib.sha256(self.problem.model_dump_json().encode()).hexdigest()

    @property
    def variable_names(self) -> list[str]:
        if self.problem.test_problem is not None:
            return [f"x{i + 1}" for i in range(self.problem.test_problem.n_var)]
        return [v.name for v in self.problem.variables]

    @property
    def objective_names(self) -> list[str]:
        if self.problem.test_problem is not None:
            return [f"f{j + 1}" for j in range(pymoo_test_problem(self.problem).n_obj)]
        return [o.index for o in self.problem.objectives]

    @property
    def senses(self) -> list[str]:
        if self.problem.test_problem is not None:
            return ["min"] * len(self.objective_names)
        from casadrone.indices import INDICES

        return [o.sense or INDICES[o.index].sense for o in self.problem.objectives]

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        if self.problem.test_problem is not None:
            tp = pymoo_test_problem(self.problem)
            return np.asarray(tp.xl, float), np.asarray(tp.xu, float)
        return (np.array([v.lower for v in self.problem.variables]),
                np.array([v.upper for v in self.problem.variables]))


def pymoo_test_problem(cfg: ProblemConfig) -> Any:
    """The pymoo test problem named by ``cfg.test_problem``."""
    from pymoo.problems import get_problem

    tp = cfg.test_problem
    if tp is None:
        raise ValueError(f"problem {cfg.name!r} names no test problem")
    if tp.name == "dtlz2":
        return get_problem("dtlz2", n_var=tp.n_var, n_obj=tp.n_obj)
    return get_problem(tp.name, n_var=tp.n_var)


_SETUPS: dict[str, EvaluationSetup] = {}


def _setup(key: str, problem: ProblemConfig) -> EvaluationSetup:
    """The evaluation setup of a problem, built once per process (the model and compiled lap are
    cached inside the chain's modules, so the first evaluation pays for them only once)."""
    from casadrone.evaluate import DEFAULT_TRACK, EvaluationSetup

    if key in _SETUPS:
        return _SETUPS[key]

    for plugin in problem.plugins:  # workers start fresh: register custom indices here too
        import_plugin(plugin)
    assert problem.airframe is not None  # a casadrone problem (a test problem has no setup)
    template = load_airframe(problem.airframe)
    if problem.fixed:
        template = template.model_validate({**template.model_dump(), **problem.fixed})
    track = load(TrackConfig, problem.track or DEFAULT_TRACK)
    _SETUPS[key] = EvaluationSetup(
        template=template,
        controller=load_controller(problem.controller),
        track=track,
        integrator=problem.integrator,
        **limit_setup(problem, template, periodic=track.end == "periodic"),
    )
    return _SETUPS[key]


def limit_setup(problem: ProblemConfig, template: AirframeConfig, periodic: bool = False
                ) -> dict:
    """Limit-lap settings of a problem that optimises or constrains a limit-lap index: the
    options (the problem's ``limit_lap:`` settings; ``periodic``: its track ends where it
    starts), and the per-study warm-start references (the template and the centre of the
    decision-variable box), identical in every worker."""
    from casadrone.indices import limit_index_names

    names = [o.index for o in problem.objectives] + [c.index for c in problem.constraints]
    if not limit_index_names(names):
        return {}
    from casadrone.evaluate import theta_of

    keys = [v.name for v in problem.variables]
    centre = {v.name: 0.5 * (v.lower + v.upper) for v in problem.variables}
    template_theta = {k: float(getattr(template, k)) for k in keys} if keys else theta_of(template)
    # resimulate: every converged warm start is flown by CVODES (~30 ms) and counts only if it
    # passes the targets, so a lap that exploits the discretisation never reaches the front.
    options = lap_options(problem.limit_lap, periodic)
    # the command's fast path falls back to the grid-continuation starts (a minute of CPU);
    # a candidate that no start verifies is a recorded failure instead
    return {"limit": replace(options, starts=("closed-loop",), fallback_starts=(),
                             point_mass_reference=False, resimulate=True, sensitivities=False),
            "limit_references": (template_theta, centre)}


def study_setup(study: Study) -> EvaluationSetup:
    """The cached evaluation setup of a study in this process."""
    return _setup(study.key, study.problem)


def evaluate_rows(study: Study, X: np.ndarray) -> list[Record]:
    """Evaluate decision vectors (rows of X) in this process, in order."""
    X = np.atleast_2d(np.asarray(X, float))
    names = study.variable_names
    if study.problem.test_problem is not None:
        tp = pymoo_test_problem(study.problem)
        out = []
        for x in X:
            start = time.perf_counter()
            F = np.asarray(tp.evaluate(x[None, :])).ravel()
            out.append(Record(theta=dict(zip(names, map(float, x), strict=True)),
                              status="completed",
                              indices=dict(zip(study.objective_names, map(float, F), strict=True)),
                              wall_time_s=time.perf_counter() - start))
        return out
    from casadrone.evaluate import evaluate

    setup = study_setup(study)
    records = []
    for x in X:
        ev = evaluate(dict(zip(names, map(float, x), strict=True)), setup)
        records.append(ev.record())
    return records


def objectives_and_constraints(
    study: Study, records: list[Record]
) -> tuple[np.ndarray, np.ndarray]:
    """pymoo F (minimised) and G (≤ 0 feasible) of a batch of records."""
    cfg = study.problem
    names, senses = study.objective_names, study.senses
    cons = [] if cfg.test_problem is not None else cfg.constraints
    F = np.full((len(records), len(names)), FAILED_F)
    G = np.zeros((len(records), 1 + 2 * len(cons)))
    for i, rec in enumerate(records):
        if rec.status != "completed":
            G[i, 0] = FAILURE_CV.get(rec.stage, 1.0)
            continue
        F[i] = [rec.indices[n] * (-1.0 if s == "max" else 1.0)
                for n, s in zip(names, senses, strict=True)]
        for j, c in enumerate(cons):
            value = rec.indices[c.index]
            G[i, 1 + 2 * j] = (value - c.max) if c.max is not None else 0.0
            G[i, 2 + 2 * j] = (c.min - value) if c.min is not None else 0.0
    return F, G


class CandidateProblem(Problem):
    """pymoo problem: a whole batch (one generation) goes to the backend at once.

    ``backend`` (an object with ``evaluate(study, X) -> list[Record]``) is attached by the runner
    and dropped when pickled (checkpoints), as are the records of the last batch and the study
    (its absolute input paths belong to where the run was: the runner attaches the study of the
    run directory it resumes, so a moved or copied run never reads the original's inputs).
    """

    def __init__(self, study: Study, backend: Any = None) -> None:
        xl, xu = study.bounds
        super().__init__(n_var=len(xl), n_obj=len(study.objective_names),
                         n_ieq_constr=1 + 2 * (0 if study.problem.test_problem else
                                               len(study.problem.constraints)),
                         xl=xl, xu=xu)
        self.study = study
        self.backend = backend
        self.last_records: list[Record] = []

    def _evaluate(self, X: np.ndarray, out: dict, *args: Any, **kwargs: Any) -> None:
        if self.backend is None:
            raise RuntimeError("no evaluation backend attached")
        records = self.backend.evaluate(self.study, X)
        self.last_records = list(records)
        out["F"], out["G"] = objectives_and_constraints(self.study, records)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state["backend"] = None
        state["last_records"] = []
        state["study"] = None
        return state
