"""``casadrone limit-lap``: the time-optimal lap of one airframe (:mod:`casadrone.limit.lap`):
load (the airframe, the track and the limit lap's settings,
:class:`casadrone.config.limitlap.LimitLapConfig`) → solve → print."""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Annotated, Any

import typer

from casadrone.airframe import Airframe, build_airframe
from casadrone.cli.common import (
    AirframeArg,
    JsonOpt,
    PlotOpt,
    QuietOpt,
    TrackOpt,
    app,
    check_plot_dir,
    cost_text,
    print_json,
    progress_lines,
    registry_option,
    reports_config_errors,
    save_figures,
)
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.io import ConfigError, load, resolve_config
from casadrone.config.limitlap import LimitLapConfig, choices, lap_key, read_limit_lap
from casadrone.config.track import DEFAULT_TRACK, TrackConfig
from casadrone.limit.check import lap_propulsion
from casadrone.limit.lap import (
    DEFAULT_INTERVALS,
    LimitLap,
    LimitLapOptions,
    check_inputs,
    closed_loop_lap,
    frame_clearance_m,
    track_targets,
)
from casadrone.limit.race import race, race_text
from casadrone.limit.search import lap_options
from casadrone.limit.sensitivity import percent_of_range
from casadrone.model import param_names, rotor_states
from casadrone.pool import make_pool, pool_spec, usable_cores
from casadrone.propulsion import max_static_thrust

#: What the propulsion did (:func:`casadrone.limit.check.lap_propulsion`), added to ``--json``.
PROPULSION_KEYS = ("top_speed_m_s", "thrust_at_top_speed_n", "max_advance_ratio",
                   "data_advance_ratio", "beyond_data_share", "min_thrust_ratio")

#: The figures ``limit-lap --plot`` writes (:func:`casadrone.plots.limit_lap_figures` and the
#: thrust against airspeed), checked before any solve (:func:`check_plot_dir`).
LIMIT_FIGURES = ("limit-top-view", "limit-3d", "limit-time-histories", "limit-thrust-airspeed")

#: The limit lap's settings (:class:`LimitLapConfig`), each a ``key=value`` argument; the
#: options below are aliases of those (``--certify``: ``search=certify``).
LAP_KEYS = tuple(LimitLapConfig.model_fields)


def _about(key: str) -> str:
    """The help of a limit-lap key: its schema's description (one declaration of each), with
    its default where that does not say it."""
    field = LimitLapConfig.model_fields[key]
    text = str(field.description)
    return text if field.default is None or "default" in text else (
        f"{text}; default {field.default}")


def _bound(key: str, which: str) -> int:
    """A numeric key's bound (``ge`` or ``le``) as its schema states it."""
    return next(getattr(m, which) for m in LimitLapConfig.model_fields[key].metadata
                if getattr(m, which, None) is not None)


def _choice(key: str) -> Any:
    """``--KEY NAME``: one of the key's values (:func:`casadrone.config.limitlap.choices`),
    refused naming the option otherwise."""
    return registry_option(lambda: choices(key), key, _about(key))


def _number(key: str) -> Any:
    return typer.Option(min=_bound(key, "ge"), max=_bound(key, "le"), help=_about(key))


LapOverridesArg = Annotated[list[str] | None, typer.Argument(
    help="key=value overrides of the airframe (alpha_deg=75) and of the limit lap's settings: "
         f"{', '.join(LAP_KEYS)} (each also an option below, but starts: "
         "starts=\\[fine-grid,coarse-grid])")]


@dataclass(frozen=True)
class LapSetup:
    """What a limit lap is flown from: the airframe (its config and the built frame), the track
    (and its file) and the options."""

    config: AirframeConfig
    frame: Airframe
    track_path: Path
    track: TrackConfig
    options: LimitLapOptions
    search: str = "fast"  # the settings' search (casadrone.limit.search.SEARCHES)


