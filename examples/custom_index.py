"""Define a custom index and optimise it: altitude holding (examples/plugins/altitude_hold.py)
against lap time.

Run: ``python examples/custom_index.py [OUT_DIR]`` (``CASADRONE_EXAMPLE_SMALL=1``: tiny budget).
"""

import os
import sys
import tempfile
from pathlib import Path

import casadrone as cd

ROOT = Path(__file__).resolve().parent.parent
PLUGIN = "examples/plugins/altitude_hold.py"


def main(out: str | None = None):
    small = os.environ.get("CASADRONE_EXAMPLE_SMALL") == "1"
    budget = (["algorithm.population=16", "algorithm.generations=3",
               "algorithm.settings.n_ind_ga=8"] if small
              else ["algorithm.population=60", "algorithm.generations=20",
                    "algorithm.settings.n_ind_ga=30"])
    problem = cd.load_problem(ROOT / "problems" / "quick.yaml", budget + [
        f"plugins=[{PLUGIN}]",
        "objectives=[{index: Jz, sense: min}, {index: J3, sense: min}]",
        "constraints=[]",
    ])
    out = Path(out or tempfile.mkdtemp(prefix="casadrone-custom-")) / "run"
    result = cd.run(problem, out, cd.BackendConfig(name="serial" if small else "processes",
                                                   workers=2), quiet=True)
    print(f"{len(result.X)} airframes trade altitude holding against lap time:")
    for x, f in zip(result.X, result.F, strict=True):
        print(f"  Jz {f[0]:.4f} m  J3 {f[1]:.3f} s   alpha {x[2]:.1f} deg  beta {x[3]:.1f} deg")
    return result


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else None)
