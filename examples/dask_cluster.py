"""Evaluate a generation on a Dask cluster.

With no address a LocalCluster of 2 single-threaded workers is started here; give a scheduler
address (``python examples/dask_cluster.py tcp://scheduler:8786``) to use a real cluster, whose
workers need casadrone installed (``pip install 'casadrone[dask]'``). Each worker builds and
compiles the evaluation chain once, then evaluates its share of every generation.
The same is available from the command line:
``casadrone run problems/quick.yaml --out runs/q --backend dask --scheduler tcp://…``.
"""

import os
import sys
import tempfile
from pathlib import Path

import casadrone as cd

ROOT = Path(__file__).resolve().parent.parent


def main(scheduler: str | None = None):
    small = os.environ.get("CASADRONE_EXAMPLE_SMALL") == "1"
    budget = (["algorithm.population=16", "algorithm.generations=2",
               "algorithm.settings.n_ind_ga=8"] if small else [])
    problem = cd.load_problem(ROOT / "problems" / "quick.yaml", budget)
    backend = cd.BackendConfig(name="dask", workers=2, scheduler=scheduler)
    out = Path(tempfile.mkdtemp(prefix="casadrone-dask-")) / "run"
    result = cd.run(problem, out, backend, quiet=small)
    print(f"dask: {result.n_evaluations} evaluations, {len(result.X)} on the front, in {out}")
    return result


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
