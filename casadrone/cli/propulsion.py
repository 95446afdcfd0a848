"""``casadrone fit-propulsion``: an airframe's ``propulsion:`` section fitted from a thrust-stand
log (:mod:`casadrone.thruststand`)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from casadrone.cli.common import (
    JsonOpt,
    PlotOpt,
    app,
    bad_input,
    check_plot_dir,
    print_json,
    reports_config_errors,
    save_figures,
)


@app.command("fit-propulsion")
@reports_config_errors
def fit_propulsion_command(
    log: Annotated[Path, typer.Argument(
        help="thrust-stand CSV log, units in the header (e.g. 'Thrust (kgf)', 'Torque (N·m)')")],
    diameter_in: Annotated[float | None, typer.Option(
        "--diameter-in", help="propeller diameter (inch), e.g. 5.1")] = None,
    diameter_m: Annotated[float | None, typer.Option(
        "--diameter-m", help="propeller diameter (m), instead of --diameter-in")] = None,
    air_density: Annotated[float, typer.Option(
        "--air-density", help="air density during the test (kg/m³; ISA sea level 1.225)")] = 1.225,
    motor_poles: Annotated[int | None, typer.Option(
        "--motor-poles", min=2, max=64,
        help="motor poles, to turn a raw commutation frequency logged as 'Motor Electrical Speed "
        "(RPM)' into rotor speed (Tyto/RCbenchmark software already logs rotor rpm there)")] = None,
    esc_min_us: Annotated[float | None, typer.Option(
        "--esc-min-us", help="ESC signal at zero duty (default: 1000 µs for a log of 'ESC signal "
        "(µs)', 48 for a DShot log: 'ESC signal' without a unit)")] = None,
    esc_max_us: Annotated[float | None, typer.Option(
        "--esc-max-us", help="ESC signal at full duty (default: 2000 µs; 2047 for DShot)")] = None,
    shape: Annotated[str | None, typer.Option(
        "--shape", help="J-dependence of CT and CP from a shipped propeller dataset, scaled to "
        "the fitted static values (e.g. uiuc-da4022-5x3.75-3blade); default: static only")
    ] = None,
    out: Annotated[Path | None, typer.Option(
        "--out", help="write the section as a YAML file (refused if it exists, unless --force)")
    ] = None,
    force: Annotated[bool, typer.Option("--force", help="replace an existing --out file")] = False,
    plot: PlotOpt = None,
    as_json: JsonOpt = False,
):
    """Fit a propulsion: section (propeller CT0/CP0, DC motor KV/R/I0, battery resistance, rotor
    inertia from step tests) from a thrust-stand log, print the fit residuals.

    Examples:

      casadrone fit-propulsion stand.csv --diameter-in 5.1 --out prop.yaml --plot fit/

      casadrone fit-propulsion stand.csv --diameter-in 5 --shape uiuc-da4022-5x3.75-3blade

      casadrone fit-propulsion stand.csv --diameter-m 0.127 --motor-poles 14 --json
    """
    from casadrone.optimise.store import atomic_write
    from casadrone.thruststand import LogError, fit_propulsion, read_log

    if (diameter_in is None) == (diameter_m is None):
        raise bad_input(["fit-propulsion: give the propeller diameter: --diameter-in or "
                         "--diameter-m (one of them)"])
    if shape is not None and shape not in shipped_propellers():
        raise bad_input([f"--shape: {shape!r} is not a shipped propeller dataset (shipped: "
                         f"{', '.join(shipped_propellers())})"])
    if out is not None and out.exists() and not (force and out.is_file()):
        raise bad_input([f"--out: {out}: exists (give --force to replace a file)"])
    check_plot_dir(plot)
    D = diameter_m if diameter_m is not None else 0.0254 * (diameter_in or 0.0)
    try:
        stand = read_log(log, motor_poles)
        fit = fit_propulsion(stand, D, air_density, esc_min_us, esc_max_us)
    except LogError as exc:
        raise bad_input([str(exc)]) from None
    if out is not None:
        atomic_write(out, section_yaml(fit, shape))
    figures = []
    if plot is not None:
        from casadrone.plots import propulsion_fit_figures

        plot.mkdir(parents=True, exist_ok=True)
        figures = save_figures(propulsion_fit_figures(fit, stand), plot)
    if as_json:
        print_json({**fit.as_dict(shape), "out": str(out) if out else None, "figures": figures})
        return
    _print_text(fit)
    if out is not None:
        typer.echo(f"wrote {out}")
    for path in figures:
        typer.echo(f"wrote {path}")


def shipped_propellers() -> list[str]:
    """Names of the propeller datasets in the package data (``data/propulsion/*.csv``)."""
    from importlib import resources

    folder = resources.files("casadrone") / "data" / "propulsion"
    return sorted(p.name[:-4] for p in folder.iterdir()
                  if p.name.endswith(".csv") and p.name != "parts.csv")


def section_yaml(fit, shape: str | None = None) -> str:
    """The ``propulsion:`` section as YAML, with a comment naming its source and residuals."""
    import yaml

    head = [f"# propulsion: section fitted by casadrone fit-propulsion from {fit.source}",
            f"# {len(fit.plateaus)} steady points ({fit.steady_source}), {len(fit.steps)} step "
            "responses; residuals:"]
    head += [f"#   {r.quantity}: rms {r.rms:.4g} {r.unit} ({100 * r.relative_rms:.2f} %), "
             f"max {r.max_abs:.4g} {r.unit}" for r in fit.residuals]
    body = yaml.safe_dump({"propulsion": fit.section(shape)}, sort_keys=False)
    return "\n".join(head) + "\n" + body


def _print_text(fit) -> None:
    typer.echo(f"{fit.source}: {len(fit.plateaus)} steady points from {fit.steady_source}, "
               f"{len(fit.steps)} step responses")
    zero, full = fit.esc_range
    unit = " µs" if fit.esc_protocol == "pwm" else ""
    typer.echo(f"ESC signal {fit.esc_protocol.upper() if fit.esc_protocol == 'dshot' else 'PWM'}"
               f", duty 0 at {zero:g}{unit}, 1 at {full:g}{unit}")
    if fit.steady_source == "averaged rows":
        typer.echo("           (no plateau and rows seconds apart: each row taken as one "
                   "averaged steady point; no step response fitted)")
    typer.echo(f"propeller  CT0 {fit.ct0:.5f}  CP0 {fit.cp0:.5f}  (D {fit.diameter_m:.4f} m, "
               f"rho {fit.air_density_kg_m3:g} kg/m³)")
    typer.echo(f"motor      KV {fit.kv_rpm_per_v:.1f} rpm/V  R {fit.resistance_ohm * 1e3:.1f} mΩ  "
               f"I0 {fit.no_load_current_a:.3f} A")
    if fit.time_constant_s is None:
        typer.echo("           time constant and rotor inertia not measured (no resolved step)")
    else:
        typer.echo(f"           time constant {fit.time_constant_s * 1e3:.1f} ms (median of "
                   f"{len(fit.steps)} steps), rotor inertia {fit.rotor_inertia_kgm2:.3g} kg·m²")
    typer.echo(f"battery    Voc {fit.open_circuit_voltage_v:.3f} V  "
               f"R_int {fit.internal_resistance_ohm * 1e3:.1f} mΩ")
    typer.echo("residuals:")
    for r in fit.residuals:
        typer.echo(f"  {r.quantity:<14} rms {r.rms:.4g} {r.unit} ({100 * r.relative_rms:.2f} %), "
                   f"max {r.max_abs:.4g} {r.unit}, {r.points} points")
