"""A race with the pack's energy and current limits (casadrone.limit.race): the solved limit lap
keeps every re-simulated sample within the pack's and the motors' current limits, its energy
balances within 0.5 %, and a race longer than the pack lasts is refused naming the pack. Each
solves SY250-propeller's limit lap on the paper track (minutes): slow."""

from __future__ import annotations

import numpy as np
import pytest

from casadrone.config.airframe import load_airframe
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.evaluate import DEFAULT_TRACK
from casadrone.limit.race import CURRENT_TOL, race
from casadrone.limit.result import LimitLapOptions
from casadrone.limit.search import search_options

#: SY250-propeller's pack made a 4S 650 mAh pack of 100 C (65 A) and its motors limited to 25 A:
#: at full command at rest the shipped frame draws 120 A from the pack, 30 A per motor (its
#: YAML's comment), so both limits bind on a limit lap.
PACK = ["propulsion.battery.capacity_ah=0.65", "propulsion.battery.c_rating=100",
        "propulsion.battery.cells=4", "propulsion.motor.max_current_a=25"]


def flown(overrides, laps: int = 1):
    cfg = load_airframe("SY250-propeller", overrides)
    track = load(TrackConfig, DEFAULT_TRACK).model_copy(update={"laps": laps})
    return race(cfg, track, search_options("fast", LimitLapOptions(), periodic=False))


@pytest.mark.slow
def test_the_solved_race_keeps_every_sample_within_the_current_limits():
    result = flown(PACK)
    print(result.lap.lap_time_s, result.lap.cpu_time_s, result.as_dict())  # the figures, with -s
    assert result.lap.completed, result.lap.reason
    e = result.energy
    assert e is not None and e.feasible, e
    assert e.peak_pack_current_a <= 65.0 * (1 + CURRENT_TOL)
    assert e.peak_motor_current_a <= 25.0 * (1 + CURRENT_TOL)
    assert max(e.peak_pack_current_a / 65.0, e.peak_motor_current_a / 25.0) > 0.98  # binding
    assert e.pack_current_margin_a >= 0 and e.motor_current_margin_a >= 0
    assert e.energy_balance_error < 5e-3
    assert 0 < e.end_soc < 1 and e.capacity_used_pct == pytest.approx(100 * (1 - e.end_soc))
    assert np.isfinite(e.energy_left_wh) and e.energy_left_wh > 0


@pytest.mark.slow
def test_a_race_longer_than_the_pack_lasts_is_refused_naming_the_pack():
    """A 4S 10 mAh pack holds 36 C: a 4 s limit lap drawing tens of amperes empties it."""
    result = flown(["propulsion.battery.capacity_ah=0.01", "propulsion.battery.cells=4"])
    print(result.lap.lap_time_s, result.lap.cpu_time_s, result.as_dict())  # the figures, with -s
    assert result.lap.completed, result.lap.reason
    assert not result.feasible
    assert result.reason.startswith("4S 10 mAh pack empty in lap 1 of 1")
    assert result.energy is not None and result.energy.empty_at_s < result.lap.lap_time_s


def test_a_race_of_two_laps_without_a_shipped_lap_flies_from_the_fallback_start():
    """A race whose only start is the shipped lap, on a track of two laps none is shipped for
    (what `casadrone build --laps 2` asks of build-small), flies from the fallback start
    (the point mass): on the co-design tests' short track (SY250, 8 intervals per leg) it
    completes, from that start, in less than twice the one-lap flight (the second lap starts at
    speed) and more than once."""
    from pathlib import Path

    short = load(TrackConfig, Path(__file__).resolve().parents[1] / "data" / "codesign"
                 / "short-track.yaml")
    cfg = load_airframe("SY250")
    opts = LimitLapOptions(intervals=8, sensitivities=False, point_mass_reference=False,
                           starts=("library",), fallback_starts=("point-mass",))
    one = race(cfg, short, opts).lap
    two = race(cfg, short.model_copy(update={"laps": 2}), opts).lap
    assert one.completed and two.completed, (one.reason, two.reason)
    assert two.start == "point-mass"
    assert one.lap_time_s < two.lap_time_s < 2 * one.lap_time_s
