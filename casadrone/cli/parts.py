"""``casadrone parts``: the parts catalogue (:mod:`casadrone.parts`), with a user's own parts file
(:mod:`casadrone.config.parts`), as tables or JSON, and the propellers' fits drawn."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from casadrone.cli.common import (
    JsonOpt,
    app,
    bad_input,
    check_plot_dir,
    print_json,
    reports_config_errors,
    save_figures,
)
from casadrone.config.io import resolve_config
from casadrone.config.parts import load_parts
from casadrone.parts.catalogue import Catalogue, propeller_points, read_rows
from casadrone.parts.records import KINDS, MotorPart, PackPart, Part, PropellerPart


def _kinds() -> list[str]:
    return list(KINDS)


@app.command("parts")
@reports_config_errors
def parts_command(
    name: Annotated[str | None, typer.Argument(
        help="one part's name: print it whole (every figure with its basis and source)")] = None,
    kind: Annotated[str | None, typer.Option(
        "--kind", metavar="KIND", autocompletion=_kinds,
        help="only this kind: propeller, motor or pack")] = None,
    file: Annotated[Path | None, typer.Option(
        "--file", help="a YAML file of your own parts (propellers:, motors:, packs:), added to "
        "the catalogue; validated like every config (a shipped name: example-parts)")] = None,
    plot: Annotated[Path | None, typer.Option(
        "--plot", help="draw each propeller listed (raw points and fit, parts-NAME) and an "
        "overview of their fits (parts-propellers), PNG and SVG, into this folder")] = None,
    as_json: JsonOpt = False,
) -> None:
    """List the parts catalogue: propellers (UIUC data, fitted over their measured range),
    racing motors and LiPo packs, each with its source; a name prints one part whole.

    Every figure is marked datasheet, measured or assumed. Bad input (an unknown kind or name, a
    --file that is not a valid parts file) exits 2 with one line per problem, before anything
    is drawn.
    """
    if kind is not None and kind not in KINDS:
        raise bad_input([f"--kind: unknown kind {kind!r}; one of {', '.join(KINDS)}"])
    path = resolve_config(file, "parts") if file is not None else None
    catalogue = load_parts(path)
    try:
        shown = [catalogue.get(name, kind)] if name is not None else list(
            catalogue.of_kind(kind) if kind else catalogue)
    except KeyError as exc:
        raise bad_input([f"{name}: {exc.args[0]}"]) from None
    propellers = [p for p in shown if isinstance(p, PropellerPart)]
    if plot is not None:
        check_plot_dir(plot, _figure_names(propellers))
    if as_json:
        print_json({"sizes": catalogue.sizes(), "parts": [_as_json(p) for p in shown]})
    else:
        typer.echo(part_text(shown[0]) if name is not None else catalogue_text(shown, catalogue))
    if plot is not None:
        for line in save_figures(_figures(propellers), plot):
            typer.echo(f"wrote {line}", err=True)


def _as_json(part: Part) -> dict:
    return {"kind": part.kind, **part.as_dict()}


def _figure_names(propellers: list[PropellerPart]) -> list[str]:
    return [f"parts-{p.name}" for p in propellers] + (["parts-propellers"] if propellers else [])


def _figures(propellers: list[PropellerPart]) -> dict:
    from casadrone.plots import propeller_overview_figure, propeller_part_figure

    rows = read_rows("propellers.csv")
    points = {p.name: propeller_points(p.name, rows) for p in propellers}
    drawn = [p for p in propellers if points[p.name]]  # a user's propeller has no raw points
    figures = {f"parts-{p.name}": propeller_part_figure(p, points[p.name]) for p in drawn}
    if drawn:
        figures["parts-propellers"] = propeller_overview_figure(drawn, points)
    return figures


# --------------------------------------------------------------------------------------------
# Text
# --------------------------------------------------------------------------------------------


def catalogue_text(shown: list[Part], catalogue: Catalogue) -> str:
    """The listed parts as one table per kind, after the catalogue's sizes."""
    sizes = ", ".join(f"{n} {k}s" for k, n in catalogue.sizes().items())
    out = [f"parts catalogue: {sizes}"]
    for kind, table in (("propeller", _propeller_table), ("motor", _motor_table),
                        ("pack", _pack_table)):
        rows = [p for p in shown if p.kind == kind]
        if rows:
            out += ["", *table(rows)]
    out += ["", "basis per figure: d datasheet, m measured, a assumed; "
            "`casadrone parts NAME` prints one part with its sources"]
    return "\n".join(out)


def _propeller_table(parts: list) -> list[str]:
    head = (f"{'propeller':30} {'D in':>5} {'blades':>6} {'C_T0':>7} {'C_P0':>7} {'J max':>6} "
            f"{'rpm':>12} {'Re 0.75R min':>12} {'rms C_T':>8}")
    lines = [head]
    for p in parts:
        re_min = f"{p.reynolds_075_min:.3g}" if p.reynolds_075_min else "-"
        lines.append(f"{p.name:30} {p.diameter_m / 0.0254:5.2f} {p.blades:6d} "
                     f"{p.ct_coefficients[0]:7.4f} {p.cp_coefficients[0]:7.4f} "
                     f"{p.j_max_measured:6.3f} {p.rpm_min:5.0f}-{p.rpm_max:<6.0f} {re_min:>12} "
                     f"{p.ct_rms:8.4f}")
    return lines


def _marks(part: MotorPart | PackPart) -> str:
    return "".join(part.basis[f][0] for f in part.basis)


def _motor_table(parts: list) -> list[str]:
    lines = [f"{'motor':38} {'KV':>5} {'R mΩ':>6} {'I0 A@V':>8} {'Imax A':>7} {'g':>5} "
             f"{'basis':>6}"]
    lines += [f"{m.name:38} {m.kv_rpm_per_v:5.0f} {1e3 * m.resistance_ohm:6.1f} "
              f"{m.no_load_current_a:4.2f}@{m.no_load_voltage_v:<3.0f} {m.max_current_a:7.1f} "
              f"{1e3 * m.mass_kg:5.1f} {_marks(m):>6}" for m in parts]
    return lines


def _pack_table(parts: list) -> list[str]:
    lines = [f"{'pack':34} {'S':>2} {'mAh':>5} {'C':>4} {'Imax A':>7} {'R mΩ':>6} {'g':>5} "
             f"{'V full':>6} {'basis':>5}"]
    lines += [f"{b.name:34} {b.cells:2d} {1e3 * b.capacity_ah:5.0f} {b.c_rating:4.0f} "
              f"{b.max_current_a:7.1f} {1e3 * b.resistance_ohm:6.1f} {1e3 * b.mass_kg:5.1f} "
              f"{b.full_voltage_v:6.2f} {_marks(b):>5}" for b in parts]
    return lines


def part_text(part: Part) -> str:
    """One part whole: every field, a basis beside each figure that has one."""
    lines = [f"{part.kind} {part.name}"]
    for key, value in part.as_dict().items():
        if key in ("name", "basis", "source"):
            continue
        lines.append(f"  {key}: {value}")
    basis = getattr(part, "basis", None)
    if basis:
        lines.append("  basis: " + ", ".join(f"{k} {v}" for k, v in basis.items()))
    lines.append(f"  source: {part.source}")
    return "\n".join(lines)
