"""Benchmark: the fast path's library start over random Table 1 frames.

For the 50 random Table 1 frames of ``benchmarks/bench_limitlap.py --n 50 --seed 0`` (SY250
template, paper track, 40 intervals), the limit lap from the shipped lap of the track alone
(the ``library`` start of ``casadrone limit-lap``'s fast path, casadrone.limit.library: a
primal-dual warm start from SY250's certified lap), against the best of the four cold starts
(closed-loop, point-mass, coarse-grid, fine-grid) recorded for the same frames in
``benchmarks/limitlap-frames50-starts.txt`` (``python benchmarks/bench_limitlap.py --n 50
--seed 0 --intervals 40 --template SY250``, RESULTS-limitlap-frames.md; the paper model's laps
have not changed since: benchmarks/RESULTS-byte-identity.md). One core; CPU of the solve
(``time.process_time``), the NLP built before the first frame.

Run: ``python benchmarks/bench_limitlap_library.py [--n 50]``. Writes
``benchmarks/RESULTS-limitlap-library.md`` (``--out``).
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import markdown, with_summary  # noqa: E402
from casadrone.airframe import random_thetas, with_theta  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402
from casadrone.config.io import load  # noqa: E402
from casadrone.config.track import DEFAULT_TRACK, TrackConfig  # noqa: E402
from casadrone.limit.lap import LimitLapOptions, design_limit_lap  # noqa: E402
from casadrone.limit.search import search_options  # noqa: E402

HERE = Path(__file__).resolve().parent
COLD = HERE / "limitlap-frames50-starts.txt"
#: The command of the recorded cold laps (its rows: "i: completed LAP s ...").
COLD_COMMAND = ("python benchmarks/bench_limitlap.py --n 50 --seed 0 --intervals 40 "
                "--template SY250")


def recorded_cold() -> dict[int, float]:
    """Frame index → the best of the four cold starts' laps (s), as recorded."""
    out = {}
    for line in COLD.read_text().splitlines():
        m = re.match(r"(\d+): completed ([\d.]+) s", line)
        if m:
            out[int(m.group(1))] = float(m.group(2))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=50)
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-limitlap-library.md")
    args = ap.parse_args(argv)
    template = load_airframe("SY250")
    track = load(TrackConfig, DEFAULT_TRACK)
    options = replace(search_options("fast", LimitLapOptions(), periodic=False),
                      point_mass_reference=False, sensitivities=False)
    thetas, _ = random_thetas(template, 50, 0)
    cold = recorded_cold()
    design_limit_lap(template, track, options)  # builds the NLP once
    rows = []
    for i, theta in enumerate(thetas[:args.n]):
        cfg = with_theta(template, theta, name=f"frame{i}")
        c0 = time.process_time()
        lap = design_limit_lap(cfg, track, options)
        cpu = time.process_time() - c0
        rel = 100 * (lap.lap_time_s / cold[i] - 1) if i in cold else float("nan")
        rows.append((i, lap.status, lap.start, lap.lap_time_s, cold.get(i, float("nan")), rel,
                     lap.iterations, lap.ending, cpu))
        print(f"{i}: {lap.status} {lap.start} {lap.lap_time_s:.4f} s (cold {cold.get(i, 0):.4f}"
              f", {rel:+.3f} %) {lap.iterations} it {cpu:.1f} s CPU", flush=True)
    ok = [r for r in rows if r[1] == "completed"]
    rel = np.array([r[5] for r in ok])
    cpu = np.array([r[8] for r in rows])
    lib = sum(r[2].startswith("library") for r in ok)
    figure = (f"{len(ok)}/{len(rows)} verified ({lib} from the library start); lap − best cold "
              f"lap {rel.min():+.2f} to {rel.max():+.2f} % (median {np.median(rel):+.2f} %), "
              f"{(rel <= 0.1).sum()}/{len(ok)} within +0.1 %; CPU {np.median(cpu):.1f} s "
              f"median, {cpu.max():.1f} s max per frame")
    cmd = "python benchmarks/bench_limitlap_library.py" + (
        f" --n {args.n}" if args.n != 50 else "")
    lines = ["# Limit lap: the fast path's library start over random Table 1 frames", "",
             "## What was measured", "", __doc__.split("\n\n", 1)[1].split("\n\nRun:")[0], "",
             f"Command: `{cmd}`; the cold laps: `{COLD_COMMAND}`.", "", markdown(), "",
             f"Result: {figure}.", "",
             "| frame | status | start | lap (s) | best cold lap (s) | difference (%) | "
             "iterations | ending | CPU (s) |", "|---|---|---|---|---|---|---|---|---|"]
    lines += [f"| {i} | {st} | {sn} | {lap:.4f} | {c:.4f} | {r:+.3f} | {it} | {e} | {cp:.2f} |"
              for i, st, sn, lap, c, r, it, e, cp in rows]
    text = "\n".join(lines) + "\n"
    args.out.write_text(with_summary(text, [(
        "limit lap of 50 random Table 1 frames (paper track) from the shipped lap alone "
        "(the fast path's library start), against the best of four cold starts", figure,
        f"`{cmd}`")]))
    print(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
