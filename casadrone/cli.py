"""casadrone command line: a thin typer layer over the public API (DESIGN.md §10).

Every command that prints results also takes ``--json``. Bad input (a config problem, a bad
``key=value`` override, an unknown option) prints one ``FILE: key: message`` line per problem on
stderr and exits with code 2, without a traceback. Heavy modules (CasADi, the chain) are imported
inside the commands, so ``casadrone validate`` stays fast.
"""

from __future__ import annotations

import importlib
import json
import math
from enum import StrEnum
from functools import wraps
from pathlib import Path
from typing import Annotated, Any

import typer

from casadrone.config import ConfigError

app = typer.Typer(
    name="casadrone",
    help="Racing-drone airframe optimisation: validate configs, trim, linearise, design LQR-I, "
    "fly a lap, benchmark, optimise (run, resume), decide, compare and report.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

EXIT_BAD_INPUT = 2


class Condition(StrEnum):
    hover = "hover"
    forward = "forward"


class TrimSolver(StrEnum):
    ipopt = "ipopt"
    nelder_mead = "nelder-mead"
    newton = "newton"
    all = "all"


class LinMethod(StrEnum):
    exact = "exact"
    fd = "fd"
    both = "both"


class IntegratorName(StrEnum):
    rk4 = "rk4"
    cvodes = "cvodes"
    idas = "idas"


class BackendName(StrEnum):
    serial = "serial"
    processes = "processes"
    dask = "dask"


class DecideMethod(StrEnum):
    utopian = "utopian"
    compromise = "compromise"
    extreme = "extreme"


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
RunDirArg = Annotated[Path, typer.Argument(help="run directory (casadrone run --out DIR)")]
BackendOpt = Annotated[
    BackendName | None,
    typer.Option("--backend", help="evaluation backend (default: the problem's)"),
]
WorkersOpt = Annotated[
    int | None, typer.Option("-j", "--workers", min=1, help="worker processes")
]
SchedulerOpt = Annotated[
    str | None,
    typer.Option("--scheduler", help="Dask scheduler address (implies --backend dask)"),
]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="no progress lines")]
ReferenceOpt = Annotated[
    list[str] | None,
    typer.Option("--reference", help="reference airframe (name or YAML); repeat for several "
                 "[default: SY250]"),
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


def _matrix_text(M, rows: tuple[str, ...], cols: tuple[str, ...]) -> str:
    width = 10
    head = " " * 8 + "".join(f"{c:>{width}}" for c in cols)
    body = [
        f"{r:>8}" + "".join(f"{v:>{width}.4g}" for v in row)
        for r, row in zip(rows, M, strict=True)
    ]
    return "\n".join([head, *body])


# --------------------------------------------------------------------------------------------
# validate
# --------------------------------------------------------------------------------------------


def _yaml_files(paths: list[Path]) -> list[Path]:
    """The files given, with a folder expanded to every YAML below it (sorted)."""
    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            out += sorted(f for f in p.rglob("*") if f.suffix in (".yaml", ".yml"))
        else:
            out.append(p)
    return out


@app.command()
def validate(
    files: Annotated[list[Path], typer.Argument(help="config YAML files or folders of them")],
    as_json: JsonOpt = False,
) -> None:
    """Validate config files: exit 0 when all are valid, 2 otherwise (one line per problem)."""
    from casadrone.config import validate_file

    report = []
    for path in _yaml_files(files):
        try:
            validate_file(path)
            report.append({"file": str(path), "valid": True, "problems": []})
        except ConfigError as exc:
            report.append({"file": str(path), "valid": False, "problems": exc.lines})
    n_bad = sum(not r["valid"] for r in report)
    if as_json:
        print_json({"valid": n_bad == 0, "files": report})
    else:
        for r in report:
            if r["valid"]:
                typer.echo(f"{r['file']}: ok")
            for line in r["problems"]:
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
    condition: Annotated[Condition, typer.Option(help="operating point")] = Condition.hover,
    speed: Annotated[
        float | None, typer.Option(help="forward speed (m/s), required with forward")
    ] = None,
    solver: Annotated[
        TrimSolver, typer.Option(help="trim solver, or all to compare them")
    ] = TrimSolver.ipopt,
    as_json: JsonOpt = False,
) -> None:
    """Trim an airframe in hover or level forward flight; --solver all compares the solvers."""
    speed_mps = _check_speed(condition.value, speed)
    cfg, frame = load_airframe_or_exit(airframe, overrides)
    # the module, not the package attribute: ``casadrone.trim`` is also the public function
    trim_mod = importlib.import_module("casadrone.trim")

    if solver is TrimSolver.all:
        points = trim_mod.trim_all(frame, condition.value, speed_mps)
    else:
        points = [trim_mod.trim(frame, condition.value, speed_mps, solver.value)]
    result = {
        "airframe": frame.name,
        "condition": condition.value,
        "speed_mps": speed_mps,
        "mass_kg": frame.mass,
        "kappa_m": frame.kappa,
        "rotor_positions_m": frame.rotor_positions,
        "rotor_spins": frame.rotor_spins.astype(int),
        "results": [_trim_result(tp) for tp in points],
    }
    if as_json:
        print_json(result)
    else:
        typer.echo(_trim_table(result))