@app.command("limit-lap")
@reports_config_errors
def limit_lap_command(
    airframe: AirframeArg,
    overrides: LapOverridesArg = None,
    track: TrackOpt = None,
    intervals: Annotated[int | None, _number("intervals")] = None,
    attitude: Annotated[str | None, _choice("attitude")] = None,
    tilt: Annotated[str | None, _choice("tilt")] = None,
    certify: Annotated[bool, typer.Option(
        "--certify", help="search=certify (without it, the fast path: two starts, no "
        "rounds): solve from every start and run grid rounds: whether they agree "
        "(certainty, spread) and how uncertain the sensitivities are over the optima "
        "found")] = False,
    solver: Annotated[str | None, _choice("solver")] = None,
    grid_rounds: Annotated[int | None, _number("grid_rounds")] = None,
    rotor_step: Annotated[str | None, _choice("rotor_step")] = None,
    substeps: Annotated[int | None, _number("substeps")] = None,
    resimulation: Annotated[str | None, _choice("resimulation")] = None,
    workers: Annotated[str | None, typer.Option(
        help="processes that solve the independent starts and grid rounds side by side: a "
        "number (default: this machine's cores with --certify, 1 on the fast path, whose two "
        "starts are unequal and whose CPU is the figure), or a Dask scheduler's address "
        "(tcp://host:port) to solve on its cluster; the lap is the same whatever it is")] = None,
    laps: Annotated[int | None, typer.Option(
        min=1, max=20, help="laps of the race, flown from the track's start (default: the "
        "track's laps); with a pack capacity (battery.capacity_ah) the state of charge is "
        "followed through it and a race the pack cannot fly is infeasible")] = None,
    as_json: JsonOpt = False,
    plot: PlotOpt = None,
    quiet: QuietOpt = False,
) -> None:
    """Fly the limit lap: the minimum-time lap of the airframe through the track's waypoints
    (or gates), with ESC commands in [0, 1], thrust lag and the track's tilt limit.

    By default one start (the fast path); --certify solves from every start with grid rounds.
    Prints the lap time, the point-mass reference (attitude dynamics removed; the best of a few
    local optima of that relaxation, not a bound), split and lap times, whether the starts
    agree (certainty), how each solve ended (optimal, acceptable, failed), the share of
    saturated commands, the re-simulation miss and dT/dθ per decision variable (ms per 1 % of
    its Table 1 range; with --certify, with its uncertainty over the optima found). A
    lap the solver cannot find (no convergence) is a result with status "failed" and a reason,
    exit code 0; a bad config (a malformed track, a frame too heavy to hover, a gate narrower
    than twice the frame's clearance) or a bad setting (solver=snopt) is bad input, exit
    code 2.

    Every setting of the limit lap is a key=value argument (solver=fatrop), the same keys as
    a problem file's limit_lap section; the options are their aliases.

    Progress (the set-up, each start and grid round with its lap, iterations and CPU, any
    compile) goes to stderr as it happens; -q silences it.

    --plot DIR saves the limit lap beside the closed-loop lap (top view, 3-D) and its speed and
    commands over time.
    """
    check_plot_dir(plot, LIMIT_FIGURES)
    given = {"search": "certify" if certify else None, "intervals": intervals,
             "attitude": attitude, "tilt": tilt, "solver": solver, "grid_rounds": grid_rounds,
             "rotor_step": rotor_step, "substeps": substeps, "resimulation": resimulation}
    setup = load_setup(airframe, overrides or [], track,
                       {k: v for k, v in given.items() if v is not None})
    if laps is not None:
        setup = replace(setup, track=setup.track.model_copy(update={"laps": laps}))
    n_workers, scheduler = _workers(workers, setup.search == "certify")
    with progress_lines("limit-lap", quiet):
        pool = make_pool(n_workers, scheduler)
        try:
            flown = race(setup.config, setup.track, setup.options, frame=setup.frame, pool=pool)
        finally:
            pool.close()
    result = lap_result(setup, flown.lap, plot)
    if flown.energy is not None:
        result["race"] = flown.as_dict()
    if not flown.feasible:
        result |= {"status": "failed", "reason": flown.reason}
    if as_json:
        print_json(result)
        return
    typer.echo("\n".join([_text(setup.config.name, setup.track.name, result,
                                setup.frame.propulsion), *race_text(flown)]))


def _workers(text: str | None, certify: bool) -> tuple[int, str | None]:
    """(processes, Dask scheduler address or None) of ``--workers`` (its default: this
    machine's cores with ``--certify``, else 1); ConfigError naming the option for a bad value
    or an address without the dask extra."""
    if text is None:
        return (usable_cores() if certify else 1), None
    try:
        n, scheduler = pool_spec(text)
    except ValueError as exc:
        raise ConfigError([f"--workers {exc}"]) from None
    if scheduler is not None and importlib.util.find_spec("distributed") is None:
        raise ConfigError([f"--workers {text}: a Dask scheduler needs the dask extra: pip "
                           "install 'casadrone[dask]'"])
    return n, scheduler


