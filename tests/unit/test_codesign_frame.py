"""p(θ), hover thrusts and feasibility rules of casadrone.codesign.frame against the numeric
chain (casadrone.massprops → casadrone.airframe.build_airframe) and the airframe schema."""

from __future__ import annotations

import numpy as np
import pytest

from casadrone.airframe import TABLE1_BOUNDS, build_airframe, decision_keys, with_theta
from casadrone.codesign.frame import SymbolicFrame, param_vector
from casadrone.config import AirframeConfig, load_airframe


def _frame(name: str, bounds=TABLE1_BOUNDS) -> SymbolicFrame:
    cfg = load_airframe(name)
    keys = decision_keys(cfg)
    return SymbolicFrame(cfg, keys, np.array([bounds[k][0] for k in keys]),
                         np.array([bounds[k][1] for k in keys]))


@pytest.mark.parametrize("name", ["SY250-components", "SY250"])
def test_parameter_vector_equals_the_numeric_build_at_random_theta(name):
    """Oracle: build_airframe of the validated config (massprops' numpy sums, hover by
    numpy.linalg.solve). Observed agreement: p to 5e-19, hover thrusts to 4e-13 N."""
    fr = _frame(name)
    rng = np.random.default_rng(7)
    checked = 0
    while checked < 20:
        s = rng.uniform(0, 1, len(fr.keys))
        theta = {k: float(v) for k, v in fr.theta(s).items()}
        try:
            frame = build_airframe(with_theta(fr.cfg, theta))
        except Exception:  # an invalid body or overlapping rotors: not a frame
            continue
        p, hover, _, mass, _ = fr.function(s)
        np.testing.assert_allclose(np.asarray(p).ravel(), frame.p, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(np.asarray(hover).ravel(), frame.hover_thrusts(),
                                   rtol=1e-10, atol=1e-12)
        assert float(mass) == pytest.approx(frame.mass, rel=1e-14)
        # the same formulas on plain numbers (no CasADi Function): the same vector
        np.testing.assert_allclose(np.asarray(param_vector(fr.cfg, theta, frame.p)).ravel(),
                                   frame.p, rtol=1e-12, atol=1e-15)
        checked += 1


def test_components_mass_moves_with_the_arms():
    """Oracle: the parts' arithmetic by hand: four 0.074 kg/m rods of 125 mm, four 30 g motors,
    83 g body and 80 g battery (configs/airframes/SY250-components.yaml) = 0.320 kg."""
    fr = _frame("SY250-components")
    s = fr.normalise({"lambda_a_mm": 125.0, "lambda_b_mm": 125.0, "alpha_deg": 90.0,
                      "beta_deg": 90.0})
    assert float(fr.function(s)[3]) == pytest.approx(0.083 + 0.080 + 4 * 0.030
                                                     + 4 * 0.125 * 0.074, rel=1e-12)


def test_overlap_rows_agree_with_the_schema():
    """Oracle: the airframe schema's overlap check (AirframeConfig validation). Every gap row is
    ≥ 0 exactly when the schema finds no overlapping pair, over a box wide enough to hold both."""
    wide = {**TABLE1_BOUNDS, "alpha_deg": (30.0, 120.0), "beta_deg": (30.0, 120.0)}
    fr = _frame("SY250-components", wide)
    gaps = [i for i, n in enumerate(fr.row_names) if n.startswith("gap")]
    rng = np.random.default_rng(3)
    seen = {True: 0, False: 0}
    for _ in range(200):
        s = rng.uniform(0, 1, len(fr.keys))
        theta = {k: float(v) for k, v in fr.theta(s).items()}
        overlap = any("overlap" in m for _, m in AirframeConfig.problems(
            {**dict(fr.cfg), **theta}))
        rows = np.asarray(fr.function(s)[2]).ravel()[gaps]
        assert (rows.min() < 0) == overlap
        seen[overlap] += 1
    assert min(seen.values()) > 10  # both cases were exercised


def test_rigid_body_rows_agree_with_the_schema():
    """Oracle: the schema's triangle inequalities (free mass model, inertia keys varied)."""
    fr = _frame("SY250")
    rows = [i for i, n in enumerate(fr.row_names) if n.startswith("rigid")]
    rng = np.random.default_rng(5)
    seen = {True: 0, False: 0}
    for _ in range(200):
        s = rng.uniform(0, 1, len(fr.keys))
        theta = {k: float(v) for k, v in fr.theta(s).items()}
        bad = any("rigid body" in m for _, m in AirframeConfig.problems(
            {**dict(fr.cfg), **theta}))
        assert (np.asarray(fr.function(s)[2]).ravel()[rows].min() < 0) == bad
        seen[bad] += 1
    assert min(seen.values()) > 10
