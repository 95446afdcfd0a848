"""The report's trim-solver study: the first candidate (else the template) trimmed by every solver
from seeded starts across the envelope, with the study's figures (:mod:`casadrone.trimstudy`).

The chain trims every candidate in hover from the analytic guess, which is already the answer;
this part shows how far from that guess each solver still finds the trim, and where in the
envelope the candidate's trims become hard."""

from __future__ import annotations

from casadrone.airframe import build_airframe, with_theta
from casadrone.optimise.problem import study_setup
from casadrone.report.analysis import Candidate, Run
from casadrone.report.markup import Figures, Html, cell, note, table
from casadrone.trimplots import basin_figure, envelope_figure, residual_figure
from casadrone.trimstudy import (
    StudyOptions,
    analytic_guess,
    basin_slice,
    draw_starts,
    residual_history,
    trim_study,
)

#: Operating points of the report's study: hover, level flight to 40 m/s, climb, descent, turns.
POINTS = "hover,forward:10,forward:20,forward:40,climb,turn"


def trim_study_part(run: Run, cands: list[Candidate], figs: Figures, starts: int) -> str:
    """HTML of the study (empty with ``starts`` < 0)."""
    if starts < 0:
        return ""

    setup = study_setup(run.study)
    theta, who = (cands[0].theta, f"candidate {cands[0].label}") if cands else (
        {}, f"the template {setup.template.name}")
    frame = build_airframe(with_theta(setup.template, theta))
    o = StudyOptions(starts=starts, seed=0)
    study = trim_study(frame, POINTS, o)
    fast = study.points[[p.point.label for p in study.points].index("forward 40 m/s")]
    guess = analytic_guess(frame, fast.point)
    histories = [residual_history(frame, fast.point, s, z0, o.trim, name)
                 for name, z0 in (("the analytic guess", guess),
                                  ("random start 1", draw_starts(guess, fast.point, o)[1]))
                 for s in o.solvers]
    tol = {s: o.trim.nelder_mead_tolerance if s == "nelder-mead" else o.trim.tolerance
           for s in o.solvers}
    rows = [[p.point.label, s.solver, cell(100 * s.success_rate, ".0f"),
             *(s.outcomes[k] for k in ("converged", "other-trim", "out-of-domain", "failed",
                                       "diverged")),
             cell(s.iterations_median, ".0f"), cell(1e3 * s.wall_time_median_s, ".2f"),
             cell(s.residual_median, ".1e")]
            for p in study.points for s in p.summaries]
    text = (f"Every solver trims {who} from the same {starts + 1} starts per operating point: "
            f"the analytic guess and {starts} draws (seed {o.seed}) with roll and pitch within "
            f"±{o.angle_spread_deg:g}° and commands within ±{100 * o.command_spread:g} % of it. "
            "Outcomes: converged (to the reference trim), other trim, out-of-domain (a root of "
            "the equations beyond the tilt limit: inverted on negative thrust, or tail first), "
            "failed (no root within the iteration cap), diverged (non-finite). The chain uses "
            f"'{setup.trim_solver}' from the analytic guess. Recompute with more starts: "
            f"casadrone trim-study with the candidate's θ as overrides.")
    parts: list[str] = [
        "<h4>Trim solvers across the envelope</h4>", note(text),
        table(["point", "solver", "success (%)", "converged", "other trim", "out-of-domain",
               "failed", "diverged", "iterations (median)", "time (ms, median)",
               "residual (median, SI)"], rows, "wide"),
        figs.embed(envelope_figure(study), "trim-study-envelope",
                   "Success rate and iterations (median, quartiles) against speed per solver."),
        figs.embed(basin_figure(basin_slice(frame, fast.point, o, grid=9)), "trim-study-basins",
                   "Basins of attraction at 40 m/s: outcome from each start of a roll–pitch "
                   "slice through the analytic guess."),
        figs.embed(residual_figure(histories, tol), "trim-study-residuals",
                   "Residual histories at 40 m/s, from the analytic guess and a random start."),
    ]
    return Html("".join(parts))
