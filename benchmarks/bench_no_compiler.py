"""Benchmark: one candidate evaluation with and without a C compiler.

Without a C compiler (``CC`` naming no program, and an empty compile cache so that no library
compiled earlier is found) casadrone's closed-loop lap runs on CasADi's virtual machine instead
of its generated C. This times ``evaluate(θ, setup)`` for SY250 (the paper problems' frozen gain,
rk4) both ways, each in its own process on one core, after a warm-up call: the median CPU time of
``--repeats`` calls, and their ratio.

Run: ``python benchmarks/bench_no_compiler.py [--repeats 20]`` (prints; no file written).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

CHILD = """
import json, statistics, sys, time
sys.path.insert(0, {root!r})
from casadrone.evaluate import default_setup, evaluate, theta_of
setup = default_setup()
theta = theta_of(setup.template)
first = evaluate(theta, setup)
assert first.completed, (first.stage, first.reason)
cpu = []
for _ in range({repeats}):
    t = time.process_time()
    ev = evaluate(theta, setup)
    cpu.append(time.process_time() - t)
print(json.dumps({{"median_s": statistics.median(cpu), "J1": ev.indices["J1"]}}))
"""


def timed(repeats: int, compiler: bool) -> dict:
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    with tempfile.TemporaryDirectory() as cache:
        if not compiler:
            env.update(CC="no-such-compiler", CASADRONE_CACHE=cache)
        out = subprocess.run([sys.executable, "-c", CHILD.format(root=str(ROOT),
                                                                 repeats=repeats)],
                             env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=20)
    args = ap.parse_args(argv)
    c = timed(args.repeats, True)
    v = timed(max(3, args.repeats // 4), False)
    print(f"evaluate(SY250), frozen gain, rk4, one core, median CPU: compiled "
          f"{1e3 * c['median_s']:.2f} ms, virtual machine {1e3 * v['median_s']:.1f} ms "
          f"({v['median_s'] / c['median_s']:.1f}x); J1 {c['J1']:.6f} / {v['J1']:.6f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