def _check_speed(condition: str, speed: float | None) -> float:
    if speed is not None and not math.isfinite(speed):
        raise bad_input([f"--speed: must be a finite number (got {speed})"])
    if condition == "hover":
        if speed not in (None, 0.0):
            raise bad_input([f"--speed: hover has no speed (got {speed}); use --condition forward"])
        return 0.0
    if speed is None:
        raise bad_input(["--speed: required with --condition forward (m/s)"])
    return float(speed)


def _trim_result(tp) -> dict:
    return {
        "solver": tp.solver,
        "success": tp.success,
        "residual_norm": tp.residual_norm,
        "iterations": tp.iterations,
        "wall_time_s": tp.wall_time_s,
        "message": tp.message,
        "x0": dict(zip(tp.state_names, (float(v) for v in tp.x0), strict=True)),
        "u0": tp.u0,
        "thrusts_N": tp.thrusts,
    }


def _trim_table(r: dict) -> str:
    import numpy as np

    pos = np.asarray(r["rotor_positions_m"]) * 1000
    rotors = zip(("FR", "FL", "RL", "RR"), pos, strict=True)
    lines = [
        f"{r['airframe']}: {r['condition']}"
        + (f" at {r['speed_mps']:g} m/s" if r["condition"] == "forward" else "")
        + f", mass {r['mass_kg']:.3f} kg, kappa {r['kappa_m']:.4f} m",
        "rotors (mm, body x fwd, y left): "
        + "  ".join(f"{n}({x:.1f}, {y:.1f})" for n, (x, y, _) in rotors),
        "",
        f"{'solver':<12}{'ok':<4}{'residual':>11}{'iter':>7}{'time (s)':>10}  "
        f"{'theta (deg)':>11}  {'u0 (delta1..4)':<31}{'T (N)':<27}{'max|du0|':>9}",
    ]
    ok = [res for res in r["results"] if res["success"]]
    ref = np.asarray(ok[0]["u0"]) if ok else None
    for res in r["results"]:
        u0 = np.asarray(res["u0"])
        agree = f"{np.max(np.abs(u0 - ref)):9.1e}" if ref is not None else f"{'-':>9}"
        lines.append(
            f"{res['solver']:<12}{'yes' if res['success'] else 'NO':<4}"
            f"{res['residual_norm']:>11.2e}{res['iterations']:>7d}{res['wall_time_s']:>10.4f}  "
            f"{math.degrees(res['x0']['theta']):>11.4f}  "
            + " ".join(f"{v:7.5f}" for v in u0) + "  "
            + " ".join(f"{v:6.4f}" for v in res["thrusts_N"]) + f"{agree}"
        )
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
    condition: Annotated[Condition, typer.Option(help="operating point")] = Condition.hover,
    speed: Annotated[float | None, typer.Option(help="forward speed (m/s)")] = None,
    as_json: JsonOpt = False,
) -> None:
    """Linearise about the (ipopt) trim point: E, A′, B′ and A, B with state and input names."""
    speed_mps = _check_speed(condition.value, speed)
    cfg, frame = load_airframe_or_exit(airframe, overrides)
    lin_mod = importlib.import_module("casadrone.linearise")  # the module, as in trim
    from casadrone.trim import trim as trim_fn

    tp = trim_fn(frame, condition.value, speed_mps, "ipopt")
    if not tp.success:
        raise bad_input([f"{cfg.name}: trim: {tp.message}"])
    first = "fd" if method is LinMethod.fd else "exact"
    lm = lin_mod.linearise(frame, tp, first)
    result = {
        "airframe": frame.name,
        "condition": condition.value,
        "method": method.value,
        "state_names": list(lm.state_names),
        "input_names": list(lm.input_names),
        "x0": lm.x0,
        "u0": lm.u0,
        "E": lm.E,
        "A_prime": lm.A_prime,
        "B_prime": lm.B_prime,
        "A": lm.A,
        "B": lm.B,
    }
    if method is LinMethod.both:
        cmp = lin_mod.compare(lm, lin_mod.linearise(frame, tp, "fd"))
        result |= {
            "max_abs_diff_A": cmp.max_abs_diff_A,
            "max_abs_diff_B": cmp.max_abs_diff_B,
            "max_rel_diff": cmp.max_rel_diff,
        }
    if as_json:
        print_json(result)
        return
    names, inputs = tuple(lm.state_names), tuple(lm.input_names)
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


