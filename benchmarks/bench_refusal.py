"""How long a refused command takes: ``casadrone report RUN --out DIR`` naming a directory must
exit 2 before any work (it used to read and evaluate the run first: 19 s). The functional test
(tests/integration/test_hardening.py) checks that the run is never read; this times it.

Run: ``python benchmarks/bench_refusal.py [--n 20]``: a one-generation run of ``quick`` is made in
a temporary directory, then the refusal is timed n times in-process (typer's CliRunner, imports
warm) and once through the console script beside this python (a cold process: imports
included). Prints the median and maximum; nothing is written to the checkout.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=20)
    args = parser.parse_args()
    from typer.testing import CliRunner

    from casadrone.cli import app
    from casadrone.config.problem import BackendConfig
    from casadrone.optimise.checks import load_problem
    from casadrone.optimise.runner import run

    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        problem = load_problem(ROOT / "problems" / "quick.yaml",
                               ["algorithm.population=8", "algorithm.generations=1",
                                "algorithm.settings.n_ind_ga=4"])
        run(problem, out, BackendConfig(name="serial"), quiet=True)
        runner, times = CliRunner(), []
        for _ in range(args.n):
            start = time.perf_counter()
            result = runner.invoke(app, ["report", str(out), "--out", tmp])
            times.append(time.perf_counter() - start)
            assert result.exit_code == 2, result.output
        start = time.perf_counter()
        done = subprocess.run([str(Path(sys.executable).parent / "casadrone"), "report", str(out),
                               "--out", tmp], capture_output=True, text=True)
        cold = time.perf_counter() - start
        assert done.returncode == 2, done.stderr
    print(f"report --out DIR refused, in-process ({args.n} runs): median "
          f"{statistics.median(times) * 1e3:.1f} ms, max {max(times) * 1e3:.1f} ms; "
          f"console script (cold process): {cold:.2f} s")


if __name__ == "__main__":
    main()
