"""The verdict of a run's candidates against a baseline airframe: does each candidate dominate it,
by how much per index, and is each difference larger than the evaluation's noise.

:func:`compare_to_baseline` is pure: a candidate's indices against the baseline's, each with its
sense and noise. Dominance is Pareto dominance on the run's objectives (no objective worse, one
better); "dominates beyond noise" counts a difference within the noise as a tie.

The noise of one design's index (:func:`design_noise`) is the larger of two changes that should
not matter:

* **integrator**: |J − J'| where J' is the same lap with the integrator refined, the RK4 step
  halved (``substeps`` doubled) or, for CVODES/IDAS, both tolerances 100 times tighter; the
  project's own yardstick for integrator error (``benchmarks/sensitivity.py``: rk4 against CVODES
  at 1e-10, the same size, ~1e-7 relative);
* **jitter**: the largest |J(θ + δ) − J(θ)| over a few moves δ of every decision variable by
  ±0.1 % of its bound range (0.05 mm on a 50 mm arm range, 0.025° on 25°, random signs, seeded),
  far below a frame's manufacturing tolerance. It bounds the lap's roughness (a waypoint switch
  moving by a controller sample, a limit reached a sample earlier) and includes the smooth change
  over that step, so it is an upper bound of the noise.

A difference between a candidate and the baseline is within noise when it is at most the sum of
the two designs' noises. Indices not flown by the closed-loop lap (``J3_limit``) carry no noise
here (NaN: not measured).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.results import AsDict

if TYPE_CHECKING:
    from casadrone.evaluate import EvaluationSetup

__all__ = ["DesignNoise", "IndexComparison", "Verdict", "compare_to_baseline", "design_noise",
           "format_verdicts", "refined"]

Direction = Literal["better", "worse", "equal"]

#: Size of a jitter move: this fraction of each variable's bound range.
JITTER_STEP = 1e-3
#: Number of jitter moves per design.
JITTER_MOVES = 4


@dataclass(frozen=True)
class IndexComparison(AsDict):
    """One index of a candidate against the baseline.

    Attributes:
        index: the index name; unit: its unit; sense: ``"min"`` or ``"max"`` (the run's sense
            for an objective, the index's own otherwise); objective: whether the run optimised it.
        candidate, baseline: the two values (unit).
        difference: candidate − baseline (unit).
        difference_pct: 100 × (candidate − baseline) / |baseline| (%; NaN for a zero baseline).
        direction: ``"better"``, ``"worse"`` or ``"equal"`` for the candidate, by the sense.
        noise: the two designs' noises summed (unit; NaN where not measured).
        within_noise: |difference| ≤ noise; None where the noise is not measured.
    """

    index: str
    unit: str
    sense: Literal["min", "max"]
    objective: bool
    candidate: float
    baseline: float
    difference: float
    difference_pct: float
    direction: Direction
    noise: float
    within_noise: bool | None


@dataclass(frozen=True)
class Verdict(AsDict):
    """A candidate against the baseline.

    Attributes:
        candidate: the candidate's label (``"A"``); baseline: the baseline airframe's name.
        indices: every index compared, the objectives first.
        dominates: Pareto dominance on the objectives (none worse, at least one better).
        dominates_beyond_noise: the same with every difference within the noise counted as a
            tie; None when an objective's noise is not measured.
    """

    candidate: str
    baseline: str
    indices: tuple[IndexComparison, ...]
    dominates: bool
    dominates_beyond_noise: bool | None

    @property
    def objectives(self) -> tuple[IndexComparison, ...]:
        return tuple(c for c in self.indices if c.objective)


def _direction(difference: float, sense: str) -> Direction:
    if difference == 0.0:
        return "equal"
    return "better" if (difference < 0.0) == (sense == "min") else "worse"


def compare_index(index: str, unit: str, sense: Literal["min", "max"], objective: bool,
                  candidate: float, baseline: float, noise: float = math.nan
                  ) -> IndexComparison:
    """One index of a candidate against the baseline (see :class:`IndexComparison`)."""
    d = float(candidate) - float(baseline)
    pct = 100.0 * d / abs(baseline) if baseline != 0.0 else math.nan
    within = None if not math.isfinite(noise) else bool(abs(d) <= noise)
    return IndexComparison(index, unit, sense, objective, float(candidate), float(baseline), d,
                           pct, _direction(d, sense), float(noise), within)


def compare_to_baseline(candidate: str, baseline: str, values: Mapping[str, float],
                        baseline_values: Mapping[str, float], senses: Mapping[str, str],
                        objectives: Sequence[str], units: Mapping[str, str] | None = None,
                        noise: Mapping[str, float] | None = None) -> Verdict:
    """A candidate's indices against the baseline's.

    Args:
        candidate, baseline: names for the result.
        values, baseline_values: index name → value, in the index's unit.
        senses: index name → ``"min"``/``"max"`` for every index compared (the indices compared
            are those in ``senses`` with a value on both sides, the objectives first).
        objectives: the run's objectives (dominance is decided on these).
        units: index name → unit (default ``"–"``).
        noise: index name → the noise of the difference (the two designs' noises summed, same
            unit); missing or NaN: not measured.

    Raises:
        ValueError: an objective without a value on either side.
    """
    missing = [n for n in objectives if n not in values or n not in baseline_values]
    if missing:
        raise ValueError(f"no value of {', '.join(missing)} for {candidate} or {baseline}")
    order = list(objectives) + [n for n in senses if n not in objectives]
    rows = tuple(compare_index(n, (units or {}).get(n, "–"),
                               "max" if senses[n] == "max" else "min", n in objectives,
                               values[n], baseline_values[n], (noise or {}).get(n, math.nan))
                 for n in order if n in values and n in baseline_values)
    obj = [r for r in rows if r.objective]
    dominates = (all(r.direction != "worse" for r in obj)
                 and any(r.direction == "better" for r in obj))
    if any(r.within_noise is None for r in obj):
        beyond = None
    else:
        clear = [r.direction for r in obj if not r.within_noise]
        beyond = "worse" not in clear and "better" in clear
    return Verdict(candidate, baseline, rows, dominates, beyond)


# ---------------------------------------------------------------------------------------------
# The noise of an evaluation
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class DesignNoise(AsDict):
    """The indices of one design and their noise (see the module docstring).

    Attributes:
        design: the design's name; values: its indices as flown (closed-loop lap).
        integrator: index → |J − J(refined integrator)|.
        jitter: index → largest |J(θ + δ) − J(θ)| over the jitter moves that flew the lap.
        moves: jitter moves flown (of :data:`JITTER_MOVES`; a move that fails is left out).
        status: ``"completed"``, or the stage at which the design's own lap failed (no noise).
    """

    design: str
    values: dict[str, float]
    integrator: dict[str, float] = field(default_factory=dict)
    jitter: dict[str, float] = field(default_factory=dict)
    moves: int = 0
    status: str = "completed"

    _properties = ("noise",)

    @property
    def noise(self) -> dict[str, float]:
        """Index → the larger of the integrator change and the jitter."""
        return {n: max(self.integrator.get(n, 0.0), self.jitter.get(n, 0.0))
                for n in self.integrator}


def refined(setup: EvaluationSetup) -> EvaluationSetup:
    """The same evaluation with its integrator refined: RK4 with half the step, a SUNDIALS
    integrator with both tolerances 100 times tighter; no limit lap."""
    o = setup.sim_options
    opts = (replace(o, substeps=2 * o.substeps) if setup.integrator == "rk4"
            else replace(o, rtol=o.rtol / 100, atol=o.atol / 100))
    return replace(setup, sim_options=opts, limit=None)


def jitter_moves(theta: Mapping[str, float], bounds: Mapping[str, tuple[float, float]],
                 moves: int = JITTER_MOVES, step: float = JITTER_STEP, seed: int = 0
                 ) -> list[dict[str, float]]:
    """``moves`` copies of θ with every variable in ``bounds`` moved by ±``step`` of its range
    (random signs, seeded); a move that would leave the bounds goes the other way."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(moves):
        moved = dict(theta)
        for name, (lo, hi) in bounds.items():
            d = float(rng.choice((-1.0, 1.0))) * step * (hi - lo)
            v = theta[name] + d
            moved[name] = v if lo <= v <= hi else theta[name] - d
        out.append(moved)
    return out


def design_noise(name: str, theta: Mapping[str, float], setup: EvaluationSetup,
                 bounds: Mapping[str, tuple[float, float]], moves: int = JITTER_MOVES,
                 seed: int = 0) -> DesignNoise:
    """Fly one design (closed-loop lap, no limit lap) and measure its noise: the integrator
    refined once, and ``moves`` jitter moves of the variables in ``bounds``."""
    from casadrone.evaluate import evaluate

    setup = replace(setup, limit=None)
    tag = getattr(theta, "airframe", None)  # a reference's θ flies on its own template

    def fly(th: Mapping[str, float], s: EvaluationSetup = setup):
        from casadrone.evaluate import Theta

        return evaluate(Theta(th, tag) if tag is not None else dict(th), s)

    ev = fly(theta)
    if not ev.completed:
        return DesignNoise(name, {}, status=ev.stage or ev.status)
    values = dict(ev.indices)
    fine = fly(theta, refined(setup))
    integ = {n: abs(fine.indices[n] - v) if fine.completed and n in fine.indices else math.inf
             for n, v in values.items()}
    laps = [e for e in (fly(m) for m in jitter_moves(theta, bounds, moves, seed=seed))
            if e.completed]
    jit = {n: max((abs(e.indices[n] - v) for e in laps if n in e.indices), default=0.0)
           for n, v in values.items()}
    return DesignNoise(name, values, integ, jit, len(laps))


# ---------------------------------------------------------------------------------------------
# Text
# ---------------------------------------------------------------------------------------------


def headline(v: Verdict) -> str:
    """One sentence: whether the candidate dominates the baseline, and where it is worse."""
    worse = [c.index for c in v.objectives if c.direction == "worse"]
    text = f"{v.candidate} dominates {v.baseline}: {'yes' if v.dominates else 'no'}"
    if worse:
        text += f" (worse on {', '.join(worse)})"
    if v.dominates_beyond_noise is None:
        return text + "; the noise of an objective is not measured"
    noisy = [c.index for c in v.objectives if c.within_noise]
    text += (f"; counting differences within the noise as ties: "
             f"{'yes' if v.dominates_beyond_noise else 'no'}")
    return text + (f" ({', '.join(noisy)} within noise)" if noisy else "")


def pct_text(pct: float) -> str:
    """A signed percentage: two significant digits below 1 %, one decimal above; ``—`` for NaN."""
    if not math.isfinite(pct):
        return "—"
    return f"{pct:+.1f} %" if abs(pct) >= 1.0 else f"{pct:+.2g} %"


def change_text(c: IndexComparison) -> str:
    """``"J3 +0.1 % worse"``, with ``"(within noise)"`` where it is."""
    pct = pct_text(c.difference_pct)
    tail = " (within noise)" if c.within_noise else ""
    return f"{c.index} {pct} {c.direction}{tail}"


def format_verdicts(verdicts: Sequence[Verdict], how: str) -> str:
    """The block ``casadrone decide`` prints: per candidate the headline and each objective's
    change, then how the baseline was flown and the noise measured (``how``)."""
    if not verdicts:
        return ""
    lines = [f"Verdict against {verdicts[0].baseline}:"]
    for v in verdicts:
        lines.append(f"  {headline(v)}")
        lines.append("    " + "; ".join(change_text(c) for c in v.objectives))
    lines.append(f"  ({how})")
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------
# A run's candidates against a baseline
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunVerdict(AsDict):
    """A run's candidates against one baseline airframe.

    Attributes:
        baseline: the baseline airframe's name.
        verdicts: one per candidate whose lap completed.
        noise: the baseline's noise, then each candidate's (:class:`DesignNoise`).
        how: how the baseline was flown and the noise measured, in words.
        baseline_values: the baseline's indices (closed-loop lap, and what the caller gave).
        baseline_theta: the baseline's decision variables (its config's values).
    """

    baseline: str
    verdicts: tuple[Verdict, ...]
    noise: tuple[DesignNoise, ...]
    how: str
    baseline_values: dict[str, float] = field(default_factory=dict)
    baseline_theta: dict[str, float] = field(default_factory=dict)


def noise_method(integrator: str, moves: int = JITTER_MOVES) -> str:
    """How the noise is measured, in words."""
    fine = ("the RK4 step halved" if integrator == "rk4"
            else f"{integrator}'s tolerances 100 times tighter")
    return (f"noise of each value: the larger of its change with {fine} and its largest change "
            f"over {moves} moves of every decision variable by ±{100 * JITTER_STEP:g} % of its "
            "bound range (far below manufacturing tolerance); a difference is within noise when "
            "it is at most the two designs' noises summed")


def default_baseline(problem) -> str | Path:
    """The baseline of a problem's verdict: its airframe template as the config file gives it
    (the frame the study starts from, with the same mass model), SY250 without one."""
    return problem.airframe if problem.airframe is not None else "SY250"


def run_verdict(study, candidates: Sequence, reference: str | Path | AirframeConfig = "SY250",
                baseline_values: Mapping[str, float] | None = None) -> RunVerdict:
    """Fly the baseline ``reference`` (its own airframe config) and the candidates on the run's
    platform, measure each one's noise and compare (:func:`compare_to_baseline`).

    Args:
        study: the run's :class:`casadrone.optimise.problem.Study`.
        candidates: :class:`casadrone.compare.Candidate` objects; their stored objectives take
            precedence over the re-flown values (they are the front's).
        reference: the baseline airframe (name, YAML or a loaded config).
        baseline_values: indices of the baseline already flown (a limit lap the caller solved);
            they complete the closed-loop values flown here.
    """
    from casadrone.evaluate import theta_of
    from casadrone.indices import INDICES
    from casadrone.optimise.problem import study_setup

    setup = study_setup(study)
    cfg = load_airframe(reference) if isinstance(reference, str | Path) else reference
    lo, hi = study.bounds
    bounds = {n: (float(a), float(b)) for n, a, b in zip(study.variable_names, lo, hi,
                                                          strict=True)}
    base_theta = theta_of(cfg)
    base = design_noise(cfg.name, base_theta, replace(setup, template=cfg),
                        {n: b for n, b in bounds.items() if n in base_theta})
    noises = [base]
    objectives = list(study.objective_names)
    senses = {n: INDICES[n].sense for n in INDICES} | dict(zip(objectives, study.senses,
                                                               strict=True))
    units = {n: INDICES[n].unit for n in INDICES}
    base_values = base.values | dict(baseline_values or {})
    verdicts = []
    for c in candidates:
        dn = design_noise(c.label, c.theta, setup, bounds)
        noises.append(dn)
        if dn.status != "completed" or base.status != "completed":
            continue
        values = dn.values | dict(c.objectives)
        if any(n not in base_values for n in objectives):
            continue
        noise = {n: dn.noise.get(n, math.nan) + base.noise.get(n, math.nan) for n in senses}
        verdicts.append(compare_to_baseline(c.label, cfg.name, values, base_values, senses,
                                            objectives, units, noise))
    how = (f"{cfg.name} flown now with its own airframe config on the run's track, controller "
           f"and integrator; {noise_method(setup.integrator)}")
    return RunVerdict(cfg.name, tuple(verdicts), tuple(noises), how, base_values,
                      dict(base_theta))
