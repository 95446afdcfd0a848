"""``casadrone codesign``: the fastest frame of a problem in one NLP (:mod:`casadrone.codesign`)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from casadrone.cli.common import (
    EXIT_FAILED,
    JsonOpt,
    QuietOpt,
    app,
    check_out_folder,
    cost_text,
    jsonable,
    print_json,
    progress_lines,
    reports_config_errors,
)
from casadrone.codesign.checks import load_codesign_problem

if TYPE_CHECKING:  # co-design is imported when the command runs (CasADi)
    from casadrone.codesign.driver import CodesignResult


@app.command("codesign")
@reports_config_errors
def codesign_command(
    problem: Annotated[str, typer.Argument(help="co-design problem YAML, or a shipped name "
                                           "(codesign-paper, codesign-season)")],
    overrides: Annotated[list[str] | None, typer.Argument(
        help="dotted key=value overrides, e.g. codesign.starts=2 limit_lap.intervals=20 "
        "limit_lap.starts=[point-mass]")] = None,
    out: Annotated[Path | None, typer.Option(help="folder for result.json (and a front's run "
                                             "directory); must be new or empty")] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Co-design: the frame with the fastest limit lap, found in one solve (on one track, or the
    weighted sum or the worst of a season's tracks).

    The frame's dimensions are solved for together with the lap, from the template's geometry
    and codesign.starts random feasible frames (all reported). The result and every point of a
    front are checked: the lap is flown again with the frame fixed and with the reference
    integrator, and each dimension is either inside its range with no gain left or at a bound
    that holds it; a sentence says what holds the frame (the co-design concept page explains
    the checks).

    Progress (each start with its objective, iterations and CPU, the certificate, each front
    point, any compile) goes to stderr as it happens; -q silences it.

    Exit codes: 0 for a co-design that converged; 2 for bad input, refused before any solve
    (one line naming the file and key: a closed-loop index (J1-J5, Jp), an objective with
    sense: max, a gate no frame of the box can pass, a limit_lap setting co-design cannot pose
    (it reads limit_lap.intervals and limit_lap.starts), an --out that cannot be a new folder);
    3 (EXIT_FAILED) when no start converged: the result, status "failed" with its reason, is
    still printed and written to --out.
    """
    check_out_folder(out)
    cfg = load_codesign_problem(problem, overrides or [])
    from casadrone.codesign.design import codesign

    with progress_lines("codesign", quiet):
        result = codesign(cfg, run_dir=out)
    data = result.as_dict()
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        (out / "result.json").write_text(json.dumps(jsonable(data), indent=2) + "\n")
    if as_json:
        print_json(data)
    else:
        typer.echo(text(result))
    if result.status != "completed":
        raise typer.Exit(EXIT_FAILED)


def objective_text(objective: float, combine: str, laps_s: dict[str, float]) -> str:
    """The headline figure: one track's lap as the lap (the objective is that lap), a season's
    objective beside its tracks' laps (``sum``: the weighted sum; ``worst``: the slowest)."""
    if len(laps_s) == 1:
        ((track, lap),) = laps_s.items()
        return f"lap {lap:.4f} s on {track}"
    laps = ", ".join(f"{k} {v:.4f} s" for k, v in laps_s.items())
    return f"objective {objective:.4f} s ({combine} of {len(laps_s)} tracks; {laps})"


def text(result: CodesignResult) -> str:
    """The result as lines: the frame, its laps, every start, the certificate."""
    head = f"{result.problem}: co-design {result.status.upper()}"
    if result.best is None:
        return f"{head}: {result.reason}"
    b = result.best
    theta = ", ".join(f"{k} {v:.2f}" for k, v in b.theta.items())
    lines = [f"{head}: {objective_text(b.objective, result.combine, b.laps_s)}",
             f"  frame: {theta}; mass {b.mass_kg:.4f} kg, span {b.span_m:.4f} m; "
             f"{result.intervals} intervals per leg",
             f"  {cost_text(result.cpu_s, result.wall_time_s, result.build_cpu_s)}", "  starts:"]
    for s in result.starts:
        th = ", ".join(f"{v:.2f}" for v in s.theta.values())
        lines.append(f"    {s.label:<10} {s.status:<28} {s.objective:>9.4f} s  θ = ({th})  "
                     f"{s.iterations} it, {s.cpu_s:.1f} s CPU")
    if len(result.distinct) > 1:
        lines.append(f"  {len(result.distinct)} distinct local optima (differing by > 0.1 %):")
        for p in result.distinct:
            th = ", ".join(f"{v:.2f}" for v in p.theta.values())
            lines.append(f"    {p.objective:.4f} s at ({th})")
    if result.certificate is not None:
        lines.append(result.certificate.text())
    if result.front is not None:
        f = result.front
        lines.append(f"  front: lap against {f.measure}, {len(f.points)} points, "
                     f"{f.cpu_s:.1f} s CPU" + (f" (stopped at {f.stopped})" if f.stopped else ""))
        for p in f.points:
            th = ", ".join(f"{v:.2f}" for v in p.point.theta.values())
            lines.append(f"    lap {p.point.objective:.4f} s  {f.measure} {p.measure:.5g}  "
                         f"θ = ({th})  {p.point.iterations} it")
            if p.certificate is not None:
                lines.append(f"      certificate {p.certificate.summary()}")
        certs = [p.certificate for p in f.points if p.certificate is not None]
        if certs:
            lines.append(f"  front certificates: {sum(c.passed for c in certs)} of "
                         f"{len(f.points)} points passed")
    return "\n".join(lines)
