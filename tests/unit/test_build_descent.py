"""The descent of a ranked dominant race along its own gradient (casadrone.build.descent),
checked on races whose time is a known function of the frame: a quadratic in λa whose minimum
is inside the box (the secant is exact there: the optimum in two races), a race the pack cannot
fly past a frame (the step shrinks, the last feasible race is kept), and a gain too small to
chase (stops after one race); and the build's confirmation using it instead of a co-design."""

from __future__ import annotations

import math

import numpy as np
import pytest

from casadrone.build import descent
from casadrone.build.checks import load_build_problem
from casadrone.build.dominance import stationary
from casadrone.build.search import screened
from casadrone.build.solve import BuildResult

KEYS = ("lambda_a_mm", "lambda_b_mm")
LOWER, UPPER = np.array([100.0, 100.0]), np.array([150.0, 150.0])
T0, SLOPE_B = 4.0, 1.2e-3  # s; s per mm of λb (pointing out of the box at its lower bound)


@pytest.fixture(scope="module")
def combo():
    problem = load_build_problem("build-small")
    return problem, screened(problem)[0][0]


def bowl(a_star: float, curvature: float, feasible_below: float = math.inf):
    """T(λa, λb) = T0 + c (λa - a*)² + SLOPE_B (λb - 100) and its exact gradient; the race
    infeasible (no lap, no gradient) at λa above ``feasible_below``."""
    def time_of(theta):
        return T0 + curvature * (theta[KEYS[0]] - a_star) ** 2 + SLOPE_B * (theta[KEYS[1]] - 100)

    def race(combo, theta, cpu=20.0):
        ok = theta[KEYS[0]] <= feasible_below
        grad = {KEYS[0]: 2 * curvature * (theta[KEYS[0]] - a_star), KEYS[1]: SLOPE_B} if ok \
            else {}
        return BuildResult(combo, "raced", race_s=time_of(theta) if ok else math.nan,
                           feasible=ok, theta=dict(theta), race_gradient=grad, cpu_s=cpu,
                           geometry_by="dominance")
    return time_of, race


def run(combo, race, start):
    seen = []

    def race_at(theta, near):
        seen.append((dict(theta), near.theta))
        return race(combo, theta)

    def flat(r):
        return stationary(r.theta, r.race_gradient, KEYS, LOWER, UPPER)
    first = race(combo, start, cpu=30.0)
    best, settled = descent.descend(first, KEYS, LOWER, UPPER, race_at, flat)
    return first, best, settled, seen


def test_a_quadratic_race_reaches_its_optimum_inside_the_box_in_two_races(combo):
    """From the corner (100, 100), a* = 101.3 mm, 1 ms/mm² (the gain left after the first step,
    0.64 ms, is above the tolerance): the first step is 1 % of the box (0.5 mm);
    the secant of two exact gradients of a quadratic is its curvature, so the second race is at
    a* itself; λb, whose slope points out of the box, stays at its bound. Each race starts from
    the best before it; the CPU is all three races'."""
    _, problem_combo = combo
    _, race = bowl(101.3, 1e-3)
    first, best, settled, seen = run(problem_combo, race, {KEYS[0]: 100.0, KEYS[1]: 100.0})
    assert settled and best.geometry_by == "descent"
    assert [t[KEYS[0]] for t, _ in seen] == pytest.approx([100.5, 101.3], abs=1e-9)
    assert best.theta[KEYS[0]] == pytest.approx(101.3, abs=1e-9)
    assert best.theta[KEYS[1]] == 100.0
    assert seen[1][1][KEYS[0]] == pytest.approx(100.5)  # the second race starts from the first
    assert best.race_s == pytest.approx(T0) and best.race_s < first.race_s
    assert best.cpu_s == pytest.approx(70.0)


def test_a_step_the_pack_cannot_fly_shrinks_and_the_fastest_flown_race_is_kept(combo):
    """a* = 103 mm but no lap past 100.2 mm: the 0.5 mm step fails (no gradient: halved), so
    does 0.25 mm, 0.125 mm flies and is faster; three races spent, the gradient still points
    in: not settled (the build co-designs from 100.125 mm)."""
    _, problem_combo = combo
    time_of, race = bowl(103.0, 2e-4, feasible_below=100.2)
    first, best, settled, seen = run(problem_combo, race, {KEYS[0]: 100.0, KEYS[1]: 100.0})
    assert [t[KEYS[0]] for t, _ in seen] == pytest.approx([100.5, 100.25, 100.125])
    assert not settled and best.feasible
    assert best.theta[KEYS[0]] == pytest.approx(100.125)
    assert best.race_s == pytest.approx(time_of(best.theta)) and best.race_s < first.race_s
    assert best.cpu_s == pytest.approx(90.0)


