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
