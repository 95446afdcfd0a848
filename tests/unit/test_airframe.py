"""Airframe geometry: the paper's frame converted and pinned, families, allocation."""

import math

import numpy as np
import pytest

from casadrone.airframe import TABLE1_BOUNDS, build_airframe, family, from_paper_frame, with_theta
from casadrone.config.airframe import load_airframe
from casadrone.config.io import ConfigError


def paper_rotors(la, lb, alpha_deg, beta_deg):
    """Paper Fig. 1: nose on +y, x to the right; rotors FR, FL, RL, RR written in that frame."""
    a, b = math.radians(alpha_deg) / 2, math.radians(beta_deg) / 2
    return np.array([
        [la * math.sin(a), la * math.cos(a), 0.0],     # front-right: right (+x), forward (+y)
        [-la * math.sin(a), la * math.cos(a), 0.0],    # front-left
        [-lb * math.sin(b), -lb * math.cos(b), 0.0],   # rear-left
        [lb * math.sin(b), -lb * math.cos(b), 0.0],    # rear-right
    ])


def test_paper_front_right_is_front_right_here():
    # a rotor the paper puts ahead (+y_p) and to the right (+x_p)…
    r = from_paper_frame(np.array([0.05, 0.12, 0.0]))
    # …is ahead (+x, nose) and to the right (−y, y points left) here, at the same distance
    assert r[0] == pytest.approx(0.12) and r[1] == pytest.approx(-0.05) and r[2] == 0.0


@pytest.mark.parametrize("name", ["SY250", "HS200", "HS210", "NSY200"])
def test_rotor_positions_equal_paper_figure_converted(name):
    cfg = load_airframe(name)
    frame = build_airframe(cfg)
    expected = from_paper_frame(paper_rotors(cfg.lambda_a_mm, cfg.lambda_b_mm, cfg.alpha_deg,
                                             cfg.beta_deg)) / 1000
    np.testing.assert_allclose(frame.rotor_positions, expected, atol=1e-15)
    # arm lengths and the angles between the nose arms and between the tail arms
    r = frame.rotor_positions
    np.testing.assert_allclose(np.linalg.norm(r[:2], axis=1), cfg.lambda_a_mm / 1000)
    np.testing.assert_allclose(np.linalg.norm(r[2:], axis=1), cfg.lambda_b_mm / 1000)
    cos_alpha = r[0] @ r[1] / np.linalg.norm(r[0]) / np.linalg.norm(r[1])
    assert math.degrees(math.acos(cos_alpha)) == pytest.approx(cfg.alpha_deg)
    assert frame.diagonal_mm == pytest.approx(cfg.lambda_a_mm + cfg.lambda_b_mm)


def test_families_follow_the_paper_definition():
    assert family(90, 90) == "SY"
    assert family(90, 75) == "HS" and family(80, 90) == "HS"
    assert family(80, 80) == "NSY"
    assert [build_airframe(load_airframe(n)).family for n in ("SY220", "HS210", "NSY200")] == \
        ["SY", "HS", "NSY"]


def test_allocation_matrix_maps_thrusts_to_force_and_moments():
    frame = build_airframe(load_airframe("HS210"))
    T = np.array([1.0, 2.0, 3.0, 4.0])
    r, s = frame.rotor_positions, frame.rotor_spins
    # Σ r_i × (0, 0, T_i) + Σ s_i κ T_i e_z, by hand
    moment = sum(np.cross(r[i], [0, 0, T[i]]) for i in range(4)) + [0, 0, frame.kappa * s @ T]
    np.testing.assert_allclose(frame.allocation_matrix @ T, [T.sum(), *moment], atol=1e-15)
    # diagonal rotors spin alike (FR with RL, FL with RR), the pairs oppositely
    assert s[0] == s[2] and s[1] == s[3] and s[0] == -s[1]


def test_random_thetas_inside_table1_with_valid_geometry():
    from casadrone.airframe import TABLE1_BOUNDS, random_thetas
    from casadrone.config.airframe import min_rotor_gap_mm

    base = load_airframe("SY250")
    thetas, rejected = random_thetas(base, 40, seed=3)
    assert len(thetas) == 40 and rejected > 0  # Table 1 contains overlapping-rotor frames
    for th in thetas:
        for k, (lo, hi) in TABLE1_BOUNDS.items():
            assert lo <= th[k] <= hi
        gap = min_rotor_gap_mm(th["lambda_a_mm"], th["lambda_b_mm"], th["alpha_deg"],
                               th["beta_deg"])
        assert gap >= base.prop_diameter_mm
    assert random_thetas(base, 40, seed=3) == (thetas, rejected)
    assert random_thetas(base, 40, seed=4)[0] != thetas


def test_with_theta_fast_path_equals_full_validation():
    """Per candidate only the replaced fields and the cross-field checks are re-run; the result
    (and every refusal, with its message) must be the full schema's."""
    from pydantic import ValidationError

    from casadrone.config.airframe import AirframeConfig, load_airframe

    template = load_airframe("SY250")
    rng = np.random.default_rng(3)
    accepted = refused = 0
    for _ in range(300):
        theta = {k: float(rng.uniform(0.5 * lo, 1.5 * hi)) for k, (lo, hi) in TABLE1_BOUNDS.items()}
        if rng.random() < 0.1:
            theta["lambda_a_mm"] = [float("nan"), -1.0, True, "12"][int(rng.integers(4))]
        try:
            full = AirframeConfig.model_validate({**template.model_dump(), **theta})
        except ValidationError:
            full = None
        try:
            fast = with_theta(template, theta)
        except ConfigError:
            fast = None
        assert (fast is None) == (full is None), theta
        if full is not None:
            assert fast == full
            accepted += 1
        else:
            refused += 1
    assert accepted > 50 and refused > 50