@app.command()
@reports_config_errors
def lqr(
    airframe: AirframeArg,
    overrides: OverridesArg = None,
    controller: Annotated[
        str | None,
        typer.Option(help="controller YAML or name (default: configs/controllers/default.yaml)"),
    ] = None,
    ensemble: Annotated[
        int | None, typer.Option(min=1, help="also apply the gain to N perturbed plants")
    ] = None,
    as_json: JsonOpt = False,
    plot: PlotOpt = None,
) -> None:
    """Design the hover LQR-I gain and certify it (eigenvalues, Lyapunov P, optional ensemble).

    --plot DIR saves the robustness figures (paper Figs B1, B2): the closed-loop eigenvalue
    cloud and the hover disturbance responses of the nominal and perturbed plants. Without
    --ensemble they use the controller's robustness.n_plants perturbed plants.
    """
    import numpy as np

    from casadrone.config import load_controller

    check_plot_dir(plot)
    cfg, frame = load_airframe_or_exit(airframe, overrides)
    ctrl = load_controller(controller)
    from casadrone import control

    reference = None
    if ctrl.gain_policy == "frozen":
        _, reference = load_airframe_or_exit(str(ctrl.reference_airframe), None)
    design = control.design_for(frame, ctrl, reference)
    eig = np.asarray(design.closed_loop_eigenvalues)
    result = {
        "airframe": frame.name,
        "controller": ctrl.name,
        "gain_policy": ctrl.gain_policy,
        "sample_time_s": design.sample_time_s,
        "state_names": list(design.state_names),
        "K": design.K,
        "closed_loop_eigenvalues": [[float(e.real), float(e.imag)] for e in eig],
        "spectral_radius": float(np.max(np.abs(eig))),
        "stable": design.stable,
        "lyapunov_min_eig": design.lyapunov_min_eig,
    }
    ens = None
    if ensemble is not None or plot is not None:
        ens = control.robustness_ensemble(frame, design, ctrl, ensemble)
        result |= {
            "ensemble_n": ens.n,
            "ensemble_stable": ens.stable,
            "ensemble_n_stable": int(np.sum(ens.stable_each)),
            "ensemble_max_spectral_radius": ens.max_spectral_radius,
        }
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
    typer.echo("K (rows delta1..4) =\n" + _matrix_text(design.K, ("d1", "d2", "d3", "d4"),
                                                    tuple(design.state_names)))
    if ens is not None:
        typer.echo(f"ensemble: {result['ensemble_n_stable']} of {ens.n} perturbed plants stable, "
                   f"max spectral radius {ens.max_spectral_radius:.6f}")
    for path in result.get("figures", []):
        typer.echo(f"figure: {path}")


# --------------------------------------------------------------------------------------------
# simulate
# --------------------------------------------------------------------------------------------

INTERVAL_KEYS = ("waypoint", "split_time_s", "effort_V", "pair_thrust_max_N", "pair_thrust_min_N")


