"""Reference table, Eq. 21 gains and the Table-4-style benchmark of the five reference airframes."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from casadrone.benchmark import (
    DEFAULT_TRACK,
    MEASURED_LABEL,
    REFERENCE_NAMES,
    format_table,
    run_benchmark,
    to_json,
)
from casadrone.compare import gain_pct
from casadrone.config.airframe import load_airframe
from casadrone.config.io import load
from casadrone.config.reference import DEFAULT_REFERENCE, Table4Reference, load_reference
from casadrone.config.track import TrackConfig
from casadrone.optimise.checks import validate_file


def test_eq21_on_hand_numbers():
    # Eq. 21: (t_benchmark − t_candidate) / t_benchmark × 100; positive = faster
    assert gain_pct(8.0, 10.0) == pytest.approx(20.0, abs=1e-12)
    assert gain_pct(12.0, 10.0) == pytest.approx(-20.0, abs=1e-12)
    assert gain_pct(355.0, 396.7) == pytest.approx(100 * 41.7 / 396.7, rel=1e-12)  # 10.5117 %
    # maximised quantities: positive still means better
    assert gain_pct(12.0, 10.0, sense="max") == pytest.approx(20.0, abs=1e-12)
    np.testing.assert_allclose(gain_pct([5.0, 15.0], [10.0, 10.0]), [50.0, -50.0], atol=1e-12)
    with pytest.raises(ValueError, match="zero"):
        gain_pct(1.0, 0.0)
    with pytest.raises(ValueError, match="sense"):
        gain_pct(1.0, 2.0, sense="better")


def test_reference_file_validates_and_holds_table4():
    assert isinstance(validate_file(DEFAULT_REFERENCE), Table4Reference)
    ref = load_reference()
    assert tuple(ref.airframes) == REFERENCE_NAMES
    for name, row in ref.airframes.items():
        assert len(row.split_times_s) == len(row.effort_v) == 4
        assert len(row.pair_thrust_max_n) == len(row.pair_thrust_min_n) == 4
        assert load_airframe(row.airframe).name == name  # the config the row refers to
    sy = ref.airframes["SY250"]  # spot check against the printed table
    assert sy.split_times_s == [154.66, 162.33, 389.1, 396.7]
    assert sy.effort_v == [-1.16, -2.09, 1.16, -0.26]
    assert (sy.pair_thrust_max_n[1], sy.pair_thrust_min_n[1]) == (9.32, -7.45)
    assert ref.airframes["NSY200"].split_times_s[-1] == 487.5


@pytest.fixture(scope="module")
def table():
    return run_benchmark("rk4")


def test_benchmark_flies_all_five(table):
    assert [r.airframe for r in table.rows] == list(REFERENCE_NAMES)
    for r in table.rows:
        assert r.status == "completed", f"{r.airframe}: {r.reason}"
        # Plausible lap: the route is 20 m of climb plus 105 m of legs. The guidance caps the
        # speed at 15 m/s, so no lap can beat 125 m / 15 m/s ≈ 8.3 s; flown entirely at the 4 m/s
        # corner speed it would take ~31 s, so beyond 40 s the vehicle is hovering or lost.
        assert 8.0 < r.lap_time_s < 40.0
        assert r.indices["J3"] == pytest.approx(r.lap_time_s, abs=1e-12)
        assert r.indices["J1"] > r.indices["J2"] > 0  # faster on the straights than the curves
        splits = [i.split_time_s for i in r.intervals]
        assert len(splits) == 4 and np.all(np.diff(splits) > 0)
        assert r.measured is not None and r.measured.split_times_s[-1] > 300  # other time base
        for i in r.intervals:
            assert i.pair_thrust_min_N <= i.pair_thrust_max_N
            assert math.isfinite(i.effort_V)


def test_benchmark_output(table):
    text = format_table(table)
    assert MEASURED_LABEL in text
    for name in REFERENCE_NAMES:
        assert f"{name}: lap" in text
    data = json.loads(to_json(table))
    assert data["measured_label"] == MEASURED_LABEL
    assert len(data["rows"]) == 5 and len(data["rows"][0]["simulated"]) == 4
    assert data["rows"][0]["measured"]["split_times_s"][0] == 154.66
    assert data["index_units"]["J4"] == "m/s²"


def test_failed_lap_is_a_row_not_an_exception():
    short = load(TrackConfig, DEFAULT_TRACK).model_copy(update={"time_limit_s": 2.0})
    table = run_benchmark("rk4", airframes=("SY250",), track=short)
    row = table.row("SY250")
    assert row.status == "failed" and "time-out" in row.reason
    assert row.intervals == () and row.indices == {} and math.isnan(row.lap_time_s)
    assert "FAILED: time-out" in format_table(table)
    assert json.loads(to_json(table))["rows"][0]["lap_time_s"] is None
