"""A race whose re-simulation breaks a current limit by a little, raced again under that limit
lowered (casadrone.build.solve.current_derate, derated; casadrone.build.search.evaluate): the
factors from the race's own figures, the airframe's limits as the model builds them, and the
order of the fallbacks."""

from __future__ import annotations

import math

import pytest

from casadrone.airframe import build_airframe
from casadrone.build.checks import load_build_problem
from casadrone.build.search import screened
from casadrone.build.solve import BuildResult, combination_start, current_derate, derated


@pytest.fixture(scope="module")
def small():
    problem = load_build_problem("build-small")
    return problem, screened(problem)[0]


def over(combo, motor_margin: float, pack_margin: float = 20.0, **kw) -> BuildResult:
    """A completed race at a 36.6 A motor limit and a 169 A pack limit with these margins."""
    fields = dict(race_s=4.0, feasible=False, end_soc=0.9, race_lap=object(),
                  peak_motor_current_a=36.6 - motor_margin, motor_current_margin_a=motor_margin,
                  peak_pack_current_a=169.0 - pack_margin, pack_current_margin_a=pack_margin)
    return BuildResult(combo, "raced", **(fields | kw))


def test_a_limit_broken_by_a_tenth_of_an_ampere_is_lowered_by_twice_that(small):
    """The motor's 36.6 A broken by 0.1 A: its factor 1 - 2 × 0.1 / 36.6, the pack's 1."""
    _, kept = small
    pack, motor = current_derate(over(kept[0], -0.1))
    assert pack == 1.0 and motor == pytest.approx(1 - 0.2 / 36.6)
    pack, motor = current_derate(over(kept[0], 1.0, pack_margin=-1.69))
    assert pack == pytest.approx(0.98) and motor == 1.0


def test_no_derate_for_a_flown_race_a_flat_pack_no_lap_or_a_large_excess(small):
    _, kept = small
    assert current_derate(over(kept[0], 0.5, feasible=True)) is None
    assert current_derate(over(kept[0], -0.1, end_soc=-0.01)) is None  # ran out: not a node
    assert current_derate(over(kept[0], -0.1, race_lap=None)) is None
    assert current_derate(over(kept[0], -0.1 * 36.6)) is None  # 10 % over: not the nodes
    assert current_derate(over(kept[0], math.nan, pack_margin=math.nan)) is None


def test_derated_limits_are_the_models_limits_scaled(small):
    """The airframe the model builds from the derated config has each limit scaled: the
    motor's own ``max_current_a``, the pack's C rating × capacity."""
    problem, kept = small
    cfg = combination_start(problem, kept[0])
    plain, low = build_airframe(cfg), build_airframe(derated(cfg, 0.9, 0.99))
    assert low.max_motor_current_a == pytest.approx(0.99 * plain.max_motor_current_a)
    assert low.max_pack_current_a == pytest.approx(0.9 * plain.max_pack_current_a)
    assert low.mass == plain.mass


def test_evaluate_races_a_limit_breaker_again_derated_from_its_own_lap(small, monkeypatch):
    """The dominant race breaks the motor limit by 0.1 A: raced again from its own lap at its
    flown charge, derated; that one flies and is kept with both races' CPU; no race alone,
    no co-design."""
    from casadrone.build import search

    problem, kept = small
    first = over(kept[0], -0.1, flown_soc=0.91, cpu_s=30.0)
    calls = []

    def race_dominant(problem_, combo, laps, theta, bound_s, seeds=None, soc=None,
                      derate=None):
        calls.append((seeds, soc, derate))
        if derate is None:
            return first
        return over(combo, 0.4, feasible=True, cpu_s=10.0, race_s=4.01)

    def codesign(*a, **k):
        raise AssertionError("co-designed")
    monkeypatch.setattr(search, "race_dominant", race_dominant)
    monkeypatch.setattr(search, "solve_combination", codesign)
    got = search.evaluate(problem, kept[0], None)
    assert len(calls) == 2
    seeds, soc, derate = calls[1]
    assert seeds.warm_starts == (first.race_lap,) and soc == 0.91
    assert derate == pytest.approx((1.0, 1 - 0.2 / 36.6))
    assert got.feasible and got.race_s == 4.01 and got.cpu_s == 40.0
