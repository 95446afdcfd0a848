"""``casadrone build``: propeller, motor and pack chosen with the frame geometry for a race
(:mod:`casadrone.build`)."""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from casadrone.airframe import build_airframe
from casadrone.build import resume
from casadrone.build.checks import load_build_problem
from casadrone.build.search import Build, build
from casadrone.cli.common import (
    EXIT_FAILED,
    JsonOpt,
    QuietOpt,
    app,
    bad_input,
    check_out_folder,
    cost_text,
    jsonable,
    print_json,
    progress_lines,
    reports_config_errors,
)
from casadrone.export import FORMATS
from casadrone.export.source import ExportSource
from casadrone.progress import emit

if TYPE_CHECKING:
    from casadrone.build.solve import BuildResult

#: The ranking CSV's columns (BuildResult fields and properties), in order.
RANKING_COLUMNS = ("rank", "label", "race_s", "lap_s", "laps", "bound_s", "mass_kg",
                   "thrust_to_weight", "hover_throttle", "hover_pack_current_a",
                   "peak_pack_current_a", "peak_motor_current_a", "pack_current_margin_a",
                   "motor_current_margin_a", "energy_used_wh", "energy_left_wh", "end_soc",
                   "certified")


@app.command("build")
@reports_config_errors
def build_command(
    problem: Annotated[str, typer.Argument(help="build problem YAML, or a shipped name "
                                           "(build-small)")],
    overrides: Annotated[list[str] | None, typer.Argument(
        help="dotted key=value overrides, e.g. build.rank=5 limit_lap.intervals=20")] = None,
    laps: Annotated[int | None, typer.Option(min=1, max=20, help="laps of the race (default: "
                                             "build.laps, else the track's)")] = None,
    out: Annotated[Path | None, typer.Option(help="folder for result.json, ranking.csv and the "
                                             "winner's bill of materials; new, empty, or a "
                                             "stopped build of the same problem to resume")
                   ] = None,
    as_json: JsonOpt = False,
    quiet: QuietOpt = False,
) -> None:
    """Build: the propeller, motor and pack of the catalogue, with the frame geometry, that fly
    the race fastest.

    Every combination of the parts the problem names is screened without a solve (refused with
    its reason: propellers that overlap at every frame of the box, tips past max_tip_mach,
    thrust-to-weight below 1, a hover current over the pack's C x capacity or the motor's
    largest), bounded by its point-mass race at the box's least mass, and raced best-first on
    the problem's backend (processes, or Dask with an address), pruned where its bound is above
    the rank-th best race found so far. A combination is raced at the frame of the geometry box
    that dominates the others (lightest, least inertia, most angular authority) where the box
    has one, else co-designed; the ranked ones are co-designed. Each frame flies the race with
    its pack's state of charge; a race the pack cannot fly is infeasible, with the reason.

    Exit codes: 0 when some build flies the race; 2 for bad input, refused before any solve (one
    line naming the file and key: an unknown part, a template not of the propeller kind, an
    --out that holds anything but a build of this problem and race); 3 (EXIT_FAILED) when no
    combination flies it (the result is still printed and written to --out).

    Every result is kept in --out as it is known: run the same command again after a stop and
    the build resumes, solving only the combinations it does not hold.
    """
    cfg = load_build_problem(problem, overrides or [])
    why = None if out is None else resume.folder_problem(out, cfg, laps)
    if why:
        raise bad_input([f"--out: {out}: {why}"])
    if out is not None and not out.exists():
        check_out_folder(out)  # a folder that cannot be made
    held = resume.held(out)
    if out is not None:
        resume.begin(out, cfg, laps)
    record = recorder(out)
    with progress_lines("build", quiet):
        if held:
            emit("stage", f"resuming: {len(held)} combinations held in {out}")
        result = build(cfg, laps, record, held)
    data = result.as_dict()
    if out is not None:
        write_outputs(out, result)
    if as_json:
        print_json(data)
    else:
        typer.echo(text(result))
    if not result.ranking:
        raise typer.Exit(EXIT_FAILED)


def recorder(folder: Path | None) -> Callable[[BuildResult], None]:
    """Each combination's result appended to ``folder/combinations.jsonl`` and kept whole in
    ``folder/state/`` as it is known (a result is on disk whatever happens to the later ones,
    and a stopped build resumes from it: :mod:`casadrone.build.resume`); nothing without a
    folder."""
    def record(r: BuildResult) -> None:
        if folder is None:
            return
        resume.keep(folder, r)
        with (folder / "combinations.jsonl").open("a") as f:
            f.write(json.dumps(jsonable(r.as_dict())) + "\n")
    return record


