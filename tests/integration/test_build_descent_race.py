"""The descent from a dominant frame on real races (slow): build-small's winner, DA4022 +
1750 KV + 6S on the paper track, whose race's gradient at the short-arm corner points into the
box in λa. The gradient is checked against a second method (central differences of the lap
re-solved ±0.1 mm around the corner at the race's voltage), and the build's confirmation
(casadrone.build.search.confirm) ends faster than the corner, inside the box, without a
co-design, near the co-design's optimum (brute force: λa 100.3-101.7 mm)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from casadrone.airframe import with_theta
from casadrone.build import search
from casadrone.build.checks import load_build_problem
from casadrone.build.dominance import dominant_theta, stationary
from casadrone.build.search import confirm, screened
from casadrone.build.solve import (
    combination_start,
    geometry_box,
    lap_options,
    race_dominant,
    race_track,
)
from casadrone.limit.lap import design_limit_lap
from casadrone.limit.race import with_open_circuit_voltage
from casadrone.limit.result import LapSeeds
from casadrone.propulsion.electric import pack_of

pytestmark = pytest.mark.slow


def test_the_winners_corner_descends_into_the_box_by_a_gradient_that_matches_its_races(
        monkeypatch):
    problem = load_build_problem("build-small", [
        "build.propellers=[uiuc-da4022-5x3.75-3blade]",
        "build.motors=[tmotor-velox-v2207-v2-1750kv]",
        "build.packs=[cnhl-black-v2-1300mah-6s]", "build.certify=false",
        "backend.name=serial"])
    (combo,), _ = screened(problem)
    keys, lower, upper = geometry_box(problem)
    theta = dominant_theta(combination_start(problem, combo), keys, lower, upper)
    corner = race_dominant(problem, combo, None, theta)
    assert corner.feasible and not stationary(corner.theta, corner.race_gradient, keys,
                                              lower, upper)
    g = corner.race_gradient["lambda_a_mm"]
    assert g < 0  # into the box
    # the lap re-solved ±0.1 mm around the corner at the race's own voltage (two races flown
    # at voltages 0.01 of charge apart differ by as much as the step gains), tightly, warm
    cfg = combination_start(problem, combo)
    pack = pack_of(cfg.propulsion.battery)
    assert pack is not None
    volts = float(pack.ocv(corner.flown_soc))
    again = replace(lap_options(problem, cfg), starts=(), sensitivities=False,
                    resimulate=False, tol=1e-10)

    def lap_at(value: float) -> float:
        frame = with_open_circuit_voltage(with_theta(cfg, {**theta, "lambda_a_mm": value}),
                                          volts)
        return design_limit_lap(frame, race_track(problem, None), again,
                                LapSeeds(warm_starts=(corner.race_lap,))).lap_time_s
    central = (lap_at(100.1) - lap_at(99.9)) / 0.2
    assert g == pytest.approx(central, rel=0.1)  # measured: -0.333 against -0.324 ms/mm

    def codesign(*a, **k):
        raise AssertionError("co-designed")
    monkeypatch.setattr(search, "solve_combination", codesign)
    done = confirm(problem, corner, None)
    assert done.geometry_by == "descent" and done.feasible
    assert done.race_s < corner.race_s
    assert 100.0 < done.theta["lambda_a_mm"] < 102.0
    assert done.theta["lambda_b_mm"] == pytest.approx(100.0)
    assert done.cpu_s > corner.cpu_s
