"""The dominant frame's race against the co-design (a second method): on the co-design tests'
short track, a combination of build-small raced at its box's dominant frame without a
co-design equals its frame co-designed from the template's geometry and raced, and the co-design
lands on the dominant frame; a build ranks by co-designed frames only."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from casadrone.airframe import with_theta
from casadrone.build.checks import load_build_problem
from casadrone.build.dominance import dominant_theta, stationary
from casadrone.build.search import build, screened
from casadrone.build.solve import (
    combination_start,
    geometry_box,
    lap_options,
    race_dominant,
    race_track,
    solve_combination,
)
from casadrone.limit.lap import design_limit_lap
from casadrone.limit.race import race, with_open_circuit_voltage
from casadrone.limit.result import LapSeeds

ROOT = Path(__file__).resolve().parents[2]
SHORT = [f"track={ROOT / 'tests/data/codesign/short-track.yaml'}", "limit_lap.intervals=16",
         "limit_lap.starts=[closed-loop, point-mass, coarse-grid]", "backend.name=serial",
         "build.certify=false"]
ONE = ["build.propellers=[uiuc-da4022-5x3.75-3blade]",
       "build.motors=[tmotor-velox-v2207-v2-1750kv]"]


@pytest.fixture(scope="module")
def short():
    return load_build_problem("build-small", [*SHORT, *ONE,
                                              "build.packs=[cnhl-black-v2-1300mah-4s]"])


def test_the_dominant_frames_race_is_the_codesigned_race(short):
    (combo,), _ = screened(short)
    keys, lower, upper = geometry_box(short)
    theta = dominant_theta(combination_start(short, combo), keys, lower, upper)
    assert theta is not None
    fast = race_dominant(short, combo, None, theta)
    full = solve_combination(short, combo, None)
    assert fast.outcome == full.outcome == "raced" and fast.feasible and full.feasible
    assert fast.geometry_by == "dominance" and full.geometry_by == "co-design"
    for key in keys:  # the co-design, from the template's 125 mm arms, ends at the corner
        assert full.theta[key] == pytest.approx(theta[key], abs=0.01)
    assert fast.race_s == pytest.approx(full.race_s, rel=1e-3)
    assert fast.mass_kg == pytest.approx(full.mass_kg, rel=1e-9)
    # the race's gradient at the corner (envelope theorem) points out of the box, as forward
    # differences of the race re-solved 2 mm in say (a second method): the corner is
    # first-order optimal and the build takes its race without a co-design
    assert stationary(fast.theta, fast.race_gradient, keys, lower, upper)
    for key in keys:
        inner = race_dominant(short, combo, None, {**theta, key: theta[key] + 2.0},
                              seeds=LapSeeds(warm_starts=(fast.race_lap,)))
        assert fast.race_gradient[key] > 0
        assert (inner.race_s - fast.race_s) / 2.0 > 0, key


@pytest.fixture(scope="module")
def corner_race(short):
    """(the combination's airframe, its dominant θ, the race's options, its race there)."""
    (combo,), _ = screened(short)
    keys, lower, upper = geometry_box(short)
    cfg = combination_start(short, combo)
    theta = dominant_theta(cfg, keys, lower, upper)
    assert theta is not None
    options = replace(lap_options(short, cfg), sensitivities=True)
    return cfg, theta, options, race(with_theta(cfg, theta), race_track(short, None), options)


def test_a_race_flown_first_at_a_neighbours_end_charge_takes_one_pass(short, corner_race):
    """From the full pack the race takes two passes (the second at its end's voltage); seeded
    from it and told its end state of charge, the same race takes one, flies that charge's
    voltage, ends within SOC_TOL of it, and its time is the two-pass race's within 1e-4."""
    from casadrone.limit.race import SOC_TOL

    cfg, theta, options, run = corner_race
    assert len(run.passes) == 2 and run.passes[0].soc_flown == 1.0
    end = run.energy.end_soc
    again = race(with_theta(cfg, theta), race_track(short, None), options,
                 seeds=LapSeeds(warm_starts=(run.lap,)), soc=end)
    (one,) = again.passes
    assert one.soc_flown == end and abs(again.energy.end_soc - end) < SOC_TOL
    assert again.feasible
    assert again.lap.lap_time_s == pytest.approx(run.lap.lap_time_s, rel=1e-4)


def test_the_races_gradient_equals_central_differences_of_its_lap(short, corner_race):
    """dT/dθ of the race (the envelope theorem) against central differences of the lap
    re-solved ±0.1 mm around the corner at the race's own voltage, warm from the race, to a
    tight tolerance. The short track starts from rest at hover, so a frame's start state (its
    hover rotor speeds) moves with θ, and the start is fixed by bounds as well as by a row on
    the parameter: IPOPT put the multiplier on the bounds, and the gradient without them was
    4.0e-5 s/mm in λa and 2.45e-4 in λb against forward differences of 1.55e-4 and 1.11e-4
    (casadrone.limit.lap.start_sensitivity). With them: 1.50e-4 and 1.09e-4."""
    cfg, theta, options, run = corner_race
    keys = tuple(theta)
    volts = run.passes[-1].open_circuit_voltage_v
    again = replace(options, starts=(), sensitivities=False, resimulate=False, tol=1e-10)

    def lap_at(key: str, value: float) -> float:
        frame = with_open_circuit_voltage(with_theta(cfg, {**theta, key: value}), volts)
        out = design_limit_lap(frame, race_track(short, None), again,
                               LapSeeds(warm_starts=(run.lap,)))
        assert out.completed, out.reason
        return out.lap_time_s
    h = 0.1
    for key in keys:
        fd = (lap_at(key, theta[key] + h) - lap_at(key, theta[key] - h)) / (2 * h)
        assert run.lap.sensitivities[key] == pytest.approx(fd, rel=0.1), (key, fd)


def test_a_certified_build_ranks_codesigned_frames_only(short):
    """Two packs, rank 1, certificates asked for: the other combination is raced at its
    dominant frame alone, the winner is co-designed from its dominant frame (its co-design
    point kept for the certificate) and every CPU second is counted once."""
    problem = load_build_problem("build-small", [
        *SHORT, *ONE, "build.packs=[cnhl-ministar-650mah-4s, cnhl-black-v2-1300mah-4s]",
        "build.rank=1", "build.certify=true"])
    done = build(problem)
    (winner,) = done.ranking
    assert winner.geometry_by == "co-design" and winner.point is not None
    assert winner.certificate is not None
    assert winner.combination.pack.name == "cnhl-black-v2-1300mah-4s"
    others = [r for r in done.results if r.label != winner.label]
    assert [r.geometry_by for r in others] == ["dominance"]
    assert all(math.isfinite(r.race_s) and r.race_s > winner.race_s for r in others)
    assert len({r.label for r in done.results}) == len(done.results)
