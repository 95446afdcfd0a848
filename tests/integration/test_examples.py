"""Every example runs (tiny budgets via CASADRONE_EXAMPLE_SMALL) and prints what it promises."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def run_example(name: str, *args: str) -> str:
    env = {**os.environ, "CASADRONE_EXAMPLE_SMALL": "1"}
    out = subprocess.run([sys.executable, str(ROOT / "examples" / name), *args], cwd=ROOT,
                         env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout


def test_evaluate_airframe():
    text = run_example("evaluate_airframe.py", "NSY200")
    assert "lap completed" in text
    assert text.count("waypoint ") == 4
    for key in ("J1", "J2", "J3", "J4", "J5", "Jp"):
        assert f"  {key} = " in text


def test_trim_solvers_split_matches_hand_ratio():
    text = run_example("trim_solvers.py")
    line = next(ln for ln in text.splitlines() if ln.startswith("hover front/rear thrust ratio"))
    solver = float(line.split("solver ")[1].split(",")[0])
    by_hand = float(line.split("= ")[-1])
    assert solver == pytest.approx(by_hand, rel=1e-9)
    assert text.count("True") == 6  # three solvers converge in hover and forward flight


def test_quick_optimisation_candidates_fly(tmp_path):
    text = run_example("quick_optimisation.py", str(tmp_path))
    for label in ("A (utopian)", "B (compromise)", "C (extreme)"):
        assert label in text
    assert text.count("flies: completed") == 3
    assert (tmp_path / "run" / "pareto.csv").exists()


def test_custom_index_is_optimised(tmp_path):
    text = run_example("custom_index.py", str(tmp_path))
    assert "trade altitude holding against lap time" in text
    header = (tmp_path / "run" / "pareto.csv").read_text().splitlines()[0].split(",")
    assert header[-2:] == ["Jz", "J3"]


@pytest.mark.slow
def test_dask_cluster():
    pytest.importorskip("distributed")
    text = run_example("dask_cluster.py")
    # 16 + 2 x 8 evaluations, whatever the cluster prints around it
    assert "dask: 32 evaluations" in text, text
