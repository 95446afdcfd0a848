"""Independent tasks side by side (casadrone.pool) and the limit lap's use of it
(casadrone.limit.parallel): results in the rows' order whatever order the tasks were handed
out or ended in; the workers' CPU counted; ``--workers`` read and refused as the command line
does. Oracles: tasks that burn a known CPU time, and that end in the reverse order of the rows
(sleeping less the later they come). The workers import this module: it imports no solver."""

from __future__ import annotations

import os
import time

import pytest

from casadrone.pool import ProcessPool, SerialPool, make_pool, pool_spec


def burn(seconds: float) -> int:
    """Spend ``seconds`` of this process's CPU time; return its pid."""
    c0 = time.process_time()
    while time.process_time() - c0 < seconds:
        pass
    return os.getpid()


def late(i: int, n: int) -> int:
    """``i``, after sleeping longer the earlier it comes (the last row ends first)."""
    time.sleep(0.05 * (n - i))
    return i


@pytest.fixture(scope="module")
def pool():
    p = ProcessPool(2)
    yield p
    p.close()


def test_a_process_pool_returns_the_rows_order_and_counts_its_workers_cpu(pool):
    n = 6
    assert list(pool.map(late, [(i, n) for i in range(n)])) == list(range(n))
    before = pool.worker_cpu_s()
    pids = list(pool.map(burn, [(0.3,)] * 4))
    assert os.getpid() not in pids and len(set(pids)) <= 2  # in the workers, at most two
    assert pool.worker_cpu_s() - before >= 4 * 0.3 - 1e-3  # at least the CPU they burnt


def test_in_order_hands_out_by_rank_and_returns_in_the_rows_order(pool):
    """The rows handed out last-first (rank -i), returned first-first."""
    from casadrone.limit.parallel import in_order  # CasADi: not in the workers' import

    handed: list[int] = []

    class Recording(SerialPool):
        def map(self, fn, rows):
            rows = list(rows)
            handed.extend(r[0] for r in rows)
            return super().map(fn, rows)

    rows = [(i, 4) for i in range(4)]
    assert in_order(Recording(), late, rows, lambda row: -row[0]) == [0, 1, 2, 3]
    assert handed == [3, 2, 1, 0]
    assert in_order(pool, late, rows, lambda row: -row[0]) == [0, 1, 2, 3]


def test_serial_pool_runs_here_and_spends_no_worker_cpu():
    p = make_pool(1)
    assert isinstance(p, SerialPool) and p.workers == 1
    assert list(p.map(burn, [(0.01,)])) == [os.getpid()]
    assert p.worker_cpu_s() == 0.0


@pytest.mark.parametrize("text, expected", [
    ("1", (1, None)), ("2", (2, None)), ("16", (16, None)),
    ("tcp://10.0.0.1:8786", (1, "tcp://10.0.0.1:8786")),
])
def test_pool_spec_reads_a_number_or_an_address(text, expected):
    assert pool_spec(text) == expected


@pytest.mark.parametrize("text, words", [("0", "at least 1"), ("-3", "at least 1"),
                                         ("two", "neither"), ("", "neither")])
def test_pool_spec_refuses_what_is_neither(text, words):
    with pytest.raises(ValueError, match=words):
        pool_spec(text)


@pytest.mark.parametrize("value", ["0", "two"])
def test_limit_lap_refuses_bad_workers_in_one_line_before_any_solve(value):
    from typer.testing import CliRunner

    from casadrone.cli import app

    t0 = time.process_time()
    out = CliRunner().invoke(app, ["limit-lap", "SY250", "--workers", value])
    assert out.exit_code == 2, out.output
    lines = [line for line in out.output.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("--workers"), out.output
    assert "Traceback" not in out.output
    assert time.process_time() - t0 < 5  # refused before the NLP is built


def pid_after(seconds: float) -> int:
    """This process's pid, after ``seconds`` (so that two tasks take both workers)."""
    time.sleep(seconds)
    return os.getpid()


#: A parent that starts a two-process pool, prints its workers' pids and waits to be killed.
PARENT = """
import sys, time
from casadrone.pool import ProcessPool
from tests.unit.test_pool import pid_after
pool = ProcessPool(2)
print(*sorted(set(pool.map(pid_after, [(0.5,), (0.5,)]))), flush=True)
time.sleep(600)
"""


def test_the_workers_end_when_their_parent_is_killed():
    """SIGKILL, which the parent cannot handle: the kernel ends its workers
    (casadrone.lifeline.worker_init, prctl PDEATHSIG) instead of leaving them running."""
    import signal
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    parent = subprocess.Popen([sys.executable, "-c", PARENT], stdout=subprocess.PIPE, text=True,
                              cwd=root, env={**os.environ, "PYTHONPATH": str(root)})
    try:
        pids = [int(p) for p in parent.stdout.readline().split()]  # type: ignore[union-attr]
        assert len(pids) == 2 and all(_alive(p) for p in pids)
    finally:
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=30)
    deadline = time.monotonic() + 10
    while any(_alive(p) for p in pids) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not any(_alive(p) for p in pids)


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, dead but not yet reaped, counts as ended)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False
