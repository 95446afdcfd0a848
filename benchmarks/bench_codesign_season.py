"""Benchmark: the season frame (paper track + gate track) beside each track's own fastest frame.

Runs ``casadrone codesign --json`` on ``codesign-season`` (the sum of both limit laps),
``codesign-paper`` and ``codesign-gates`` (each track alone) with the same overrides (default
``codesign.starts=0 limit_lap.intervals=20``: the template start, 20 intervals per leg), each under
``/usr/bin/time`` (CPU = user + system), into ``--dir``; then prints, per track, the season
frame's lap beside the single-track optimum's, both frames' θ, and why each frame is what it is:
the certificate's variable states and reduced gradients and the active constraints with their
multipliers.

Run: ``python benchmarks/bench_codesign_season.py --dir /tmp/season`` (add ``--read`` to only
print the tables of an earlier run). ``--cross NAME.json`` instead flies the frame of one
single-track result (``casadrone codesign codesign-gates ... --json`` written to a file) on the
season's other tracks: its limit lap from the default three starts, posed as co-design poses it
(the same gate clearance and intervals; ``--intervals``, default 40).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

PROBLEMS = ("codesign-season", "codesign-paper", "codesign-gates")
TRACK_OF = {"codesign-paper": "paper", "codesign-gates": "gates"}  # the season's labels


def run(folder: Path, overrides: list[str]) -> None:
    root = Path(__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=str(root))
    for name in PROBLEMS:
        with open(folder / f"{name}.json", "w") as out, open(folder / f"{name}.err", "w") as err:
            subprocess.run(["/usr/bin/time", "-f", "%U %S %e", "-o", str(folder / f"{name}.time"),
                            sys.executable, "-m", "casadrone", "codesign", name, *overrides,
                            "--json"], stdout=out, stderr=err, env=env, check=False)


def _why(result: dict) -> str:
    cert = result.get("certificate") or {}
    parts = [f"{v['key']} {v['state']} (reduced {v['reduced_gradient']:+.3g} s/box)"
             for v in cert.get("variables", []) if v["state"] != "interior"]
    parts += [f"{k} ({v:+.3g})" for k, v in cert.get("active_constraints", {}).items()]
    return "; ".join(parts) or "none"


def tables(folder: Path) -> str:
    results = {n: json.loads((folder / f"{n}.json").read_text()) for n in PROBLEMS}
    cpu = {}
    for n in PROBLEMS:
        user, system, wall = (float(v) for v in (folder / f"{n}.time").read_text().split()[-3:])
        cpu[n] = (user + system, wall)
    season = results["codesign-season"]["best"]
    keys = results["codesign-season"]["keys"]
    out = ["| frame | " + " | ".join(keys) + " | lap paper (s) | lap gates (s) | sum (s) | "
           "certificate | CPU (s) |", "|---" * (len(keys) + 6) + "|"]

    def row(label: str, name: str, laps: dict) -> str:
        r = results[name]
        th = " | ".join(f"{r['best']['theta'][k]:.2f}" for k in keys)
        cert = (r.get("certificate") or {}).get("passed")
        lp, lg = laps.get("paper", float("nan")), laps.get("gates", float("nan"))
        return (f"| {label} | {th} | {lp:.4f} | {lg:.4f} | {lp + lg:.4f} | "
                f"{'passed' if cert else 'FAILED'} | {cpu[name][0]:.0f} |")

    out.append(row("season (sum)", "codesign-season", season["laps_s"]))
    for name, label in TRACK_OF.items():
        out.append(row(f"{label} alone", name, {label: results[name]["best"]["objective"]}))
    lines = ["\n".join(out), ""]
    for name, label in TRACK_OF.items():
        own = results[name]["best"]["objective"]
        lap = season["laps_s"][label]
        lines.append(f"- {label}: season frame {lap:.4f} s against its own optimum {own:.4f} s "
                     f"({100 * (lap - own) / own:+.3f} %).")
    lines.append("")
    for name in PROBLEMS:
        lines.append(f"- why, {name}: {_why(results[name])}")
    return "\n".join(lines)


def cross(path: Path, intervals: int) -> None:
    """The single-track optimum of ``path`` flown on the season's other tracks (its own limit
    lap, the default starts), printed with its CPU."""
    import time

    import numpy as np

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
    from casadrone.airframe import with_theta
    from casadrone.codesign import driver
    from casadrone.codesign.checks import load_codesign_problem
    from casadrone.config.codesign import DEFAULT_LAP_STARTS
    from casadrone.limit.lap import LimitLapOptions, design_limit_lap

    result = json.loads(path.read_text())
    cfg = load_codesign_problem("codesign-season")
    template = driver.template_of(cfg)
    keys = tuple(v.name for v in cfg.variables)
    lower = np.array([v.lower for v in cfg.variables])
    upper = np.array([v.upper for v in cfg.variables])
    labels, tracks, _ = driver._tracks(cfg)
    options = LimitLapOptions(intervals=intervals, sensitivities=False,
                              point_mass_reference=False, starts=DEFAULT_LAP_STARTS,
                              gate_clearance_m=driver.gate_clearance(template, lower, upper,
                                                                     keys))
    frame = with_theta(template, result["best"]["theta"])
    for label, track in zip(labels, tracks, strict=True):
        if track.name in result["best"]["laps_s"]:
            continue
        c0 = time.process_time()
        lap = design_limit_lap(frame, track, options)
        print(f"{result['problem']} frame {result['best']['theta']} on {label}: {lap.status}, "
              f"{lap.lap_time_s:.6f} s from {lap.start}, miss {lap.resimulation_miss_m:.4f} m, "
              f"{time.process_time() - c0:.1f} s CPU", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", type=Path)
    ap.add_argument("--read", action="store_true", help="only print the tables")
    ap.add_argument("--cross", type=Path, help="fly this single-track result's frame on the "
                    "other tracks instead")
    ap.add_argument("--intervals", type=int, default=40, help="intervals per leg of --cross")
    ap.add_argument("overrides", nargs="*",
                    default=["codesign.starts=0", "limit_lap.intervals=20"])
    args = ap.parse_args(argv)
    if args.cross:
        cross(args.cross, args.intervals)
        return 0
    if args.dir is None:
        ap.error("give --dir (or --cross)")
    if not args.read:
        args.dir.mkdir(parents=True, exist_ok=True)
        run(args.dir, args.overrides)
    print(tables(args.dir))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
