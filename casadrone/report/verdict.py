"""The report's opening section: the candidates against the baseline airframe
(:mod:`casadrone.verdict`), and what the problem keeps fixed (mass model, impossible bodies)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from casadrone.compare import Candidate
from casadrone.config.airframe import INERTIA_KEYS
from casadrone.evaluate import Evaluation
from casadrone.optimise.problem import study_setup
from casadrone.report.analysis import Run
from casadrone.report.markup import Html, cell, empty_front, esc, note, num, table
from casadrone.verdict import (
    IndexComparison,
    RunVerdict,
    Verdict,
    headline,
    pct_text,
    run_verdict,
)

#: Text of a geometry failure that is an impossible body (casadrone.config.airframe's
#: inertia_problems): moments that break the triangle inequality, or no positive definite tensor.
IMPOSSIBLE_BODY = ("no rigid body has these moments", "not positive definite")
#: The parts-based variant of the quick problem (mass and inertia follow the geometry).
PARTS_PROBLEM = "problems/quick-parts.yaml"


def impossible_bodies(history: list[dict]) -> int:
    """Evaluations refused at the geometry stage as an impossible body (any of its reasons)."""
    return sum(h["status"] != "completed" and h["stage"] == "geometry"
               and any(m in (h["reason"] or "") for m in IMPOSSIBLE_BODY) for h in history)


def mass_model_note(run: Run) -> Html:
    """What the problem fixes and frees of the mass properties, with the share of impossible
    bodies among the run's evaluations, and where the parts-based variant is."""
    t = study_setup(run.study).template
    n = len(run.history)
    if t.mass_model != "free":
        return note(f"Mass properties: mass, centre of mass and inertia follow from the parts of "
                    f"{t.name} for each geometry (mass_model: {t.mass_model}), so a longer arm "
                    "is also a heavier frame.")
    free = [k for k in INERTIA_KEYS if k in run.study.variable_names]
    bad = impossible_bodies(run.history)
    share = f"{bad} of {n} evaluations ({100 * bad / n:.1f} %)" if n else "no evaluation yet"
    what = (f"the inertias {', '.join(free)} are decision variables of their own, free of the "
            "geometry (the paper's set-up, Table 1), so some combinations are bodies no mass "
            f"distribution can have: {share} of this run were such impossible bodies, refused "
            "before flying" if free else "the inertias are fixed too")
    return note(f"Mass properties: this problem keeps the mass fixed at {num(t.mass_kg)} kg "
                f"({t.name}'s, mass_model: free) whatever the arms, and {what}. For mass and "
                "inertia computed from the parts for each geometry (a longer arm weighs more and "
                f"turns slower), run the parts-based variant {PARTS_PROBLEM} (airframe "
                "SY250-components, mass_model: components; "
                f"casadrone run {PARTS_PROBLEM} --out runs/quick-parts).")


def _direction_text(c: IndexComparison) -> str:
    return {"better": f"better ({'higher' if c.sense == 'max' else 'lower'})",
            "worse": f"worse ({'lower' if c.sense == 'max' else 'higher'})",
            "equal": "equal"}[c.direction]


def _noise_text(c: IndexComparison) -> str:
    if c.within_noise is None:
        return "not measured"
    return "yes" if c.within_noise else "no"


def verdict_table(v: Verdict) -> Html:
    """Per index: both values, the difference (unit and %), its direction, the noise."""
    rows = [[c.index + ("" if c.objective else " (not an objective)"), c.sense, c.unit,
             cell(c.baseline), cell(c.candidate), cell(c.difference, "+.4g"),
             Html(f'<td class="num">{esc(pct_text(c.difference_pct))}</td>'), _direction_text(c),
             cell(c.noise, ".2g"), _noise_text(c)] for c in v.indices]
    head = ["index", "sense", "unit", v.baseline, v.candidate, f"{v.candidate} − {v.baseline}",
            "change (%)", f"{v.candidate} is", "noise (±)", "within noise"]
    return table(head, rows)


