"""Shared test fixtures and paths."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"
DATA = Path(__file__).resolve().parent / "data"
BAD = DATA / "bad"


@pytest.fixture
def bad_dir() -> Path:
    """Folder of deliberately broken config files (``tests/data/bad``)."""
    return BAD


@pytest.fixture
def cli_runner():
    """A typer CliRunner; ``result.stdout`` and ``result.stderr`` are kept apart."""
    from typer.testing import CliRunner

    return CliRunner()


def installed_script(name: str) -> Path:
    """A console script installed with this interpreter's packages (``casadrone``, ``dask``):
    found in ``sys.executable``'s folder, never on PATH, so that a run through a virtual
    environment's python without activating it runs the same commands (and the same tests) as an
    activated one. Missing is a failure, not a skip: ``pip install -e .[dev]`` installs both."""
    path = Path(sys.executable).parent / name
    if not path.is_file():
        pytest.fail(f"{name}: no such console script beside {sys.executable} "
                    f"(install the package with pip install -e '.[dev]')")
    return path


@pytest.fixture
def console() -> list[str]:
    """The ``casadrone`` console script as a command list (see :func:`installed_script`)."""
    return [str(installed_script("casadrone"))]


# A session of at least PRECOMPILE_FROM tests (the suite, or most of it) first compiles the solver
# blocks its tests will need, side by side (casadrone.precompile: the quadrotor's limit-lap and
# co-design blocks, one to four minutes of one core each). On a fresh machine with 2 cores that is
# about 7 minutes instead of 13 spent one after the other inside the first tests that use them;
# with the cache filled it costs seconds. A few selected tests compile only what they use.
# CASADRONE_PRECOMPILE=0 turns it off.
PRECOMPILE_FROM = 200


def pytest_collection_finish(session):
    if len(session.items) < PRECOMPILE_FROM or os.environ.get("CASADRONE_PRECOMPILE") == "0":
        return
    import time

    from casadrone.precompile import SHIPPED, precompile, ready_lines

    reporter = session.config.pluginmanager.get_plugin("terminalreporter")

    def write(line: str) -> None:  # each block as it is ready: minutes on a fresh machine
        if reporter is not None:
            reporter.write_line(f"casadrone.precompile: {line}")

    t0 = time.perf_counter()
    try:
        precompile(report=ready_lines(len(SHIPPED), write))
        line = (f"{len(SHIPPED)} solver-block libraries ready in "
                f"{time.perf_counter() - t0:.1f} s")
    except Exception as err:  # e.g. no compiler: the tests that need one say so themselves
        line = f"failed ({err}); each test compiles what it uses"
    write(line)


# A skip that can fire in CI hides a test that did not run: with CASADRONE_FORBID_SKIPS=1 (set by
# .ci/run) every skipped test fails the session, listed by name.
def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if os.environ.get("CASADRONE_FORBID_SKIPS") != "1":
        return
    skipped = terminalreporter.stats.get("skipped", [])
    if skipped:
        terminalreporter.write_line(
            f"CASADRONE_FORBID_SKIPS=1: {len(skipped)} skipped test(s), which CI does not allow:",
            red=True)
        for rep in skipped:
            why = rep.longrepr[-1] if isinstance(rep.longrepr, tuple) else rep.longrepr
            terminalreporter.write_line(f"  {rep.nodeid}: {why}")


def pytest_sessionfinish(session, exitstatus):
    if os.environ.get("CASADRONE_FORBID_SKIPS") != "1" or exitstatus != 0:
        return
    reporter = session.config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None and reporter.stats.get("skipped"):
        session.exitstatus = 1
