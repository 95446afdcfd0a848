"""Mutation check: plant known one-line bugs, one at a time, and see which default tests fail.

Each bug of issues 22 and 47 is planted in a temporary copy of the checkout (the package, its
tests and data; never the checkout itself), then the default tests relevant to it run there
(``-m 'not slow'``, as CI runs them). A bug that no default test fails is a blind spot of the
suite. Not run by CI (it runs the tests eight times over); run it by hand after changing the
code or the tests a mutant touches::

    python tests/mutation/plant.py                 # every bug, results table on stdout
    python tests/mutation/plant.py box-index       # one bug (names below)

Each bug is found by its exact source text anywhere under ``casadrone/`` (so a file that moves
is still found); a bug whose text is not found exactly once is reported as ``site not found``,
meaning the code changed and this script must follow it. Exit status: 0 when every planted bug
fails at least one test, 1 otherwise.

The results of the last run against main are in ``tests/mutation/RESULTS.md``.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class Mutant:
    """One planted bug: ``old`` (exact source text, found once under casadrone/) becomes
    ``new``; ``tests`` are the default-suite test files relevant to it."""

    name: str
    what: str
    old: str
    new: str
    tests: tuple[str, ...]


LIMIT_TESTS = ("tests/unit/test_limitlap.py", "tests/integration/test_limitlap_optimality.py")
MODEL_TESTS = ("tests/unit/test_trim.py", "tests/unit/test_linearise.py",
               "tests/unit/test_control.py", "tests/unit/test_airframe.py",
               "tests/integration/test_frozen_wrench.py",
               "tests/integration/test_limitlap_optimality.py")

MUTANTS = (
    Mutant("yaw-torque-sign", "yaw reaction torque sign flipped in the model",
           "s[i] * kappa * T[i] * ez", "-s[i] * kappa * T[i] * ez", MODEL_TESTS),
    Mutant("parallel-axis", "parallel-axis term dropped in the mass properties",
           "J = hub - point_inertia(mass, com)", "J = hub",
           ("tests/unit/test_massprops.py",)),
    Mutant("betaflight-swap", "Betaflight roll and pitch columns swapped",
           "Binv[:, 1], Binv[:, 2], -Binv[:, 3]", "Binv[:, 2], Binv[:, 1], -Binv[:, 3]",
           ("tests/unit/test_export.py",)),
    Mutant("box-index", "ε-archive box index off by one",
           "return np.ceil(ratio, out=ratio).astype(np.int64)",
           "return np.ceil(ratio, out=ratio).astype(np.int64) + 1",
           ("tests/unit/test_boxarchive.py", "tests/unit/test_evmoga.py")),
    Mutant("resume-previous", "resume restarts from the previous checkpoint (redoes a generation)",
           "for name in (CHECKPOINT, PREVIOUS_CHECKPOINT):",
           "for name in (PREVIOUS_CHECKPOINT, CHECKPOINT):",
           ("tests/integration/test_hardening.py", "tests/integration/test_optimise.py")),
    Mutant("bound-2K", "point-mass thrust bound 4K → 2K (the lower bound corrupted)",
           "ul[:, 3], uu[:, 3] = 0.0, 4 * rotor_thrust_bound(airframe)",
           "ul[:, 3], uu[:, 3] = 0.0, 2 * rotor_thrust_bound(airframe)", LIMIT_TESTS),
    Mutant("sensitivity-x2", "limit-lap sensitivities scaled ×2",
           "out = -point.lam_p[:len(pb.frame.p)].copy()",
           "out = -2 * point.lam_p[:len(pb.frame.p)].copy()", LIMIT_TESTS),
    Mutant("thrust-0.9K", "every rotor's thrust capped at 0.9 K inside the limit-lap NLP",
           "        return 0.0, float(airframe.thrust_gain)\n    return 0.0, max_speed(",
           "        return 0.0, 0.9 * float(airframe.thrust_gain)\n    return 0.0, max_speed(",
           LIMIT_TESTS),
    Mutant("gate-height-hw", "a rectangular gate's upper height row reads its half width",
           "(up - t.hh, -np.inf, 0.0)", "(up - t.hw, -np.inf, 0.0)",
           ("tests/unit/test_limitlap.py",)),
    Mutant("stand-lbf", "the thrust stand's lbf read as the pound's mass (g_n forgotten)",
           '"lbf": 4.4482216152605', '"lbf": 0.45359237', ("tests/unit/test_thruststand.py",)),
    Mutant("stand-kgfcm", "the thrust stand's kgf·cm read as kgf·mm",
           '"kgf·cm": G0 * 1e-2', '"kgf·cm": G0 * 1e-3', ("tests/unit/test_thruststand.py",)),
    Mutant("study-unconverged-root", "the trim study counts an unconverged solve as a root",
           "return bool(np.all(np.isfinite(tp.x0))) and tp.residual_norm <= tol",
           "return bool(np.all(np.isfinite(tp.x0)))", ("tests/unit/test_trimstudy.py",)),
    Mutant("study-no-wrap", "the trim study's root distance without its ±π wrap",
           "d[:2] = np.minimum(d[:2], 2 * math.pi - d[:2])", "d[:2] = np.minimum(d[:2], d[:2])",
           ("tests/unit/test_trimstudy.py",)),
)


def copy_checkout(dest: Path) -> None:
    """The package, tests, data and configuration of the checkout (no .git, no caches)."""
    ignore = shutil.ignore_patterns(".git", "__pycache__", "*.pyc", ".pytest_cache", "*.egg-info",
                                    "build", "dist", ".venv", "venv")
    for entry in ROOT.iterdir():
        if entry.name in {".git", ".venv", "venv", "build", "dist"}:
            continue
        target = dest / entry.name
        if entry.is_symlink():
            os.symlink(os.readlink(entry), target)
        elif entry.is_dir():
            shutil.copytree(entry, target, symlinks=True, ignore=ignore)
        else:
            shutil.copy2(entry, target)


def plant(copy: Path, mutant: Mutant) -> Path | None:
    """Replace the mutant's text in the copy; the file, or None if not found exactly once."""
    hits = [(f, f.read_text(encoding="utf-8")) for f in sorted((copy / "casadrone").rglob("*.py"))]
    hits = [(f, s) for f, s in hits if s.count(mutant.old) >= 1]
    if len(hits) != 1 or hits[0][1].count(mutant.old) != 1:
        return None
    f, s = hits[0]
    f.write_text(s.replace(mutant.old, mutant.new), encoding="utf-8")
    return f


