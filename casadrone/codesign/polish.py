"""Polish of an optimiser's front members by the co-design NLP (the hybrid of ev-MOGA and
co-design, ``algorithm.settings.polish``).

A member θ_m with objectives (T_m, m_m) — the limit lap and the measures the co-design NLP holds
(:data:`casadrone.config.codesign.FRONT_MEASURES`) — is improved by one co-design solve: the lap
minimised over trajectory and θ together with every other objective held at the member's value
as an ε-constraint, m ≤ m_m. The solve starts from θ_m and the member's own limit lap (its limit
lap on the polish grid, warm-started from the template's, :func:`casadrone.codesign.driver.
initial_vector`), so the polished frame θ_p is the local optimum nearest the member, not a new
search.

What the solve returns is a *proposal*: its lap is that of a trajectory held to the member's
effort, not θ_p's minimum-time lap, so it is not the optimiser's objective value of θ_p (the
optimiser's J3_limit of a frame is its minimum-time lap, and ``effort`` that lap's effort). The
optimiser evaluates θ_p as it evaluates any candidate (:mod:`casadrone.optimise.hybrid`), and a
polish counts as an improvement only when that evaluation is not dominated by the member
(:func:`improves`). A solve that fails is a recorded result; the member stays either way.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from casadrone.config.airframe import load_airframe
from casadrone.config.codesign import FRONT_MEASURES, LAP_INDEX, CodesignProblemConfig


@dataclass(frozen=True)
class Polished:
    """One member's polish: where it started and what the co-design NLP reached (``values``:
    the polished point's lap and measures by index name; ``accepted``: the solve converged)."""

    theta_member: dict[str, float]
    member: dict[str, float]
    theta: dict[str, float]
    values: dict[str, float]
    accepted: bool
    status: str
    reason: str
    iterations: int
    cpu_s: float
    fixed_lap_s: float = math.nan  # the limit lap re-solved with θ fixed (the check)
    resimulation_miss_m: float = math.nan
    point: Any = field(default=None, repr=False, compare=False)  # the CodesignPoint

    def as_dict(self) -> dict[str, Any]:
        return {"theta_member": self.theta_member, "member": self.member, "theta": self.theta,
                "values": self.values, "accepted": self.accepted, "status": self.status,
                "reason": self.reason, "iterations": self.iterations, "cpu_s": self.cpu_s,
                "fixed_lap_s": self.fixed_lap_s,
                "resimulation_miss_m": self.resimulation_miss_m}


def polish_problem(problem, intervals: int | None = None):
    """The co-design problem of an optimiser's ``problem``: the same airframe, track, box and
    objectives, posed on ``intervals`` per leg (None: the limit lap's default for the
    template's propulsion, the grid the evaluation chain's limit lap uses), no random starts,
    the template's lap from the closed-loop start."""
    from casadrone.limit.result import DEFAULT_INTERVALS

    if intervals is None:
        assert problem.airframe is not None  # a casadrone problem
        intervals = DEFAULT_INTERVALS[load_airframe(problem.airframe).propulsion.model]
    data = problem.model_dump()
    data["algorithm"] = {"name": problem.algorithm.name}
    # the template's lap from the closed-loop start alone: the evaluation chain's own cold
    # start for J3_limit (casadrone.optimise.problem); the default three cost three times more.
    # The polish poses its laps as co-design does (CODESIGN_LAP_FIXED), whatever else the
    # optimiser's limit_lap section says.
    data["codesign"] = {"starts": 0}
    data["limit_lap"] = {"intervals": intervals, "starts": ["closed-loop"]}
    return CodesignProblemConfig.model_validate(data)


_PREPARED: dict[str, Any] = {}


def prepared(problem) -> Any:
    """:func:`casadrone.codesign.driver.prepare` of a co-design problem, once per process."""
    from casadrone.codesign.driver import prepare

    key = problem.model_dump_json()
    if key not in _PREPARED:
        _PREPARED[key] = prepare(problem)
    return _PREPARED[key]


def measures_of(names: list[str]) -> tuple[str, ...]:
    """The ε-constrained measures among objective ``names`` (every one but the lap)."""
    return tuple(n for n in names if n != LAP_INDEX)


def _dominated(a: dict[str, float], b: dict[str, float]) -> bool:
    """True when ``a`` Pareto-dominates ``b`` (minimised, the same keys)."""
    x, y = np.array([a[k] for k in b]), np.array(list(b.values()))
    return bool(np.all(x <= y) and np.any(x < y))


def improves(member: dict[str, float], values: dict[str, float]) -> bool:
    """The polished frame's objectives ``values`` are not Pareto-dominated by the member's
    (minimised, the same keys) and differ from them."""
    return bool(values) and values != member and not _dominated(member, values)


def polish_member(prep, theta: dict[str, float], member: dict[str, float],
                  check: bool = False) -> Polished:
    """Polish one member (``member``: its objectives by index name, the lap ``J3_limit`` among
    them) in the co-design problem ``prep`` (:func:`prepared`): the proposal θ_p and the
    co-design point's values (see the module docstring). ``check``: also re-solve θ_p's
    minimum-time limit lap with θ fixed from the polished point, and fly it with CVODES
    (:func:`casadrone.codesign.certificate.fixed_lap_check`), into ``fixed_lap_s`` and
    ``resimulation_miss_m``."""
    from casadrone.codesign.certificate import fixed_lap_check
    from casadrone.codesign.driver import constrained, initial_vector, solve_from
    from casadrone.codesign.front import measure_value

    c0 = time.process_time()
    names = measures_of(list(member))
    bad = [n for n in names if n not in FRONT_MEASURES]
    if bad:
        raise ValueError(f"the co-design NLP cannot hold {', '.join(bad)}")
    eps_prep = constrained(prep, names)
    theta = {k: float(v) for k, v in theta.items()}
    z0 = initial_vector(prep, theta)
    if z0 is None:
        return Polished(theta, dict(member), theta, {}, False, "no start",
                        "the member has no limit lap on the polish grid", 0,
                        time.process_time() - c0)
    ok, status, pt = solve_from(eps_prep, z0, {n: float(member[n]) for n in names})
    values = ({LAP_INDEX: pt.objective, **{n: measure_value(eps_prep, pt, n) for n in names}}
              if ok else {})
    fixed, miss = math.nan, math.nan
    if ok and check:
        lap = fixed_lap_check(eps_prep, pt)
        fixed, miss = lap.fixed_lap_s, lap.miss_m
    return Polished(theta, dict(member), dict(pt.theta), values, ok, status,
                    "" if ok else f"the co-design NLP did not converge ({status})",
                    pt.iterations, time.process_time() - c0, fixed, miss, pt)


def spread(F: np.ndarray, count: int) -> np.ndarray:
    """Indices of ``count`` rows of a front ``F`` (rows in any order) spread evenly along its
    first objective, both ends included (all rows when there are fewer)."""
    order = np.argsort(F[:, 0], kind="stable")
    if len(order) <= count:
        return order
    return order[np.unique(np.round(np.linspace(0, len(order) - 1, count)).astype(int))]
