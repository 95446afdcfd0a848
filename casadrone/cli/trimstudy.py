"""``casadrone trim-study``: the trim solvers from many starts across the flight envelope."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

import typer

from casadrone.airframe import Airframe
from casadrone.cli.common import (
    AirframeArg,
    JsonOpt,
    OverridesArg,
    PlotOpt,
    QuietOpt,
    app,
    bad_input,
    check_plot_dir,
    load_airframe_or_exit,
    print_json,
    progress_lines,
    reports_config_errors,
    save_figures,
)
from casadrone.conditions import OperatingPoint, envelope
from casadrone.trimstudy import (
    MAX_SOLVES,
    StudyOptions,
    TrimStudy,
    analytic_guess,
    basin_slice,
    draw_starts,
    residual_history,
    solve_count,
)
from casadrone.trimstudy import trim_study as run_study

#: The option of each field of :class:`casadrone.trimstudy.StudyOptions`.
OPTION_OF = {"starts": "--starts", "seed": "--seed", "angle_spread_deg": "--angle-spread",
             "command_spread": "--command-spread", "solvers": "--solvers",
             "reference_solver": "--reference", "distinct_tolerance": "--distinct-tolerance"}

#: The figures ``trim-study --plot`` writes, checked before any work (:func:`check_plot_dir`).
TRIM_STUDY_FIGURES = ("trim-study-envelope", "trim-study-basins", "trim-study-residuals")


@app.command("trim-study")
@reports_config_errors
def trim_study(
    airframe: AirframeArg,
    overrides: OverridesArg = None,
    conditions: Annotated[str, typer.Option(
        help="operating points, comma-separated: a condition's name (hover, forward, climb, "
        "turn) for its default points, or forward:20, forward:0..40/5, climb:10:-30 (m/s, deg), "
        "turn:10:60 (m/s, deg/s)")] = "hover,forward,climb,turn",
    starts: Annotated[int, typer.Option(
        help="random starts per point and solver, besides the analytic guess")] = 20,
    seed: Annotated[int, typer.Option(help="seed of the starts")] = 0,
    angle_spread: Annotated[float, typer.Option(
        help="starts: roll and pitch uniform within ± this of the guess (deg)")] = 60.0,
    command_spread: Annotated[float, typer.Option(
        help="starts: each command uniform within ± this fraction of the guess")] = 0.8,
    solvers: Annotated[str, typer.Option(
        help="solvers compared, comma-separated")] = "ipopt,nelder-mead,newton",
    reference: Annotated[str, typer.Option(
        help="solver whose trim from the analytic guess is the reference")] = "newton",
    distinct_tolerance: Annotated[float, typer.Option(
        help="roots closer than this (max-norm of the unknowns, rad and commands) are one")
    ] = 1e-4,
    basin_grid: Annotated[int, typer.Option(
        help="--plot: starts per axis of the basin-of-attraction slice")] = 21,
    plot_point: Annotated[str | None, typer.Option(
        help="--plot: the operating point of the basin and residual figures (as in "
        "--conditions; default the study's fastest level point)")] = None,
    as_json: JsonOpt = False,
    plot: PlotOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """Compare the trim solvers from many starts at operating points across the envelope:
    success rate, iterations, wall time, residual, distance from the reference, distinct roots.

    Progress (each operating point as it is studied, each basin slice of --plot) goes to
    stderr; -q silences it."""
    check_plot_dir(plot, TRIM_STUDY_FIGURES)
    points, options, focus = _parse(conditions, starts, seed, angle_spread, command_spread,
                                    solvers, reference, distinct_tolerance, basin_grid, plot_point)
    check_size(len(points), options, basin_grid if plot else 0)
    _, frame = load_airframe_or_exit(airframe, overrides)

    with progress_lines("trim-study", quiet):
        study = run_study(frame, points, options)
        written = _figures(frame, study, focus or _fastest_level(study), basin_grid, plot) \
            if plot else []
    if as_json:
        print_json(study.as_dict() | ({"figures": written} if plot else {}))
        return
    typer.echo(study_text(study))
    for path in written:
        typer.echo(f"wrote {path}")


def _parse(conditions: str, starts: int, seed: int, angle_spread: float,
           command_spread: float, solvers: str, reference: str,
           distinct_tolerance: float, basin_grid: int, plot_point: str | None) -> tuple[Any, ...]:
    """(points, StudyOptions, plot point or None); exit 2 naming the option on a bad value."""
    try:
        points = envelope(conditions)
    except ValueError as exc:
        raise bad_input([f"--conditions: {exc}"]) from None
    focus = None
    if plot_point is not None:
        try:
            (focus,) = envelope(plot_point)
        except ValueError as exc:
            raise bad_input([f"--plot-point: {exc} (one point expected)"]) from None
    if not 2 <= basin_grid <= 201:
        raise bad_input([f"--basin-grid: {basin_grid} is out of range (2 to 201)"])
    names = tuple(s.strip() for s in solvers.split(","))
    try:
        options = StudyOptions(starts=starts, seed=seed, angle_spread_deg=angle_spread,
                               command_spread=command_spread, solvers=names,
                               reference_solver=reference, distinct_tolerance=distinct_tolerance)
    except ValueError as exc:
        field, _, message = str(exc).partition(": ")
        raise bad_input([f"{OPTION_OF.get(field, field)}: {message}"]) from None
    return points, options, focus


def check_size(points: int, options: StudyOptions, basin_grid: int) -> None:
    """Exit 2 naming the options when the study asks for more than
    :data:`casadrone.trimstudy.MAX_SOLVES` trim solves."""
    n = solve_count(points, options, basin_grid)
    if n > MAX_SOLVES:
        basin = f" + {basin_grid}² --basin-grid starts" if basin_grid else ""
        raise bad_input([
            f"--conditions, --starts, --solvers: ({points} point(s) x {options.starts + 1} "
            f"start(s){basin}) x {len(options.solvers)} solver(s) = {n} trim solves, more "
            f"than the {MAX_SOLVES} a study may ask for (the default study is 819 solves, 16 s "
            "of CPU): fewer points, starts or solvers"])


def _fastest_level(study: TrimStudy) -> OperatingPoint:
    level = [p.point for p in study.points if p.point.condition in ("hover", "forward")]
    return max(level or [p.point for p in study.points], key=lambda p: p.speed_mps)


def _figures(frame: Airframe, study: TrimStudy, point: OperatingPoint, grid: int,
             folder: Path) -> list[str]:
    """The envelope, basin and residual-history figures of a study, saved in ``folder``."""
    from casadrone.trimplots import basin_figure, envelope_figure, residual_figure

    o = study.options
    guess = analytic_guess(frame, point)
    starts = {"the analytic guess": guess}
    if o.starts:
        starts["random start 1"] = draw_starts(guess, point, o)[1]
    histories = [residual_history(frame, point, s, z0, o.trim, name)
                 for name, z0 in starts.items() for s in o.solvers]
    tol = {s: o.trim.nelder_mead_tolerance if s == "nelder-mead" else o.trim.tolerance
           for s in o.solvers}
    figures = {
        "trim-study-envelope": envelope_figure(study),
        "trim-study-basins": basin_figure(basin_slice(frame, point, o, grid)),
        "trim-study-residuals": residual_figure(
            histories, tol, f"{study.airframe}, {point.label}: residual histories"),
    }
    return save_figures(figures, folder)


def study_text(study: TrimStudy) -> str:
    """A table per operating point: each solver's outcomes and costs."""
    o = study.options
    lines = [f"{study.airframe}: trim solvers from {o.starts} random starts and the analytic "
             f"guess per point (seed {o.seed}; roll, pitch ±{o.angle_spread_deg:g} deg, "
             f"commands ±{100 * o.command_spread:g} %); {study.wall_time_s:.1f} s",
             "outcomes: conv = at the reference, other = another trim, outside = a root beyond "
             "the domain (tilt), fail = no root, div = non-finite"]
    head = (f"  {'solver':<12}{'success':>8}{'conv':>6}{'other':>6}{'outside':>8}{'fail':>6}"
            f"{'div':>5}  {'iterations med [q25-q75]':>25}{'time ms med [q25-q75]':>24}"
            f"{'residual med':>13}{'max dist':>10}{'roots':>6}")
    for p in study.points:
        ref = f"reference by {p.reference_solver}" if p.reference is not None else "no reference"
        lines += ["", f"{p.point.label} ({ref}; {len(p.solutions)} distinct root(s), "
                  f"{sum(s.in_domain for s in p.solutions)} in the domain)", head]
        for s in p.summaries:
            c = s.outcomes
            its = f"{s.iterations_median:.0f} [{s.iterations_q25:.0f}-{s.iterations_q75:.0f}]"
            ms = (f"{1e3 * s.wall_time_median_s:.2f} [{1e3 * s.wall_time_q25_s:.2f}-"
                  f"{1e3 * s.wall_time_q75_s:.2f}]")
            lines.append(
                f"  {s.solver:<12}{100 * s.success_rate:>7.0f}%{c['converged']:>6}"
                f"{c['other-trim']:>6}{c['out-of-domain']:>8}{c['failed']:>6}{c['diverged']:>5}  "
                f"{its:>25}{ms:>24}{s.residual_median:>13.1e}{s.distance_max:>10.1e}"
                f"{s.solutions:>6}")
    return "\n".join(lines)
