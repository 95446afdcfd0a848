"""``casadrone fit-propulsion``: an airframe's ``propulsion:`` section fitted from a thrust-stand
log (:mod:`casadrone.thruststand`)."""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

import typer

from casadrone.cli.common import (
    JsonOpt,
    app,
    bad_input,
    check_plot_dir,
    figure_paths,
    foreign_figure_line,
    print_json,
    reports_config_errors,
    save_figures,
)
from casadrone.config.io import resolve_config
from casadrone.config.propulsion import shipped_datasets
from casadrone.outfile import OutputRefused, check_out, write_out
from casadrone.thruststand import (
    AIR_DENSITY_RANGE,
    DIAMETER_RANGE_M,
    ESC_SIGNAL_RANGE,
    PARTS,
    LogError,
    PropulsionFit,
    check_log_file,
    fit_propulsion,
    fitted_problem,
    read_log,
)

#: The figures ``--plot`` writes (:func:`casadrone.plots.propulsion_fit_figures`), each in each
#: format (:data:`casadrone.cli.common.FIGURE_FORMATS`): their paths are checked before the log
#: is read.
FIGURES = ("propulsion-fit-steady", "propulsion-fit-steps")


def _parts() -> list[str]:
    """The ``--part`` choices: the parts of :data:`casadrone.thruststand.PARTS`, and all."""
    return [*PARTS, "all"]


