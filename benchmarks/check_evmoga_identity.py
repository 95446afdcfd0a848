"""ev-MOGA before and after the vectorised archive give bit-identical archives (issue 10, item 1).

Runs ``bench_evmoga_zdt.py``'s ev-MOGA settings (P 800, 8 children, G 2400, 20 000 evaluations;
n_div 200 for ZDT1/ZDT2, 20 for DTLZ2) with the ev-MOGA of git revision ``--old`` (default
683f05d, the sequential archive, loaded from git into a temporary module) and with the current
one, and compares the final archives (X and F, in order) bit for bit, plus the wall time of each.

Run: ``python benchmarks/check_evmoga_identity.py [--seeds 0 1 4] [--problems zdt1 zdt2 dtlz2]``
Writes ``benchmarks/RESULTS-identity.md``.
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))


def old_evmoga(revision: str):
    """The EvMOGA class of ``casadrone/optimise/evmoga.py`` at ``revision``."""
    text = subprocess.run(["git", "show", f"{revision}:casadrone/optimise/evmoga.py"], cwd=HERE,
                          capture_output=True, text=True, check=True).stdout
    path = Path(tempfile.mkdtemp()) / "evmoga_old.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("evmoga_old", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.EvMOGA


def one(cls, name: str, seed: int) -> tuple[np.ndarray, np.ndarray, float]:
    from bench_evmoga_zdt import GENERATIONS, N_IND_GA, N_IND_P, PROBLEMS
    from pymoo.optimize import minimize
    from pymoo.problems import get_problem

    kwargs, n_div = PROBLEMS[name]
    algorithm = cls(n_ind_p=N_IND_P, n_ind_ga=N_IND_GA, n_div=n_div, generations=GENERATIONS)
    start = time.perf_counter()
    res = minimize(get_problem(name, **kwargs), algorithm, ("n_gen", GENERATIONS + 1), seed=seed)
    return res.X, res.F, time.perf_counter() - start


def main() -> None:
    from casadrone.optimise.evmoga import EvMOGA

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", default="683f05d")
    parser.add_argument("--seeds", type=int, nargs="*", default=[0, 1, 4])
    parser.add_argument("--problems", nargs="*", default=["zdt1", "zdt2", "dtlz2"])
    parser.add_argument("--out", type=Path, default=HERE / "RESULTS-identity.md")
    args = parser.parse_args()
    import machine

    old = old_evmoga(args.old)
    lines = [
        "# ev-MOGA: vectorised archive against the sequential one, whole runs",
        "",
        f"`python benchmarks/check_evmoga_identity.py` — bench_evmoga_zdt.py's ev-MOGA settings "
        f"(P 800, 8 children, G 2400, 20 000 evaluations), the ev-MOGA of git {args.old} "
        "(sequential archive) against the current one; final archives compared bit for bit "
        "(X and F, in order). Wall times under the machine's load, one process each.",
        "",
        machine.markdown(),
        "",
        "| problem | seed | archive size | identical X and F | wall old (s) | wall new (s) |",
        "|---|---:|---:|---|---:|---:|",
    ]
    print("\n".join(lines), flush=True)
    ok = True
    for name in args.problems:
        for seed in args.seeds:
            X0, F0, t0 = one(old, name, seed)
            X1, F1, t1 = one(EvMOGA, name, seed)
            same = X0.shape == X1.shape and np.array_equal(X0, X1) and np.array_equal(F0, F1)
            ok &= same
            lines.append(f"| {name.upper()} | {seed} | {len(F1)} | {'yes' if same else 'NO'} "
                         f"| {t0:.1f} | {t1:.1f} |")
            print(lines[-1], flush=True)
    args.out.write_text("\n".join(lines) + "\n")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
