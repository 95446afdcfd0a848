"""Dask backend: back-to-back generations, a scheduler and workers started as separate processes
(as a cluster user does), a worker killed mid-run."""

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from casadrone.config.problem import BackendConfig
from casadrone.optimise.checks import load_problem
from casadrone.optimise.problem import Study, evaluate_rows
from casadrone.optimise.runner import run
from casadrone.rundir.store import RunStore

distributed = pytest.importorskip("distributed")

QUICK = "problems/quick.yaml"
TINY = ["algorithm.population=16", "algorithm.generations=3", "algorithm.settings.n_ind_ga=8"]
ROOT = Path(__file__).resolve().parents[2]


def _records_equal(a, b) -> bool:
    strip = [{k: v for k, v in r.__dict__.items() if k != "wall_time_s"} for r in a]
    return strip == [{k: v for k, v in r.__dict__.items() if k != "wall_time_s"} for r in b]


def test_twenty_back_to_back_evaluate_calls_all_succeed():
    """The same study evaluated 20 times in a row on one cluster: every call returns, equal to
    the serial records (the scattered study used to be released by the previous call's futures
    while the next call scattered it again: FutureCancelledError about 1 call in 10)."""
    from distributed import LocalCluster

    from casadrone.optimise.backends import DaskBackend

    study = Study(load_problem(QUICK, TINY))
    lo, hi = study.bounds
    X = lo + (hi - lo) * np.random.default_rng(0).random((6, len(lo)))
    expected = evaluate_rows(study, X)
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                      dashboard_address=None) as cluster:
        backend = DaskBackend(workers=2, scheduler=cluster.scheduler_address)
        try:
            for _ in range(20):
                assert _records_equal(backend.evaluate(study, X), expected)
        finally:
            backend.close()


# --------------------------------------------------------------------------------------------
# A scheduler and workers started with the `dask` command line, as separate processes
# --------------------------------------------------------------------------------------------


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask_cli() -> list[str]:
    """The `dask` command installed with distributed beside this python (not looked up on PATH:
    a venv's python run without activating the venv finds it too)."""
    exe = Path(sys.executable).parent / "dask"
    assert exe.is_file(), f"no `dask` console script beside {sys.executable}"
    return [str(exe)]


