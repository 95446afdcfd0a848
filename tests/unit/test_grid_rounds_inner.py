"""The limit lap's inner laps (the grid-continuation starts' own grids, the fallback reference)
run no grid rounds of their own: ``grid_rounds`` applies to the lap the user asked for, so a
start costs what it costs without it (a leaked setting made the fine-grid start run its own
rounds on 45 and 90 intervals)."""

from __future__ import annotations

import os
from dataclasses import replace
from types import SimpleNamespace

from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.evaluate import DEFAULT_TRACK
from casadrone.limit import starts
from casadrone.limit.result import LapSeeds, LimitLapOptions

OPTIONS = LimitLapOptions(intervals=40, grid_rounds=3)


def _recording():
    seen = []

    def lap_of(frame, track, options, seeds):
        seen.append(options)
        return SimpleNamespace(completed=False)
    return seen, lap_of


def test_grid_continuation_starts_solve_their_grid_without_rounds():
    pb = SimpleNamespace(options=OPTIONS, frame=None, track=None, seeds=LapSeeds(),
                         layout=SimpleNamespace(intervals=40))
    for start in (starts.coarse_grid_start, starts.fine_grid_start):
        seen, lap_of = _recording()
        assert start(pb, lap_of) is None
        (opts,) = seen
        assert opts.grid_rounds == 0 and opts.intervals != 40
    # nor the fast path's fallback starts: an inner lap that fails is the outer start's failure
    fast = replace(OPTIONS, fallback_starts=("coarse-grid", "fine-grid"))
    assert starts.inner_options(fast, starts=()).fallback_starts == ()


def test_the_fallback_reference_lap_runs_no_rounds():
    seen, lap_of = _recording()
    starts._REFERENCE_LAPS.clear()
    starts.reference_lap("SY250", load(TrackConfig, DEFAULT_TRACK), OPTIONS, lap_of)
    starts._REFERENCE_LAPS.clear()
    (opts,) = seen
    assert opts.grid_rounds == 0


def test_the_command_runs_grid_rounds_with_certify_and_the_library_does_not(monkeypatch):
    """``casadrone limit-lap`` answers from the fast path's starts without rounds by default;
    ``--certify`` runs every cold start and COMMAND_GRID_ROUNDS rounds unless told
    ``--grid-rounds``; the library's default (what the evaluation and co-design fly per frame)
    stays 0 rounds."""
    from typer.testing import CliRunner

    import casadrone.limit.race as race_module
    from casadrone.cli import app
    from casadrone.config.limitlap import COMMAND_GRID_ROUNDS
    from casadrone.limit.result import LimitLap
    from casadrone.limit.search import SEARCHES

    seen, workers = [], []

    def fake(cfg, track, options, seeds=None, frame=None, pool=None):
        seen.append((options.starts, options.grid_rounds))
        workers.append(pool.workers)
        return LimitLap(status="failed", reason="not solved: the options were recorded")

    monkeypatch.setattr(race_module, "design_limit_lap", fake)
    runner = CliRunner()
    for args in ([], ["--certify"], ["--certify", "--grid-rounds", "0"], ["--grid-rounds", "2"],
                 ["--certify", "--workers", "1"], ["--workers", "3"]):
        r = runner.invoke(app, ["limit-lap", "SY250", "--json", *args])
        assert r.exit_code == 0, r.output
    fast, every = SEARCHES["fast"].starts, SEARCHES["certify"].starts
    assert seen == [(fast, 0), (every, COMMAND_GRID_ROUNDS), (every, 0), (fast, 2),
                    (every, COMMAND_GRID_ROUNDS), (fast, 0)]
    # processes: the cores this process may use with --certify, one on the fast path, or as told
    cores = len(os.sched_getaffinity(0))
    assert workers == [1, cores, cores, 1, 1, 3]
    assert COMMAND_GRID_ROUNDS > 0 and len(every) > len(fast)
    assert set(fast) | set(SEARCHES["fast"].fallback_starts) <= set(every)  # certify ⊇ fast
    assert LimitLapOptions().grid_rounds == 0