def spread_table(run: Run, rv: RunVerdict) -> Html:
    """Per objective: the front's range (unit and % of the baseline) against the largest noise
    measured on any design, and their ratio."""
    rows = []
    for k, n in enumerate(run.study.objective_names):
        col = run.F[:, k]
        span = float(col.max() - col.min())
        base = rv.baseline_values.get(n)
        noise = max((d.noise.get(n, float("nan")) for d in rv.noise if d.status == "completed"),
                    default=float("nan"))
        rows.append([n, run.unit(n), cell(col.min()), cell(col.max()), cell(span, ".3g"),
                     cell(100 * span / abs(base) if base else None, ".2g"), cell(noise, ".2g"),
                     cell(span / noise if noise > 0 else None, ".3g")])
    return table(["objective", "unit", "front min", "front max", "front range",
                  f"range (% of {rv.baseline})", "largest noise of a design", "range / noise"],
                 rows)


def _noise_details(rv: RunVerdict) -> Html:
    names = list(rv.noise[0].noise) if rv.noise and rv.noise[0].noise else []
    rows = [[d.design, d.moves] + [cell(d.integrator.get(n), ".1e") for n in names]
            + [cell(d.jitter.get(n), ".1e") for n in names] for d in rv.noise
            if d.status == "completed"]
    head = (["design", "jitter moves flown"] + [f"{n} integrator" for n in names]
            + [f"{n} jitter" for n in names])
    return Html("<details><summary>Noise of each design (index units)</summary>"
                f"{table(head, rows, 'wide')}</details>")


def section_verdict(run: Run, cands: list[Candidate], rv: RunVerdict | None) -> str:
    """The opening section: per candidate, whether it dominates the baseline, by how much per
    index and whether each difference is within the evaluation's noise."""
    if run.test_problem:
        return note("A pymoo test problem has no baseline airframe to compare with.")
    if not cands:
        return empty_front(run)
    if rv is None or not rv.verdicts:
        why = ("the baseline's lap failed" if rv and rv.noise and rv.noise[0].status !=
               "completed" else "the baseline has no value of every objective (a co-design "
               "run's limit-lap objectives are not solved for the baseline here)")
        return note(f"No verdict against the baseline: {why}.", "warn") + mass_model_note(run)
    parts: list[str] = [f"<p>Every candidate against <b>{esc(rv.baseline)}</b>, the baseline "
                        "airframe (drawn on every front figure):</p><ul>"]
    parts += [f"<li><b>{esc(headline(v))}</b>.</li>" for v in rv.verdicts]
    parts.append("</ul>")
    for v in rv.verdicts:
        parts.append(f"<h3>{esc(v.candidate)} against {esc(v.baseline)}</h3>{verdict_table(v)}")
    parts.append(note(f"{rv.how[0].upper()}{rv.how[1:]}. Change: 100 × (candidate − "
                      "baseline) / |baseline|; better or worse by each index's sense (max: "
                      "higher is better). Dominance is decided on the run's objectives only."))
    parts.append("<h3>The front's spread against the noise</h3>" + spread_table(run, rv))
    parts.append(_noise_details(rv))
    parts.append(mass_model_note(run))
    return "".join(parts)


def baseline_verdict(run: Run, cands: list[Candidate], reference: tuple[Any, Evaluation]
                     ) -> RunVerdict:
    """The verdict against the first reference airframe, with the indices the report flew for
    it (its limit lap included, where the problem has one)."""
    cfg, ev = reference
    return run_verdict(run.study, cands, cfg, ev.indices if ev.completed else None)


@dataclass(frozen=True)
class Baseline:
    """The baseline as the front figures draw it: its name, its value of each objective and of
    each decision variable (None where its config has not every variable)."""

    name: str
    objectives: list[float]
    theta: list[float] | None


def baseline_of(run: Run, rv: RunVerdict | None) -> Baseline | None:
    """The baseline for the front figures; None without a value of every objective."""
    names = run.study.objective_names
    if rv is None or any(n not in rv.baseline_values for n in names):
        return None
    variables = run.study.variable_names
    theta = ([rv.baseline_theta[n] for n in variables]
             if all(n in rv.baseline_theta for n in variables) else None)
    return Baseline(rv.baseline, [rv.baseline_values[n] for n in names], theta)
