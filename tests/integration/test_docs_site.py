"""The documentation site in a real browser: every page of the built site (``mkdocs build
--strict``) is loaded in headless Chromium from a local HTTP server; each renders its heading and
figures without a console error or a failed request, and every internal link (page, file and
``#anchor``) resolves.

``.ci/run`` builds the site once and passes it in ``CASADRONE_DOCS_SITE``; without it the test
builds the site itself. In CI a missing browser fails the test (see ``chromium.py``); a missing
``mkdocs`` console script fails it everywhere. The console script's own build is always run here
(``build_site``): that is how the README says to build the site.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import urllib.error
import urllib.request
from collections import deque
from pathlib import Path
from urllib.parse import urldefrag, urlparse

import pytest
from chromium import PAGE_PROBE, Chromium, find_chromium

from tests.conftest import installed_script

ROOT = Path(__file__).resolve().parents[2]


def build_site(out: Path) -> subprocess.CompletedProcess:
    """``mkdocs build --strict`` into ``out``, run as the README and getting-started say: the
    ``mkdocs`` console script (beside ``sys.executable``), from the checkout, with no
    ``PYTHONPATH`` entry for the checkout (which would put its ``benchmarks/`` and ``docs/``
    folders on the path and hide a hook that imports from them, as ``python -m mkdocs`` did)."""
    inherited = os.environ.get("PYTHONPATH", "").split(os.pathsep)
    kept = [e for e in inherited if e and Path(ROOT, e).resolve() != ROOT]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(kept), "NO_MKDOCS_2_WARNING": "1"}
    return subprocess.run([str(installed_script("mkdocs")), "build", "--strict", "-q", "-d",
                           str(out)], cwd=ROOT, env=env, capture_output=True, text=True,
                          timeout=600)


@pytest.fixture(scope="module")
def console_site(tmp_path_factory) -> Path:
    """The site as the console script builds it, strictly (always built here)."""
    out = tmp_path_factory.mktemp("site")
    done = build_site(out)
    assert done.returncode == 0, done.stderr[-4000:]
    return out


@pytest.fixture(scope="module")
def site(request) -> Path:
    """The built site: ``CASADRONE_DOCS_SITE`` when given (``.ci/run`` builds it once), else
    :func:`console_site`."""
    given = os.environ.get("CASADRONE_DOCS_SITE")
    if given:
        path = Path(given).resolve()
        assert (path / "index.html").is_file(), f"CASADRONE_DOCS_SITE={given} holds no site"
        return path
    return request.getfixturevalue("console_site")


def test_the_console_script_builds_the_site_with_a_page_per_result_file(console_site):
    """``mkdocs build --strict`` (the console script) succeeds from the checkout; the performance
    page is the results' summaries and every ``benchmarks/RESULTS-<name>.md`` has its own page,
    holding that file's last line."""
    results = sorted((ROOT / "benchmarks").glob("RESULTS-*.md"))
    assert results
    summary = (console_site / "performance" / "index.html").read_text(encoding="utf-8")
    whole = 0
    for path in results:
        name = path.stem.removeprefix("RESULTS-")
        page = console_site / "performance" / name / "index.html"
        assert page.is_file(), f"no page for {path.name}"
        assert f'href="{name}/"' in summary, f"the performance page does not link {path.name}"
        last = [ln for ln in path.read_text(encoding="utf-8").splitlines() if ln.strip()][-1]
        words = re.findall(r"[A-Za-z]{4,}", last)[:3]
        assert all(w in page.read_text(encoding="utf-8") for w in words), (path.name, words)
        whole += page.stat().st_size
    assert len(summary) < whole / 5  # the page that was every file at once
    # the examples gallery ran its examples: what evaluate_airframe.py and quick_optimisation.py
    # print (tests/integration/test_examples.py asserts the same lines)
    gallery = (console_site / "examples" / "index.html").read_text(encoding="utf-8")
    assert "lap completed" in gallery and "flies: completed" in gallery


