"""Benchmark: why a converged limit lap misses its re-simulation check (grid or open-loop growth).

The limit lap's check flies the optimal commands open loop with CVODES over the whole lap and
measures the largest target miss. A miss of metres can have two causes: the NLP's RK4 step is
too coarse for the lap (then each interval integrated by CVODES from its own node already lands
off the next node: a large local defect, and a finer grid helps), or the lap is accurate but
open-loop unstable (tiny local defects, each leg flown from its own start node lands on its
end node, and only the whole lap, flown without feedback, drifts off). For each frame this
solves the limit lap from ``--starts`` with the check off, then prints the largest local defect
(position, velocity, rotor state), the miss of each leg flown from its own start node, and the
whole lap's miss at each leg end.

Run: ``python benchmarks/bench_resimulation_legs.py --template SY250-propeller --frames 0 14 35``
(the draws of ``bench_limitlap.py``: ``--n 50 --seed 0``; one JSON line per frame on stdout).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from casadrone.airframe import build_airframe, random_thetas, with_theta  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK  # noqa: E402
from casadrone.limit.check import fly  # noqa: E402
from casadrone.limit.lap import LimitLapOptions, design_limit_lap  # noqa: E402


def legs(frame, lap) -> dict:
    """Local defects, each leg from its own start node, and the whole lap's drift."""
    x, n = lap.x, lap.layout.intervals
    defect = np.array([fly(frame, lap, i, i + 1)[-1] - x[i + 1] for i in range(len(lap.u))])
    own = [float(np.linalg.norm(fly(frame, lap, k * n, (k + 1) * n)[-1, :3] - x[(k + 1) * n, :3]))
           for k in range(len(lap.u) // n)]
    whole = fly(frame, lap)
    drift = [float(np.linalg.norm(whole[(k + 1) * n, :3] - x[(k + 1) * n, :3]))
             for k in range(len(lap.u) // n)]
    return {"defect_position_m": float(np.abs(defect[:, 0:3]).max()),
            "defect_velocity_m_s": float(np.abs(defect[:, 3:6]).max()),
            "defect_rotor": float(np.abs(defect[:, -4:]).max()),
            "leg_from_own_node_m": own, "whole_lap_at_leg_ends_m": drift}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--template", default="SY250-propeller")
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--frames", type=int, nargs="+", default=[0])
    ap.add_argument("--starts", default="point-mass")
    args = ap.parse_args(argv)
    template = load_airframe(args.template)
    track = load(TrackConfig, DEFAULT_TRACK)
    thetas, _ = random_thetas(template, args.n, args.seed)
    options = LimitLapOptions(starts=tuple(args.starts.split(",")),  # type: ignore[arg-type]
                              resimulate=False, refinements=0, fallback_reference=None,
                              sensitivities=False, point_mass_reference=False)
    for i in args.frames:
        cfg = with_theta(template, thetas[i], name=f"frame{i}")
        c0 = time.process_time()
        lap = design_limit_lap(cfg, track, options)
        row = {"frame": i, "status": lap.status, "lap_s": lap.lap_time_s, "start": lap.start,
               "cpu_s": time.process_time() - c0}
        if lap.completed:
            row |= legs(build_airframe(cfg), lap)
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
