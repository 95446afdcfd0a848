"""The limit lap side by side (casadrone.limit.parallel) gives the lap of one process: the same
starts, misses, chosen optimum and JSON apart from timings, with two spawned processes and with
a two-worker Dask LocalCluster. The case: SY250 on a 30 m straight and a 2.5 m curve, 10
intervals per leg, the ``--certify`` search (four cold starts, grid rounds, sensitivities), the
cheapest one whose starts and rounds all run (about 15 s of CPU in one process).

Oracle: the serial call, the one the parallel path must reproduce bit for bit (IPOPT with MUMPS
is deterministic for the same inputs); that the work was done in the workers, not here: their
CPU (casadrone.pool) and the result's ``workers``."""

from __future__ import annotations

import json

import pytest

from casadrone.cli.common import jsonable
from casadrone.config.airframe import load_airframe
from casadrone.limit.lap import LimitLapOptions, design_limit_lap
from casadrone.limit.search import search_options
from casadrone.pool import DaskPool, ProcessPool
from tests.integration.test_limitlap_optimality import TRACK

pytestmark = pytest.mark.slow

OPTIONS = search_options("certify", LimitLapOptions(intervals=10), periodic=False)
TIMINGS = ("cpu_time_s", "wall_time_s", "workers")


def untimed(lap) -> str:
    """The lap's JSON without what a pool changes: CPU, wall time and the number of workers."""
    d = {k: v for k, v in jsonable(lap.as_dict()).items() if k not in TIMINGS}
    d["starts"] = [{k: v for k, v in s.items() if k != "wall_time_s"} for s in d["starts"]]
    return json.dumps(d, sort_keys=True, allow_nan=True)


@pytest.fixture(scope="module")
def serial():
    lap = design_limit_lap(load_airframe("SY250"), TRACK, OPTIONS)
    assert lap.completed and lap.workers == 1, lap.reason
    assert any(s.start.startswith("grid-") for s in lap.starts)  # the rounds ran
    return lap


def _same_through(pool, serial) -> None:
    try:
        lap = design_limit_lap(load_airframe("SY250"), TRACK, OPTIONS, pool=pool)
        worker_cpu = pool.worker_cpu_s()
    finally:
        pool.close()
    assert lap.workers == 2 and worker_cpu > 1.0  # the solves ran in the workers
    assert lap.cpu_time_s >= worker_cpu
    assert lap.lap_time_s == serial.lap_time_s and lap.start == serial.start
    # repr: a start that did not run (the library's on a track with no shipped lap) has NaN
    # figures, equal in print where == says NaN != NaN
    assert [repr((s.start, s.lap_time_s, s.resimulation_miss_m)) for s in lap.starts] == \
        [repr((s.start, s.lap_time_s, s.resimulation_miss_m)) for s in serial.starts]
    assert untimed(lap) == untimed(serial)


def test_two_processes_give_the_lap_of_one(serial):
    _same_through(ProcessPool(2), serial)


def test_a_dask_cluster_gives_the_lap_of_one(serial):
    pytest.importorskip("distributed")
    _same_through(DaskPool(2), serial)
