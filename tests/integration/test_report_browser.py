"""The report renders in a real browser: headless Chromium screenshots it, figures included."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from casadrone.config.problem import BackendConfig
from casadrone.optimise.checks import load_problem
from casadrone.optimise.runner import run
from casadrone.report import write_report

ROOT = Path(__file__).resolve().parents[2]
CHROMIUM = next((shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")
                 if shutil.which(n)), None)
TAB_GREEN = np.array([44, 160, 44]) / 255  # a line of the convergence figure (no CSS colour)


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="no chromium on this machine")
def test_report_renders_with_its_figures(tmp_path):
    from matplotlib.image import imread

    problem = load_problem(ROOT / "problems" / "quick.yaml",
                           ["algorithm.population=16", "algorithm.generations=2",
                            "algorithm.settings.n_ind_ga=8"])
    run(problem, tmp_path / "run", BackendConfig(name="serial"), quiet=True)
    html = write_report(tmp_path / "run")
    shot = tmp_path / "report.png"
    subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run",
         f"--user-data-dir={tmp_path / 'profile'}", f"--screenshot={shot}",
         "--window-size=1400,4000", html.resolve().as_uri()],
        check=True, capture_output=True, timeout=120)
    rgb = imread(shot)[..., :3]
    assert rgb.shape[:2] == (4000, 1400)
    ink = np.any(rgb < 0.9, axis=2)
    assert 0.02 < ink.mean() < 0.9  # text, tables and figures, not a blank or black page
    # the first figure (convergence, below the problem tables) is drawn: its green line shows
    green = np.linalg.norm(rgb - TAB_GREEN, axis=2) < 0.12
    assert green.sum() > 300
