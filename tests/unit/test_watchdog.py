"""The guard around fatrop's solves (casadrone.limit.watchdog): a child that stops evaluating is
ended, one that keeps evaluating is not, and a stalled fatrop solve falls back to IPOPT.

Oracles: the process table (/proc: the ended child no longer exists), wall clocks against the
stall limit, the unguarded call's own result, and IPOPT's solve of the same NLP."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from casadrone.limit.watchdog import beat, run_guarded

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="the guard needs os.fork")


def test_result_comes_back_equal_to_the_unguarded_call():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(300, 300))

    def work():
        beat()
        return np.linalg.inv(a), "label"

    got = run_guarded(work, stall_s=5.0)
    assert got.outcome == "ok" and got.cpu_s > 0
    np.testing.assert_array_equal(got.value[0], np.linalg.inv(a))
    assert got.value[1] == "label"


def test_a_silent_child_is_ended_and_gone(tmp_path):
    """A child blocked in C (select on nothing) with no beat: ended after the limit, not after
    its own 60 s, and its process no longer exists."""
    pid_file = tmp_path / "pid"

    def stall():
        pid_file.write_text(str(os.getpid()))
        beat()
        select.select([], [], [], 60.0)

    t0 = time.monotonic()
    got = run_guarded(stall, stall_s=1.0)
    took = time.monotonic() - t0
    assert got.outcome == "stalled" and "no evaluation" in got.message
    assert 1.0 <= took < 10.0, took
    pid = int(pid_file.read_text())
    assert pid != os.getpid() and not Path(f"/proc/{pid}").exists()


def test_a_child_that_keeps_evaluating_is_not_ended():
    """Four times the limit in all, beating every 0.1 s: finishes normally."""
    def busy():
        for _ in range(20):
            beat()
            time.sleep(0.1)
        return 42

    got = run_guarded(busy, stall_s=0.5)
    assert got.outcome == "ok" and got.value == 42


def test_errors_and_deaths_are_results_not_exceptions():
    def raises():
        raise RuntimeError("first line\nlast line")

    err = run_guarded(raises)
    assert err.outcome == "error" and err.message.endswith("last line")
    died = run_guarded(lambda: os._exit(3))
    assert died.outcome == "died" and died.value is None


def test_stalled_fatrop_solve_falls_back_to_ipopt(monkeypatch):
    """fatrop replaced by a solve that hangs in C: the limit-lap solve gives it up after the
    limit, says so, and returns IPOPT's optimum of the same NLP from the same start."""
    from casadrone.limit import nlp as nlp_module
    from casadrone.limit.nlp import solve
    from tests.unit.test_limitlap_stagewise import out_and_back

    nlp, w0, P, lbx, ubx = out_and_back()
    ref = solve(nlp, w0, P, lbx, ubx)

    def hangs(*args, **kwargs):
        beat()
        select.select([], [], [], 60.0)

    monkeypatch.setattr(nlp_module, "solve_stagewise", hangs)  # where solve looks them up
    monkeypatch.setattr(nlp_module, "STALL_S", 1.0)
    t0 = time.monotonic()
    sol = solve(nlp, w0, P, lbx, ubx, solver="fatrop")
    assert time.monotonic() - t0 < 20.0
    assert sol.solver == "ipopt" and sol.success
    assert sol.fatrop is not None and sol.fatrop[0].startswith("fatrop stalled")
    np.testing.assert_allclose(sol.objective, ref.objective, rtol=1e-9)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(PR_SET_PDEATHSIG)")
def test_a_killed_run_takes_its_solve_with_it(tmp_path):
    """A process guarding a solve that hangs in C is killed (SIGKILL, as a killed run is): the
    child does not outlive it (/proc), though its own stall limit (600 s) is far away."""
    pid_file = tmp_path / "child"
    script = (
        "import select, sys\n"
        "from pathlib import Path\n"
        "from casadrone.limit.watchdog import beat, run_guarded\n"
        "def hang():\n"
        f"    Path({str(pid_file)!r}).write_text(str(__import__('os').getpid()))\n"
        "    beat()\n"
        "    select.select([], [], [], 3600)\n"
        "run_guarded(hang, stall_s=600)\n")
    parent = subprocess.Popen([sys.executable, "-c", script])
    try:
        deadline = time.monotonic() + 60
        while not (pid_file.exists() and pid_file.read_text()) and time.monotonic() < deadline:
            time.sleep(0.05)
        child = int(pid_file.read_text())
        assert Path(f"/proc/{child}").exists()
    finally:
        parent.kill()
        parent.wait()
    deadline = time.monotonic() + 10
    while Path(f"/proc/{child}").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
        try:  # reaped by init once gone; a zombie still has /proc/PID: read its state
            if (Path(f"/proc/{child}/stat").read_text().split(")")[1].split()[0]) == "Z":
                break
        except (OSError, IndexError):
            break
    state = ""
    try:
        state = Path(f"/proc/{child}/stat").read_text().split(")")[1].split()[0]
    except (OSError, IndexError):
        pass
    if state not in ("", "Z"):  # the child outlived its parent: end it, then fail
        os.kill(child, signal.SIGKILL)
    assert state in ("", "Z"), f"the child {child} outlived its parent (state {state})"
