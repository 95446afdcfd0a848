"""The report renders in a real browser: headless Chromium loads it (figures included) without a
console error or a failed request, every link in it resolves, and a screenshot shows its first
figure drawn. In CI a missing browser fails this test (see ``chromium.py``)."""

from __future__ import annotations

from pathlib import Path
from urllib.parse import unquote, urldefrag, urlparse

import numpy as np
from chromium import PAGE_PROBE, Chromium, find_chromium

from casadrone.config.problem import BackendConfig
from casadrone.optimise.checks import load_problem
from casadrone.optimise.runner import run
from casadrone.report import write_report

ROOT = Path(__file__).resolve().parents[2]
TAB_GREEN = np.array([44, 160, 44]) / 255  # a line of the convergence figure (no CSS colour)


def test_report_renders_with_its_figures_and_links(tmp_path):
    from matplotlib.image import imread

    chromium = find_chromium()
    problem = load_problem(ROOT / "problems" / "quick.yaml",
                           ["algorithm.population=16", "algorithm.generations=2",
                            "algorithm.settings.n_ind_ga=8"])
    run(problem, tmp_path / "run", BackendConfig(name="serial"), quiet=True)
    html = write_report(tmp_path / "run").resolve()
    with Chromium(chromium, tmp_path / "profile", width=1400, height=6000) as browser:
        report = browser.load(html.as_uri(), PAGE_PROBE)
        shot = browser.screenshot(tmp_path / "report.png", full_page=False)
    assert not report.errors and not report.failed_requests, report
    probe = report.probe
    figures = probe["imgs"] + probe["svgs"]
    assert len(figures) >= 3, probe  # convergence, front, airframes at least
    assert all(i["ok"] for i in probe["imgs"]), probe["imgs"]
    assert all(s["w"] > 50 and s["h"] > 50 for s in probe["svgs"]), probe["svgs"]
    # every link: an anchor of the report itself, or a file written beside it
    local = [urldefrag(link) for link in probe["links"] if link.startswith("file:")]
    assert local, "the report links its candidates' exports"
    for target, fragment in local:
        path = Path(unquote(urlparse(target).path))
        assert path.is_file(), f"link to a missing file: {path}"
        if path == html and fragment:
            assert fragment in probe["ids"], f"link to a missing anchor: #{fragment}"

    rgb = imread(shot)[..., :3]
    assert rgb.shape[:2] == (6000, 1400)
    ink = np.any(rgb < 0.9, axis=2)
    assert 0.02 < ink.mean() < 0.9  # text, tables and figures, not a blank or black page
    # the first figure (convergence, below the verdict and problem tables) is drawn: its green
    # line shows
    green = np.linalg.norm(rgb - TAB_GREEN, axis=2) < 0.12
    assert green.sum() > 300
