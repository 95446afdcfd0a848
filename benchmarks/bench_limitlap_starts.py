"""Benchmark: what each start of the limit lap gives, per frame and track (cost against gain).

For each ``--frames`` airframe on each ``--tracks`` track, one ``limit_lap`` call with every
start strategy (``closed-loop``, ``point-mass``, ``coarse-grid``; no fallback) and the chosen
``--attitude`` / ``--tilt``; per start: converged or not, lap time, IPOPT iterations, wall time
and re-simulation miss; per call: the chosen lap, ``certainty``, the spread over verified
starts, the point-mass reference, CPU time, and the time of each lap on multi-lap courses.

Run: ``python benchmarks/bench_limitlap_starts.py --frames SY250 HS210 --tracks paper-rectangle``
(writes ``benchmarks/RESULTS-limitlap-starts.md``, ``--out``; one JSON line per call on stdout).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import markdown  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load, resolve_config  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.limit.lap import LimitLapOptions, design_limit_lap  # noqa: E402

HERE = Path(__file__).resolve().parent
STARTS = LimitLapOptions().starts


def one(frame: str, track: str, options: LimitLapOptions) -> dict:
    """One call: the chosen lap and every start's outcome."""
    trk = load(TrackConfig, resolve_config(track, "tracks"))
    c0 = time.process_time()
    lap = design_limit_lap(load_airframe(frame), trk, options)
    before = [s.lap_time_s for s in lap.starts if s.success and "-round-" not in s.start
              and s.resimulation_miss_m <= options.max_miss_m]
    return {"frame": frame, "track": track, "status": lap.status, "reason": lap.reason[:300],
            "lap_time_s": lap.lap_time_s, "start": lap.start, "certainty": lap.certainty,
            "spread_s": lap.spread_s, "reference_s": lap.point_mass_reference_s,
            "lap_times_s": [float(t) for t in lap.lap_times_s],
            "miss_m": lap.resimulation_miss_m, "cpu_s": time.process_time() - c0,
            "wall_s": lap.wall_time_s, "starts_lap_s": min(before, default=float("nan")),
            "grid_laps_s": {str(k): v for k, v in lap.grid_laps_s.items()},
            "starts": [(s.start, s.success, s.return_status, s.lap_time_s, s.iterations,
                        s.wall_time_s, s.resimulation_miss_m) for s in lap.starts]}


def rounds_table(rows: list[dict]) -> list[str]:
    """The grid rounds' gain: the starts' lap, the chosen lap, the other grids' laps."""
    out = ["| frame | track | starts' lap (s) | with grid rounds (s) | gain | chosen start | "
           "other grids' laps (s) | CPU (s) |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        gain = 100 * (r["starts_lap_s"] - r["lap_time_s"]) / r["starts_lap_s"]
        grids = ", ".join(f"{k}: {v:.4f}" for k, v in sorted(r["grid_laps_s"].items(),
                                                           key=lambda kv: int(kv[0])))
        out.append(f"| {r['frame']} | {r['track']} | {r['starts_lap_s']:.4f} | "
                   f"{r['lap_time_s']:.4f} | {gain:.3f} % | {r['start']} | {grids} | "
                   f"{r['cpu_s']:.0f} |")
    return out


def table(rows: list[dict]) -> list[str]:
    out = ["| frame | track | lap (s) | chosen start | certainty | spread (s) | point-mass "
           "reference (s) | CPU (s) | per start: lap (s) / iterations / wall (s) |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        per = "; ".join(f"{s[0]}: {s[3]:.4f} / {s[4]} / {s[5]:.0f}" if s[1] else
                        f"{s[0]}: {s[2]} / {s[4]} / {s[5]:.0f}" for s in r["starts"])
        out.append(f"| {r['frame']} | {r['track']} | {r['lap_time_s']:.4f} | {r['start']} | "
                   f"{r['certainty']} | {r['spread_s']:.4f} | {r['reference_s']:.4f} | "
                   f"{r['cpu_s']:.0f} | {per} |")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", nargs="+", default=["SY250"])
    ap.add_argument("--tracks", nargs="+", default=["paper-rectangle"])
    ap.add_argument("--attitude", default="euler")
    ap.add_argument("--tilt", default="axes")
    ap.add_argument("--intervals", type=int, default=LimitLapOptions().intervals)
    ap.add_argument("--grid-rounds", type=int, default=0,
                    help="grid rounds after the starts (LimitLapOptions.grid_rounds)")
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-limitlap-starts.md")
    args = ap.parse_args(argv)
    options = LimitLapOptions(intervals=args.intervals, starts=STARTS, sensitivities=False,
                              fallback_reference=None, attitude=args.attitude,
                              tilt_limit=args.tilt, grid_rounds=args.grid_rounds)
    rows = []
    for track in args.tracks:
        for frame in args.frames:
            rows.append(one(frame, track, options))
            print(json.dumps(rows[-1]), flush=True)
    cmd = "python benchmarks/bench_limitlap_starts.py " + " ".join(argv or sys.argv[1:])
    args.out.write_text("\n".join([
        "# Limit lap: what each start gives", "", f"Command: `{cmd}`", "",
        markdown(), "", *table(rows), "",
        *(rounds_table(rows) + [""] if args.grid_rounds else [])]), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
