"""Benchmark: which starts reach the best limit-lap optimum, on which grid, at what cost.

For each ``--frames`` airframe on ``--track`` (Euler attitude, tilt axes, no fallback, no
sensitivities), three stages, each ``limit_lap`` call timed in CPU seconds:

1. **own starts on every grid**: for each of ``--grids`` (intervals per leg) one call per start
   of ``--starts`` (``closed-loop``, ``point-mass``, ``relaxed-tolerance``, ...);
2. **grid continuation**: on each grid, the best lap of every *other* grid resampled onto it
   (``resampled-i`` of ``LimitLapOptions.warm_starts``), one call each;
3. **neighbouring frames** (``--cross``): on ``--target-grid``, the best lap of every other
   frame of the run as a primal-dual warm start (``warm-i``: the NLP is the same for every frame,
   only the parameter p differs).

One JSON line per call on stdout (``--log`` as well); the markdown summary (best per grid,
which strategy reached it, within 0.1 % or not, CPU) goes to ``--out``.

Run: ``python benchmarks/bench_limitlap_optimum.py --frames SY250 HS210 --grids 30 40 50 60``
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import markdown  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load, resolve_config  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.limit.lap import LapSeeds, LimitLap, LimitLapOptions, design_limit_lap  # noqa: E402

HERE = Path(__file__).resolve().parent
REL = 1e-3  # "the same optimum": within 0.1 % of the best


def call(frame: str, track: TrackConfig, options: LimitLapOptions, warm: LimitLap | None,
         strategy: str, grid: int, log) -> tuple[dict, LimitLap]:
    c0 = time.process_time()
    lap = design_limit_lap(load_airframe(frame), track, options,
                           LapSeeds(warm_starts=(warm,) if warm is not None else ()))
    row = {"frame": frame, "grid": grid, "strategy": strategy, "status": lap.status,
           "lap_time_s": lap.lap_time_s if lap.completed else None,
           "miss_m": lap.resimulation_miss_m, "iterations": lap.iterations,
           "cpu_s": round(time.process_time() - c0, 2),
           "starts": [(s.start, s.return_status, s.lap_time_s, s.iterations)
                      for s in lap.starts]}
    print(json.dumps(row), flush=True)
    if log is not None:
        log.write(json.dumps(row) + "\n")
        log.flush()
    return row, lap


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", nargs="+", default=["SY250"])
    ap.add_argument("--track", default="paper-rectangle")
    ap.add_argument("--grids", nargs="+", type=int, default=[40])
    ap.add_argument("--starts", nargs="+", default=["closed-loop", "point-mass"])
    ap.add_argument("--target-starts", nargs="*", default=[],
                    help="starts solved on --target-grid only (e.g. closed-loop)")
    ap.add_argument("--rounds", type=int, default=2,
                    help="grid-continuation rounds (each resamples every grid's best so far)")
    ap.add_argument("--no-continuation", action="store_true")
    ap.add_argument("--cross", action="store_true", help="neighbouring frames' optima")
    ap.add_argument("--target-grid", type=int, default=40)
    ap.add_argument("--log", type=Path, default=None)
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-limitlap-optimum.md")
    args = ap.parse_args(argv)
    track = load(TrackConfig, resolve_config(args.track, "tracks"))
    base = LimitLapOptions(sensitivities=False, fallback_reference=None,
                           point_mass_reference=False)
    log = args.log.open("a", encoding="utf-8") if args.log else None
    rows: list[dict] = []
    best: dict[tuple[str, int], LimitLap] = {}

    def keep(frame: str, grid: int, lap: LimitLap) -> None:
        old = best.get((frame, grid))
        if lap.completed and (old is None or lap.lap_time_s < old.lap_time_s):
            best[(frame, grid)] = lap

    for frame in args.frames:
        for grid in args.grids:
            starts = args.starts + (args.target_starts if grid == args.target_grid else [])
            for s in starts:
                opts = replace(base, intervals=grid, starts=(s,),
                               point_mass_reference=s in ("point-mass", "relaxed-tolerance"))
                row, lap = call(frame, track, opts, s, grid, log)
                rows.append(row)
                keep(frame, grid, lap)
        tried: set[tuple[int, float]] = set()  # (grid, lap time of the start resampled onto it)
        for r in range(args.rounds if not args.no_continuation and len(args.grids) > 1 else 0):
            own = {g: best.get((frame, g)) for g in args.grids}
            improved = False
            for grid in args.grids:
                for other, lap in own.items():
                    if other == grid or lap is None or (grid, lap.lap_time_s) in tried:
                        continue
                    tried.add((grid, lap.lap_time_s))
                    opts = replace(base, intervals=grid, starts=())
                    old = best.get((frame, grid))
                    row, new = call(frame, track, opts, lap, f"grid-{other}" + (
                        f" (round {r + 1})" if r else ""), grid, log)
                    rows.append(row)
                    keep(frame, grid, new)
                    improved |= old is None or best[(frame, grid)].lap_time_s < old.lap_time_s \
                        * (1 - 1e-5)
            if not improved:
                break
    if args.cross:
        g = args.target_grid
        own = {f: best.get((f, g)) for f in args.frames}
        for frame in args.frames:
            for other, lap in own.items():
                if other == frame or lap is None:
                    continue
                opts = replace(base, intervals=g, starts=())
                row, new = call(frame, track, opts, lap, f"frame-{other}", g, log)
                rows.append(row)
                keep(frame, g, new)
    cmd = "python benchmarks/bench_limitlap_optimum.py " + " ".join(argv or sys.argv[1:])
    args.out.write_text("\n".join([
        "# Limit lap: which starts reach the best optimum", "", f"Command: `{cmd}`", "",
        markdown(), "", *summary(rows), ""]), encoding="utf-8")
    return 0


def summary(rows: list[dict]) -> list[str]:
    """Per frame and grid: the best lap, every strategy's lap and gap to it, CPU."""
    out = ["| frame | grid | strategy | lap (s) | gap to best | within 0.1 % | iterations | "
           "CPU (s) |", "|---|---|---|---|---|---|---|---|"]
    keys = sorted({(r["frame"], r["grid"]) for r in rows})
    for frame, grid in keys:
        sel = [r for r in rows if r["frame"] == frame and r["grid"] == grid]
        times = [r["lap_time_s"] for r in sel if r["lap_time_s"] is not None]
        b = min(times) if times else float("nan")
        for r in sel:
            t = r["lap_time_s"]
            gap = f"{100 * (t / b - 1):.3f} %" if t is not None else "-"
            ok = "yes" if t is not None and t <= b * (1 + REL) else "no"
            out.append(f"| {frame} | {grid} | {r['strategy']} | "
                       f"{t:.4f} | {gap} | {ok} | {r['iterations']} | {r['cpu_s']:.0f} |"
                       if t is not None else
                       f"| {frame} | {grid} | {r['strategy']} | {r['status']} | - | no | "
                       f"{r['iterations']} | {r['cpu_s']:.0f} |")
    return out


if __name__ == "__main__":
    raise SystemExit(main())