@app.command()
@reports_config_errors
def simulate(
    airframe: AirframeArg,
    overrides: OverridesArg = None,
    track: Annotated[
        str | None,
        typer.Option(help="track YAML or name (default: configs/tracks/paper-rectangle.yaml)"),
    ] = None,
    controller: Annotated[
        str | None,
        typer.Option(help="controller YAML or name (default: configs/controllers/default.yaml)"),
    ] = None,
    integrator: Annotated[
        IntegratorName, typer.Option(help="rk4 (fast, compiled) or cvodes/idas (reference)")
    ] = IntegratorName.rk4,
    as_json: JsonOpt = False,
    plot: PlotOpt = None,
) -> None:
    """Fly one lap through the whole chain (trim, LQR-I, closed loop) and print its indices.

    A lap that fails (the airframe too heavy to follow the track, diverged, timed out) is a
    result, not an error: status "failed" with its stage and reason, exit code 0. An airframe
    the config check rejects is bad input, exit code 2: e.g. SY250 with mass_kg=4 cannot hover
    at all (its weight is above the full thrust of the four rotors), while mass_kg=3 hovers but
    fails the lap (attitude beyond the track's limit).

    --plot DIR saves the track top view, the 3-D track and the time histories (PNG and SVG).
    """
    check_plot_dir(plot)
    cfg, _ = load_airframe_or_exit(airframe, overrides)
    from casadrone.config import load, load_controller, resolve_config
    from casadrone.evaluate import DEFAULT_TRACK, EvaluationSetup, evaluate, theta_of
    from casadrone.guidance import TrackConfig
    from casadrone.indices import INDICES

    setup = EvaluationSetup(
        template=cfg,
        controller=load_controller(controller),
        track=load(TrackConfig, resolve_config(track, "tracks") if track else DEFAULT_TRACK),
        integrator=integrator.value,
    )
    ev = evaluate(theta_of(cfg), setup, keep_trajectory=True)
    result = {
        "airframe": cfg.name,
        "track": setup.track.name,
        "controller": setup.controller.name,
        "integrator": integrator.value,
        "status": ev.status,
        "stage": ev.stage,
        "reason": ev.reason,
        "indices": ev.indices,
        "index_units": {k: INDICES[k].unit for k in ev.indices},
        "intervals": [{k: getattr(i, k) for k in INTERVAL_KEYS} for i in ev.intervals],
        "wall_time_s": ev.wall_time_s,
    }
    if plot is not None:
        if ev.trajectory is None:
            typer.echo(f"--plot: nothing to plot, the evaluation failed before the lap "
                       f"({ev.stage})", err=True)
        else:
            from casadrone import plots

            flights = {cfg.name: ev.trajectory}
            result["figures"] = save_figures({
                "track-top-view": plots.track_top_view(flights),
                "track-3d": plots.trajectory_3d(flights),
                "time-histories": plots.time_histories(flights),
            }, plot)
    if as_json:
        print_json(result)
        return
    typer.echo(_simulate_text(result))


def _simulate_text(r: dict) -> str:
    from casadrone.indices import INDICES

    head = f"{r['airframe']}: track {r['track']}, controller {r['controller']}, {r['integrator']}"
    if r["status"] != "completed":
        lines = [f"{head}: lap FAILED at {r['stage']}: {r['reason']} "
                 f"({r['wall_time_s']:.2f} s)"]
    else:
        lines = [f"{head}: lap completed in {r['indices'].get('J3', math.nan):.3f} s "
                 f"({r['wall_time_s']:.2f} s wall time)"]
        for name, value in r["indices"].items():
            index = INDICES[name]
            lines.append(f"  {name:<4}{value:>10.4f} {index.unit:<5} {index.description}")
        lines.append(f"  {'interval':>8}{'split time (s)':>16}{'effort (V)':>12}"
                     f"{'pair thrust max/min (N)':>26}")
        for i in r["intervals"]:
            lines.append(f"  {i['waypoint']:>8}{i['split_time_s']:>16.3f}{i['effort_V']:>12.4f}"
                         f"{i['pair_thrust_max_N']:>15.3f} / {i['pair_thrust_min_N']:<8.3f}")
    lines += [f"figure: {p}" for p in r.get("figures", [])]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# benchmark
# --------------------------------------------------------------------------------------------