def load_setup(airframe: str, overrides: list[str], track: str | None,
               given: dict[str, Any]) -> LapSetup:
    """The limit lap's inputs: ``key=value`` overrides of the limit lap's keys (on the
    options ``given``) and of the airframe's, the track; ConfigError for bad input, and for a
    problem the limit lap cannot pose (:func:`casadrone.limit.problem.check_inputs`), found
    before any solve."""
    settings = read_limit_lap(given, [o for o in overrides if lap_key(o)])
    cfg = load_airframe(airframe, [o for o in overrides if not lap_key(o)])
    track_path = _track_path(track)
    trk = load(TrackConfig, track_path)
    frame = build_airframe(cfg)
    options = lap_options(settings, periodic=trk.end == "periodic")
    resolved = options if options.intervals is not None else replace(
        options, intervals=DEFAULT_INTERVALS.get(frame.propulsion, 40))  # as limit_lap does
    impossible = check_inputs(trk, resolved, frame_clearance_m(frame,
                                                               cfg.prop_diameter_mm / 1000))
    if impossible:  # known before any solve: bad input, not a failed lap
        raise ConfigError([f"{track_path}: {impossible} (refused before any solve)"])
    return LapSetup(cfg, frame, track_path, trk, options, settings.search)


def lap_result(setup: LapSetup, lap: LimitLap, plot: Path | None) -> dict[str, Any]:
    """The command's result: the lap's own (:meth:`LimitLap.as_dict`), what the propulsion
    did, dT/dp by parameter name, and the figures ``plot`` saved."""
    result = lap.as_dict()
    prop = lap_propulsion(setup.frame, lap.x_euler, lap.u)
    result |= {k: prop[k] for k in PROPULSION_KEYS}
    result["param_sensitivity"] = named_parameters(lap.param_sensitivity,
                                                   setup.frame.propulsion)
    if plot is not None:
        result["figures"] = _figures(setup, lap, plot, prop)
    return result


def named_parameters(values: Iterable[float], propulsion: str) -> dict[str, float]:
    """dT/dp keyed by the model's parameter names (s per SI unit of each): ``--json`` gave a
    bare list of 31 numbers (50 with ``propeller``) in an order only the code states
    (casadrone.model.param_names). Empty for a failed lap (no sensitivities)."""
    names = param_names(propulsion)
    floats = [float(v) for v in values]
    return dict(zip(names, floats, strict=True)) if len(floats) == len(names) else {}


def _track_path(track: str | None) -> Path:
    """The track file of ``--track`` (the paper's rectangle without one). An empty or blank
    name is refused (:func:`casadrone.config.io.resolve_config`) naming the option: it read as
    no ``--track`` at all and flew the default track for minutes (``--track ""`` from an unset
    shell variable)."""
    if track is None:
        return DEFAULT_TRACK
    try:
        return resolve_config(track, "tracks")
    except ConfigError as exc:
        raise ConfigError([f"--track {line}" for line in exc.lines]) from None


def _figures(setup: LapSetup, lap: LimitLap, folder: Path, prop: Any) -> list[str]:
    if not lap.completed:
        typer.echo("--plot: nothing to plot, the limit lap failed", err=True)
        return []
    from casadrone import plots  # only with --plot: it imports matplotlib

    frame, trk = setup.frame, setup.track
    traj = closed_loop_lap(frame, trk)
    targets = track_targets(trk, setup.options, frame_clearance_m(
        frame, setup.config.prop_diameter_mm / 1000))
    figures = plots.limit_lap_figures(lap, traj, trk.waypoints_m, targets)
    figures["limit-thrust-airspeed"] = plots.thrust_against_airspeed(
        prop, lap.u, max_static_thrust(frame), frame.propulsion)
    return save_figures(figures, folder)


def _rotor_text(r: dict) -> str:
    """The propeller figures of the text summary (none with ``paper``: no rotor speed)."""
    if not math.isfinite(r["max_advance_ratio"]):
        return ""
    data = (f" (propeller data to {r['data_advance_ratio']:.2f}, "
            f"{100 * r['beyond_data_share']:.1f} % of rotor-nodes beyond)"
            if math.isfinite(r["data_advance_ratio"]) else "")
    return (f"; lowest thrust / thrust without inflow {r['min_thrust_ratio']:.2f}; highest "
            f"advance ratio {r['max_advance_ratio']:.2f}{data}")


def _start_text(r: dict, propulsion: str = "paper") -> list[str]:
    """The start state flown (the optimised one with ``end: periodic``), Euler-model layout;
    every group with its unit (the rotor states' depends on ``propulsion``)."""
    x = r.get("start_state")
    if x is None or len(x) != 16:
        return []
    x = [float(v) for v in x]
    def vec(v: list[float], fmt: str) -> str:
        return "(" + ", ".join(format(c, fmt) for c in v) + ")"

    eul = [math.degrees(a) for a in x[9:12]]
    rotors = rotor_states(propulsion)
    return [f"  start state: position {vec(x[0:3], '.3f')} m, velocity {vec(x[3:6], '.3f')} m/s, "
            f"body rates {vec(x[6:9], '.3f')} rad/s, roll/pitch/yaw {vec(eul, '.2f')} deg, "
            f"{rotors.what} {vec(x[12:16], '.4g')} {rotors.unit}"]


