"""Commands that fly laps: simulate (one airframe), benchmark (the paper's reference airframes)."""

from __future__ import annotations

import math
from typing import Annotated

import typer

from casadrone.airframe import build_airframe
from casadrone.cli.common import (
    AirframeArg,
    ControllerOpt,
    JsonOpt,
    OverridesArg,
    PlotOpt,
    TrackOpt,
    app,
    check_plot_dir,
    load_airframe_or_exit,
    print_json,
    registry_option,
    reports_config_errors,
    save_figures,
)
from casadrone.config.airframe import MOTOR_NUMBERING, ROTOR_LABELS, ROTOR_NAMES, AirframeConfig
from casadrone.config.controller import load_controller
from casadrone.config.io import load, resolve_config
from casadrone.config.track import TrackConfig
from casadrone.export.mixers import spin_word
from casadrone.numtext import fixed


def _integrators() -> list[str]:
    from casadrone.simulate import INTEGRATORS

    return list(INTEGRATORS)


IntegratorOpt = Annotated[str, registry_option(
    _integrators, "integrator", "a plant integrator of casadrone.simulate.INTEGRATORS: rk4 "
    "(fast, compiled) or cvodes/idas (reference)")]


# --------------------------------------------------------------------------------------------
# simulate
# --------------------------------------------------------------------------------------------

#: The figures ``simulate --plot`` writes, checked before any work (:func:`check_plot_dir`).
SIMULATE_FIGURES = ("track-top-view", "track-3d", "time-histories")


@app.command()
@reports_config_errors
def simulate(
    airframe: AirframeArg,
    overrides: OverridesArg = None,
    track: TrackOpt = None,
    controller: ControllerOpt = None,
    integrator: IntegratorOpt = "rk4",
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
    check_plot_dir(plot, SIMULATE_FIGURES)
    cfg, _ = load_airframe_or_exit(airframe, overrides)
    from casadrone.evaluate import DEFAULT_TRACK, EvaluationSetup, evaluate, theta_of
    from casadrone.indices import INDICES

    setup = EvaluationSetup(
        template=cfg,
        controller=load_controller(controller),
        track=load(TrackConfig, resolve_config(track, "tracks") if track else DEFAULT_TRACK),
        integrator=integrator,
    )
    ev = evaluate(theta_of(cfg), setup, keep_trajectory=True)
    result = {"airframe": cfg.name, "track": setup.track.name,
              "controller": setup.controller.name, "integrator": integrator, **ev.as_dict(),
              "index_units": {k: INDICES[k].unit for k in ev.indices}, "rotors": _rotors(cfg)}
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


def _rotors(cfg: AirframeConfig) -> list[dict]:
    """Each rotor by position, with its firmware motor numbers, place, spin and hover thrust (the
    table that says which motor is which; empty for a frame that cannot be built)."""
    try:
        af = build_airframe(cfg)
    except ValueError:
        return []
    hover = af.hover_thrusts()
    return [{"position": ROTOR_LABELS[i], "name": ROTOR_NAMES[i],
             "x_mm": 1000 * float(af.rotor_positions[i, 0]),
             "y_mm": 1000 * float(af.rotor_positions[i, 1]), "spin": spin_word(af.rotor_spins[i]),
             "hover_thrust_N": float(hover[i]),
             **{f"{key}_motor": n.motor(i) for key, n in MOTOR_NUMBERING.items()}}
            for i in range(4)]


def _rotor_lines(rotors: list[dict]) -> list[str]:
    firm = "".join(f"{n.firmware + ' motor':>18}" for n in MOTOR_NUMBERING.values())
    lines = [f"  {'rotor':<7}{'x fwd (mm)':>11}{'y left (mm)':>13}{'spin':>6}"
             f"{'hover thrust (N)':>18}{firm}"]
    for r in rotors:
        lines.append(f"  {r['position']:<7}{r['x_mm']:>+11.1f}{r['y_mm']:>+13.1f}{r['spin']:>6}"
                     f"{r['hover_thrust_N']:>18.4f}"
                     + "".join(f"{r[f'{key}_motor']:>18d}" for key in MOTOR_NUMBERING))
    return lines


def _simulate_text(r: dict) -> str:
    from casadrone.indices import INDICES, INTERVAL_LEGEND

    head = f"{r['airframe']}: track {r['track']}, controller {r['controller']}, {r['integrator']}"
    if r["status"] != "completed":
        lines = [f"{head}: lap FAILED at {r['stage']}: {r['reason']} "
                 f"({r['wall_time_s']:.2f} s)"]
    else:
        lines = [f"{head}: lap completed in {r['indices'].get('J3', math.nan):.3f} s "
                 f"({r['wall_time_s']:.2f} s wall time)"]
        for name, value in r["indices"].items():
            index = INDICES[name]
            lines.append(f"  {name:<4}{fixed(value, '>10.4f')} {index.unit:<5} "
                         f"{index.description}")
        lines.append(f"  {'interval':>8}{'split time (s)':>16}{'effort (V)':>12}"
                     f"{'pair thrust max/min (N)':>26}")
        for i in r["intervals"]:
            lines.append(f"  {i['waypoint']:>8}{fixed(i['split_time_s'], '>16.3f')}"
                         f"{fixed(i['effort_V'], '>12.4f')}"
                         f"{fixed(i['pair_thrust_max_N'], '>15.3f')} / "
                         f"{fixed(i['pair_thrust_min_N'], '<8.3f')}".rstrip())
        lines += [f"  {line}" for line in INTERVAL_LEGEND]
    if r.get("rotors"):
        lines += _rotor_lines(r["rotors"])
    lines += [f"figure: {p}" for p in r.get("figures", [])]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------
# benchmark
# --------------------------------------------------------------------------------------------


@app.command()
@reports_config_errors
def benchmark(
    integrator: IntegratorOpt = "rk4",
    as_json: JsonOpt = False,
) -> None:
    """Fly the five reference airframes (paper Table 4): the Table-4-style table.

    Per airframe and interval, the simulated split time, roll effort and opposing-pair thrust
    beside the values the paper measured (a different time base: compare trends).
    """
    from casadrone.benchmark import format_table, run_benchmark

    table = run_benchmark(integrator)
    if as_json:
        print_json(table.as_dict())
    else:
        typer.echo(format_table(table), nl=False)
