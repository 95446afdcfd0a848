"""Benchmark: the limit lap over random Table 1 frames (solve time, success, spread, correlations).

For ``--n`` random frames inside paper Table 1 (SY250 template, paper track, overlapping-rotor
draws resampled), on one core:

- **cold**: ``limit_lap`` with its default starts (``LimitLapOptions().starts``: closed-loop,
  point-mass, coarse-grid and fine-grid; the best verified one) plus the point-mass reference
  and the CVODES re-simulation: success rate, CPU time (process time, single-threaded),
  iterations of the winning start, lap / point-mass reference, re-simulation miss;
- **warm**: the same frame solved again from a primal-dual warm start of its nearest
  neighbour (normalised θ distance) among the other frames: CPU time, iterations, and the
  difference to the cold lap (negative: the warm start found a better local optimum);
- **spread** of the limit lap over the frames and its Spearman rank correlation against thrust
  balance (max/min hover thrust over the rotors), control effectiveness (smallest of roll and
  pitch angular acceleration per newton of differential thrust, arm/inertia), mass (constant
  under the paper's free mass model: reported as such) and inertia (Ixx + Iyy).

Run: ``python benchmarks/bench_limitlap.py [--n 50] [--seed 0] [--template SY250]``. Writes
``benchmarks/RESULTS-limitlap-frames.md`` (``--out``). Target: ≤ 1 s CPU per warm solve.

``--solver fatrop`` solves every start with fatrop (IPOPT where fatrop fails:
``LimitLapOptions.solver``). ``--laps-json FILE`` writes each frame's cold lap; ``--compare-json
FILE`` reads another run's and reports how many frames' laps agree within 0.01 % (the same
frames: the same ``--n``, ``--seed`` and ``--template``), e.g. the two solvers' answers with the
command's whole start strategy.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import cpu_time, markdown  # noqa: E402
from benchmarks.table1 import nearest, unit_positions  # noqa: E402
from casadrone.airframe import build_airframe, random_thetas, with_theta  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK  # noqa: E402
from casadrone.limit.lap import LapSeeds, LimitLapOptions, design_limit_lap  # noqa: E402

HERE = Path(__file__).resolve().parent


def features(frame) -> dict[str, float]:
    """Frame properties the limit lap is correlated against."""
    T = frame.hover_thrusts()
    r = frame.rotor_positions
    J = np.diag(frame.inertia)
    roll = np.min(np.abs(r[:, 1])) / J[0]
    pitch = np.min(np.abs(r[:, 0])) / J[1]
    return {"thrust balance (max/min hover thrust)": float(T.max() / T.min()),
            "control effectiveness (min arm/inertia, 1/(kg m))": float(min(roll, pitch)),
            "mass (kg)": float(frame.mass), "inertia Ixx + Iyy (kg m²)": float(J[0] + J[1])}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--intervals", type=int, default=LimitLapOptions().intervals)
    ap.add_argument("--template", default="SY250",
                    help="airframe whose decision variables are drawn (SY250: Table 1's seven "
                         "keys, free mass model; SY250-components: the four geometry keys, mass "
                         "and inertia from the parts)")
    ap.add_argument("--starts", default=",".join(LimitLapOptions().starts),
                    help="cold starts, comma-separated (default: the library's)")
    ap.add_argument("--resimulation", choices=("lap", "legs"), default="lap",
                    help="what the re-simulation check flies (LimitLapOptions.resimulation)")
    ap.add_argument("--solver", choices=("ipopt", "fatrop"), default="ipopt")
    ap.add_argument("--laps-json", type=Path, default=None, help="write each frame's cold lap")
    ap.add_argument("--compare-json", type=Path, default=None,
                    help="another run's --laps-json: how many laps agree within 0.01 %%")
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-limitlap-frames.md")
    args = ap.parse_args(argv)
    template = load_airframe(args.template)
    track = load(TrackConfig, DEFAULT_TRACK)
    options = LimitLapOptions(intervals=args.intervals,
                              starts=tuple(args.starts.split(",")),  # type: ignore[arg-type]
                              resimulation=args.resimulation, solver=args.solver)
    thetas, _ = random_thetas(template, args.n, args.seed)
    keys = list(thetas[0])
    unit = unit_positions(thetas)
    design_limit_lap(template, track, options)  # warm-up: builds the NLPs once
    cold = []
    for i, theta in enumerate(thetas):
        cfg = with_theta(template, theta, name=f"frame{i}")
        c0 = cpu_time()
        lap = design_limit_lap(cfg, track, replace(options, sensitivities=False))
        cold.append((cfg, lap, cpu_time() - c0))
        print(f"{i}: {lap.status} {lap.lap_time_s:.4f} s "
              f"(reference {lap.point_mass_reference_s:.4f}) "
              f"{cold[-1][2]:.1f} s CPU {lap.reason} starts: "
              + ", ".join(f"{s.start} {s.lap_time_s:.4f}" if s.success else
                          f"{s.start} {s.return_status}" for s in lap.starts), flush=True)
    ok = [i for i, (_, lap, _) in enumerate(cold) if lap.completed]
    warm = []
    for i in ok:
        others = [j for j in ok if j != i]
        if not others:
            break
        j = nearest(i, others, unit)[0]
        wopts = replace(options, starts=(), point_mass_reference=False, resimulate=False,
                        sensitivities=False)
        c0 = cpu_time()
        lap = design_limit_lap(cold[i][0], track, wopts, LapSeeds(warm_starts=(cold[j][1],)))
        warm.append((i, lap, cpu_time() - c0))
    laps = np.array([cold[i][1].lap_time_s for i in ok])
    lbs = np.array([cold[i][1].point_mass_reference_s for i in ok])
    misses = np.array([cold[i][1].resimulation_miss_m for i in ok])
    feats = [features(build_airframe(cold[i][0])) for i in ok]
    med = np.median
    lines = ["# Limit lap over random Table 1 frames", "", markdown(), "",
             f"Command: `python benchmarks/bench_limitlap.py --n {args.n} --seed {args.seed} "
             + (f"--intervals {args.intervals} " if args.intervals else "")
             + f"--template {args.template} --starts "
             f"{args.starts}"
             + (f" --resimulation {args.resimulation}" if args.resimulation != "lap" else "")
             + (f" --solver {args.solver}" if args.solver != "ipopt" else "")
             + "` (paper track, one "
             f"core; decision variables {', '.join(keys)}).", "",
             "| quantity | value |", "|---|---|",
             f"| frames | {args.n} |",
             f"| cold success | {len(ok)}/{args.n} |",
             f"| cold CPU per frame (median, max; {len(options.starts)} starts "
             f"({', '.join(options.starts)}) + point-mass reference + re-simulation) | "
             f"{med([c[2] for c in cold]):.1f} s, {max(c[2] for c in cold):.1f} s |",
             f"| cold iterations of the winning start (median) | "
             f"{med([cold[i][1].iterations for i in ok]) if ok else float('nan'):.0f} |"]
    for name in options.starts:  # how each cold start fared, and how often it won
        conv = sum(any(s.start == name and s.success for s in c[1].starts) for c in cold)
        won = sum(cold[i][1].start == name for i in ok)
        lines.append(f"| start {name}: converged, won | {conv}/{args.n}, {won} |")
    if warm:
        wok = [w for w in warm if w[1].completed]
        diff = [w[1].lap_time_s - cold[w[0]][1].lap_time_s for w in wok]
        lines += [f"| warm success (from nearest neighbour) | {len(wok)}/{len(warm)} |",
                  f"| warm CPU per solve (median, max) | {med([w[2] for w in warm]):.2f} s, "
                  f"{max(w[2] for w in warm):.2f} s |",
                  f"| warm iterations (median) | {med([w[1].iterations for w in wok]):.0f} |",
                  f"| warm lap − cold lap (median, min, max) | {med(diff):+.4f}, "
                  f"{min(diff):+.4f}, {max(diff):+.4f} s |"]
    if ok:
        lines += [f"| limit lap (min, median, max) | {laps.min():.3f}, {med(laps):.3f}, "
                  f"{laps.max():.3f} s |",
                  f"| spread (max − min) / median | {100 * np.ptp(laps) / med(laps):.1f} % |",
                  f"| lap / point-mass reference (min, median, max) | {np.nanmin(laps / lbs):.3f}, "
                  f"{np.nanmedian(laps / lbs):.3f}, {np.nanmax(laps / lbs):.3f} |",
                  f"| re-simulation miss (median, max) | {med(misses):.4f}, "
                  f"{misses.max():.4f} m |", "",
                  "Spearman rank correlation of the limit lap with:", "",
                  "| feature | ρ | p |", "|---|---|---|"]
        for name in feats[0]:
            v = np.array([f[name] for f in feats])
            if np.ptp(v) == 0:
                lines.append(f"| {name} | – (constant: {v[0]:g}) | – |")
                continue
            rho, p = spearmanr(v, laps)
            lines.append(f"| {name} | {rho:+.2f} | {p:.2g} |")
    mine = {str(i): float(cold[i][1].lap_time_s) for i in ok}
    if args.laps_json:
        args.laps_json.write_text(json.dumps(mine, indent=1) + "\n")
    if args.compare_json:
        theirs = json.loads(args.compare_json.read_text())
        both = sorted(set(mine) & set(theirs), key=int)
        rel = np.array([(mine[k] - theirs[k]) / theirs[k] for k in both])
        if len(rel):
            lines += ["", f"Against `{args.compare_json.name}` ({len(both)} frames solved by "
                      f"both): within 0.01 %: {int(np.sum(np.abs(rel) <= 1e-4))}/{len(both)}; "
                      f"this run faster on {int(np.sum(rel < -1e-4))}, slower on "
                      f"{int(np.sum(rel > 1e-4))}; |difference| median "
                      f"{100 * np.median(np.abs(rel)):.4f} %, max {100 * np.abs(rel).max():.4f} %."]
    args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
