"""``casadrone export``: an airframe or a run's candidate for a flight controller, a simulator or
the cutter (:mod:`casadrone.export`)."""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from casadrone.cli.common import app, bad_input, registry_option, reports_config_errors
from casadrone.export import FORMATS, export, write_export
from casadrone.export.plate import PlateOptions, arm_width_problem
from casadrone.export.source import source_of
from casadrone.outfile import OutputRefused, check_out


def _formats() -> list[str]:
    return list(FORMATS)


class Pattern(StrEnum):
    p16x16 = "16x16"
    p16x19 = "16x19"


@app.command("export")
@reports_config_errors
def export_command(
    source: Annotated[str, typer.Argument(
        help="airframe YAML or reference name (SY250, ...), or a run directory")],
    overrides: Annotated[list[str] | None, typer.Argument(
        help="key=value overrides of the airframe, e.g. alpha_deg=75")] = None,
    fmt: Annotated[str, registry_option(
        _formats, "format", "an export format of casadrone.export.FORMATS: betaflight (mmix "
        "lines), px4 (QGroundControl parameter file), px4-shell (param set lines), urdf, svg or "
        "dxf (1:1 plate outline, mm)", "--format", "-f")] = "betaflight",
    candidate: Annotated[str | None, typer.Option(
        help="of a run directory: A (utopian), B (compromise), C (extreme) or a pareto.csv row "
        "(0-based)")] = None,
    out: Annotated[Path | None, typer.Option(
        "--out", "-o", help="write to this new file (default: print); never inside a run "
        "directory")] = None,
    force: Annotated[bool, typer.Option(
        "--force", help="replace the --out file if it exists")] = False,
    arm_width: Annotated[float, typer.Option(
        help="svg/dxf: arm width (mm)", min=1.0)] = 14.0,
    pattern: Annotated[Pattern, typer.Option(
        help="svg/dxf: motor mounting hole pattern (mm)")] = Pattern.p16x19,
) -> None:
    """Export an airframe or a run's candidate: Betaflight mix, PX4 parameters, URDF, 1:1 plate.

    Betaflight custom mix (mmix lines), PX4 CA_ROTOR* parameters, URDF, or the frame plate as a 1:1
    SVG/DXF. Every file names the casadrone version, the airframe or run and the candidate.
    """
    options = PlateOptions(arm_width_mm=arm_width, pattern=pattern.value)
    if arm_width_problem(options):
        raise bad_input([f"--arm-width: {arm_width_problem(options)}"])
    if out is not None:
        try:
            check_out(out, force)  # before reading anything
        except OutputRefused as exc:
            raise bad_input([f"--out: {exc}"]) from None
    try:
        src = source_of(source, candidate, overrides)
    except (FileNotFoundError, ValueError) as exc:
        raise bad_input([f"{source}: {exc}" if str(source) not in str(exc) else str(exc)]) from None
    try:
        if out is None:
            typer.echo(export(src, fmt, options), nl=False)
        else:
            typer.echo(f"wrote {write_export(src, fmt, out, options, force)}")
    except OutputRefused as exc:
        raise bad_input([f"--out: {exc}"]) from None
    except (ValueError, RuntimeError) as exc:
        raise bad_input([f"{source}: {exc}"]) from None
