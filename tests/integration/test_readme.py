"""The README's Python block, saved verbatim to a file and run as a plain script (no
``if __name__ == "__main__":``, with the quick problem's two spawned worker processes)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def readme_python_block() -> str:
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(encoding="utf-8"),
                        re.S)
    # The tour is the first Python block; later ones (the SLURM cluster recipe) need a cluster.
    assert blocks and "import casadrone as cd" in blocks[0], "the README opens with the Python tour"
    return blocks[0]


def run_script(path: Path, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, str(path)], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def test_readme_python_block_runs_verbatim_as_a_script(tmp_path):
    script = tmp_path / "tour.py"
    script.write_text(readme_python_block(), encoding="utf-8")
    assert "__main__" not in script.read_text()
    done = run_script(script, tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    run_dir = tmp_path / "runs" / "py"
    assert (run_dir / "pareto.csv").is_file()
    assert [p.name for p in (tmp_path / "runs").iterdir()] == ["py"]  # no second, dead run
    assert "mmix 0 " in (run_dir / "A-betaflight.txt").read_text()
    assert "Traceback" not in done.stderr and "BrokenProcessPool" not in done.stderr


def test_unguarded_dask_local_cluster_is_refused_before_anything_exists(tmp_path):
    pytest.importorskip("distributed")
    script = tmp_path / "dask_run.py"
    script.write_text(textwrap.dedent("""\
        import casadrone as cd
        problem = cd.load_problem("quick", ["backend.name=dask", "backend.workers=1"])
        cd.run(problem, "runs/d")
        """), encoding="utf-8")
    done = run_script(script, tmp_path, timeout=300)
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert "dask_run.py:3" in last and """'if __name__ == "__main__":'""" in last
    assert not (tmp_path / "runs").exists()


def test_guarded_call_is_left_alone(tmp_path):
    from casadrone.optimise.mainguard import unguarded_main_call

    assert unguarded_main_call() is None  # pytest's own __main__ runs its code under the guard
    script = tmp_path / "probe.py"
    script.write_text(textwrap.dedent("""\
        from casadrone.optimise.mainguard import unguarded_main_call
        def probe():
            return unguarded_main_call()
        print("top", probe())
        if __name__ == "__main__":
            print("guarded", probe())
        """), encoding="utf-8")
    done = run_script(script, tmp_path)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == f"top {script}:4" and lines[1] == "guarded None"
