"""Benchmark: one periodic lap against two (``end: periodic``) on a closed circuit.

The paper rectangle at 20 m without its climb (start on the finish), ``end: periodic``: for each
``--frames`` airframe the limit lap of one lap and of ``laps: 2`` at ``--intervals`` per leg with
the default starts; per call the lap, each lap's time, the chosen start, certainty, the
re-simulation miss, the optimised start state (speed, Euler angles) and the CPU time; then
(T2 − 2 T1) / (2 T1), which issue 19 wants within 0.5 %.

Run: ``python benchmarks/bench_limitlap_periodic.py --frames SY250`` (one JSON line per call on
stdout).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK  # noqa: E402
from casadrone.limit.lap import LimitLapOptions, design_limit_lap  # noqa: E402

CLOSED = ["climb_to_m=null", "start_position_m=[0, 0, 20]", "end=periodic"]


def one(frame: str, laps: int, options: LimitLapOptions) -> dict:
    """One periodic limit-lap call of ``laps`` laps."""
    trk = load(TrackConfig, DEFAULT_TRACK, [*CLOSED, f"laps={laps}"])
    c0 = time.process_time()
    lap = design_limit_lap(load_airframe(frame), trk, options)
    x0 = lap.start_state
    return {"frame": frame, "laps": laps, "status": lap.status, "reason": lap.reason[:300],
            "lap_time_s": lap.lap_time_s, "lap_times_s": [float(t) for t in lap.lap_times_s],
            "start": lap.start, "certainty": lap.certainty, "spread_s": lap.spread_s,
            "miss_m": lap.resimulation_miss_m, "cpu_s": time.process_time() - c0,
            "start_speed_m_s": float(np.linalg.norm(x0[3:6])) if len(x0) else None,
            "start_euler_deg": [float(np.degrees(a)) for a in x0[9:12]] if len(x0) else None,
            "starts": [(s.start, s.return_status, s.lap_time_s) for s in lap.starts]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", nargs="+", default=["SY250"])
    ap.add_argument("--intervals", type=int, default=None)
    args = ap.parse_args(argv)
    options = LimitLapOptions(intervals=args.intervals, sensitivities=False,
                              fallback_reference=None)
    for frame in args.frames:
        rows = [one(frame, laps, options) for laps in (1, 2)]
        for r in rows:
            print(json.dumps(r), flush=True)
        t1, t2 = rows[0]["lap_time_s"], rows[1]["lap_time_s"]
        print(json.dumps({"frame": frame, "two_minus_twice_one_rel": (t2 - 2 * t1) / (2 * t1)}),
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
