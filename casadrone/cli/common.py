"""The typer app and what every command shares: argument types, exit code 2 for bad input
(one ``FILE: key: message`` line per problem on stderr), JSON output, figures."""

from __future__ import annotations

import json
import math
from functools import wraps
from pathlib import Path
from typing import Annotated, Any

import typer

from casadrone.configio import ConfigError

app = typer.Typer(
    name="casadrone",
    help="Racing-drone airframe optimisation: validate configs, trim, linearise, design LQR-I, "
    "fly a lap, benchmark, optimise (run, resume), decide, compare and report.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

EXIT_BAD_INPUT = 2


def _print_version(value: bool) -> None:
    if value:
        from casadrone import __version__

        typer.echo(f"casadrone {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[bool, typer.Option(
        "--version", callback=_print_version, is_eager=True,
        help="print the casadrone version and exit")] = False,
) -> None:
    """Racing-drone airframe optimisation."""

AirframeArg = Annotated[
    str, typer.Argument(help="airframe YAML, or a reference name (SY250, HS200, ...)")
]
OverridesArg = Annotated[
    list[str] | None,
    typer.Argument(help="key=value overrides of the airframe, e.g. alpha_deg=75 lambda_a_mm=140"),
]
JsonOpt = Annotated[bool, typer.Option("--json", help="print one JSON object instead of text")]
PlotOpt = Annotated[
    Path | None, typer.Option("--plot", help="save figures (PNG and SVG) into this folder")
]


def bad_input(lines: list[str]) -> typer.Exit:
    """Print one line per problem on stderr; the caller raises the returned Exit (code 2)."""
    for line in lines:
        typer.echo(line, err=True)
    return typer.Exit(EXIT_BAD_INPUT)


def reports_config_errors(command):
    """Turn a ConfigError raised anywhere in ``command`` into its lines and exit code 2."""

    @wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except ConfigError as exc:
            raise bad_input(exc.lines) from None

    return wrapper


def jsonable(value: Any) -> Any:
    """numpy arrays/scalars → lists/floats; complex → [re, im]; NaN/inf → null (strict JSON)."""
    import numpy as np

    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, np.bool_ | bool):
        return bool(value)
    if isinstance(value, np.integer | int):
        return int(value)
    if isinstance(value, complex | np.complexfloating):
        return [jsonable(float(value.real)), jsonable(float(value.imag))]
    if isinstance(value, np.floating | float):
        return float(value) if math.isfinite(value) else None
    return value


def print_json(obj: Any) -> None:
    typer.echo(json.dumps(jsonable(obj), indent=2, allow_nan=False))


def load_airframe_or_exit(airframe: str, overrides: list[str] | None):
    """(config, Airframe) of an airframe path or name with overrides; ConfigError propagates."""
    from casadrone.airframe import build_airframe
    from casadrone.config import load_airframe

    cfg = load_airframe(airframe, overrides or [])
    return cfg, build_airframe(cfg)


def check_plot_dir(folder: Path | None) -> None:
    """Exit 2 before any work when ``--plot`` names something that cannot be a folder."""
    if folder is not None and folder.exists() and not folder.is_dir():
        raise bad_input([f"--plot: {folder}: exists and is not a folder"])


def save_figures(figures: dict, folder: Path) -> list[str]:
    """Save each named figure as PNG and SVG in ``folder``; the paths written."""
    from casadrone.plots import save_figure

    return [str(p) for name, fig in figures.items() for p in save_figure(fig, folder / name)]