class DaskProcesses:
    """`dask scheduler` and `dask worker` processes on localhost, stopped at exit."""

    def __init__(self, tmp: Path):
        self.tmp, self.procs = tmp, []
        self.address = f"tcp://127.0.0.1:{_free_port()}"
        self.env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep
                    + os.environ.get("PYTHONPATH", "")}

    def start_scheduler(self) -> None:
        port = self.address.rsplit(":", 1)[1]
        self._spawn("scheduler", [*_dask_cli(), "scheduler", "--host", "127.0.0.1", "--port",
                                  port, "--dashboard-address", ":0", "--no-show"])

    def start_worker(self, name: str) -> subprocess.Popen:
        return self._spawn(name, [*_dask_cli(), "worker", self.address, "--nworkers", "1",
                                  "--nthreads", "1", "--name", name, "--no-dashboard"])

    def _spawn(self, name: str, cmd: list[str]) -> subprocess.Popen:
        log = open(self.tmp / f"{name}.log", "w")  # noqa: SIM115 (closed with the process)
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                cwd=self.tmp, start_new_session=True)
        self.procs.append((proc, log))
        return proc

    def wait_for_workers(self, n: int, timeout: float = 60.0) -> None:
        from distributed import Client

        with Client(self.address, timeout=timeout) as client:
            client.wait_for_workers(n, timeout=timeout)

    def stop(self) -> None:
        for proc, log in reversed(self.procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
            log.close()


@pytest.fixture()
def dask_processes(tmp_path):
    procs = DaskProcesses(tmp_path)
    procs.start_scheduler()
    yield procs
    procs.stop()


@pytest.fixture(scope="module")
def serial_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("serial") / "run"
    run(load_problem(QUICK, TINY), out, BackendConfig(name="serial"), quiet=True)
    return out


def test_scheduler_address_smoke(dask_processes):
    """Fast smoke test: one `dask worker` process on a `dask scheduler` process; a generation
    evaluated through --scheduler's backend equals the serial records."""
    from casadrone.optimise.backends import make_backend

    dask_processes.start_worker("w1")
    dask_processes.wait_for_workers(1)
    study = Study(load_problem(QUICK, TINY))
    lo, hi = study.bounds
    X = lo + (hi - lo) * np.random.default_rng(1).random((4, len(lo)))
    backend = make_backend(BackendConfig(name="dask", scheduler=dask_processes.address))
    try:
        assert _records_equal(backend.evaluate(study, X), evaluate_rows(study, X))
    finally:
        backend.close()


@pytest.mark.slow
def test_cli_run_on_separately_started_scheduler_equals_serial(dask_processes, serial_run,
                                                               tmp_path):
    """`casadrone run --scheduler ADDR` against `dask scheduler` + 2 `dask worker` processes
    gives the serial run's pareto.csv."""
    for name in ("w1", "w2"):
        dask_processes.start_worker(name)
    dask_processes.wait_for_workers(2)
    out = tmp_path / "dask-run"
    cli = [sys.executable, "-c", "from casadrone.cli import app; app()"]
    cmd = [*cli, "run", str(ROOT / QUICK), *TINY, "--out",
           str(out), "--backend", "dask", "--scheduler", dask_processes.address, "--quiet"]
    done = subprocess.run(cmd, capture_output=True, text=True, env=dask_processes.env,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert (out / "pareto.csv").read_text() == (serial_run / "pareto.csv").read_text()


@pytest.mark.slow
def test_worker_killed_mid_generation_gives_the_same_pareto(dask_processes, tmp_path):
    """A run on 2 `dask worker` processes; one is killed (SIGKILL) while it is evaluating a
    generation's chunk. The scheduler re-runs its chunks on the survivor: the run completes with
    the pareto.csv (and history) of the serial run."""
    import threading

    from distributed import Client

    problem = load_problem(QUICK, ["algorithm.population=16", "algorithm.generations=6",
                                   "algorithm.settings.n_ind_ga=48"])
    serial = tmp_path / "serial"
    run(problem, serial, BackendConfig(name="serial"), quiet=True)

    victim = dask_processes.start_worker("victim")
    dask_processes.start_worker("survivor")
    dask_processes.wait_for_workers(2)
    killed, stop = threading.Event(), threading.Event()

    def kill_when_busy():
        with Client(dask_processes.address) as client:
            info = client.scheduler_info()["workers"]
            addr = next(a for a, w in info.items() if w["name"] == "victim")
            while not stop.is_set():
                busy = client.processing(workers=[addr]).get(addr, ())
                if any(str(k).startswith("evaluate_rows") for k in busy):
                    os.killpg(victim.pid, signal.SIGKILL)
                    killed.set()
                    return
                time.sleep(0.002)

    def progress(gen, stats):  # start watching once generation 1 has been stored
        if gen == 1:
            threading.Thread(target=kill_when_busy, daemon=True).start()

    out = tmp_path / "dask-run"
    try:
        run(problem, out, BackendConfig(name="dask", scheduler=dask_processes.address),
            quiet=True, progress=progress)
    finally:
        stop.set()
    assert killed.is_set() and victim.wait(10) is not None
    assert RunStore(out).manifest["status"] == "completed"
    assert (out / "pareto.csv").read_text() == (serial / "pareto.csv").read_text()
    strip = [{k: v for k, v in r.items() if k != "wall_time_s"} for r in RunStore(out).history()]
    assert strip == [{k: v for k, v in r.items() if k != "wall_time_s"}
                     for r in RunStore(serial).history()]
