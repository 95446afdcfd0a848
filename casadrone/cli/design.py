"""Commands on one airframe, design layer of the chain: validate, trim, linearise, lqr."""

from __future__ import annotations

import importlib
import math
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from casadrone.cli.common import (
    EXIT_BAD_INPUT,
    AirframeArg,
    ControllerOpt,
    JsonOpt,
    OverridesArg,
    PlotOpt,
    app,
    bad_input,
    check_plot_dir,
    load_airframe_or_exit,
    print_json,
    registry_option,
    reports_config_errors,
    save_figures,
)
from casadrone.conditions import CONDITION_REGISTRY, CONDITIONS, OperatingPoint
from casadrone.config.airframe import ROTOR_LABELS
from casadrone.config.controller import load_controller
from casadrone.config.io import DATA_DIR, ConfigError, kind_dir
from casadrone.config.problem import ProblemConfig
from casadrone.config.track import MAX_SPEED_MPS
from casadrone.config.validation import SCHEMAS_BY_FOLDER, FileReport, check_config_file
from casadrone.numtext import fixed
from casadrone.trim import TRIM_SOLVERS
from casadrone.trim import trim as trim_fn

if TYPE_CHECKING:
    import numpy as np

#: The trim conditions, from their one registry (:mod:`casadrone.conditions`).
Condition = StrEnum("Condition", {name: name for name in CONDITIONS})  # type: ignore[misc]
HOVER = Condition("hover")


def _trim_solvers() -> list[str]:
    return list(TRIM_SOLVERS)


class LinMethod(StrEnum):
    exact = "exact"
    fd = "fd"
    both = "both"