@pytest.fixture(scope="module")
def server(site):
    """A local HTTP server of the site (the way a user or a host serves it); its base URL."""
    proc = subprocess.Popen([sys.executable, "-u", "-m", "http.server", "0", "--bind",
                             "127.0.0.1", "--directory", str(site)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        line = proc.stdout.readline()
        port = re.search(r"port (\d+)", line)
        assert port, f"http.server said {line!r}"
        yield f"http://127.0.0.1:{port.group(1)}/"
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def is_page(url: str) -> bool:
    path = urlparse(url).path
    return path.endswith("/") or path.endswith(".html")


def test_every_page_renders_with_its_figures_and_every_link_resolves(site, server, tmp_path):
    chromium = find_chromium()
    seen: dict[str, dict] = {}
    anchors: list[tuple[str, str, str]] = []  # (from page, target page, fragment)
    files: set[str] = set()
    problems: list[str] = []
    queue = deque([server])
    with Chromium(chromium, tmp_path / "profile") as browser:
        while queue:
            url = queue.popleft()
            if url in seen:
                continue
            report = browser.load(url, PAGE_PROBE)
            probe = seen[url] = report.probe
            where = url[len(server) - 1:]
            problems += [f"{where}: {e}" for e in report.errors + report.failed_requests]
            if probe.get("h1", 0) < 1 or probe.get("text", 0) < 200:
                problems.append(f"{where}: no heading or almost no text ({probe.get('text')})")
            problems += [f"{where}: image not rendered: {i['src']}"
                         for i in probe.get("imgs", []) if not i["ok"]]
            problems += [f"{where}: empty figure ({s})" for s in probe.get("svgs", [])
                         if not (s["w"] > 50 and s["h"] > 50 and s["shapes"] > 5)]
            for link in probe.get("links", []):
                target, fragment = urldefrag(link)
                if not target.startswith(server):
                    continue  # outside the site: not followed (no network in CI)
                if is_page(target):
                    queue.append(target)
                    if fragment:
                        anchors.append((where, target, fragment))
                else:
                    files.add(target)
        for where, target, fragment in anchors:
            if fragment not in seen[target].get("ids", []):
                problems.append(f"{where}: link to {target[len(server) - 1:]}#{fragment}: "
                                "no such anchor")
    for url in sorted(files):
        try:
            with urllib.request.urlopen(url, timeout=10) as response:
                assert response.status == 200
        except (urllib.error.URLError, AssertionError) as exc:
            problems.append(f"link to {url[len(server) - 1:]}: {exc}")
    assert not problems, "\n".join(problems)

    # every page of the site was reached from the home page through its links
    pages = {server + str(p.relative_to(site).parent).replace(".", "").strip("/") + "/"
             for p in site.rglob("index.html")}
    pages = {p.replace("//", "/").replace("http:/", "http://") for p in pages}
    assert pages <= set(seen), f"pages no link reaches: {sorted(pages - set(seen))}"
    # the figures this test exists for are there: the executed tutorial's lap, the concepts'
    # airframes, the home page's picture
    assert seen[server + "tutorial/"]["svgs"], "the tutorial's lap figure is missing"
    assert seen[server + "concepts/chain/"]["svgs"], "the concept page's airframes are missing"
    assert any(i["src"].endswith(".png") for i in seen[server]["imgs"])
    assert len(seen) >= 15


def test_the_browser_check_sees_what_it_must_refuse(tmp_path):
    """The harness itself: a page with a console error, an uncaught exception, a missing image
    and a working figure is reported as such (so a clean report above means something)."""
    page = tmp_path / "bad.html"
    gif = "R0lGODlhAQABAIAAAAAAAP///yH5BAEAAAAALAAAAAABAAEAAAIBRAA7"  # a valid 1×1 GIF
    page.write_text("<html><body><h1>bad</h1><img src='missing.png'>"
                    f"<img src='data:image/gif;base64,{gif}' alt=''>"
                    "<svg width='100' height='100'><path d='M0 0L9 9'/></svg>"
                    "<script>console.error('broken on purpose'); undefined_function();</script>"
                    "</body></html>", encoding="utf-8")
    with Chromium(find_chromium(), tmp_path / "profile") as browser:
        report = browser.load(page.as_uri(), PAGE_PROBE)
    assert any("broken on purpose" in e for e in report.errors), report.errors
    assert any("undefined_function" in e for e in report.errors), report.errors
    assert any("missing.png" in r for r in report.failed_requests + report.errors), report
    assert [i["ok"] for i in report.probe["imgs"]] == [False, True]
    assert report.probe["svgs"] == [{"w": 100, "h": 100, "shapes": 1}]
