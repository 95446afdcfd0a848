"""Benchmark: the whole ``casadrone codesign PROBLEM --json`` command's CPU, one process per
variant, after the compile cache is warm.

Each variant is the command with its overrides (``--variant NAME OVERRIDE...``; default: the
problem as shipped, and with ``codesign.starts=0``), run as a child process; its CPU is the
child's user + system time (``resource.getrusage(RUSAGE_CHILDREN)``: what ``/usr/bin/time``
reports, imports and the certificate included). Printed and written (``--json``) per variant:
the CPU, the wall time, the machine's load average before and after, the command's own phases
(``build_cpu_s``: the template's limit lap and the NLP's build; each start's CPU, lap, θ and
iterations), the best frame and lap, how many starts reach it within 0.1 %, and the
certificate (passed, lap gap, re-simulation miss).

Run: ``python benchmarks/bench_codesign_command.py codesign-paper --json out.json`` (the shipped
problem with 5 random starts, and its template start alone), or with variants:
``--variant full limit_lap.starts=[closed-loop,point-mass,coarse-grid]``.

``--template-laps point-mass closed-loop coarse-grid`` instead times, in this process, the
template's limit lap on the problem's (first) track from each start alone (``a+b``: several),
posed as co-design poses it (its intervals and gate clearance, no point-mass reference): the lap,
the start chosen, the iterations and the CPU (user + system, and the minor page faults), and the
last cold solve's CPU in IPOPT's function calls (``nlp_g``, ``nlp_jac_g``, ``nlp_hess_l``). The
first one also builds the NLP. ``--keep-heap`` first applies the command line's malloc settings
(:func:`casadrone.heap.keep_heap`), as ``casadrone codesign`` does.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: Two laps agree within this fraction (the issue's 0.1 %).
AGREE_REL = 1e-3


def run_variant(problem: str, overrides: list[str]) -> dict:
    """One command in a child process: its CPU (user + system), wall and its JSON result."""
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
           "MKL_NUM_THREADS": "1",
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "result.json"
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        load0, w0 = os.getloadavg(), time.perf_counter()
        with out.open("w") as fh:
            proc = subprocess.run([sys.executable, "-m", "casadrone", "codesign", problem,
                                   *overrides, "--json"], stdout=fh, stderr=subprocess.PIPE,
                                  text=True, env=env, cwd=ROOT)
        wall = time.perf_counter() - w0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        text = out.read_text()
    user, system = after.ru_utime - before.ru_utime, after.ru_stime - before.ru_stime
    row: dict = {"overrides": overrides, "exit": proc.returncode, "cpu_s": user + system,
                 "user_s": user, "system_s": system, "wall_s": wall,
                 "load_before": load0, "load_after": os.getloadavg()}
    if proc.returncode != 0:
        row["stderr"] = proc.stderr[-2000:]
        return row
    data = json.loads(text)
    best = data["best"]
    row.update(status=data["status"], build_cpu_s=data["build_cpu_s"],
               command_cpu_s=data["cpu_s"], best_lap_s=best and best["objective"],
               best_theta=best and best["theta"],
               starts=[{k: s[k] for k in ("label", "status", "objective", "theta",
                                          "iterations", "cpu_s")} for s in data["starts"]])
    if best:
        row["starts_at_best"] = sum(
            1 for s in data["starts"]
            if s["success"] and abs(s["objective"] - best["objective"]) <= AGREE_REL
            * best["objective"])
    cert = data.get("certificate")
    if cert:
        row["certificate"] = {"passed": cert["passed"], "reason": cert["reason"],
                              "tracks": cert["tracks"], "variables": cert["variables"]}
    return row


def template_laps(problem: str, starts: list[str], keep: bool = False) -> None:
    """The template's limit lap from each start set (see the module docstring)."""
    from dataclasses import replace

    import numpy as np

    from casadrone.codesign import driver
    from casadrone.codesign.checks import load_codesign_problem
    from casadrone.limit.lap import LimitLapOptions, design_limit_lap
    from casadrone.limit.nlp import _NLPS

    if keep:
        from casadrone.heap import keep_heap

        print(f"keep_heap: {keep_heap()}")

    cfg = load_codesign_problem(problem)
    template = driver.template_of(cfg)
    keys = tuple(v.name for v in cfg.variables)
    lower = np.array([v.lower for v in cfg.variables])
    upper = np.array([v.upper for v in cfg.variables])
    _, tracks, _ = driver._tracks(cfg)
    base = LimitLapOptions(intervals=cfg.limit_lap.intervals, sensitivities=False,
                           point_mass_reference=False,
                           gate_clearance_m=driver.gate_clearance(template, lower, upper, keys))
    for names in starts:
        r0 = resource.getrusage(resource.RUSAGE_SELF)
        lap = design_limit_lap(template, tracks[0], replace(base, starts=tuple(names.split("+"))))
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        print(f"{names}: {lap.status}, lap {lap.lap_time_s:.6f} s from {lap.start}, "
              f"{[(s.start, s.iterations) for s in lap.starts]}, "
              f"{r1.ru_utime - r0.ru_utime:.2f} s user + {r1.ru_stime - r0.ru_stime:.2f} s "
              f"system, {r1.ru_minflt - r0.ru_minflt} page faults, load "
              f"{os.getloadavg()[0]:.1f}", flush=True)
        nlp = next((n for n in _NLPS.values() if n.layout == lap.layout), None)
        if nlp is not None:
            st = nlp.cold.stats()
            print("  last cold solve: " + ", ".join(
                f"{k} {st.get('t_proc_' + k, float('nan')):.3f} s / {st.get('n_call_' + k, 0)}"
                for k in ("nlp_g", "nlp_jac_g", "nlp_hess_l")), flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problem", help="a co-design problem (path or shipped name)")
    ap.add_argument("--variant", nargs="+", action="append", metavar=("NAME", "OVERRIDE"),
                    help="a named variant and its overrides (repeatable)")
    ap.add_argument("--json", type=Path, help="write the rows here too")
    ap.add_argument("--template-laps", nargs="+", metavar="START",
                    help="time the template's limit lap from each start instead")
    ap.add_argument("--keep-heap", action="store_true",
                    help="with --template-laps: the command line's malloc settings first")
    args = ap.parse_args(argv)
    if args.template_laps:
        sys.path.insert(0, str(ROOT))
        template_laps(args.problem, args.template_laps, args.keep_heap)
        return 0
    variants = [(v[0], v[1:]) for v in args.variant] if args.variant else [
        ("shipped", []), ("template-start", ["codesign.starts=0"])]
    rows = {}
    for name, overrides in variants:
        row = run_variant(args.problem, overrides)
        rows[name] = row
        cert = row.get("certificate") or {}
        print(f"{name}: exit {row['exit']}, CPU {row['cpu_s']:.1f} s (user {row['user_s']:.1f}"
              f" + system {row['system_s']:.1f}), wall {row['wall_s']:.0f} s, load "
              f"{row['load_before'][0]:.1f}->{row['load_after'][0]:.1f}; build "
              f"{row.get('build_cpu_s', float('nan')):.1f} s; best "
              f"{row.get('best_lap_s') or float('nan'):.5f} s {row.get('best_theta')}; "
              f"{row.get('starts_at_best', 0)}/{len(row.get('starts', []))} starts within 0.1 %;"
              f" certificate {cert.get('passed')}", flush=True)
        for s in row.get("starts", []):
            print(f"    {s['label']}: {s['status']}, {s['objective']:.5f} s, "
                  f"{s['iterations']} iterations, {s['cpu_s']:.2f} s CPU", flush=True)
        if args.json:
            args.json.write_text(json.dumps(rows, indent=1, default=float))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
