"""The dominant frame of a geometry box (casadrone.build.dominance), checked against what the
mass model's physics says of each box: arms that carry parts outward (components), arms with a
given inertia (free), and arm angles that trade roll for pitch."""

from __future__ import annotations

import numpy as np
import pytest

from casadrone.airframe import build_airframe, with_theta
from casadrone.build.checks import load_build_problem
from casadrone.build.dominance import dominant_theta, dominates
from casadrone.build.search import screened
from casadrone.build.solve import combination_start, geometry_box
from casadrone.config.airframe import AirframeConfig
from casadrone.config.io import DATA_DIR, load

AIRFRAMES = DATA_DIR / "configs" / "airframes"


def roll_pitch(frame) -> tuple[float, float]:
    """Σ|y| / Ixx and Σ|x| / Iyy of the rotors about the centre of mass, typed in here."""
    r = frame.rotor_positions
    return (float(np.abs(r[:, 1]).sum() / frame.inertia[0, 0]),
            float(np.abs(r[:, 0]).sum() / frame.inertia[1, 1]))


@pytest.fixture(scope="module")
def small():
    problem = load_build_problem("build-small")
    kept, _ = screened(problem)
    return problem, kept


def test_the_short_arm_corner_dominates_every_frame_of_build_smalls_box(small):
    """Every part on an arm moves out with it: mass and inertia grow with the arms, the inertia
    (∝ λ²) faster than the arm (∝ λ). The short-arm corner is returned for the lightest and the
    heaviest pack alike, and it is lighter, of smaller principal moments and of more roll and
    pitch authority than 40 random frames of the box (not the grid the search looked at)."""
    problem, kept = small
    keys, lower, upper = geometry_box(problem)
    rng = np.random.default_rng(46)
    for combo in (kept[0], kept[-1]):
        cfg = combination_start(problem, combo)
        theta = dominant_theta(cfg, keys, lower, upper)
        assert theta == dict(zip(keys, lower, strict=True)), combo.label
        d = build_airframe(with_theta(cfg, theta))
        for point in rng.uniform(lower, upper, size=(40, len(keys))):
            f = build_airframe(with_theta(cfg, dict(zip(keys, point, strict=True))))
            assert d.mass < f.mass
            assert np.all(np.diag(d.inertia) < np.diag(f.inertia))
            assert all(a > b for a, b in zip(roll_pitch(d), roll_pitch(f), strict=True))


def test_with_a_given_inertia_the_longest_arms_dominate():
    """mass_model free: the mass and inertia are given, whatever the arms; a longer arm makes
    more torque from the same thrust, so the box's long corner dominates (and the short one
    does not)."""
    cfg = load(AirframeConfig, AIRFRAMES / "SY250.yaml")
    keys, lower, upper = ("lambda_a_mm", "lambda_b_mm"), np.array([125.0, 125.0]), \
        np.array([160.0, 160.0])
    assert dominant_theta(cfg, keys, lower, upper) == dict(zip(keys, upper, strict=True))
    long_, short = (build_airframe(with_theta(cfg, dict(zip(keys, x, strict=True))))
                    for x in (upper, lower))
    assert dominates(long_, short) and not dominates(short, long_)


def test_no_frame_dominates_where_the_arm_angle_trades_roll_for_pitch():
    """The front arms' angle α swings the front rotors from the x axis toward the y axis:
    roll authority grows with it and pitch authority falls (checked here on the frames), so
    no α is best about both axes and the combination is co-designed."""
    cfg = load(AirframeConfig, AIRFRAMES / "SY250.yaml")
    keys, lower, upper = ("alpha_deg",), np.array([70.0]), np.array([110.0])
    narrow, wide = (build_airframe(with_theta(cfg, {"alpha_deg": a})) for a in (70.0, 110.0))
    (roll_n, pitch_n), (roll_w, pitch_w) = roll_pitch(narrow), roll_pitch(wide)
    assert roll_w > roll_n and pitch_w < pitch_n
    assert dominant_theta(cfg, keys, lower, upper) is None


def test_a_frame_dominates_itself_and_no_heavier_copy_dominates_it():
    from dataclasses import replace

    frame = build_airframe(load(AirframeConfig, AIRFRAMES / "SY250.yaml"))
    heavier = replace(frame, mass=frame.mass * 1.01)
    assert dominates(frame, frame)
    assert dominates(frame, heavier) and not dominates(heavier, frame)


