"""A race whose re-simulation breaks a current limit by a little, raced again under that limit
lowered (casadrone.build.solve.current_derate, derated; casadrone.build.search.evaluate): the
factors from the race's own figures, the airframe's limits as the model builds them, and the
order of the fallbacks."""

from __future__ import annotations

import math
from dataclasses import replace

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


def test_a_limit_broken_by_a_tenth_of_an_ampere_is_lowered_by_that_much(small):
    """The motor's 36.6 A broken by 0.1 A: its factor 1 - 0.1 / 36.6, the pack's 1; the
    pack's 169 A broken by 1.69 A (1 %): 0.99."""
    _, kept = small
    pack, motor = current_derate(over(kept[0], -0.1))
    assert pack == 1.0 and motor == pytest.approx(1 - 0.1 / 36.6)
    pack, motor = current_derate(over(kept[0], 1.0, pack_margin=-1.69))
    assert pack == pytest.approx(0.99) and motor == 1.0


def test_a_derated_race_still_over_a_limit_is_lowered_again_from_its_own_derate(small):
    """A race solved under a motor limit at 0.99 of the part's that still breaks the part's
    by 0.1 A: the next factor is 0.99 × (1 - 0.1 / 36.6) (its account is against the
    part's own limit, so the excess is the part's), the pack's derate kept."""
    _, kept = small
    pack, motor = current_derate(over(kept[0], -0.1, derate=(0.98, 0.99)))
    assert pack == pytest.approx(0.98)
    assert motor == pytest.approx(0.99 * (1 - 0.1 / 36.6))
    assert motor < 0.99  # lower than the derate it broke


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


def evaluated(problem, combo, monkeypatch, answer, codesigned=None):
    """``search.evaluate`` of ``combo`` with its races answered by ``answer(n, derate)`` (n:
    the race's index) and its co-design by ``codesigned`` (an error where None); the calls'
    (seeds, soc, derate) beside the result."""
    from casadrone.build import search
    calls = []

    def race_dominant(problem_, combo_, laps, theta, bound_s, seeds=None, soc=None,
                      derate=None):
        calls.append((seeds, soc, derate))
        return answer(len(calls) - 1, derate)

    def codesign(*a, **k):
        if codesigned is None:
            raise AssertionError("co-designed")
        return codesigned
    monkeypatch.setattr(search, "race_dominant", race_dominant)
    monkeypatch.setattr(search, "solve_combination", codesign)
    return search.evaluate(problem, combo, None), calls


def test_evaluate_races_a_limit_breaker_again_derated_from_its_own_lap(small, monkeypatch):
    """The dominant race breaks the motor limit by 0.1 A: raced again from its own lap at its
    flown charge, derated; that one flies and is kept with both races' CPU; no race alone,
    no co-design."""
    problem, kept = small
    first = over(kept[0], -0.1, flown_soc=0.91, cpu_s=30.0)
    got, calls = evaluated(problem, kept[0], monkeypatch, lambda n, derate: first if n == 0
                           else over(kept[0], 0.4, feasible=True, cpu_s=10.0, race_s=4.01))
    assert len(calls) == 2
    seeds, soc, derate = calls[1]
    assert seeds.warm_starts == (first.race_lap,) and soc == 0.91
    assert derate == pytest.approx((1.0, 1 - 0.1 / 36.6))
    assert got.feasible and got.race_s == 4.01 and got.cpu_s == 40.0


def test_evaluate_derates_again_while_the_derated_race_breaks_a_limit(small, monkeypatch):
    """The first derated race still breaks the motor limit by 0.05 A: a second derate, lower
    again, from the first derated race's lap and charge; the second flies and is kept with
    the three races' CPU. One that never flies stops after MAX_DERATES derated races and
    goes on to the co-design."""
    from casadrone.build.solve import MAX_DERATES

    problem, kept = small
    first = over(kept[0], -0.1, flown_soc=0.91, cpu_s=30.0)
    still_over = over(kept[0], -0.05, flown_soc=0.9, cpu_s=10.0, race_s=4.005)
    answers = [lambda d: first, lambda d: replace(still_over, derate=d),
               lambda d: over(kept[0], 0.4, feasible=True, cpu_s=5.0, race_s=4.01, derate=d)]
    got, calls = evaluated(problem, kept[0], monkeypatch, lambda n, d: answers[n](d))
    assert len(calls) == 3
    (_, _, d1), (seeds, soc, d2) = calls[1], calls[2]
    assert soc == 0.9 and seeds.warm_starts == (still_over.race_lap,)
    assert d2[1] == pytest.approx(d1[1] * (1 - 0.05 / 36.6)) and d2[1] < d1[1]
    assert got.feasible and got.race_s == 4.01 and got.cpu_s == 45.0

    never = over(kept[0], -0.1, flown_soc=0.91, cpu_s=1.0)
    codesigned = over(kept[0], 0.3, feasible=True, cpu_s=100.0, race_s=4.02)
    got, calls = evaluated(problem, kept[0], monkeypatch,
                           lambda n, d: replace(never, derate=d), codesigned)
    assert len(calls) == 1 + MAX_DERATES
    assert got.race_s == 4.02 and got.cpu_s == 100.0 + 1 + MAX_DERATES
