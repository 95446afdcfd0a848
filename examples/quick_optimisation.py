"""Run a quick optimisation from Python, then pick the A/B/C candidates and fly them.

Run: ``python examples/quick_optimisation.py [OUT_DIR]``. Set ``CASADRONE_EXAMPLE_SMALL=1`` for a
tiny budget (the test suite does).
"""

import os
import sys
import tempfile
from pathlib import Path

import casadrone as cd

ROOT = Path(__file__).resolve().parent.parent


def main(out: str | None = None):
    small = os.environ.get("CASADRONE_EXAMPLE_SMALL") == "1"
    overrides = (["algorithm.population=16", "algorithm.generations=3",
                  "algorithm.settings.n_ind_ga=8"] if small else [])
    problem = cd.load_problem(ROOT / "problems" / "quick.yaml", overrides)
    out = Path(out or tempfile.mkdtemp(prefix="casadrone-quick-")) / "run"
    result = cd.run(problem, out, cd.BackendConfig(name="serial" if small else "processes",
                                                   workers=2), quiet=small)
    print(f"{result.n_evaluations} evaluations, {len(result.X)} Pareto-optimal airframes in {out}")

    senses = [o.sense for o in problem.objectives]
    setup = cd.default_setup(problem.airframe, problem.controller, problem.track)
    picks = {}
    for label, method, objective in (("A", "utopian", None), ("B", "compromise", None),
                                     ("C", "extreme", 0)):
        d = cd.decide(result.F, senses, method, objective)
        theta = dict(zip(result.variable_names, result.X[d.index], strict=True))
        ev = cd.evaluate(theta, setup)
        picks[label] = (theta, ev)
        geometry = ", ".join(f"{k} {v:.4g}" for k, v in theta.items())
        print(f"{label} ({method}): {geometry}\n   flies: {ev.status}, "
              + ", ".join(f"{k} {v:.3f}" for k, v in ev.indices.items()))
    return result, picks


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
