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
    assert sorted(p.name for p in (tmp_path / "runs").iterdir()) == ["py", "py-A-betaflight.txt"]
    assert "mmix 0 " in (tmp_path / "runs" / "py-A-betaflight.txt").read_text()  # beside the run
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


def test_readme_fits_a_screen_and_every_link_and_figure_exists():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 150
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [t for t in targets if "://" not in t]
    assert any(t.startswith("docs/") for t in local), "the README links into the documentation"
    missing = [t for t in local if not (ROOT / t).exists()]
    assert not missing, f"README links to missing files: {missing}"


def test_readme_figures_name_the_command_that_draws_them():
    """Each figure is followed, in its caption, by the casadrone command that reproduces it and
    the file that command writes under the same name as the figure's source."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    figures = [i for i, line in enumerate(lines) if line.startswith("![")]
    assert figures
    for i in figures:
        caption = " ".join(lines[i + 1:i + 4])
        assert "`casadrone " in caption, f"figure on line {i + 1} has no command beside it"
        assert re.search(r"writes it as `[^`]+\.png`", caption), caption


def test_readme_figure_is_what_its_command_draws(tmp_path, cli_runner):
    """The README's lap figure, redrawn by the command its caption names, at the defaults."""
    from matplotlib.image import imread

    from casadrone.cli import app

    done = cli_runner.invoke(app, ["simulate", "SY250", "--plot", str(tmp_path)])
    assert done.exit_code == 0, done.output
    new = imread(tmp_path / "track-top-view.png")
    shipped = imread(ROOT / "docs" / "sy250-lap.png")
    assert new.shape == shipped.shape
    differs = (abs(new - shipped).max(axis=2) > 0.1).mean()
    assert differs < 0.002, f"{differs:.4%} of the pixels differ"  # observed: 0 (same drawing)
