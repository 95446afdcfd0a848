"""The limit lap's inner laps (the grid-continuation starts' own grids, the fallback reference)
run no grid rounds of their own: ``grid_rounds`` applies to the lap the user asked for, so a
start costs what it costs without it (a leaked setting made the fine-grid start run its own
rounds on 45 and 90 intervals)."""

from __future__ import annotations

from types import SimpleNamespace

from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.evaluate import DEFAULT_TRACK
from casadrone.limit import starts
from casadrone.limit.result import LimitLapOptions

OPTIONS = LimitLapOptions(intervals=40, grid_rounds=3)


def _recording():
    seen = []

    def lap_of(frame, track, options):
        seen.append(options)
        return SimpleNamespace(completed=False)
    return seen, lap_of


def test_grid_continuation_starts_solve_their_grid_without_rounds():
    pb = SimpleNamespace(options=OPTIONS, frame=None, track=None,
                         layout=SimpleNamespace(intervals=40))
    for start in (starts.coarse_grid_start, starts.fine_grid_start):
        seen, lap_of = _recording()
        assert start(pb, lap_of) is None
        (opts,) = seen
        assert opts.grid_rounds == 0 and opts.intervals != 40


def test_the_fallback_reference_lap_runs_no_rounds():
    seen, lap_of = _recording()
    starts._REFERENCE_LAPS.clear()
    starts.reference_lap("SY250", load(TrackConfig, DEFAULT_TRACK), OPTIONS, lap_of)
    starts._REFERENCE_LAPS.clear()
    (opts,) = seen
    assert opts.grid_rounds == 0