@app.command("fit-propulsion")
@reports_config_errors
def fit_propulsion_command(
    log: Annotated[Path, typer.Argument(
        help="thrust-stand CSV log, units in the header (e.g. 'Thrust (kgf)', 'Torque (N·m)'), "
        "or a shipped log's name: example-5in (synthetic, casadrone/data/thruststand)")],
    diameter_in: Annotated[float | None, typer.Option(
        "--diameter-in", help="propeller diameter (inch), e.g. 5.1")] = None,
    diameter_m: Annotated[float | None, typer.Option(
        "--diameter-m", help="propeller diameter (m), instead of --diameter-in")] = None,
    air_density: Annotated[float, typer.Option(
        "--air-density", help="air density during the test (kg/m³; ISA sea level 1.225)")] = 1.225,
    motor_poles: Annotated[int | None, typer.Option(
        "--motor-poles", min=2, max=64,
        help="motor poles (even), to turn a raw commutation frequency logged as 'Motor Electrical "
        "Speed (RPM)' into rotor speed (Tyto/RCbenchmark software already logs rotor rpm there)")
    ] = None,
    esc_min_us: Annotated[float | None, typer.Option(
        "--esc-min-us", help="ESC signal at zero duty (default: 1000 µs for a log of 'ESC signal "
        "(µs)', 48 for a DShot log: 'ESC signal' without a unit)")] = None,
    esc_max_us: Annotated[float | None, typer.Option(
        "--esc-max-us", help="ESC signal at full duty (default: 2000 µs; 2047 for DShot)")] = None,
    part: Annotated[list[str] | None, typer.Option(
        "--part", metavar="PART", autocompletion=_parts,
        help="fit only this part: propeller, motor or battery (repeat the option for two; "
        "default all). The motor fit takes the ESC as lossless with its duty linear in the "
        "signal, which DShot ESCs seldom are: --part propeller fits the propeller without it")
    ] = None,
    shape: Annotated[str | None, typer.Option(
        "--shape", help="J-dependence of CT and CP from a shipped propeller dataset, scaled to "
        "the fitted static values (e.g. uiuc-da4022-5x3.75-3blade); default: static only")
    ] = None,
    out: Annotated[Path | None, typer.Option(
        "--out", help="write the section as a YAML file (refused if it exists, unless --force; "
        "never the log itself nor a file in a run directory)")] = None,
    force: Annotated[bool, typer.Option(
        "--force", help="replace an existing --out file, and existing files of the --plot "
        "figures' names that casadrone did not write")] = False,
    plot: Annotated[Path | None, typer.Option(
        "--plot", help="save figures (PNG and SVG) into this folder (a figure casadrone wrote "
        "is replaced; any other file of a figure's name is refused, unless --force)")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Fit a propulsion: section (propeller CT0/CP0, DC motor KV/R/I0, battery resistance, rotor
    inertia from step tests) from a thrust-stand log, print each part with its residuals.

    Each part is fitted alone: one whose fit is not physical is marked refused, with the
    reason, and the others are kept and printed (exit 0). Exit 2, writing nothing, when every
    part asked for is refused, or when one is and --out asks for the section.

    Every destination (--out, the --plot figures) is checked before the log is read and its
    folder created before any file is written: a refused command writes nothing. A figure
    casadrone wrote (marked in its metadata) is replaced without --force, as by every --plot.
    """
    check_plot_dir(plot)
    problem = (option_problem(diameter_in, diameter_m, air_density, motor_poles, esc_min_us,
                              esc_max_us) or shape_problem(shape) or part_problem(part))
    if problem is not None:
        raise bad_input([problem])
    log = shipped_log(log)
    try:
        check_log_file(log)
    except LogError as exc:
        raise bad_input([str(exc)]) from None
    problem = next(destination_problems(log, out, plot, force), None)
    if problem is not None:
        raise bad_input([problem])
    D = diameter_m if diameter_m is not None else 0.0254 * (diameter_in or 0.0)
    try:
        stand = read_log(log, motor_poles)
        fit = fit_propulsion(stand, D, air_density, esc_min_us, esc_max_us,
                             parts=PARTS if not part or "all" in part else tuple(part))
    except LogError as exc:
        raise bad_input([str(exc)]) from None
    fitted_shape = shape if "propeller" in fit.fitted else None
    if not fit.fitted or (out is not None and fit.refused):  # the fit shown, nothing written
        _report(fit, fitted_shape, as_json)
        line = refusal_line(fit, *fit.refused[0])
        if fit.fitted:
            line += (f"; --out not written, it would lack the {fit.refused[0][0]} (--part "
                     "chooses the parts to write)")
        raise bad_input([line])
    problem = fitted_problem(fit, fitted_shape) if fitted_shape else None
    if problem is not None:  # the static section passed; the shape's J-dependence did not
        raise bad_input([f"{log.name}: with --shape {shape}: {problem}"])
    files: dict[tuple[str, Path], str | bytes] = {}
    if out is not None:
        files["--out", out] = section_yaml(fit, fitted_shape)
    if plot is not None:
        from casadrone.plots import propulsion_fit_figures

        figures = render_figures(propulsion_fit_figures(fit, stand), plot)
        files |= {("--plot", path): data for path, data in figures.items()}
    problem = make_folders(list(files))
    if problem is not None:
        raise bad_input([problem])
    try:
        written = [str(write_out(path, data, force or replaceable_figure(flag, path)))
                   for (flag, path), data in files.items()]
    except OutputRefused as exc:  # a file that appeared since the check
        raise bad_input([str(exc)]) from None
    shown_out = written.pop(0) if out is not None else None
    _report(fit, fitted_shape, as_json, shown_out, written)


def _report(fit: PropulsionFit, shape: str | None, as_json: bool, out: str | None = None,
            figures: list[str] | None = None) -> None:
    """The fit on stdout, as text or JSON, with the files written."""
    if as_json:
        print_json({**fit.as_dict(shape), "out": out, "figures": figures or []})
        return
    _print_text(fit)
    for path in ([out] if out else []) + (figures or []):
        typer.echo(f"wrote {path}")


def shipped_log(log: Path) -> Path:
    """``log`` as given when anything is there (:func:`casadrone.thruststand.check_log_file`
    says what a folder or a FIFO is), else the shipped log of that name (the convention of
    :func:`casadrone.config.io.resolve_config`: ``example-5in``); ConfigError naming the
    shipped logs when there is none."""
    if log.exists() or log.is_symlink():
        return log
    return resolve_config(log, "thruststand")


def refusal_line(fit: PropulsionFit, part: str, why: str) -> str:
    """One line saying that ``part`` of ``fit`` is refused, and why."""
    return f"{fit.source}: {part} refused: {why}"


def option_problem(diameter_in: float | None, diameter_m: float | None, air_density: float,
                   motor_poles: int | None, esc_min_us: float | None, esc_max_us: float | None
                   ) -> str | None:
    """The first option outside its range (NaN and inf included), as one line naming it."""
    if (diameter_in is None) == (diameter_m is None):
        return ("fit-propulsion: give the propeller diameter: --diameter-in or --diameter-m (one "
                "of them)")
    inch = tuple(d / 0.0254 for d in DIAMETER_RANGE_M)
    ranges = (("--diameter-in", diameter_in, inch, "inch"),
              ("--diameter-m", diameter_m, DIAMETER_RANGE_M, "m"),
              ("--air-density", air_density, AIR_DENSITY_RANGE, "kg/m³"),
              ("--esc-min-us", esc_min_us, ESC_SIGNAL_RANGE, "µs or DShot value"),
              ("--esc-max-us", esc_max_us, ESC_SIGNAL_RANGE, "µs or DShot value"))
    for flag, value, (lo, hi), unit in ranges:
        if value is not None and not lo <= value <= hi:
            return f"{flag}: {value:g} is not a number in {lo:.4g}-{hi:.4g} ({unit})"
    if motor_poles is not None and motor_poles % 2:
        return (f"--motor-poles: {motor_poles} is odd; a motor has an even number of poles (two "
                "per pole pair)")
    return None


def part_problem(parts: list[str] | None) -> str | None:
    """A ``--part`` naming no part, as one line; else None."""
    unknown = [p for p in parts or [] if p not in _parts()]
    if unknown:
        return f"--part: {unknown[0]!r} is not a part (one of {', '.join(_parts())})"
    return None


def shape_problem(shape: str | None) -> str | None:
    """``--shape`` naming no shipped propeller dataset, as one line; else None."""
    if shape is None or shape in shipped_datasets():
        return None
    return (f"--shape: {shape!r} is not a shipped propeller dataset (shipped: "
            f"{', '.join(shipped_datasets())})")


def destinations(out: Path | None, plot: Path | None) -> list[tuple[str, Path]]:
    """(option, path) of every file the command may write: ``--out`` and each --plot figure."""
    figures = [] if plot is None else [("--plot", p) for p in figure_paths(plot, FIGURES)]
    return ([("--out", out)] if out is not None else []) + figures


def destination_problems(log: Path, out: Path | None, plot: Path | None, force: bool
                         ) -> Iterator[str]:
    """One line per destination that must not be written, checked before any work."""
    targets = destinations(out, plot)
    if out is not None and any(_same_file(out, path) for _, path in targets[1:]):
        yield f"--out: {out}: is also a --plot figure; choose another --out"
    for flag, path in targets:
        problem = destination_problem(flag, path, log, force)
        if problem is not None:
            yield problem


def destination_problem(flag: str, path: Path, log: Path, force: bool) -> str | None:
    """Why ``path`` (given by ``flag``) must not be written, as one line; None if it may. Never
    the log, a dangling symbolic link, a folder or a file in a run directory
    (:func:`casadrone.outfile.check_out`); an existing file only with ``force``, or without it
    a figure casadrone wrote (:func:`replaceable_figure`); never where its folder cannot be
    written."""
    what = "--out" if flag == "--out" else "--plot folder"
    if path.is_symlink() and not path.exists():
        return (f"{flag}: {path}: is a dangling symbolic link (to {os.readlink(path)}); it was "
                f"left untouched, choose another {what} (--force does not apply here)")
    if _same_file(path, log):
        return (f"{flag}: {path}: is the input log; it was left untouched, choose another {what} "
                "(--force does not apply here)")
    try:
        check_out(path, force=True)
    except OutputRefused as exc:
        return f"{flag}: {exc}"
    if path.exists() and not force and not replaceable_figure(flag, path):
        if flag == "--plot":
            return foreign_figure_line([path], flag, " or pass --force to replace it")
        return (f"{flag}: {path}: exists and was left untouched; choose another {what} or pass "
                "--force to replace it")
    folder = _existing_folder(path)
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"{flag}: {path}: the folder {folder} is not writable"
    return None


def replaceable_figure(flag: str, path: Path) -> bool:
    """Whether ``path`` is a ``--plot`` figure casadrone wrote, which a run replaces without
    ``--force`` (:func:`casadrone.plots.is_casadrone_figure`)."""
    if flag != "--plot":
        return False
    from casadrone.plots import is_casadrone_figure  # only now: it imports matplotlib

    return is_casadrone_figure(path)


def _same_file(a: Path, b: Path) -> bool:
    """Whether ``a`` and ``b`` name one file (through links, either spelling)."""
    try:
        return os.path.samefile(a, b)
    except OSError:
        return os.path.abspath(a) == os.path.abspath(b)


def _existing_folder(path: Path) -> Path:
    """The nearest folder above ``path`` that exists."""
    return next(f for f in Path(os.path.abspath(path)).parents if f.is_dir())


def render_figures(figures: dict, folder: Path) -> dict[Path, bytes]:
    """Each figure's files (:func:`casadrone.cli.common.save_figures`), read back from a
    temporary folder: path in ``folder`` → bytes, nothing written there yet."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="casadrone-fit-propulsion-") as tmp:
        return {folder / Path(p).name: Path(p).read_bytes()
                for p in save_figures(figures, Path(tmp))}


def make_folders(targets: list[tuple[str, Path]]) -> str | None:
    """Create the folder of each (option, path), as one line the first that cannot be."""
    for flag, path in targets:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            why = exc.strerror or str(exc)
            return f"{flag}: {path}: its folder {path.parent} cannot be created: {why}"
    return None


def section_yaml(fit: PropulsionFit, shape: str | None = None) -> str:
    """The ``propulsion:`` section as YAML, with a comment naming its source and residuals."""
    import yaml

    head = [f"# propulsion: section fitted by casadrone fit-propulsion from {fit.source}",
            f"# {len(fit.plateaus)} steady points ({fit.steady_source}), {len(fit.steps)} step "
            "responses; residuals:"]
    head += [f"#   {r.quantity}: rms {r.rms:.4g} {r.unit} ({100 * r.relative_rms:.2f} %), "
             f"max {r.max_abs:.4g} {r.unit}" for r in fit.residuals if r.part in fit.fitted]
    head += [f"# {part}: not in this section: {state}; give it from its datasheet"
             for part, state in _missing_parts(fit)]
    body = yaml.safe_dump({"propulsion": fit.section(shape)}, sort_keys=False)
    return "\n".join(head) + "\n" + body


def _print_text(fit: PropulsionFit) -> None:
    typer.echo(f"{fit.source}: {len(fit.plateaus)} steady points from {fit.steady_source}, "
               f"{len(fit.steps)} step responses")
    zero, full = fit.esc_range
    unit = " µs" if fit.esc_protocol == "pwm" else ""
    typer.echo(f"ESC signal {fit.esc_protocol.upper() if fit.esc_protocol == 'dshot' else 'PWM'}"
               f", duty 0 at {zero:g}{unit}, 1 at {full:g}{unit}")
    if fit.steady_source == "averaged rows":
        typer.echo("           (no plateau and rows seconds apart: each row taken as one "
                   "averaged steady point; no step response fitted)")
    why = dict(fit.refused)
    for part in fit.parts:
        typer.echo(f"{part:<10} {fit.status(part).upper() if part in why else 'fitted':<8} "
                   f"{_values_text(fit, part)}")
        for r in (r for r in fit.residuals if r.part == part):
            typer.echo(f"           {r.quantity:<14} rms {r.rms:.4g} {r.unit} "
                       f"({100 * r.relative_rms:.2f} %), max {r.max_abs:.4g} {r.unit}, "
                       f"{r.points} points")
        if part in why:
            typer.echo(f"           why: {why[part]}")
    if fit.time_constant_s is None:
        typer.echo("rotor      time constant not measured (no resolved step)")
    else:
        inertia = ("rotor inertia not worked out (it needs the fitted motor and battery)"
                   if fit.rotor_inertia_kgm2 is None
                   else f"rotor inertia {fit.rotor_inertia_kgm2:.3g} kg·m²")
        typer.echo(f"rotor      time constant {fit.time_constant_s * 1e3:.1f} ms (median of "
                   f"{len(fit.steps)} steps), {inertia}")
    for part, state in _missing_parts(fit):
        typer.echo(f"not in the section: {part} ({state})")


def _values_text(fit: PropulsionFit, part: str) -> str:
    """The fitted values of ``part`` as the console shows them."""
    if part == "propeller":
        return (f"CT0 {fit.ct0:.5f}  CP0 {fit.cp0:.5f}  (D {fit.diameter_m:.4f} m, "
                f"rho {fit.air_density_kg_m3:g} kg/m³)")
    if part == "motor":
        return (f"KV {fit.kv_rpm_per_v:.1f} rpm/V  R {fit.resistance_ohm * 1e3:.1f} mΩ  "
                f"I0 {fit.no_load_current_a:.3f} A")
    return (f"Voc {fit.open_circuit_voltage_v:.3f} V  "
            f"R_int {fit.internal_resistance_ohm * 1e3:.1f} mΩ")


def _missing_parts(fit: PropulsionFit) -> list[tuple[str, str]]:
    """(part, refused or not fitted) of each part the section lacks."""
    return [(p, fit.status(p)) for p in PARTS if p not in fit.fitted]
