"""The typer app and what every command shares: argument types, exit code 2 for bad input
(one ``FILE: key: message`` line per problem on stderr), JSON output, figures."""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from functools import wraps
from pathlib import Path
from typing import Annotated, Any

import typer

from casadrone.airframe import Airframe, build_airframe
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.io import ConfigError
from casadrone.heap import keep_heap
from casadrone.progress import listening, printer
from casadrone.rundir.store import NotARunDirectory, RunDamaged, RunInProgress


class _App(typer.Typer):
    """The typer app, run so that a bad command-line option is one line too: ``COMMAND:
    message``, exit code 2 (click would print a usage block)."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        import sys

        # The console script, ``python -m casadrone`` and ``python -c "...app()"`` all name the
        # program ``casadrone`` in their messages (click would take it from sys.argv[0]: ``-c``).
        kwargs.setdefault("prog_name", "casadrone")
        # the process is casadrone's: keep MUMPS's freed workspace for its next factorization
        # (casadrone.heap: a system-time saving, the same numbers)
        keep_heap()
        if "standalone_mode" in kwargs:
            return super().__call__(*args, **kwargs)
        try:
            code = super().__call__(*args, standalone_mode=False, **kwargs)
        except _CLICK_ERROR as exc:
            if isinstance(exc, _USAGE_ERROR) and type(exc).__name__ != "NoArgsIsHelpError":
                where = exc.ctx.command_path if exc.ctx is not None else "casadrone"
                message = " ".join(exc.format_message().split())
                typer.echo(f"{where}: {message} (see '{where} --help')", err=True)
                sys.exit(EXIT_BAD_INPUT)
            exc.show()
            sys.exit(exc.exit_code)
        except typer.Abort:
            typer.echo("interrupted", err=True)
            sys.exit(130)
        sys.exit(code if isinstance(code, int) else 0)


def _flags_take_no_value() -> None:
    """Show a flag as a flag (``--json``), not as ``--json <bool>``: typer's help gives every
    option its type, a flag's too, although a flag takes no value (``--json true`` is refused)."""
    import typer.core

    option = typer.core.TyperOption
    if getattr(option.display_type_rich, "_casadrone", False):
        return
    shown = option.display_type_rich

    def display_type_rich(self: Any, ctx: Any) -> Any:
        return None if self.is_flag and not self.count else shown(self, ctx)

    display_type_rich._casadrone = True  # type: ignore[attr-defined]
    option.display_type_rich = display_type_rich  # type: ignore[method-assign]


_flags_take_no_value()

# typer (>= 0.20) carries its own copy of click: its exception classes, found from typer's own.
# (typed Any: the copy is private to typer, so no public name types them)
_USAGE_ERROR: Any = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "UsageError")
_CLICK_ERROR: Any = next(c for c in typer.BadParameter.__mro__ if c.__name__ == "ClickException")


app = _App(
    name="casadrone",
    help="Racing-drone airframe optimisation. Check configs (validate); trim, linearise and "
    "design the LQR-I controller (lqr) of an airframe, and its mass properties (massprops); "
    "fly a lap (simulate, benchmark) or the fastest possible lap (limit-lap); optimise a "
    "design problem (run, resume), choose designs on its front (decide) and compare and "
    "report them (compare, report); find the fastest frame in one solve (codesign); compare "
    "the trim solvers (trim-study); fit a thrust-stand log (fit-propulsion); list the cited "
    "propellers, motors and packs (parts) and choose them with the frame for a race (build); "
    "export a design "
    "for flight firmware or a 1:1 plate (export).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

EXIT_BAD_INPUT = 2
#: A command that ran and found no result (``codesign``: no start converged); its result, with
#: status "failed" and the reason, is still printed and written.
EXIT_FAILED = 3


def unwrapped(doc: str) -> str:
    """A docstring as help text: each paragraph on one line (blank lines between paragraphs
    kept), so that the help formatter wraps it to the terminal. Typer's rich help keeps a
    docstring's single line breaks, and a docstring wrapped at 100 columns read at 80 as lines
    broken mid-sentence. A paragraph that starts with ``\\b`` keeps its lines (click's rule)."""
    import inspect

    paragraphs = inspect.cleandoc(doc).split("\n\n")
    return "\n\n".join(p if p.startswith("\b") else " ".join(p.split()) for p in paragraphs)


def command_name(command: typer.models.CommandInfo) -> str:
    """The name a registered command is called by (typer's rule: the function's, dashed)."""
    if command.name:
        return command.name
    assert command.callback is not None
    return command.callback.__name__.replace("_", "-")


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
    Path | None, typer.Option(
        "--plot", help="save figures (PNG and SVG) into this folder (a figure casadrone wrote "
        "is replaced; any other file of a figure's name is refused)")
]
#: The shipped names ``--track`` and ``--controller`` default to, shown whole in --help (a path
#: was cut at 80 columns: "configs/tracks/paper-rectang…").
DEFAULT_TRACK_NAME = "paper-rectangle"
DEFAULT_CONTROLLER_NAME = "default"
QuietOpt = Annotated[bool, typer.Option(
    "--quiet", "-q", help="no progress lines on stderr (errors are still printed)")]