def test_a_gain_below_the_tolerance_is_not_chased(combo):
    """A bowl as shallow as build-small's winner's (c = 0.115 ms/mm², a* = 101.3 mm: a slope
    of -0.3 ms/mm at the corner, its co-designs at λa 100.3-101.7 mm): after the 0.5 mm
    step the secant (exact here) says c (a* - 100.5)² = 0.07 ms is left, below 1e-4 of the
    race: it stops there, settled, after one race."""
    _, problem_combo = combo
    _, race = bowl(101.3, 1.15e-4)
    left = 1.15e-4 * (101.3 - 100.5) ** 2
    assert left < descent.GAIN_RTOL * T0
    _, best, settled, seen = run(problem_combo, race, {KEYS[0]: 100.0, KEYS[1]: 100.0})
    assert len(seen) == 1 and settled
    assert best.theta[KEYS[0]] == pytest.approx(100.5)


def test_a_slower_step_keeps_the_dominant_race(combo):
    """a* below the corner cannot be reached (the box stops it) but a gradient that lies
    (it says -1e-3 s/mm while every step is slower) is stepped on once, shrunk, and the
    dominant race kept, unchanged but for the CPU."""
    _, problem_combo = combo

    def liar(c, theta, cpu=20.0):
        return BuildResult(c, "raced", race_s=T0 + 1e-3 * (theta[KEYS[0]] - 100.0) + 0.01,
                           feasible=True, theta=dict(theta), cpu_s=cpu, geometry_by="dominance",
                           race_gradient={KEYS[0]: -1e-3, KEYS[1]: SLOPE_B})
    first, best, settled, seen = run(problem_combo, liar, {KEYS[0]: 100.0, KEYS[1]: 100.0})
    assert len(seen) == descent.MAX_RACES and not settled
    assert best.theta == first.theta and best.race_s == first.race_s
    assert best.geometry_by == "dominance" and best.cpu_s == pytest.approx(30 + 20 * len(seen))
    assert "no faster frame in 3 races" in best.reason


def test_the_build_confirms_a_ranked_dominant_race_by_descent_not_co_design(combo,
                                                                            monkeypatch):
    """An uncertified build: the ranked dominant race at the corner with its gradient into the
    box is descended with the build's own race (race_dominant, seeded from the best race) and
    never co-designed; the ranking's race is the descent's."""
    from casadrone.build import search
    from casadrone.build.pool import Pool
    from casadrone.config.problem import BackendConfig

    problem, c = combo
    problem = problem.model_copy(update={"build": problem.build.model_copy(
        update={"rank": 1, "certify": False})})
    _, race = bowl(101.3, 1e-3)
    lap = object()

    def race_dominant(problem_, combo_, laps, theta, bound_s, seeds, soc, derate):
        assert seeds.warm_starts and seeds.warm_starts[0] is lap
        assert soc == 0.91  # the voltage the best race's last pass flew, not its end's
        assert derate == (1.0, 0.99)  # the best race's current limits
        return replace_lap(race(combo_, theta))

    def replace_lap(r):
        from dataclasses import replace
        return replace(r, race_lap=lap, end_soc=0.9, flown_soc=0.91, derate=(1.0, 0.99))

    def codesign(*a, **k):
        raise AssertionError("co-designed")
    monkeypatch.setattr(search, "race_dominant", race_dominant)
    monkeypatch.setattr(search, "solve_combination", codesign)
    first = replace_lap(race(c, {KEYS[0]: 100.0, KEYS[1]: 100.0}))
    out = search.confirmed(problem, [first], None, Pool(BackendConfig()))
    assert out[0].geometry_by == "descent"
    assert out[0].theta[KEYS[0]] == pytest.approx(101.3)
    assert search.ranking(out, 1)[0].race_s == pytest.approx(T0)


def test_a_frame_refused_before_any_solve_ends_the_descent_unsettled(combo):
    """A step whose frame is refused (no θ in its result: an invalid airframe) teaches the
    secant nothing: the descent stops there, the dominant race kept and the combination left
    to the co-design."""
    _, problem_combo = combo
    _, race = bowl(101.3, 1e-3)

    def refused(c, theta, cpu=20.0):
        return BuildResult(c, "failed", reason="the frame is not valid", cpu_s=0.5)
    first = race(problem_combo, {KEYS[0]: 100.0, KEYS[1]: 100.0}, cpu=30.0)
    best, settled = descent.descend(
        first, KEYS, LOWER, UPPER, lambda theta, near: refused(problem_combo, theta),
        lambda r: stationary(r.theta, r.race_gradient, KEYS, LOWER, UPPER))
    assert not settled and best.theta == first.theta and best.cpu_s == pytest.approx(30.5)