@app.command()
@reports_config_errors
def benchmark(
    integrator: Annotated[
        IntegratorName, typer.Option(help="rk4 (fast, compiled) or cvodes/idas (reference)")
    ] = IntegratorName.rk4,
    as_json: JsonOpt = False,
) -> None:
    """Fly the five reference airframes (paper Table 4): the Table-4-style table.

    Per airframe and interval, the simulated split time, roll effort and opposing-pair thrust
    beside the values the paper measured (a different time base: compare trends).
    """
    from casadrone.benchmark import format_table, run_benchmark, to_json

    table = run_benchmark(integrator.value)
    if as_json:
        typer.echo(to_json(table))
    else:
        typer.echo(format_table(table), nl=False)


# --------------------------------------------------------------------------------------------
# run, resume
# --------------------------------------------------------------------------------------------


def backend_config(base, name: BackendName | None, workers: int | None,
                   scheduler: str | None):
    """The problem's backend section with the command-line choices applied (validated)."""
    from casadrone.config import BackendConfig, validate_data

    if scheduler is not None:
        if name not in (None, BackendName.dask):
            raise bad_input([f"--scheduler: only with --backend dask (got --backend {name})"])
        name = BackendName.dask
    data = base.model_dump()
    if name is not None:
        data["name"] = name.value
        if name is not BackendName.dask:
            data["scheduler"] = None
        if name is BackendName.serial:
            data["workers"] = 1
    if workers is not None:
        data["workers"] = workers
    if scheduler is not None:
        data["scheduler"] = scheduler
    cfg = validate_data(BackendConfig, data, "--backend", Path.cwd())
    if cfg.name == "serial" and workers not in (None, 1):
        typer.echo(f"-j {workers}: ignored by the serial backend (use --backend processes)",
                   err=True)
    return cfg


def require_run_dir(run_dir: Path) -> None:
    """Exit 2 unless ``run_dir`` is a run directory (it has config.yaml and manifest.json)."""
    from casadrone.optimise.store import CONFIG, MANIFEST

    if not run_dir.exists():
        raise bad_input([f"{run_dir}: no such run directory"])
    if not run_dir.is_dir():
        raise bad_input([f"{run_dir}: not a directory"])
    missing = [f for f in (CONFIG, MANIFEST) if not (run_dir / f).is_file()]
    if missing:
        raise bad_input([f"{run_dir}: not a run directory (no {', '.join(missing)})"])


def open_problem(run_dir: Path):
    """The resolved problem of a run directory; an unreadable config.yaml is bad input."""
    from casadrone.optimise.store import CONFIG, RunStore

    try:
        return RunStore(run_dir).problem()
    except Exception as exc:  # noqa: BLE001 (yaml or pydantic: a damaged run directory)
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise bad_input([f"{run_dir / CONFIG}: not a valid resolved problem: {first}"]) from None


def run_summary(run_dir: Path) -> list[str]:
    """The run directory and a short summary of its front (from pareto.csv)."""
    from casadrone.indices import INDICES
    from casadrone.optimise.problem import Study
    from casadrone.optimise.store import RunStore

    store = RunStore(run_dir)
    m = store.manifest
    study = Study(store.problem())
    header, rows = store.read_pareto()
    n_var = len(header) - len(study.objective_names)
    lines = [f"run directory: {run_dir}",
             f"Pareto front: {len(rows)} design(s) from {m.get('n_evaluations')} evaluations "
             f"(pareto.csv)"]
    if not rows:
        lines.append("  no feasible design: every evaluation failed or broke a constraint "
                     "(see history.sqlite)")
        return lines
    for j, (name, sense) in enumerate(zip(study.objective_names, study.senses, strict=True)):
        col = [r[n_var + j] for r in rows]
        best = max(col) if sense == "max" else min(col)
        unit = INDICES[name].unit if name in INDICES else ""
        lines.append(f"  {name:<4} ({sense}) {min(col):>10.4g} … {max(col):<10.4g} {unit:<5} "
                     f"best {best:.6g}")
    lines.append(f"choose designs with: casadrone decide {run_dir}")
    return lines


def _failure_summary(run_dir: Path) -> list[str]:
    from collections import Counter

    from casadrone.optimise.store import RunStore

    hist = RunStore(run_dir).history()
    failed = [r for r in hist if r["status"] != "completed"]
    stages = Counter(r["stage"] for r in failed)
    lines = [f"{len(hist) - len(failed)} of {len(hist)} evaluations completed"]
    for stage, n in stages.most_common():
        example = next(r["reason"] for r in failed if r["stage"] == stage)
        lines.append(f"  {n:>6} failed at {stage}, e.g. {example}")
    return lines