def test_a_dominant_race_that_finds_no_lap_is_co_designed(small, monkeypatch):
    """evaluate: a box with a dominant frame is raced there; where that race finds no lap, or
    breaks a limit, the combination is co-designed, its CPU the two solves' together; a race
    seeded from a neighbour that breaks a limit is first raced again alone, and kept where that
    one flies; a box without a dominant frame is co-designed at once."""
    import math

    from casadrone.build import search
    from casadrone.build.solve import BuildResult
    from casadrone.limit.result import LapSeeds

    problem, kept = small
    calls = []

    def dominant(problem, combo, laps, theta, bound_s, seeds=None, soc=None, lap=math.nan,
                 ok=False):
        calls.append(("dominant", theta))
        return BuildResult(combo, "raced", race_s=lap, cpu_s=2.0, geometry_by="dominance",
                           feasible=ok)

    def codesign(problem, combo, laps, bound_s, seeds, start):
        calls.append(("co-design", start))
        return BuildResult(combo, "raced", race_s=5.0, cpu_s=30.0)
    monkeypatch.setattr(search, "solve_combination", codesign)
    monkeypatch.setattr(search, "race_dominant", dominant)
    got = search.evaluate(problem, kept[0], None)
    assert [c[0] for c in calls] == ["dominant", "co-design"]
    assert calls[0][1] == {"lambda_a_mm": 100.0, "lambda_b_mm": 100.0}
    assert got.geometry_by == "co-design" and got.cpu_s == 32.0
    calls.clear()  # a race that breaks a current limit: co-designed, its result kept
    monkeypatch.setattr(search, "race_dominant", lambda *a: dominant(*a, lap=4.0))
    got = search.evaluate(problem, kept[0], None)
    assert [c[0] for c in calls] == ["dominant", "co-design"] and got.race_s == 5.0
    calls.clear()
    monkeypatch.setattr(search, "race_dominant", lambda *a: dominant(*a, lap=4.0, ok=True))
    got = search.evaluate(problem, kept[0], None)
    assert [c[0] for c in calls] == ["dominant"] and got.race_s == 4.0
    calls.clear()  # seeded from a neighbour and over a limit: raced again alone, which flies
    seeded = LapSeeds(warm_starts=("neighbour's race",))

    def by_seed(problem, combo, laps, theta, bound_s, seeds=None, soc=None):
        calls.append(("dominant", seeds, soc))
        ok = seeds is None or not seeds.warm_starts
        return BuildResult(combo, "raced", race_s=4.0 if ok else 3.9, cpu_s=2.0,
                           geometry_by="dominance", feasible=ok)
    monkeypatch.setattr(search, "race_dominant", by_seed)
    got = search.evaluate(problem, kept[0], None, seeds=seeded, soc=0.9)
    assert [c[0] for c in calls] == ["dominant", "dominant"] and calls[0][1] is seeded
    assert calls[0][2] == 0.9  # the neighbour's end state of charge, for the first race only
    assert not (calls[1][1] or LapSeeds()).warm_starts and calls[1][2] is None
    assert got.race_s == 4.0 and got.feasible and got.cpu_s == 4.0
    calls.clear()
    monkeypatch.setattr(search, "dominant_theta", lambda *a: None)
    got = search.evaluate(problem, kept[0], None)
    assert [c[0] for c in calls] == ["co-design"]


def test_confirmation_codesigns_the_ranking_until_it_holds_no_dominant_race(small, monkeypatch):
    """rank 2 over dominant races of 4.0, 4.1 and 4.2 s whose gradient is unknown (not
    stationary): the first two are co-designed; the second's co-design comes out at 4.3 s
    (slower than its dominant race: the argument failed there), which lets the 4.2 s one into
    the ranking, and it is co-designed in turn (4.15 s). The ranking ends 4.0, 4.15, all
    co-designed, each CPU the two solves' together."""
    from casadrone.build import search
    from casadrone.build.pool import Pool
    from casadrone.build.solve import BuildResult
    from casadrone.config.problem import BackendConfig

    problem, kept = small
    problem = problem.model_copy(update={"build": problem.build.model_copy(update={"rank": 2})})
    dominant = [BuildResult(c, "raced", race_s=t, feasible=True, cpu_s=1.0,
                            geometry_by="dominance", theta={"lambda_a_mm": 100.0})
                for c, t in zip(kept[:3], (4.0, 4.1, 4.2), strict=True)]
    codesigned = {kept[0].label: 4.0, kept[1].label: 4.3, kept[2].label: 4.15}
    asked = []

    def codesign(problem, combo, laps, bound_s, seeds, start):
        asked.append(combo.label)
        assert start == {"lambda_a_mm": 100.0}
        return BuildResult(combo, "raced", race_s=codesigned[combo.label], feasible=True,
                           cpu_s=10.0)
    monkeypatch.setattr(search, "solve_combination", codesign)
    out = search.confirmed(problem, dominant, None, Pool(BackendConfig()))
    assert asked == [kept[0].label, kept[1].label, kept[2].label]
    ranked = search.ranking(out, 2)
    assert [(r.label, r.race_s) for r in ranked] == [(kept[0].label, 4.0), (kept[2].label, 4.15)]
    assert all(r.geometry_by == "co-design" and r.cpu_s == 11.0 for r in out)