def _by_position(names: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """Model names with a rotor number (T1…T4, delta1…delta4, omega1…omega4) shown by the rotor's
    position (``T FR``, ``d FR``, ``w FR``) for the console; other names as they are."""
    short = {"T": "T", "delta": "d", "omega": "w"}
    out = []
    for n in names:
        stem, digit = n.rstrip("1234"), n[len(n.rstrip("1234")):]
        ok = stem in short and len(digit) == 1
        out.append(f"{short[stem]} {ROTOR_LABELS[int(digit) - 1]}" if ok else n)
    return tuple(out)


def _matrix_text(M: np.ndarray, rows: tuple[str, ...], cols: tuple[str, ...]) -> str:
    width = 10
    head = " " * 8 + "".join(f"{c:>{width}}" for c in cols)
    body = [
        f"{r:>8}" + "".join(fixed(float(v), f">{width}.4g") for v in row)
        for r, row in zip(rows, M, strict=True)
    ]
    return "\n".join([head, *body])


# --------------------------------------------------------------------------------------------
# validate
# --------------------------------------------------------------------------------------------


def _yaml_files(paths: list[Path]) -> list[Path]:
    """The files given, with a folder expanded to every YAML below it (sorted), and a bare name
    that is no file here taken as the shipped config of that name (``SY250``, ``quick``) or the
    shipped folder (``configs``, ``problems``)."""
    out: list[Path] = []
    for p in paths:
        if not p.exists() and str(p) in ("configs", "problems"):
            p = DATA_DIR / p
        if p.is_dir():
            out += sorted(f for f in p.rglob("*") if f.suffix in (".yaml", ".yml"))
        elif not p.exists() and len(p.parts) == 1 and p.suffix in ("", ".yaml", ".yml"):
            shipped = [kind_dir(k) / f"{p.stem}.yaml" for k in SCHEMAS_BY_FOLDER]
            out.append(next((f for f in shipped if f.is_file()), p))
        else:
            out.append(p)
    return out


@app.command()
@reports_config_errors
def validate(
    files: Annotated[list[Path], typer.Argument(
        help="config YAML files or folders of them; a shipped name (SY250, quick), or configs "
        "and problems for every shipped file; after one file, key=value overrides (validate "
        "SY250 izz_kgm2=0.0045)")],
    as_json: JsonOpt = False,
) -> None:
    """Validate config files: exit 0 when all are valid, 2 otherwise (one line per problem).

    With ``key=value`` arguments after a single file, that file is validated with the overrides
    applied, as every other command applies them."""
    overrides = [str(p) for p in files if "=" in str(p) and not p.exists()]
    files = [p for p in files if str(p) not in overrides]
    if overrides and len(files) != 1:
        raise bad_input([f"validate: key=value overrides ({overrides[0]}) apply to one file; "
                         f"got {len(files)}"])
    report: list[FileReport] = []
    for path in _yaml_files(files):
        try:
            config = check_config_file(path, overrides)
            if isinstance(config, ProblemConfig):  # the optimiser's checks: import it only now
                from casadrone.optimise.checks import check_problem

                check_problem(config, path, overrides)
            report.append(FileReport(str(path), True))
        except ConfigError as exc:
            report.append(FileReport(str(path), False, tuple(exc.lines)))
    n_bad = sum(not r.valid for r in report)
    if as_json:
        print_json({"valid": n_bad == 0, "files": [r.as_dict() for r in report]})
    else:
        for r in report:
            if r.valid:
                typer.echo(f"{r.file}: ok")
            for line in r.problems:
                typer.echo(line, err=True)
        if n_bad:
            typer.echo(f"{n_bad} of {len(report)} file(s) invalid", err=True)
    if n_bad or not report:
        if not report:
            typer.echo("no YAML files found", err=True)
        raise typer.Exit(EXIT_BAD_INPUT)


# --------------------------------------------------------------------------------------------
# trim
# --------------------------------------------------------------------------------------------


@app.command()
@reports_config_errors
def trim(
    airframe: AirframeArg,
    overrides: OverridesArg = None,
    condition: Annotated[Condition, typer.Option(help="operating point")] = HOVER,
    speed: Annotated[
        float | None, typer.Option(help="speed along the flight path (m/s), required with "
                                   "forward, climb and turn")
    ] = None,
    climb_angle: Annotated[float | None, typer.Option(
        help="climb: angle of the path above the horizon (deg, negative: descent)")] = None,
    turn_rate: Annotated[float | None, typer.Option(
        help="turn: heading rate (deg/s, positive: left)")] = None,
    solver: Annotated[str, registry_option(
        _trim_solvers, "solver", "a trim solver of casadrone.trim.TRIM_SOLVERS (ipopt, "
        "nelder-mead, newton), or all to compare them", extra=("all",))] = "ipopt",
    as_json: JsonOpt = False,
) -> None:
    """Trim an airframe in hover, level forward flight, a climb or descent, or a coordinated
    turn; --solver all compares the solvers."""
    point = operating_point_options(condition.value, speed, climb_angle, turn_rate)
    cfg, frame = load_airframe_or_exit(airframe, overrides)
    # the module, not the package attribute: ``casadrone.trim`` is also the public function
    trim_mod = importlib.import_module("casadrone.trim")

    if solver == "all":
        points = trim_mod.trim_all(frame, condition.value, **point)
    else:
        points = [trim_mod.trim(frame, condition.value, solver=solver, **point)]
    result = {
        "airframe": frame.name,
        "condition": condition.value,
        **point,
        "mass_kg": frame.mass,
        "kappa_m": frame.kappa,
        "rotor_positions_m": frame.rotor_positions,
        "rotor_spins": frame.rotor_spins.astype(int),
        "results": [tp.as_dict() for tp in points],
    }
    if as_json:
        print_json(result)
    else:
        typer.echo(_trim_table(result))


#: The option of each operating-point parameter of :mod:`casadrone.conditions`.
_OPTION_OF = {"speed_mps": "--speed", "climb_angle_deg": "--climb-angle",
              "turn_rate_dps": "--turn-rate"}


def operating_point_options(condition: str, speed: float | None, climb_angle: float | None,
                            turn_rate: float | None) -> dict[str, Any]:
    """The keyword arguments of :func:`casadrone.trim.trim` for a condition's options; exit 2
    naming the option when one is missing, not finite, foreign to the condition or out of
    range."""
    given = {"speed_mps": speed, "climb_angle_deg": climb_angle, "turn_rate_dps": turn_rate}
    wanted = CONDITION_REGISTRY[condition].parameters
    for key, value in given.items():
        option = _OPTION_OF[key]
        if value is not None and not math.isfinite(value):
            raise bad_input([f"{option}: must be a finite number (got {value})"])
        if key not in wanted and value not in (None, 0.0):
            hint = "; use --condition forward" if key == "speed_mps" else ""
            raise bad_input([f"{option}: {condition} has no {option[2:]} (got {value:g}){hint}"])
        if key in wanted and value is None:
            raise bad_input([f"{option}: required with --condition {condition}"])

    point = {key: float(given[key] or 0.0) for key in wanted}
    v = point.get("speed_mps", 0.0)
    moving = condition == "forward"  # level flight at no speed is hover; a turn on the spot is not
    if not (0.0 < v if moving else 0.0 <= v) or v > MAX_SPEED_MPS:  # the tracks' (Mach 0.3)
        what = "forward flight needs 0 <" if moving else f"{condition} needs 0 <="
        raise bad_input([f"--speed: {what} speed <= {MAX_SPEED_MPS:g} m/s (got {v:g})"])
    try:  # the physical ranges, one place for every consumer (casadrone.conditions)
        OperatingPoint(condition, **point)
    except ValueError as exc:
        key = next((k for k in _OPTION_OF if str(exc).startswith(k)), "")
        message = str(exc).removeprefix(key).removeprefix(": ").removeprefix(" ")
        raise bad_input([f"{_OPTION_OF.get(key, '--' + condition)}: {message}"]) from None
    return point


def _trim_table(r: dict) -> str:
    import numpy as np

    pos = np.asarray(r["rotor_positions_m"]) * 1000
    rotors = zip(ROTOR_LABELS, pos, strict=True)
    order = " ".join(ROTOR_LABELS)
    lines = [
        f"{r['airframe']}: {r['condition']}"
        + (f" at {r['speed_mps']:g} m/s" if "speed_mps" in r else "")
        + (f", climb angle {r['climb_angle_deg']:g} deg" if "climb_angle_deg" in r else "")
        + (f", turn rate {r['turn_rate_dps']:g} deg/s" if "turn_rate_dps" in r else "")
        + f", mass {r['mass_kg']:.3f} kg, kappa {r['kappa_m']:.4f} m",
        "rotors (mm, body x fwd, y left): "
        + "  ".join(f"{n}({x:.1f}, {y:.1f})" for n, (x, y, _) in rotors),
        "",
        f"{'solver':<12}{'ok':<4}{'residual':>11}{'iter':>7}{'CPU (ms)':>10}  {'phi (deg)':>9}  "
        f"{'theta (deg)':>11}  {'u0 (' + order + ')':<31}{'T (N, ' + order + ')':<27}"
        f"{'max|du0|':>9}",
    ]
    ok = [res for res in r["results"] if res["success"]]
    ref = np.asarray(ok[0]["u0"]) if ok else None
    for res in r["results"]:
        u0 = np.asarray(res["u0"])
        agree = f"{np.max(np.abs(u0 - ref)):9.1e}" if ref is not None else f"{'-':>9}"
        lines.append(
            f"{res['solver']:<12}{'yes' if res['success'] else 'NO':<4}"
            f"{res['residual_norm']:>11.2e}{res['iterations']:>7d}"
            f"{fixed(1000 * res['cpu_time_s'], '>10.2f')}  "
            f"{fixed(math.degrees(res['x0']['phi']), '>9.4f')}  "
            f"{fixed(math.degrees(res['x0']['theta']), '>11.4f')}  "
            + " ".join(fixed(v, "7.5f") for v in u0) + "  "
            + " ".join(fixed(v, "6.4f") for v in res["thrusts_N"]) + f"{agree}"
        )
    setup = ", ".join(f"{res['solver']} {fixed(1000 * res['setup_cpu_s'], '.0f')} ms"
                      for res in r["results"])
    lines += ["CPU (ms): CPU time of the solve alone; the one-off set-up (building the solver, "
              "importing scipy) apart:", f"  {setup}"]
    if ref is not None and len(r["results"]) > 1:
        lines.append(f"max|du0|: largest command difference from {ok[0]['solver']} "
                     "(the first solver that succeeded)")
    for res in r["results"]:
        lines.append(f"{res['solver']}: {res['message']}")
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# linearise
# --------------------------------------------------------------------------------------------


@app.command()
@reports_config_errors
def linearise(
    airframe: AirframeArg,
    overrides: OverridesArg = None,
    method: Annotated[
        LinMethod, typer.Option(help="exact (AD), fd (finite differences) or both, compared")
    ] = LinMethod.exact,
    condition: Annotated[Condition, typer.Option(help="operating point")] = HOVER,
    speed: Annotated[float | None, typer.Option(help="speed along the path (m/s)")] = None,
    climb_angle: Annotated[float | None, typer.Option(help="climb angle (deg)")] = None,
    turn_rate: Annotated[float | None, typer.Option(help="turn rate (deg/s)")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Linearise about the (ipopt) trim point: E, A′, B′ and A, B with state and input names."""
    point = operating_point_options(condition.value, speed, climb_angle, turn_rate)
    cfg, frame = load_airframe_or_exit(airframe, overrides)
    lin_mod = importlib.import_module("casadrone.linearise")  # the module, as in trim

    tp = trim_fn(frame, condition.value, solver="ipopt", **point)
    if not tp.success:
        raise bad_input([f"{cfg.name}: trim: {tp.message}"])
    first = "fd" if method is LinMethod.fd else "exact"
    lm = lin_mod.linearise(frame, tp, first)
    result = {"airframe": frame.name, "condition": condition.value, **lm.as_dict(),
              "method": method.value}
    if method is LinMethod.both:
        result |= lin_mod.compare(lm, lin_mod.linearise(frame, tp, "fd")).as_dict()
    if as_json:
        print_json(result)
        return
    names, inputs = _by_position(lm.state_names), _by_position(lm.input_names)
    typer.echo(f"{frame.name}: {condition.value} linearisation ({first})")
    typer.echo("A =\n" + _matrix_text(lm.A, names, names))
    typer.echo("B =\n" + _matrix_text(lm.B, names, inputs))
    if method is LinMethod.both:
        typer.echo(
            f"exact vs fd: max|dA| = {result['max_abs_diff_A']:.3e}, "
            f"max|dB| = {result['max_abs_diff_B']:.3e}, max relative = {result['max_rel_diff']:.3e}"
        )


# --------------------------------------------------------------------------------------------
# lqr
# --------------------------------------------------------------------------------------------


#: The figures ``lqr --plot`` writes, checked before any work (:func:`check_plot_dir`).
LQR_FIGURES = ("eigenvalue-cloud", "disturbance-responses")


@app.command()
@reports_config_errors
def lqr(
    airframe: AirframeArg,
    overrides: OverridesArg = None,
    controller: ControllerOpt = None,
    ensemble: Annotated[
        int | None,
        typer.Option(min=1, max=10000, help="also apply the gain to N perturbed plants"),
    ] = None,
    as_json: JsonOpt = False,
    plot: PlotOpt = None,
) -> None:
    """Design the hover LQR-I gain and certify it (eigenvalues, Lyapunov P, optional ensemble).

    --plot DIR saves the robustness figures (paper Figs B1, B2): the closed-loop eigenvalue
    cloud and the hover disturbance responses of the nominal and perturbed plants. Without
    --ensemble they use the controller's robustness.n_plants perturbed plants.
    """
    check_plot_dir(plot, LQR_FIGURES)
    cfg, frame = load_airframe_or_exit(airframe, overrides)
    ctrl = load_controller(controller)
    from casadrone import control

    reference = None
    if ctrl.frozen_gain:
        _, reference = load_airframe_or_exit(str(ctrl.reference_airframe), None)
    design = control.design_for(frame, ctrl, reference)
    result = {"airframe": frame.name, "controller": ctrl.name,
              "gain_policy": ctrl.gain_policy, **design.as_dict()}
    ens = None
    if ensemble is not None or plot is not None:
        ens = control.robustness_ensemble(frame, design, ctrl, ensemble)
        result |= {f"ensemble_{k}": v for k, v in ens.as_dict().items()}
    if plot is not None:
        from casadrone import plots

        result["figures"] = save_figures({
            "eigenvalue-cloud": plots.eigenvalue_cloud(design, ens),
            "disturbance-responses": plots.disturbance_responses(design, ens),
        }, plot)
    if as_json:
        print_json(result)
        return
    typer.echo(
        f"{frame.name}: LQR-I ({ctrl.name}, {ctrl.gain_policy}, Ts = {design.sample_time_s:g} s)"
    )
    verdict = "stable" if design.stable else "UNSTABLE"
    typer.echo(f"closed loop {verdict}: spectral radius {result['spectral_radius']:.6f}, "
               f"Lyapunov min eig(P) {design.lyapunov_min_eig:.4g}")

    typer.echo("K (rows: the ESC command of each rotor) =\n"
               + _matrix_text(design.K, tuple(f"d {r}" for r in ROTOR_LABELS),
                              _by_position(design.state_names)))
    if ens is not None:
        typer.echo(f"ensemble: {result['ensemble_n_stable']} of {ens.n} perturbed plants stable, "
                   f"max spectral radius {ens.max_spectral_radius:.6f}")
    for path in result.get("figures", []):
        typer.echo(f"figure: {path}")