TrackOpt = Annotated[
    str | None,
    typer.Option(help=f"track YAML or shipped name (default: {DEFAULT_TRACK_NAME})"),
]
ControllerOpt = Annotated[
    str | None,
    typer.Option(
        help=f"controller YAML or shipped name (default: {DEFAULT_CONTROLLER_NAME})"),
]


@contextmanager
def progress_lines(command: str, quiet: bool) -> Iterator[None]:
    """Run the block with the library's progress events (:mod:`casadrone.progress`) printed on
    stderr as ``COMMAND: what [CPU c s, wall w s]``, or with none at all (compiles included)
    under ``--quiet``; stdout stays the command's result (pure JSON with ``--json``)."""
    with listening(None if quiet else printer(command)):
        yield


def registry_option(names: Callable[[], Iterable[str]], what: str, help: str,
                    *flags: str, extra: tuple[str, ...] = ()) -> Any:
    """A ``--option NAME`` whose choices are the names of a registry (``extra`` added): read when
    the option is parsed or completed, so the CLI starts without importing the registry's module
    (CasADi), and a name registered there is a choice here with no change to the CLI."""

    def choices() -> list[str]:
        return [*names(), *extra]

    def check(value: str | None) -> str | None:
        if value is not None and value not in choices():
            raise typer.BadParameter(f"unknown {what} {value!r}; one of {', '.join(choices())}")
        return value

    return typer.Option(*flags, help=help, metavar=what.upper(), callback=check,
                        autocompletion=choices)


def bad_input(lines: list[str]) -> typer.Exit:
    """Print one line per problem on stderr; the caller raises the returned Exit (code 2)."""
    for line in lines:
        typer.echo(line, err=True)
    return typer.Exit(EXIT_BAD_INPUT)


#: Failures a command can meet on a good day (a full disk, a damaged run directory, a pickle or
#: database that does not read, numerics that overflow): one line each, exit code 2.
def _expected() -> tuple[type[BaseException], ...]:
    import pickle
    import sqlite3

    import yaml

    return (OSError, sqlite3.Error, pickle.PickleError, EOFError, UnicodeDecodeError,
            yaml.YAMLError, FloatingPointError, OverflowError, RunDamaged, RunInProgress,
            NotARunDirectory)


def one_line(exc: BaseException) -> str:
    """An expected failure as one line: ``FILE: what`` where a file is known."""
    import sqlite3

    if isinstance(exc, OSError) and exc.strerror:
        where = exc.filename or ""
        return f"{where}: {exc.strerror}" if where else exc.strerror
    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, sqlite3.Error):
        return f"history database: {text}"
    return text


def log_traceback(exc: BaseException) -> Path | None:
    """Write the traceback of an unexpected exception to a log file; its path (None if even
    that fails)."""
    import datetime as dt
    import os
    import traceback

    root = Path(os.environ.get("CASADRONE_CACHE") or Path.home() / ".cache" / "casadrone")
    try:
        folder = root / "logs"
        folder.mkdir(parents=True, exist_ok=True)
        stamp = dt.datetime.now(dt.UTC).strftime("%Y%m%dT%H%M%S")
        path = folder / f"error-{stamp}-{os.getpid()}.log"
        path.write_text("".join(traceback.format_exception(exc)), encoding="utf-8")
        return path
    except OSError:
        return None


def reports_config_errors(command: Callable[..., Any]) -> Callable[..., Any]:
    """Every way ``command`` can fail, as lines on stderr and an exit code, never a traceback:
    a ConfigError (one line per problem) or an expected failure (one line) exits 2; a signal
    exits 128 + its number (130 Ctrl-C, 143 SIGTERM) saying how to resume a run; anything else
    is a bug: one line naming a log file that holds the traceback, exit 1."""

    @wraps(command)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        import signal

        try:
            return command(*args, **kwargs)
        except ConfigError as exc:
            raise bad_input(exc.lines) from None
        except (typer.Exit, typer.Abort, _CLICK_ERROR):
            raise
        except KeyboardInterrupt as exc:  # also the runner's Interrupted (SIGINT, SIGTERM)
            signum = getattr(exc, "signum", signal.SIGINT)
            run_dir = getattr(exc, "run_dir", None)
            hint = (f"; state recorded, continue with: casadrone resume {run_dir}"
                    if run_dir is not None else "")
            typer.echo(f"interrupted ({signal.Signals(signum).name}){hint}", err=True)
            raise typer.Exit(128 + signum) from None
        except _expected() as exc:
            raise bad_input([one_line(exc)]) from None
        except Exception as exc:  # noqa: BLE001 (the last resort: a bug, not bad input)
            log = log_traceback(exc)
            where = f" (traceback in {log})" if log else ""
            typer.echo(f"casadrone: internal error: {type(exc).__name__}: "
                       f"{' '.join(str(exc).split())[:300]}{where}", err=True)
            raise typer.Exit(1) from None

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


