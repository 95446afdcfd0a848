"""Mass properties from the parts: hand parallel-axis sums, rod and box oracles, symmetry,
possible bodies on random geometry, monotonicity, and the full tensor used by the model."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from casadrone.airframe import GEOMETRY_KEYS, TABLE1_BOUNDS, build_airframe, random_thetas
from casadrone.cli import app
from casadrone.config.airframe import inertia_problems, load_airframe
from casadrone.evaluate import theta_of
from casadrone.massprops import box_inertia, mass_properties, rod_inertia

ASYMMETRIC = {"lambda_a_mm": 145.0, "lambda_b_mm": 105.0, "alpha_deg": 70.0, "beta_deg": 84.0}


@pytest.fixture(scope="module")
def parts_cfg():
    return load_airframe("SY250-components")


def _parts(cfg):
    c = cfg.components
    return (c.motor_mass_kg, c.arm_linear_density_kgpm, c.body_mass_kg,
            np.array(c.body_size_mm) / 1000, np.array(c.body_position_mm) / 1000,
            c.battery_mass_kg, np.array(c.battery_size_mm) / 1000,
            np.array(c.battery_position_mm) / 1000)


def test_symmetric_x_by_hand(parts_cfg):
    """SY250: four motors at (±a, ±a, 0), a = λ/√2, four rods, body and battery on the z axis."""
    mm, mu, mb, sb, pb, mB, sB, pB = _parts(parts_cfg)
    lam = 0.125
    a = lam / math.sqrt(2)
    arm = mu * lam
    M = mb + mB + 4 * mm + 4 * arm
    cz = (mb * pb[2] + mB * pB[2]) / M
    ixx = (mb / 12 * (sb[1] ** 2 + sb[2] ** 2) + mb * pb[2] ** 2
           + mB / 12 * (sB[1] ** 2 + sB[2] ** 2) + mB * pB[2] ** 2
           + 4 * mm * a ** 2 + 4 * arm / 3 * a ** 2 - M * cz ** 2)
    iyy = (mb / 12 * (sb[0] ** 2 + sb[2] ** 2) + mb * pb[2] ** 2
           + mB / 12 * (sB[0] ** 2 + sB[2] ** 2) + mB * pB[2] ** 2
           + 4 * mm * a ** 2 + 4 * arm / 3 * a ** 2 - M * cz ** 2)
    izz = (mb / 12 * (sb[0] ** 2 + sb[1] ** 2) + mB / 12 * (sB[0] ** 2 + sB[1] ** 2)
           + 4 * mm * lam ** 2 + 4 * arm / 3 * lam ** 2)
    mp = mass_properties(parts_cfg)
    assert mp.mass_kg == pytest.approx(M, rel=1e-12)
    np.testing.assert_allclose(mp.com_m, [0, 0, cz], atol=1e-15)
    np.testing.assert_allclose(mp.inertia_kgm2, np.diag([ixx, iyy, izz]), rtol=1e-12, atol=1e-15)


def test_asymmetric_frame_by_hand(parts_cfg):
    """λa ≠ λb, α ≠ β: every part about the centre of mass through its own centroid and the
    parallel-axis theorem (the code goes through the hub instead)."""
    mm, mu, mb, sb, pb, mB, sB, pB = _parts(parts_cfg)
    la, lb = 0.145, 0.105
    ha, hb = math.radians(70) / 2, math.radians(84) / 2
    rotors = [np.array(r) for r in ([la * math.cos(ha), -la * math.sin(ha), 0],
                                    [la * math.cos(ha), la * math.sin(ha), 0],
                                    [-lb * math.cos(hb), lb * math.sin(hb), 0],
                                    [-lb * math.cos(hb), -lb * math.sin(hb), 0])]
    lengths = [la, la, lb, lb]
    M = mb + mB + 4 * mm + mu * sum(lengths)
    c = (mb * pb + mB * pB + mm * sum(rotors)
         + sum(mu * L * r / 2 for L, r in zip(lengths, rotors, strict=True))) / M
    assert c[0] > 0  # longer front arms: the centre of mass moves forward

    def shift(m, d):  # parallel axis: m (|d|² I − d dᵀ)
        return m * (d @ d * np.eye(3) - np.outer(d, d))

    def box(m, s):
        x2, y2, z2 = s ** 2
        return m / 12 * np.diag([y2 + z2, x2 + z2, x2 + y2])

    J = box(mb, sb) + shift(mb, pb - c) + box(mB, sB) + shift(mB, pB - c)
    for L, r in zip(lengths, rotors, strict=True):
        u = r / L
        J += shift(mm, r - c)
        J += mu * L * L ** 2 / 12 * (np.eye(3) - np.outer(u, u)) + shift(mu * L, r / 2 - c)
    mp = mass_properties(parts_cfg, ASYMMETRIC)
    assert mp.mass_kg == pytest.approx(M, rel=1e-12)
    np.testing.assert_allclose(mp.com_m, c, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(mp.inertia_kgm2, J, rtol=1e-10, atol=1e-15)
    assert abs(mp.inertia_kgm2[0, 2]) > 1e-6  # battery on top + CoM forward: Ixz ≠ 0


def test_rod_is_ml2_over_3_and_matches_point_masses():
    m, length = 0.02, 0.13
    np.testing.assert_allclose(rod_inertia(m, np.array([length, 0, 0])),
                               np.diag([0, m * length ** 2 / 3, m * length ** 2 / 3]), atol=1e-18)
    # a rod along an arbitrary direction against 20 000 point masses along it
    end = np.array([0.08, -0.05, 0.01])
    s = (np.arange(20000) + 0.5) / 20000
    pts = s[:, None] * end
    numeric = m / len(s) * sum(p @ p * np.eye(3) - np.outer(p, p) for p in pts[::1])
    np.testing.assert_allclose(rod_inertia(m, end), numeric, rtol=1e-7, atol=1e-14)


def test_box_matches_a_grid_of_point_masses():
    m, size = 0.08, np.array([0.07, 0.035, 0.025])
    n = 30
    g = [((np.arange(n) + 0.5) / n - 0.5) * s for s in size]
    X, Y, Z = np.meshgrid(*g, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    numeric = m / len(pts) * (np.sum(pts ** 2) * np.eye(3) - pts.T @ pts)
    np.testing.assert_allclose(box_inertia(m, size), numeric, rtol=2e-3, atol=1e-15)


@pytest.mark.parametrize("angle, arm", [(90.0, 125.0), (75.0, 140.0), (68.0, 110.0)])
def test_symmetric_frames_have_no_products_of_inertia(parts_cfg, angle, arm):
    mp = mass_properties(parts_cfg, {"alpha_deg": angle, "beta_deg": angle,
                                     "lambda_a_mm": arm, "lambda_b_mm": arm})
    J = mp.inertia_kgm2
    np.testing.assert_allclose([J[0, 1], J[0, 2], J[1, 2]], 0.0, atol=1e-15)
    np.testing.assert_allclose(mp.com_m[:2], 0.0, atol=1e-15)


def test_random_table1_geometry_gives_possible_bodies(parts_cfg):
    rng = np.random.default_rng(5)
    for _ in range(200):
        theta = {k: rng.uniform(*TABLE1_BOUNDS[k]) for k in GEOMETRY_KEYS}
        J = mass_properties(parts_cfg, theta).inertia_kgm2
        m = np.linalg.eigvalsh(J)
        assert m[0] > 0 and m[2] <= m[0] + m[1]
        assert inertia_problems(J.tolist()) == []


def test_longer_arms_give_larger_yaw_inertia(parts_cfg):
    both = [mass_properties(parts_cfg, {"lambda_a_mm": a, "lambda_b_mm": a}).inertia_kgm2[2, 2]
            for a in np.linspace(100, 150, 11)]
    front = [mass_properties(parts_cfg, {"lambda_a_mm": a}).inertia_kgm2[2, 2]
             for a in np.linspace(100, 150, 11)]
    masses = [mass_properties(parts_cfg, {"lambda_a_mm": a}).mass_kg
              for a in np.linspace(100, 150, 11)]
    assert np.all(np.diff(both) > 0) and np.all(np.diff(front) > 0) and np.all(np.diff(masses) > 0)


def test_sy250_parts_weigh_the_reference_mass(parts_cfg):
    assert mass_properties(parts_cfg).mass_kg == pytest.approx(
        load_airframe("SY250").mass_kg, rel=0.02)


def test_free_mass_model_returns_the_config(parts_cfg):
    cfg = load_airframe("SY250", ["ixz_kgm2=0.0001"])
    mp = mass_properties(cfg)
    assert mp.mass_model == "free" and mp.mass_kg == 0.32
    np.testing.assert_array_equal(mp.com_m, 0.0)
    assert mp.inertia_kgm2[0, 2] == mp.inertia_kgm2[2, 0] == 0.0001


def test_components_decision_variables_are_the_geometry(parts_cfg):
    assert set(theta_of(parts_cfg)) == set(GEOMETRY_KEYS)
    thetas, _ = random_thetas(parts_cfg, 5, seed=1)
    assert all(set(t) == set(GEOMETRY_KEYS) for t in thetas)


# ---------------------------------------------------------------------------------------------
# The full tensor end to end: airframe, trim, linearisation, lap
# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def asymmetric(parts_cfg):
    from casadrone.airframe import with_theta

    return build_airframe(with_theta(parts_cfg, ASYMMETRIC))


def test_airframe_rotors_referred_to_the_centre_of_mass(parts_cfg, asymmetric):
    from casadrone.massprops import rotor_positions_mm

    mp = mass_properties(parts_cfg, ASYMMETRIC)
    hub = np.array(rotor_positions_mm(*ASYMMETRIC.values())) / 1000
    np.testing.assert_allclose(asymmetric.rotor_positions, hub - mp.com_m, atol=1e-15)
    np.testing.assert_allclose(asymmetric.inertia, mp.inertia_kgm2)
    assert asymmetric.mass == pytest.approx(mp.mass_kg)


def test_trim_and_linearisation_use_the_full_tensor(asymmetric):
    """Hover thrusts balance the moments about the CoM (allocation oracle), and the exact
    linearisation's rate rows are J⁻¹ times the allocation's moment rows (numpy's inverse of the
    full tensor against CasADi's symbolic solve)."""
    from casadrone.linearise import linearise
    from casadrone.model import RATE, THR
    from casadrone.trim import trim

    tp = trim(asymmetric, "hover", solver="newton")
    assert tp.success and tp.residual_norm < 1e-9
    np.testing.assert_allclose(tp.thrusts, asymmetric.hover_thrusts(), rtol=1e-9)
    A = linearise(asymmetric, tp).A
    expected = np.linalg.solve(asymmetric.inertia, asymmetric.allocation_matrix[1:4])
    np.testing.assert_allclose(A[RATE, THR], expected, rtol=1e-10, atol=1e-10)
    assert abs(expected[2, 0] - np.linalg.solve(np.diag(np.diag(asymmetric.inertia)),
                                                asymmetric.allocation_matrix[1:4])[2, 0]) > 1e-3


def test_lap_feels_the_products_of_inertia(asymmetric):
    from casadrone.config.controller import load_controller
    from casadrone.control import design_for
    from casadrone.evaluate import default_setup
    from casadrone.indices import compute_indices
    from casadrone.simulate import simulate

    setup = default_setup("SY250-components", "frozen-wrench-sy250")
    ctrl = load_controller("frozen-wrench-sy250")
    diagonal = dataclasses.replace(asymmetric, inertia=np.diag(np.diag(asymmetric.inertia)))
    J = {}
    for name, frame in (("full", asymmetric), ("diagonal", diagonal)):
        traj = simulate(frame, design_for(frame, ctrl, setup.reference_airframe),
                        setup.track, "rk4")
        assert traj.completed, traj.reason
        J[name] = compute_indices(traj)
    assert any(abs(J["full"][k] - J["diagonal"][k]) > 1e-6 * abs(J["full"][k]) for k in J["full"])


def test_massprops_cli(cli_runner):
    out = json.loads(cli_runner.invoke(app, ["massprops", "SY250-components", "lambda_a_mm=145",
                                             "--json"]).stdout)
    assert set(out) == {"airframe", "mass_model", "mass_kg", "com_m", "inertia_kgm2"}
    assert out["mass_model"] == "components" and len(out["com_m"]) == 3
    assert np.shape(out["inertia_kgm2"]) == (3, 3) and out["com_m"][0] > 0
    text = cli_runner.invoke(app, ["massprops", "SY250"])
    assert text.exit_code == 0 and "mass 0.3200 kg" in text.stdout
    bad = cli_runner.invoke(app, ["massprops", "SY250-components", "mass_kg=0.3"])
    assert bad.exit_code == 2
    assert "mass_kg: computed from the components" in bad.stderr


def test_schema_mass_of_the_parts_is_the_mass_model_mass(parts_cfg):
    """The mass is the sum of the parts (two arms of each length), and a pack too heavy to lift
    is refused at load by the schema's hover check on that mass."""
    c = parts_cfg.components
    rng = np.random.default_rng(2)
    for _ in range(20):
        theta = {k: rng.uniform(*TABLE1_BOUNDS[k]) for k in GEOMETRY_KEYS}
        arms = c.arm_linear_density_kgpm * 2 * (theta["lambda_a_mm"] + theta["lambda_b_mm"]) / 1e3
        total = c.body_mass_kg + c.battery_mass_kg + 4 * c.motor_mass_kg + arms
        assert mass_properties(parts_cfg, theta).mass_kg == pytest.approx(total, rel=1e-12)
    from casadrone.config.io import ConfigError

    with pytest.raises(ConfigError) as info:
        load_airframe("SY250-components", ["components.battery_mass_kg=4.0"])
    (line,) = info.value.lines
    assert ": components: cannot hover: weight" in line