def _reference_text(seconds: float, lap_s: float) -> str:
    """The point-mass reference, or why there is none: no start of that relaxation converged
    (it printed "nan s", which reads as a number gone wrong). A reference slower than the lap
    says so: the relaxation's global optimum cannot be, so it is a local one (SY250 on a 30 m
    straight: 1.192 s against a 0.996 s lap), and the figure is no bound."""
    if not math.isfinite(seconds):
        return "point-mass reference: none converged"
    if seconds > lap_s:
        return (f"point-mass reference {seconds:.3f} s, slower than the lap: a local optimum of "
                "the relaxation, no bound")
    return f"point-mass reference {seconds:.3f} s"


def _processes_cost(r: dict) -> str:
    """The limit lap's CPU and wall time, and on how many processes when more than one solved
    (the CPU is then theirs together: casadrone.limit.parallel)."""
    cost = cost_text(r["cpu_time_s"], r["wall_time_s"])
    n = r.get("workers", 1)
    return cost if n <= 1 else f"{cost} on {n} processes (CPU: all of them together)"


def _text(name: str, track: str, r: dict, propulsion: str = "paper") -> str:

    cost = cost_text(r["cpu_time_s"], r["wall_time_s"])
    if r["status"] != "completed":
        return f"{name} on {track}: limit lap FAILED: {r['reason']} ({cost})"
    splits = ", ".join(f"{t:.3f}" for t in r["split_times_s"])
    lines = [
        f"{name} on {track}: limit lap {r['lap_time_s']:.3f} s "
        f"({_reference_text(r['point_mass_reference_s'], r['lap_time_s'])}; "
        f"start {r['start']}, {r['certainty']})",
        f"  solve: the chosen start's took {r['iterations']} iterations; the whole limit lap "
        f"(every start, check and grid round) {_processes_cost(r)}",
        *_status_text(r),
        f"  split times (s): {splits}",
        f"  lap times (s): {', '.join(f'{t:.3f}' for t in r['lap_times_s'])}",
        f"  bang-bang fraction: {r['bang_bang_fraction']:.2f}; re-simulation miss: "
        f"{r['resimulation_miss_m']:.4f} m",
        f"  top speed {r['top_speed_m_s']:.1f} m/s" + _rotor_text(r),
        *_start_text(r, propulsion),
        *_sensitivity_text(r),
    ]
    lines += [f"figure: {p}" for p in r.get("figures", [])]
    return "\n".join(lines)


def _status_text(r: dict) -> list[str]:
    """How the chosen solve ended and how every start and round did (solver, its return
    status, :data:`casadrone.limit.result.Ending`): a lap is completed when it is a verified
    optimum, and the line says whether the solver called it optimal or only acceptable."""
    chosen = (f"  chosen solve: {r['ending']} ({r['return_status']})"
              + (": the solver stopped at its acceptable level (1000 x its tolerance), not "
                 "at its tolerance" if r["ending"] == "acceptable" else ""))
    per = "; ".join(f"{s['start']} {s['ending']}" + (
        f" {s['lap_time_s']:.4f} s" if s["success"] else f" ({s['return_status']})")
        for s in r["starts"])
    return [chosen, f"  solves: {per}"]


def _sensitivity_text(r: dict) -> list[str]:
    """dT/dθ in ms per 1 % of each key's Table 1 range, at the chosen optimum, with its
    uncertainty over the call's verified optima, "not resolved" where they disagree in sign,
    or a note that one optimum gives no uncertainty (casadrone.limit.sensitivity)."""
    table = [t for t in r.get("sensitivity_table", []) if math.isfinite(t["s_per_percent"])]
    if not table:
        return []
    n = table[0]["optima"]
    where = (f"at the chosen optimum ({r['start']}, {r['lap_time_s']:.4f} s)" + (
        f", uncertainty over the {n} verified optima of this call" if n > 1 else
        ": one optimum, no uncertainty (--certify solves every start and gives it)"))
    lines = [f"  sensitivity dT/dθ in ms per 1 % of the key's Table 1 range, {where}:"]
    for t in table:
        ms, unc = 1e3 * t["s_per_percent"], 1e3 * t["uncertainty_s_per_percent"]
        if not t["resolved"]:
            pct = 1e3 * percent_of_range(t["key"])
            lo, hi = t["low_s_per_unit"] * pct, t["high_s_per_unit"] * pct
            lines.append(f"    {t['key']:<14}{ms:>+10.3f}  not resolved: the optima give "
                         f"{lo:+.3f} … {hi:+.3f}")
        elif math.isfinite(unc):
            lines.append(f"    {t['key']:<14}{ms:>+10.3f} ± {unc:.3f}")
        else:
            lines.append(f"    {t['key']:<14}{ms:>+10.3f}")
    return lines
