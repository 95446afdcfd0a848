"""Benchmark: ``paper`` against ``propeller`` warm limit-lap solves on the *same* grid (issue 17).

Why. Issue 17 asks that a ``propeller`` warm solve cost ≤ 1.5× a ``paper`` one. Measured at each
model's default grid (``bench_propulsion.py --warm``) it costs 5–7×, but ``propeller`` needs a
finer grid than ``paper`` to follow its rotor speeds (80 × 3 RK4 steps per leg, or 50 × 4
exponential steps, against ``paper``'s 40 × 3; 40 × 3 misses the re-simulation by 0.3–0.5 m:
``RESULTS-propulsion.md``). This script removes the grid from the comparison: both models on
the same grids, so that what is left is what the model costs per iteration and in iterations.
Both NLPs have the same sizes (16 states, 4 commands per interval), so the same KKT structure.

For each ``--grids`` entry ``MODEL:INTERVALS:SUBSTEPS:ROTOR_STEP``: SY250 (``paper``) or
SY250-propeller on the paper track, its NLP solved from the point-mass start (IPOPT, cold, the
library's options), then ``--n`` neighbours (θ within ±5 % of the Table 1 range: the draws of
``bench_propulsion.py --warm``) each from that optimum's primal-dual warm start with the
library's far warm setting (``solve(..., warm=...)``, the NLP alone, no re-simulation): CPU
(process time, one core), iterations and CPU per iteration.

Run: ``python benchmarks/bench_propulsion_samegrid.py [--n 4] [--grids
paper:40:3:rk4,propeller:40:3:rk4,propeller:40:4:exponential,propeller:80:3:rk4]``
(markdown on stdout).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.bench_propulsion import frame_name  # noqa: E402
from benchmarks.bench_propulsion_warm import neighbours  # noqa: E402
from benchmarks.machine import cpu_time, markdown  # noqa: E402
from casadrone.airframe import build_airframe  # noqa: E402
from casadrone.config import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import TrackConfig  # noqa: E402
from casadrone.evaluate import DEFAULT_TRACK  # noqa: E402
from casadrone.limit.lap import LimitLapOptions, frame_clearance_m  # noqa: E402
from casadrone.limit.nlp import solve  # noqa: E402
from casadrone.limit.starts import prepare  # noqa: E402

#: paper's default grid for both models, propeller's exponential step on it, propeller's default
GRIDS = "paper:40:3:rk4,propeller:40:3:rk4,propeller:40:4:exponential,propeller:80:3:rk4"


def grid_runs(spec: str, n: int, seed: int) -> dict:
    """The base solve and the ``n`` warm solves of one ``MODEL:INTERVALS:SUBSTEPS:ROTOR_STEP``."""
    model, intervals, substeps, step = spec.split(":")
    track = load(TrackConfig, DEFAULT_TRACK)
    cfg = load_airframe(frame_name("SY250", model))
    options = LimitLapOptions(intervals=int(intervals), substeps=int(substeps),
                              rotor_step=step, sensitivities=False)  # type: ignore[arg-type]

    def problem(c):
        frame = build_airframe(c)
        return prepare(frame, track, options, frame_clearance_m(frame, c.prop_diameter_mm / 1000))

    pb = problem(cfg)
    c0 = cpu_time()
    base = solve(pb.full, pb.lifted, pb.P, *pb.box, lbg=pb.rows[0], ubg=pb.rows[1])
    out = {"spec": spec, "base": (base.return_status, base.objective, base.iterations,
                                  cpu_time() - c0), "warm": []}
    print(spec, "base", *out["base"], file=sys.stderr, flush=True)
    if not base.success:
        return out
    for near in neighbours(cfg, n, seed):
        q = problem(near)
        c0 = cpu_time()
        s = solve(q.full, base.point.w, q.P, *q.box, warm=base.point, lbg=q.rows[0],
                  ubg=q.rows[1])
        out["warm"].append({"ok": s.success, "it": s.iterations, "cpu": cpu_time() - c0,
                            "lap": s.objective})
        print(spec, out["warm"][-1], file=sys.stderr, flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--grids", default=GRIDS)
    args = ap.parse_args(argv)
    runs = [grid_runs(spec, args.n, args.seed) for spec in args.grids.split(",")]
    ref = next((r for r in runs if r["spec"].startswith("paper:") and r["warm"]), None)
    ref_cpu = np.median([w["cpu"] for w in ref["warm"]]) if ref else np.nan
    ref_ms = np.median([1000 * w["cpu"] / max(w["it"], 1) for w in ref["warm"]]) if ref \
        else np.nan
    lines = [markdown(), "", f"Command: `python benchmarks/bench_propulsion_samegrid.py --n "
             f"{args.n} --seed {args.seed} --grids {args.grids}`", "",
             "| model: intervals per leg × steps, step | base lap from the point-mass start "
             "(status, lap, iterations, CPU) | warm solves converged | iterations median "
             "(range) | CPU median / max (s) | ms per iteration (median) | CPU against "
             "`paper` | ms per iteration against `paper` |", "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        status, lap, it, cpu = r["base"]
        model, intervals, substeps, step = r["spec"].split(":")
        w = r["warm"]
        if not w:
            lines.append(f"| `{model}`: {intervals} × {substeps}, {step} | {status} | – | – | – "
                         "| – | – | – |")
            continue
        its = np.array([x["it"] for x in w])
        cpus = np.array([x["cpu"] for x in w])
        ms = np.median(1000 * cpus / np.maximum(its, 1))
        lines.append(
            f"| `{model}`: {intervals} × {substeps}, {step} | {status}, {lap:.4f} s, {it}, "
            f"{cpu:.1f} s | {sum(x['ok'] for x in w)}/{len(w)} | {np.median(its):g} "
            f"({its.min()}–{its.max()}) | {np.median(cpus):.2f} / {cpus.max():.2f} | {ms:.1f} "
            f"| {np.median(cpus) / ref_cpu:.2f}× | {ms / ref_ms:.2f}× |")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