def test_a_corner_is_stationary_when_no_key_can_move_in_and_gain():
    """s per mm over a 50 mm box: at the lower corner, slopes ≥ 0 are optimal; a slope of
    -1e-4 s/mm (-5 ms over the box) against a largest of 1e-3 s/mm is not (beyond 2 % of it);
    -1e-6 s/mm is (below the tolerance); inside the box a slope must be zero; a key without
    a gradient is never stationary."""
    from casadrone.build.dominance import stationary

    keys, lower, upper = ("a", "b"), np.array([100.0, 100.0]), np.array([150.0, 150.0])
    corner = {"a": 100.0, "b": 100.0}
    assert stationary(corner, {"a": 1e-3, "b": 2e-4}, keys, lower, upper)
    assert not stationary(corner, {"a": 1e-3, "b": -1e-4}, keys, lower, upper)
    assert stationary(corner, {"a": 1e-3, "b": -1e-6}, keys, lower, upper)
    assert not stationary({"a": 100.0, "b": 120.0}, {"a": 1e-3, "b": 1e-4}, keys, lower, upper)
    assert stationary({"a": 100.0, "b": 150.0}, {"a": 1e-3, "b": -1e-4}, keys, lower, upper)
    assert not stationary(corner, {"a": 1e-3}, keys, lower, upper)


def test_a_stationary_dominant_race_is_kept_unless_a_certificate_is_asked(small, monkeypatch):
    """The ranked dominant race whose gradient points out of the box is kept as it is (no
    co-design) in an uncertified build; with build.certify its co-design is made, for the
    certificate's co-design point."""
    from casadrone.build import search
    from casadrone.build.pool import Pool
    from casadrone.build.solve import BuildResult
    from casadrone.config.problem import BackendConfig

    problem, kept = small
    race = BuildResult(kept[0], "raced", race_s=4.0, feasible=True, geometry_by="dominance",
                       theta={"lambda_a_mm": 100.0, "lambda_b_mm": 100.0},
                       race_gradient={"lambda_a_mm": 1e-4, "lambda_b_mm": 3e-4})
    asked = []

    def codesign(problem, combo, laps, bound_s, seeds, start):
        asked.append(combo.label)
        return BuildResult(combo, "raced", race_s=4.0, feasible=True)
    monkeypatch.setattr(search, "solve_combination", codesign)
    for certify, calls in ((False, []), (True, [kept[0].label])):
        asked.clear()
        prob = problem.model_copy(update={"build": problem.build.model_copy(
            update={"rank": 1, "certify": certify})})
        search.confirmed(prob, [race], None, Pool(BackendConfig()))
        assert asked == calls, certify


def test_a_resumed_folder_gives_each_combination_its_latest_result(small, tmp_path):
    """A ranked combination is recorded twice (its dominant race, then its co-design): the
    folder reads back one result per combination, the latest, in the order first known."""
    from casadrone.build import resume
    from casadrone.build.solve import BuildResult

    problem, kept = small
    resume.begin(tmp_path, problem, None)
    first = BuildResult(kept[0], "raced", race_s=4.0, geometry_by="dominance")
    for r in (first, BuildResult(kept[1], "pruned", bound_s=5.0),
              BuildResult(kept[0], "raced", race_s=3.9)):
        resume.keep(tmp_path, r)
    held = resume.held(tmp_path)
    assert [(r.label, r.outcome, r.geometry_by) for r in held] == [
        (kept[0].label, "raced", "co-design"), (kept[1].label, "pruned", "co-design")]
    assert held[0].race_s == 3.9 and held[1].bound_s == 5.0
    assert len(list((tmp_path / resume.STATE).glob("*.pkl"))) == 3
