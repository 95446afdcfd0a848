"""Benchmark: the ``paper`` and ``propeller`` propulsion models side by side (issue 17).

- **closed loop**: the paper's evaluation (hover trim, LQR-I, RK4 closed-loop lap, indices) of
  SY250 and SY250-propeller: J1–J5, Jp and the CPU time per evaluation (median, interleaved);
- **limit lap** of both on the paper track (and ``--gates``: the gate track): lap, lower bound,
  re-simulation miss, top speed, thrust at top speed, advance-ratio range, lowest full-command
  thrust ratio, CPU time; then ``--warm`` frames near SY250 (random θ within ±5 % of the Table 1
  range) each solved from a primal-dual warm start of the model's own SY250 lap: CPU time;
- **reference airframes**: the five shipped frames with SY250-propeller's ``propulsion:``
  section: does the limit lap converge, with which miss.

Run: ``python benchmarks/bench_propulsion.py [--warm 5] [--evals 20] [--gates] [--frames]``.
Writes ``benchmarks/RESULTS-propulsion.md`` (``--out``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
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
from casadrone.limit.lap import LimitLapOptions, limit_lap  # noqa: E402
from casadrone.propulsion import max_static_thrust  # noqa: E402

MODELS = {"paper": "SY250", "propeller": "SY250-propeller"}
REFERENCES = ("SY250", "SY220", "HS210", "HS200", "NSY200")


def cpu(fn):
    t = time.process_time()
    out = fn()
    return out, time.process_time() - t


def closed_loop(n_evals: int) -> dict:
    setups = {k: default_setup(v) for k, v in MODELS.items()}
    thetas = {k: theta_of(s.template) for k, s in setups.items()}
    res = {k: evaluate(thetas[k], s) for k, s in setups.items()}  # warm-up and indices
    times: dict[str, list[float]] = {k: [] for k in MODELS}
    for _ in range(n_evals):
        for k, s in setups.items():
            times[k].append(cpu(lambda k=k, s=s: evaluate(thetas[k], s))[1])
    return {k: {"status": res[k].status, "reason": res[k].reason, "indices": res[k].indices,
                "cpu_ms": 1000 * float(np.median(times[k]))} for k in MODELS}


def lap_row(cfg, track, options: LimitLapOptions | None = None) -> tuple[dict, object]:
    options = options or LimitLapOptions()
    frame = build_airframe(cfg)
    lap, t = cpu(lambda: limit_lap(cfg, track, options))
    row = {"status": lap.status, "reason": lap.reason[:200], "cpu_s": t}
    if lap.completed:
        prop = lap_propulsion(frame, lap.x_euler, lap.u)
        J = prop["advance_ratio"]
        row |= {"lap_s": lap.lap_time_s, "lower_bound_s": lap.point_mass_reference_s,
                "miss_m": lap.resimulation_miss_m, "iterations": lap.iterations,
                "top_speed_m_s": prop["top_speed_m_s"],
                "thrust_at_top_n": prop["thrust_at_top_speed_n"],
                "static_full_n": max_static_thrust(frame),
                "J_range": (float(np.nanmin(J)), float(np.nanmax(J))) if np.isfinite(J).any()
                else (np.nan, np.nan),
                "min_thrust_ratio": prop["min_thrust_ratio"]}
    return row, lap


def warm_solves(name: str, lap0, track, n: int, seed: int) -> list[float]:
    cfg = load_airframe(name)
    rng = np.random.default_rng(seed)
    times = []
    for _ in range(n):
        theta = {}
        for k, (lo, hi) in TABLE1_BOUNDS.items():
            v = getattr(cfg, k)
            theta[k] = float(np.clip(v + 0.05 * (hi - lo) * rng.uniform(-1, 1), lo, hi))
        c = with_theta(cfg, theta)
        opts = LimitLapOptions(starts=(), warm_starts=(lap0,), point_mass_reference=False,
                               sensitivities=False)
        lap, t = cpu(lambda c=c, opts=opts: limit_lap(c, track, opts))
        times.append(t if lap.completed else np.nan)
    return times


def with_propeller(name: str):
    base = load_airframe(MODELS["propeller"])
    return load_airframe(name).model_copy(update={"propulsion": base.propulsion,
                                                  "name": f"{name}-propeller"})


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--evals", type=int, default=20)
    ap.add_argument("--warm", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--gates", action="store_true")
    ap.add_argument("--frames", action="store_true")
    ap.add_argument("--out", default=str(Path(__file__).with_name("RESULTS-propulsion.md")))
    a = ap.parse_args()
    lines = ["# The paper and propeller propulsion models side by side", "",
             f"`python benchmarks/bench_propulsion.py --evals {a.evals} --warm {a.warm}"
             f"{' --gates' if a.gates else ''}{' --frames' if a.frames else ''}`", "",
             markdown(), ""]

    cl = closed_loop(a.evals)
    lines += ["## Closed-loop lap (paper evaluation: hover trim, LQR-I, RK4 lap)", "",
              "| model | status | J1 | J2 | J3 | J4 | J5 | Jp | CPU per evaluation (ms) |",
              "|---|---|---|---|---|---|---|---|---|"]
    for k, r in cl.items():
        J = r["indices"]
        vals = " | ".join(f"{J.get(n, float('nan')):.4g}" for n in ("J1", "J2", "J3", "J4",
                                                                    "J5", "Jp"))
        lines.append(f"| {k} | {r['status']} {r['reason'][:60]} | {vals} | {r['cpu_ms']:.2f} |")
    ratio = cl["propeller"]["cpu_ms"] / cl["paper"]["cpu_ms"]
    lines += ["", f"Evaluation time propeller / paper: **{ratio:.2f}×** (median of {a.evals} "
              "interleaved evaluations each, CPU time).", ""]
    print("\n".join(lines[-8:]), flush=True)

    tracks = {"paper track": load(TrackConfig, DEFAULT_TRACK)}
    if a.gates:
        tracks["gate track"] = load(TrackConfig, resolve_config("multigp-cdra-gates", "tracks"))
    lines += ["## Limit lap, SY250", "",
              "| track | model | status | lap (s) | lower bound (s) | miss (m) | top speed (m/s) "
              "| thrust at top speed (N, 4 rotors) | static full thrust (N) | J range | min "
              "full-command thrust ratio | iterations | CPU (s) |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    laps = {}
    for tname, trk in tracks.items():
        for k, name in MODELS.items():
            row, lap = lap_row(load_airframe(name), trk)
            laps[(tname, k)] = lap
            if lap.completed:
                lines.append(
                    f"| {tname} | {k} | optimal | {row['lap_s']:.3f} | "
                    f"{row['lower_bound_s']:.3f} | {row['miss_m']:.2g} | "
                    f"{row['top_speed_m_s']:.1f} | "
                    f"{', '.join(f'{t:.2f}' for t in row['thrust_at_top_n'])} | "
                    f"{row['static_full_n']:.2f} | {row['J_range'][0]:.2f}–"
                    f"{row['J_range'][1]:.2f} | {row['min_thrust_ratio']:.2f} | "
                    f"{row['iterations']} | {row['cpu_s']:.1f} |")
            else:
                lines.append(f"| {tname} | {k} | failed: {row['reason']} | | | | | | | | | | "
                             f"{row['cpu_s']:.1f} |")
            print(lines[-1], flush=True)
    lines.append("")

    if a.warm:
        trk = tracks["paper track"]
        lines += ["## Warm limit-lap solves (frames within ±5 % of the Table 1 range of SY250, "
                  "warm-started from the model's own SY250 lap)", "",
                  "| model | solved | CPU median (s) | CPU max (s) |", "|---|---|---|---|"]
        med = {}
        for k, name in MODELS.items():
            lap0 = laps[("paper track", k)]
            if not lap0.completed:
                lines.append(f"| {k} | no SY250 lap to start from | | |")
                continue
            t = np.array(warm_solves(name, lap0, trk, a.warm, a.seed))
            ok = np.isfinite(t)
            med[k] = float(np.median(t[ok])) if ok.any() else np.nan
            lines.append(f"| {k} | {ok.sum()}/{len(t)} | {med[k]:.2f} | "
                         f"{np.nanmax(t) if ok.any() else np.nan:.2f} |")
            print(lines[-1], flush=True)
        if len(med) == 2:
            lines += ["", f"Warm solve propeller / paper: **{med['propeller'] / med['paper']:.2f}"
                      "×** (median CPU).", ""]

    if a.frames:
        trk = tracks["paper track"]
        lines += ["## Reference airframes with SY250-propeller's propulsion section", "",
                  "| airframe | status | lap (s) | lower bound (s) | miss (m) | top speed (m/s) "
                  "| CPU (s) |", "|---|---|---|---|---|---|---|"]
        for name in REFERENCES:
            row, lap = lap_row(with_propeller(name), trk)
            if lap.completed:
                lines.append(f"| {name} | optimal | {row['lap_s']:.3f} | "
                             f"{row['lower_bound_s']:.3f} | {row['miss_m']:.2g} | "
                             f"{row['top_speed_m_s']:.1f} | {row['cpu_s']:.1f} |")
            else:
                lines.append(f"| {name} | failed: {row['reason']} | | | | | {row['cpu_s']:.1f} |")
            print(lines[-1], flush=True)
    Path(a.out).write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