@app.command("run")
@reports_config_errors
def run_command(
    problem: Annotated[Path, typer.Argument(help="problem YAML (problems/*.yaml)")],
    overrides: Annotated[
        list[str] | None,
        typer.Argument(help="dotted problem overrides, e.g. algorithm.generations=20 "
                       "objectives.0.index=J3"),
    ] = None,
    out: Annotated[Path, typer.Option("--out", "-o", help="new run directory")] = ...,
    backend: BackendOpt = None,
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
    quiet: QuietOpt = False,
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="also print the set-up and the failures")
    ] = False,
) -> None:
    """Optimise: run a problem into a new run directory.

    Progress is one line per generation on stderr (with a bar on a terminal); at the end the run
    directory and a short summary of the Pareto front go to stdout. A killed run continues with
    'casadrone resume DIR' and ends exactly as an uninterrupted one.
    """
    from casadrone.config import load_problem
    from casadrone.optimise import runner
    from casadrone.optimise.store import MANIFEST, RunInProgress

    if quiet and verbose:
        raise bad_input(["--quiet and --verbose: choose one"])
    cfg = load_problem(problem, overrides or [])
    be = backend_config(cfg.backend, backend, workers, scheduler)
    if out.exists() and not out.is_dir():
        raise bad_input([f"--out: {out}: exists and is not a directory"])
    if (out / MANIFEST).exists():
        raise bad_input([f"--out: {out}: already holds a run; resume it with "
                         f"'casadrone resume {out}' or choose another --out"])
    if verbose:
        a = cfg.algorithm
        objectives = ", ".join(f"{o.index} ({o.sense or 'default'})" for o in cfg.objectives)
        typer.echo(f"problem {cfg.name}: {len(cfg.variables)} variables, objectives {objectives}; "
                   f"{a.name}, population {a.population}, {a.generations} generations, seed "
                   f"{cfg.seed}; backend {be.name} ({be.workers} worker(s)"
                   f"{', scheduler ' + be.scheduler if be.scheduler else ''}) -> {out}", err=True)
    try:
        runner.run(cfg, out, be, quiet=quiet)
    except RunInProgress as exc:
        raise bad_input([str(exc)]) from None
    except OSError as exc:
        typer.echo(f"{out}: the run stopped: {exc}", err=True)
        raise typer.Exit(1) from None
    if verbose:
        for line in _failure_summary(out):
            typer.echo(line, err=True)
    typer.echo("\n".join(run_summary(out)))