def cost_text(cpu_s: float, wall_s: float, build_cpu_s: float | None = None) -> str:
    """What a command's work cost, as every command prints it: this process's CPU time (s; with
    the part spent building its solver) and the wall time (s) of the same work, each named for
    what it measures: ``CPU 12.3 s in all (build 3.1 s), wall 15.0 s``. CPU is the figure to
    compare (wall time grows with whatever else the machine runs, and with compilers, which
    are other processes)."""
    build = f" in all (build {build_cpu_s:.1f} s)" if build_cpu_s is not None else ""
    return f"CPU {cpu_s:.1f} s{build}, wall {wall_s:.1f} s"


def print_json(obj: Any) -> None:
    typer.echo(json.dumps(jsonable(obj), indent=2, allow_nan=False))


def load_airframe_or_exit(airframe: str, overrides: list[str] | None
                          ) -> tuple[AirframeConfig, Airframe]:
    """(config, Airframe) of an airframe path or name with overrides; ConfigError propagates."""
    cfg = load_airframe(airframe, overrides or [])
    return cfg, build_airframe(cfg)


#: The formats each ``--plot`` figure is saved in (:func:`save_figures`).
FIGURE_FORMATS = ("png", "svg")


def figure_paths(folder: Path, names: Iterable[str]) -> list[Path]:
    """The files :func:`save_figures` writes for figures named ``names`` in ``folder``."""
    return [folder / f"{name}.{fmt}" for name in names for fmt in FIGURE_FORMATS]


def foreign_figures(paths: Iterable[Path]) -> list[Path]:
    """The paths that hold something casadrone must not replace: anything (a file, a folder, a
    link) that is not a figure casadrone wrote (:func:`casadrone.plots.is_casadrone_figure`)."""
    existing = [p for p in paths if p.exists() or p.is_symlink()]
    if not existing:
        return []
    from casadrone.plots import is_casadrone_figure  # only now: it imports matplotlib

    return [p for p in existing if not is_casadrone_figure(p)]


def foreign_figure_line(refused: list[Path], flag: str = "--plot", hint: str = "") -> str:
    """The one line that refuses ``refused`` (the first named, the others counted)."""
    more = f" (and {len(refused) - 1} more such file(s) there)" if len(refused) > 1 else ""
    return (f"{flag}: {refused[0]}: exists and is not a casadrone figure{more}; it was left "
            f"untouched, move it or choose another {flag} folder{hint}")


def check_plot_dir(folder: Path | None, names: Iterable[str] = ()) -> None:
    """Exit 2 before any work when ``--plot`` names something that cannot be a folder, or when
    a figure ``names`` would be written to (each in :data:`FIGURE_FORMATS`) exists and is not a
    figure casadrone wrote: one line on stderr. Nothing the user owns is replaced; a casadrone
    figure is (re-running a command into the same folder)."""
    if folder is None:
        return
    if folder.exists() and not folder.is_dir():
        raise bad_input([f"--plot: {folder}: exists and is not a folder"])
    problem = folder_creation_problem(folder)
    if problem:
        raise bad_input([f"--plot: {folder}: {problem}"])
    refused = foreign_figures(figure_paths(folder, names))
    if refused:
        raise bad_input([foreign_figure_line(refused)])


def folder_creation_problem(folder: Path) -> str:
    """Why ``folder`` (not yet there) cannot be made, judged by its nearest existing ancestor
    (empty when it can): a file on the way (``--plot afile/sub``) or a folder that cannot be
    written. Found before any work: a limit lap found it only when it saved its figures, minutes
    later, and its result was lost."""
    import os

    if folder.exists():
        return ""
    ancestor = next((a for a in folder.absolute().parents if a.exists()), None)
    if ancestor is None:
        return ""
    if not ancestor.is_dir():
        return f"cannot be made: {ancestor} is a file, not a folder"
    if not os.access(ancestor, os.W_OK | os.X_OK):
        return f"cannot be made: {ancestor} is not writable"
    return ""


def check_out_folder(folder: Path | None, flag: str = "--out") -> None:
    """Exit 2 before any work when ``folder`` (a command's output folder) holds something or
    cannot be made (a file on the way, a folder that cannot be written): one line naming the
    option. Nothing is overwritten."""
    if folder is None:
        return
    if folder.exists() or folder.is_symlink():
        if not folder.is_dir() or any(folder.iterdir()):
            raise bad_input([f"{flag}: {folder}: must be a new or empty folder (nothing is "
                             "overwritten)"])
        return
    problem = folder_creation_problem(folder)
    if problem:
        raise bad_input([f"{flag}: {folder}: {problem}"])


def save_figures(figures: dict, folder: Path) -> list[str]:
    """Save each named figure as PNG and SVG in ``folder``; the paths written. Every path is
    checked first (:func:`check_plot_dir`): when one holds something that is not a casadrone
    figure, none is written and the command exits 2."""
    from casadrone.plots import save_figure

    check_plot_dir(folder, figures)
    return [str(p) for name, fig in figures.items()
            for p in save_figure(fig, folder / name, FIGURE_FORMATS)]