def run_tests(copy: Path, tests: tuple[str, ...], timeout_s: float) -> tuple[str, list[str], float]:
    """Outcome (``passed``, ``failed``, ``error``, ``timeout``), the failing test ids, seconds."""
    env = {**os.environ, "PYTHONPATH": str(copy), "PYTHONDONTWRITEBYTECODE": "1"}
    env.pop("CASADRONE_FORBID_SKIPS", None)
    cmd = [sys.executable, "-m", "pytest", "-q", "-rfE", "-p", "no:cacheprovider", "-m",
           "not slow", *[t for t in tests if (copy / t.split("::")[0]).exists()]]
    start = time.perf_counter()
    try:
        done = subprocess.run(cmd, cwd=copy, env=env, capture_output=True, text=True,
                              timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return "timeout", [], time.perf_counter() - start
    failed = sorted({m.group(1) for m in re.finditer(r"^(?:FAILED|ERROR) (\S+)", done.stdout,
                                                      re.M)})
    outcome = {0: "passed", 1: "failed"}.get(done.returncode, f"error (exit {done.returncode})")
    if outcome.startswith("error"):
        failed = failed or [done.stdout.strip().splitlines()[-1] if done.stdout.strip() else
                            done.stderr.strip()[-300:]]
    return outcome, failed, time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("names", nargs="*", help="mutants to plant (default: all)")
    parser.add_argument("--timeout", type=float, default=1800.0, help="per mutant (s)")
    parser.add_argument("--sites", action="store_true",
                        help="only say where each bug would be planted (no tests run)")
    args = parser.parse_args(argv)
    chosen = [m for m in MUTANTS if not args.names or m.name in args.names]
    if args.names and len(chosen) != len(set(args.names)):
        parser.error(f"unknown mutant; choose from {', '.join(m.name for m in MUTANTS)}")
    if args.sites:
        for mutant in chosen:
            found = [f.relative_to(ROOT).as_posix() for f in sorted((ROOT / "casadrone").rglob(
                "*.py")) if mutant.old in f.read_text(encoding="utf-8")]
            print(f"{mutant.name}: {', '.join(found) or 'site not found'}")
        return 0
    rows, blind = [], 0
    for mutant in chosen:
        with tempfile.TemporaryDirectory(prefix=f"casadrone-mutant-{mutant.name}-") as tmp:
            copy = Path(tmp)
            copy_checkout(copy)
            where = plant(copy, mutant)
            if where is None:
                outcome, failed, secs = "site not found", [], 0.0
            else:
                outcome, failed, secs = run_tests(copy, mutant.tests, args.timeout)
        caught = outcome == "failed" and bool(failed)
        blind += not caught
        rows.append((mutant, outcome, failed, secs,
                     where.relative_to(copy).as_posix() if where else "-"))
        print(f"{mutant.name}: {'CAUGHT' if caught else 'NOT CAUGHT'} ({outcome}, {secs:.0f} s)"
              + "".join(f"\n    {t}" for t in failed), flush=True)
    print("\n| planted bug | file | caught by (default tests) |\n|---|---|---|")
    for mutant, outcome, failed, _, where in rows:
        by = "<br>".join(f"`{t}`" for t in failed) if outcome == "failed" else f"**{outcome}**"
        print(f"| {mutant.what} (`{mutant.name}`) | `{where}` | {by} |")
    return 1 if blind else 0


if __name__ == "__main__":
    sys.exit(main())
