"""The README's Python block, saved verbatim to a file and run as a plain script (no
``if __name__ == "__main__":``, with the quick problem's two spawned worker processes)."""

from __future__ import annotations

import json
import math
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


def test_readme_python_block_runs_verbatim_as_a_script_and_again(tmp_path):
    # run twice in the same folder, as a reader runs it again: the second run needs a new run
    # folder of its own (a run is never overwritten: a fixed "runs/py" failed the second time)
    script = tmp_path / "tour.py"
    script.write_text(readme_python_block(), encoding="utf-8")
    assert "__main__" not in script.read_text()
    for n in (1, 2):
        done = run_script(script, tmp_path)
        assert done.returncode == 0, done.stderr[-3000:]
        assert "Traceback" not in done.stderr and "BrokenProcessPool" not in done.stderr
        runs = sorted(p for p in (tmp_path / "runs").iterdir() if p.is_dir())
        assert len(runs) == n and all((r / "pareto.csv").is_file() for r in runs)
        for run_dir in runs:  # each run's export beside it, not inside
            assert "mmix 0 " in (run_dir.parent / f"{run_dir.name}-A-betaflight.txt").read_text()
    assert len(list((tmp_path / "runs").iterdir())) == 4


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


def test_readme_and_docs_state_the_recorded_compiler_less_slowdown():
    """The slowdown without a C compiler, as README and getting-started state it, is the range of
    the ratios benchmarks/RESULTS-lap.md records ("Without a C compiler"), rounded to whole
    numbers: one figure wherever it is read ("6–9×" and "about 10×" disagreed)."""
    results = (ROOT / "benchmarks" / "RESULTS-lap.md").read_text(encoding="utf-8")
    section = results.split("## Without a C compiler", 1)[1].split("\n## ", 1)[0]
    ratios = [float(r) for r in re.findall(r"\| ([\d.]+)× \|", section)]
    assert len(ratios) >= 2
    def whole(x: float) -> int:  # rounded half up (8.5× reads 9×)
        return math.floor(x + 0.5)

    stated = f"{whole(min(ratios))}–{whole(max(ratios))}× slower"
    for page in ("README.md", "docs/getting-started.md"):
        text = " ".join((ROOT / page).read_text(encoding="utf-8").split())
        assert stated in text, page
        assert "10× slower" not in text, page


def test_requirements_name_chromium():
    # the browser the browser tests need, in the README's requirements paragraph and on the
    # getting-started page's Requirements section
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    paragraph = readme.split("Requirements:", 1)[1].split("\n\n", 1)[0]
    assert "Chromium" in paragraph and "browser tests" in paragraph
    page = (ROOT / "docs" / "getting-started.md").read_text(encoding="utf-8")
    section = page.split("## Requirements", 1)[1].split("\n## ", 1)[0]
    assert "Chromium" in section and "browser tests" in section



def tour_commands() -> list[str]:
    """The command lines of the README's bash tour ("A ten-line tour"), comments dropped and
    ``&&`` chains split."""
    text = (ROOT / "README.md").read_text(encoding="utf-8").split("## A ten-line tour", 1)[1]
    block = re.search(r"```bash\n(.*?)```", text, re.S).group(1)
    lines = [line.split("  #", 1)[0].strip() for line in block.splitlines()]
    return [c.strip() for line in lines for c in line.split("&&") if c.strip()]


def test_every_tour_command_parses_and_the_trim_line_shows_the_solvers_differ(cli_runner):
    from casadrone.cli import app
    from tests.unit.test_cli_help import context

    commands = tour_commands()
    assert len(commands) >= 9
    for line in commands:
        assert context(line).command.name == line.split()[1]
    # the trim line compares the solvers where they differ (forward flight: the analytic guess
    # is not the trim; in hover every solver stopped at once, 0-1 iterations)
    (trim,) = [c for c in commands if c.split()[1] == "trim"]
    done = cli_runner.invoke(app, [*trim.split()[1:], "--json"])
    assert done.exit_code == 0, done.output
    iterations = {r["solver"]: r["iterations"] for r in json.loads(done.stdout)["results"]}
    assert len(iterations) == 3 and min(iterations.values()) >= 2
    assert iterations["nelder-mead"] > 10 * max(iterations["ipopt"], iterations["newton"])