@app.command()
@reports_config_errors
def resume(
    run_dir: RunDirArg,
    backend: BackendOpt = None,
    workers: WorkersOpt = None,
    scheduler: SchedulerOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """Continue a killed run from its last checkpoint (same end as an uninterrupted run).

    A run that has already finished is reported as complete (exit code 0): resuming is
    idempotent, so scripts may call it unconditionally.
    """
    from casadrone.optimise import runner
    from casadrone.optimise.store import CHECKPOINT, PARETO, RunInProgress, RunStore

    require_run_dir(run_dir)
    problem = open_problem(run_dir)
    manifest = RunStore(run_dir).manifest
    if manifest.get("status") == "completed" and (run_dir / PARETO).is_file():
        typer.echo(f"{run_dir}: the run is already complete (finished {manifest.get('finished')}); "
                   "nothing to resume")
        typer.echo("\n".join(run_summary(run_dir)))
        return
    if not (run_dir / CHECKPOINT).is_file():
        raise bad_input([f"{run_dir}: no {CHECKPOINT}: killed before its first generation was "
                         "stored; start it again with 'casadrone run' into a new --out"])
    be = backend_config(problem.backend, backend, workers, scheduler)
    try:
        runner.resume(run_dir, be, quiet=quiet)
    except RunInProgress as exc:
        raise bad_input([str(exc)]) from None
    except OSError as exc:
        typer.echo(f"{run_dir}: the run stopped: {exc}", err=True)
        raise typer.Exit(1) from None
    typer.echo("\n".join(run_summary(run_dir)))


# --------------------------------------------------------------------------------------------
# decide, compare, report
# --------------------------------------------------------------------------------------------


def run_error(run_dir: Path, exc: Exception) -> typer.Exit:
    """A run-directory problem (not finished, empty front, unknown objective) as bad input."""
    text = str(exc)
    return bad_input([text if text.startswith(str(run_dir)) else f"{run_dir}: {text}"])


@app.command("decide")
@reports_config_errors
def decide_command(
    run_dir: RunDirArg,
    method: Annotated[
        DecideMethod | None,
        typer.Option(help="one method (default: all three, A utopian, B compromise, C extreme)"),
    ] = None,
    objective: Annotated[
        str | None,
        typer.Option(help="objective of the extreme decision (default: the problem's first)"),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Choose designs on a finished run's front: A utopian, B compromise, C extreme.

    Reads pareto.csv and the problem's objective senses. A is the design closest to the utopian
    point, B the one closest to the front's mean point, C the best on --objective (default the
    problem's first objective), all in normalised objective space.
    """
    from dataclasses import asdict

    from casadrone.compare import run_candidates

    require_run_dir(run_dir)
    open_problem(run_dir)
    try:
        candidates = run_candidates(run_dir, (method.value,) if method else None, objective)
    except (FileNotFoundError, ValueError) as exc:
        raise run_error(run_dir, exc) from None
    if as_json:
        print_json([{"candidate": c.label, "method": c.method, "row": c.row,
                     "distance": c.distance, "objective": c.objective, "theta": c.theta,
                     "objectives": c.objectives} for c in candidates])
        return
    from casadrone.indices import INDICES

    for c in map(asdict, candidates):
        on = f" on {c['objective']}" if c["objective"] else ""
        typer.echo(f"{c['label']} {c['method']}{on}: pareto.csv row {c['row']}, distance "
                   f"{c['distance']:.4f} (normalised objective space)")
        typer.echo("    theta: " + ", ".join(f"{k}={v:.6g}" for k, v in c["theta"].items()))
        typer.echo("    objectives: " + ", ".join(
            f"{k}={v:.6g}" + (f" {INDICES[k].unit}" if k in INDICES else "")
            for k, v in c["objectives"].items()))


@app.command()
@reports_config_errors
def compare(
    run_dir: RunDirArg,
    reference: ReferenceOpt = None,
    objective: Annotated[
        str | None,
        typer.Option(help="objective of the extreme candidate C (default: the problem's first)"),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """Benchmark-relative gains (paper Eq. 21, Tables 9-11) of the run's A/B/C candidates.

    Per candidate, reference airframe and interval: the % gain in split time, roll effort and
    opposing-pair thrust max/min, positive = better (faster, less effort, smaller extremes;
    effort and thrust by magnitude). basis "simulated": the reference flown on the run's track,
    controller and integrator; basis "measured": against the paper's Table 4 (different time
    base, orientation only).
    """
    from dataclasses import asdict

    from casadrone.compare import compare_run, format_gains

    require_run_dir(run_dir)
    open_problem(run_dir)
    try:
        rows = compare_run(run_dir, tuple(reference or ("SY250",)), objective)
    except (FileNotFoundError, ValueError) as exc:
        raise run_error(run_dir, exc) from None
    if as_json:
        print_json([asdict(r) for r in rows])
    else:
        typer.echo(format_gains(rows), nl=False)


@app.command()
@reports_config_errors
def report(
    run_dir: RunDirArg,
    reference: ReferenceOpt = None,
    out: Annotated[
        Path | None, typer.Option("--out", "-o", help="report file (default: DIR/report.html)")
    ] = None,
) -> None:
    """Write the HTML report of a run (front, candidates, gains over the references)."""
    require_run_dir(run_dir)
    open_problem(run_dir)
    try:
        from casadrone.report import write_report
    except ModuleNotFoundError as exc:
        if exc.name != "casadrone.report":
            raise
        typer.echo("report: casadrone.report is not available in this installation", err=True)
        raise typer.Exit(1) from None
    try:
        path = write_report(run_dir, references=tuple(reference or ("SY250",)), out=out)
    except (FileNotFoundError, ValueError) as exc:
        raise run_error(run_dir, exc) from None
    typer.echo(str(path))
