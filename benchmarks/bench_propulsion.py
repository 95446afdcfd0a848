"""Benchmark: the ``paper`` and ``propeller`` propulsion models side by side (issue 17).

Sections (each one a flag; the results file is rewritten after every row, so an interrupted run
keeps what it measured):

- ``--closed-loop``: the paper's evaluation (hover trim, LQR-I, RK4 closed-loop lap, indices) of
  the five reference frames under both models (``NAME`` and ``NAME-propeller``): J1–J5, Jp, and
  the CPU time per evaluation of SY250 (median of ``--evals``, interleaved);
- ``--laps``: the limit lap of the five frames (``--frames``) under both models on the paper
  track and the gate track (``--tracks``): lap, point-mass reference, re-simulation miss, top
  speed, thrust at top speed, advance-ratio range, lowest full-command thrust ratio, the largest
  total thrust over the lap against the point mass's bound 4 T_b, CPU time;
- ``--data-range``: where the closed-loop lap of the five frames and SY250's level trim at
  10–40 m/s fly against the propeller data's largest advance ratio (they extrapolate beyond it);
- ``--warm N``: N frames near SY250 (θ within ±5 % of the Table 1 range) each solved from a
  primal-dual warm start of the model's own SY250 lap on the paper track: CPU per solve, both
  models side by side; ``--propeller-grid INTERVALS:SUBSTEPS:ROTOR_STEP`` (e.g.
  ``40:4:exponential``) solves the ``propeller`` laps of this section on another grid and rotor
  step (``LimitLapOptions.intervals``, ``substeps``, ``rotor_step``), ``paper`` on its default.

Run: ``python benchmarks/bench_propulsion.py --closed-loop --laps --warm 5``. Writes
``benchmarks/RESULTS-propulsion-measured.md`` (``--out``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import markdown  # noqa: E402
from casadrone.airframe import TABLE1_BOUNDS, build_airframe, with_theta  # noqa: E402
from casadrone.config import load_airframe  # noqa: E402
from casadrone.config.io import load, resolve_config  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK, default_setup, evaluate, theta_of  # noqa: E402
from casadrone.limit.check import lap_propulsion  # noqa: E402
from casadrone.limit.lap import LapSeeds, LimitLapOptions, design_limit_lap  # noqa: E402
from casadrone.model import propeller_outputs  # noqa: E402
from casadrone.propulsion import max_static_thrust, rotor_thrust_bound  # noqa: E402
from casadrone.trim import trim  # noqa: E402

REFERENCES = ("SY250", "HS210", "HS200", "NSY200", "SY220")
#: A rotor-node within this of the data's largest advance ratio counts as at the bound.
AT_BOUND = 1e-3
MODELS = ("paper", "propeller")
TRACKS = {"paper": DEFAULT_TRACK, "gates": "multigp-cdra-gates"}


def frame_name(name: str, model: str) -> str:
    """The shipped airframe of reference frame ``name`` under propulsion ``model``."""
    return name if model == "paper" else f"{name}-{model}"


def cpu(fn):
    t = time.process_time()
    out = fn()
    return out, time.process_time() - t


class Report:
    """The results file, rewritten after every row."""

    def __init__(self, path: str, head: list[str]):
        self.path, self.lines = Path(path), list(head)

    def add(self, *lines: str) -> None:
        self.lines += lines
        for line in lines:
            print(line, flush=True)
        self.path.write_text("\n".join(self.lines) + "\n")


def closed_loop(rep: Report, n_evals: int) -> None:
    rep.add("## Closed-loop lap (paper track, default controller, RK4: hover trim, LQR-I, lap, "
            "indices)", "", "| frame | model | status | J1 | J2 | J3 | J4 | J5 | Jp |",
            "|---|---|---|---|---|---|---|---|---|")
    setups = {}
    for name in REFERENCES:
        for model in MODELS:
            s = default_setup(frame_name(name, model))
            setups[(name, model)] = s
            r = evaluate(theta_of(s.template), s)
            vals = " | ".join(f"{r.indices.get(k, float('nan')):.4f}"
                              for k in ("J1", "J2", "J3", "J4", "J5", "Jp"))
            rep.add(f"| {name} | {model} | {r.status} {r.reason[:60]} | {vals} |")
    times: dict[str, list[float]] = {m: [] for m in MODELS}
    for _ in range(n_evals):
        for m in MODELS:
            s = setups[("SY250", m)]
            times[m].append(cpu(lambda s=s: evaluate(theta_of(s.template), s))[1])
    med = {m: 1000 * float(np.median(times[m])) for m in MODELS}
    rep.add("", f"CPU per evaluation of SY250 (median of {n_evals}, interleaved): paper "
            f"{med['paper']:.2f} ms, propeller {med['propeller']:.2f} ms: propeller / paper "
            f"**{med['propeller'] / med['paper']:.2f}×**.", "")


def data_range(rep: Report) -> None:
    """Where the stages other than the limit lap fly against the propeller data (they use the
    model as it is, the quadratic CT(J), CP(J) extrapolated beyond J_max)."""
    rep.add("## Outside the limit lap: the propeller data's range (J_max) in the closed-loop lap "
            "and the level trim", "", "| frame | closed-loop lap: status | J_max of the data | "
            "largest J | share of rotor-samples beyond J_max | min thrust ratio CT(J)/CT(0) | "
            "lowest rotor thrust (N) |", "|---|---|---|---|---|---|---|")
    for name in REFERENCES:
        s = default_setup(frame_name(name, "propeller"))
        r = evaluate(theta_of(s.template), s, keep_trajectory=True)
        frame = build_airframe(load_airframe(frame_name(name, "propeller")))
        tr = r.trajectory
        if tr is None or not len(tr.u):
            rep.add(f"| {name} | {r.status} | | | | | |")
            continue
        prop = lap_propulsion(frame, tr.x, tr.u)
        rep.add(f"| {name} | {r.status} | {prop['data_advance_ratio']:.3f} | "
                f"{prop['max_advance_ratio']:.3f} | {100 * prop['beyond_data_share']:.1f} % | "
                f"{prop['min_thrust_ratio']:.2f} | {np.min(prop['thrust_n']):.2f} |")
    frame = build_airframe(load_airframe("SY250-propeller"))
    rep.add("", "| SY250-propeller level trim (m/s) | solved | commands δ | J per rotor | "
            "beyond J_max? | message |", "|---|---|---|---|---|---|")
    for v in (10.0, 20.0, 30.0, 40.0):
        tp = trim(frame, "forward", v)
        J = np.asarray(propeller_outputs()(tp.x0, tp.u0, frame.p)[2]).ravel()
        rep.add(f"| {v:.0f} | {tp.success} | {', '.join(f'{d:.2f}' for d in tp.u0)} | "
                f"{', '.join(f'{j:.3f}' for j in J)} | "
                f"{'yes' if J.max() > frame.max_advance_ratio else 'no'} | {tp.message} |")
    rep.add("")


def lap_row(name: str, model: str, track_name: str, options: LimitLapOptions):
    cfg = load_airframe(frame_name(name, model))
    frame = build_airframe(cfg)
    track = load(TrackConfig, resolve_config(TRACKS[track_name], "tracks"))
    lap, t = cpu(lambda: design_limit_lap(cfg, track, options))
    head = f"| {name} | {track_name} | {model} |"
    if not lap.completed:
        return f"{head} failed: {lap.reason[:160]} | | | | | | | | | | {t:.0f} |", lap
    prop = lap_propulsion(frame, lap.x_euler, lap.u)
    J, T = prop["advance_ratio"], prop["thrust_n"]
    # J at full command (where CT(J) sets the thrust the lap can have); over every rotor-node
    # its largest value (a stopped rotor has none), the share of rotor-nodes at the data's
    # bound (J within AT_BOUND of J_max), beyond it, and with negative thrust (the quadratic
    # CT(J) extrapolated: a windmilling or stopped rotor brakes), with the lowest thrust
    full = lap.u >= 0.99
    j_max, fin = prop["data_advance_ratio"], np.isfinite(J)
    jr = (f"{np.median(J[full]):.2f} / {np.max(J[full]):.2f}; all ≤ {np.max(J[fin]):.3f}; at "
          f"bound {100 * np.mean(J >= j_max - AT_BOUND):.1f} %, beyond "
          f"{100 * np.mean(J > j_max + AT_BOUND):.1f} %, T < 0 {100 * np.mean(T < 0):.1f} % "
          f"(lowest {np.min(T):.2g} N)" if fin.any() and full.any() else "—")
    bound = 4 * rotor_thrust_bound(frame)
    peak = float(np.max(np.sum(T, axis=1)))
    starts = ", ".join(f"{s.start} {s.lap_time_s:.3f}" if s.success else f"{s.start} "
                       f"{s.return_status}" for s in lap.starts)
    return (f"{head} {lap.lap_time_s:.3f} | {lap.point_mass_reference_s:.3f} | "
            f"{lap.resimulation_miss_m * 100:.2f} | {prop['top_speed_m_s']:.1f} | "
            f"{', '.join(f'{v:.2f}' for v in prop['thrust_at_top_speed_n'])} | "
            f"{max_static_thrust(frame):.2f} | {jr} | {prop['min_thrust_ratio']:.2f} | "
            f"{peak / bound:.3f} | {starts} | {t:.0f} |"), lap


def laps(rep: Report, frames, tracks, models, options: LimitLapOptions) -> dict:
    grid = options.intervals or "the default number of (40 paper, 80 propeller)"
    rep.add(f"## Limit lap ({grid} intervals per leg, starts: {', '.join(options.starts)})", "",
            "| frame | track | model | lap (s) | point-mass reference (s) | re-simulation miss "
            "(cm) | top speed (m/s) | thrust at top speed (N, 4 rotors) | static full thrust "
            "(N) | J at full command: median / max; all rotor-nodes: largest J, share at the "
            "data's bound J_max, beyond it, with T < 0 (lowest T) | min thrust ratio CT(J)/CT(0) | "
            "max ΣT / 4 T_b | starts (lap s) | "
            "CPU (s) |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    out = {}
    for track_name in tracks:
        for name in frames:
            for model in models:
                row, lap = lap_row(name, model, track_name, options)
                out[(name, model, track_name)] = lap
                rep.add(row)
    rep.add("")
    return out


def warm_solves(rep: Report, n: int, seed: int, options: LimitLapOptions, solved: dict,
                propeller_grid: str = "") -> None:
    track = load(TrackConfig, DEFAULT_TRACK)
    per_model = {model: options for model in MODELS}
    if propeller_grid:
        intervals, substeps, rotor_step = propeller_grid.split(":")
        per_model["propeller"] = replace(options, intervals=int(intervals),
                                         substeps=int(substeps),
                                         rotor_step=rotor_step)  # type: ignore[arg-type]
        rep.add(f"`propeller` laps on {intervals} intervals per leg × {substeps} steps, rotor "
                f"step {rotor_step}.", "")
    rep.add(f"## Warm limit-lap solves ({n} frames within ±5 % of the Table 1 range around "
            "SY250, paper track, each from a primal-dual warm start of the model's own SY250 "
            "lap)", "", "| model | solved | CPU median (s) | CPU max (s) | iterations median |",
            "|---|---|---|---|---|")
    med = {}
    for model in MODELS:
        options = per_model[model]
        lap0 = solved.get(("SY250", model, "paper")) if options is per_model["paper"] else None
        if lap0 is None:
            lap0 = design_limit_lap(load_airframe(frame_name("SY250", model)), track, options)
        if not lap0.completed:
            rep.add(f"| {model} | no SY250 lap to start from | | | |")
            continue
        cfg = load_airframe(frame_name("SY250", model))
        rng = np.random.default_rng(seed)
        times, iters = [], []
        for _ in range(n):
            theta = {k: float(np.clip(getattr(cfg, k) + 0.05 * (hi - lo) * rng.uniform(-1, 1),
                                      lo, hi)) for k, (lo, hi) in TABLE1_BOUNDS.items()}
            opts = replace(options, starts=(), point_mass_reference=False, sensitivities=False,
                           fallback_reference=None)
            near = with_theta(cfg, theta)
            seeds = LapSeeds(warm_starts=(lap0,))
            lap, t = cpu(lambda c=near, o=opts, s=seeds: design_limit_lap(c, track, o, s))
            times.append(t if lap.completed else np.nan)
            iters.append(lap.iterations if lap.completed else np.nan)
        t_arr = np.array(times)
        ok = np.isfinite(t_arr)
        med[model] = float(np.median(t_arr[ok])) if ok.any() else np.nan
        rep.add(f"| {model} | {ok.sum()}/{n} | {med[model]:.2f} | "
                f"{np.nanmax(t_arr) if ok.any() else np.nan:.2f} | "
                f"{np.nanmedian(iters) if ok.any() else np.nan:.0f} |")
    if len(med) == 2:
        rep.add("", f"Warm solve propeller / paper: **{med['propeller'] / med['paper']:.2f}×** "
                "(median CPU).", "")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--closed-loop", action="store_true")
    ap.add_argument("--data-range", action="store_true")
    ap.add_argument("--evals", type=int, default=20)
    ap.add_argument("--laps", action="store_true")
    ap.add_argument("--frames", default=",".join(REFERENCES))
    ap.add_argument("--tracks", default="paper,gates")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--intervals", type=int, default=LimitLapOptions.intervals)
    ap.add_argument("--starts", default=",".join(LimitLapOptions.starts),
                    help="cold starts of the limit lap, comma-separated (default: the library's)")
    ap.add_argument("--warm", type=int, default=0)
    ap.add_argument("--propeller-grid", default="",
                    help="INTERVALS:SUBSTEPS:ROTOR_STEP of the propeller laps of --warm, e.g. "
                         "40:4:exponential (default: the library's)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", default=str(Path(__file__).with_name(
        "RESULTS-propulsion-measured.md")))
    a = ap.parse_args()
    argv = " ".join(sys.argv[1:])
    rep = Report(a.out, ["# The paper and propeller propulsion models side by side", "",
                         f"`python benchmarks/bench_propulsion.py {argv}`", "", markdown(), ""])
    options = LimitLapOptions(intervals=a.intervals, sensitivities=False,
                              starts=tuple(a.starts.split(",")))  # type: ignore[arg-type]
    if a.closed_loop:
        closed_loop(rep, a.evals)
    if a.data_range:
        data_range(rep)
    solved = laps(rep, a.frames.split(","), a.tracks.split(","), a.models.split(","),
                  options) if a.laps else {}
    if a.warm:
        warm_solves(rep, a.warm, a.seed, options, solved, a.propeller_grid)


if __name__ == "__main__":
    main()