def write_outputs(folder: Path, result: Build) -> None:
    """result.json, ranking.csv and, with a winner, its airframe (winner.yaml, which every
    ``casadrone export`` format reads) and bill of materials (bom.md, bom-csv.csv)."""
    import yaml

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "result.json").write_text(json.dumps(jsonable(result.as_dict()), indent=2) + "\n")
    (folder / "ranking.csv").write_text(ranking_csv(result.ranking))
    cfg = result.winner_airframe
    if cfg is None:
        return
    data = json.loads(cfg.model_dump_json(exclude_none=True))
    (folder / "winner.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    src = ExportSource(cfg, build_airframe(cfg), f"build {result.problem} ({folder})",
                       result.ranking[0].label)
    for fmt in ("bom", "bom-csv"):
        (folder / f"{fmt}{FORMATS[fmt].suffix}").write_text(FORMATS[fmt].write(src, None))


def ranking_csv(ranked: tuple[BuildResult, ...]) -> str:
    """The ranking as CSV (:data:`RANKING_COLUMNS`)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(RANKING_COLUMNS)
    for i, r in enumerate(ranked, start=1):
        d = r.as_dict() | {"rank": i}
        w.writerow([_cell(d[c]) for c in RANKING_COLUMNS])
    return buf.getvalue()


def _cell(v: object) -> str:
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.6g}"
    return "" if v is None else str(v)


#: How a build's frame geometry was found (BuildResult.geometry_by), in words.
GEOMETRY_BY = {"co-design": "co-designed", "dominance": "the box's dominant frame",
               "descent": "the box's dominant frame moved by its race's gradient"}


def text(result: Build) -> str:
    """The build as lines: the ranking with its figures, then every other combination."""
    counts = ", ".join(f"{n} {k}" for k, n in sorted(result.counts.items()))
    held = f", {result.resumed} read back from --out" if result.resumed else ""
    lines = [f"{result.problem}: build of a {result.laps}-lap race, {len(result.results)} "
             f"combinations ({counts}{held}); {result.backend} x{result.workers}",
             f"  {cost_text(result.cpu_s, result.wall_time_s)}"]
    if not result.ranking:
        lines.append("  no combination flies the race")
    for i, r in enumerate(result.ranking, start=1):
        th = ", ".join(f"{k} {v:.1f}" for k, v in r.theta.items())
        cert = "" if r.certified is None else (" certified" if r.certified else
                                               " certificate FAILED")
        lines += [f"  {i}. {r.label}: race {r.race_s:.4f} s (lap {r.lap_s:.4f} s, bound "
                  f"{r.bound_s:.4f} s){cert}",
                  f"     frame {th} ({GEOMETRY_BY[r.geometry_by]}); mass {r.mass_kg:.4f} kg, "
                  f"thrust/weight {r.thrust_to_weight:.2f}, hover throttle "
                  f"{r.hover_throttle:.3f}",
                  f"     peak currents: pack {r.peak_pack_current_a:.1f} A (margin "
                  f"{r.pack_current_margin_a:.1f} A), motor {r.peak_motor_current_a:.1f} A "
                  f"(margin {r.motor_current_margin_a:.1f} A); energy used "
                  f"{r.energy_used_wh:.2f} Wh, left {r.energy_left_wh:.2f} Wh (soc "
                  f"{r.end_soc:.3f})"]
    for measure, labels in result.fronts.items():
        lines.append(f"  front of race time against {measure}: " + (" > ".join(labels) or "-"))
    ranked = {r.label for r in result.ranking}
    lines.append("  others:")
    for r in sorted(result.results, key=lambda r: (r.outcome, _key(r))):
        if r.label in ranked:
            continue
        fig = f" race {r.race_s:.4f} s" if math.isfinite(r.race_s) else ""
        if r.outcome == "raced" and r.geometry_by != "co-design":
            fig += f" ({GEOMETRY_BY[r.geometry_by]})"
        why = f": {r.reason}" if r.reason else ""
        lines.append(f"    {r.outcome:<8} {r.label}{fig}{why}")
    return "\n".join(lines)


def _key(r: BuildResult) -> float:
    return r.race_s if math.isfinite(r.race_s) else (
        r.bound_s if math.isfinite(r.bound_s) else math.inf)
