"""Performance indices and the per-interval table on hand-built trajectories with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from casadrone.indices import (
    BUILTIN_NAMES,
    INDICES,
    compute_indices,
    get_index,
    interval_mask,
    interval_table,
    lap_mask,
    register_index,
    sector_mask,
    unregister_index,
)
from casadrone.simulate import Trajectory

TS = 0.01
V_BATT = 14.8
U0 = np.array([0.10, 0.10, 0.09, 0.09])
# Segment layout of a synthetic lap on a 4-waypoint track with a climb (first timed segment 1):
# climb (route segment 0), straight (1), curve (2), straight (3), curve (4), then the one sample
# at which the last waypoint is reached (segment 5 = done), which is not part of the lap.
LENGTHS = {0: 10, 1: 20, 2: 10, 3: 20, 4: 10, 5: 1}
SEG = np.concatenate([np.full(n, s) for s, n in LENGTHS.items()])
N = len(SEG)
N_LAP = N - 1
SPLITS = np.array([0.295, 0.404, 0.597, 0.703])


def make_traj(*, x=None, u=None, acc=None, seg=SEG, straight=(True, False, True, False),
              splits=SPLITS, status="completed", reason=""):
    """A Trajectory built by hand (defaults: hovering at trim, no acceleration)."""
    n = len(seg)
    if x is None:
        x = np.zeros((n, 16))
    if u is None:
        u = np.tile(U0, (n, 1))
    if acc is None:
        acc = np.zeros((n, 3))
    return Trajectory(
        status=status, reason=reason, integrator="hand", t=np.arange(n) * TS, x=x, u=u,
        p_ref=np.zeros((n, 3)), v_ref=np.zeros((n, 3)), psi_ref=np.zeros(n), acceleration=acc,
        segment=np.asarray(seg), u0=U0, battery_voltage=V_BATT,
        waypoints=np.array([[50, 0, 20], [50, 2.5, 20], [0, 2.5, 20], [0, 0, 20]], float),
        straight=tuple(straight), split_times=np.asarray(splits, float),
        first_timed_segment=1,
    )


def per_segment(values: dict[int, float]) -> np.ndarray:
    return np.concatenate([np.full(LENGTHS[s], values[s], float) for s in LENGTHS])


def test_sample_selections():
    tr = make_traj()
    assert lap_mask(tr).sum() == N_LAP and not lap_mask(tr)[-1]
    # interval 1 = climb + first straight; the others one route segment each
    assert [interval_mask(tr, j).sum() for j in (1, 2, 3, 4)] == [30, 10, 20, 10]
    assert sector_mask(tr, True).sum() == 40  # the two straights, climb excluded
    assert sector_mask(tr, False).sum() == 20
    with pytest.raises(ValueError, match="waypoint must be"):
        interval_mask(tr, 5)


def test_mean_speeds_on_straights_and_curves():
    x = np.zeros((N, 16))
    x[:, 3] = per_segment({0: 3.0, 1: 10.0, 2: 4.0, 3: 12.0, 4: 5.0, 5: 100.0})  # body u, m/s
    tr = make_traj(x=x)
    J = compute_indices(tr, ["J1", "J2"])
    assert J["J1"] == pytest.approx((20 * 10 + 20 * 12) / 40, abs=1e-12)  # climb (3 m/s) left out
    assert J["J2"] == pytest.approx((10 * 4 + 10 * 5) / 20, abs=1e-12)
    # speed is the norm of the body velocity: a diagonal velocity gives the same J1
    x2 = np.zeros((N, 16))
    x2[:, 3], x2[:, 4] = 0.6 * x[:, 3], 0.8 * x[:, 3]
    assert compute_indices(make_traj(x=x2), ["J1"])["J1"] == pytest.approx(11.0, abs=1e-12)


def test_curve_speed_is_nan_without_curves():
    J = compute_indices(make_traj(straight=(True,) * 4), ["J1", "J2"])
    assert np.isnan(J["J2"]) and np.isfinite(J["J1"])


def test_lap_time_is_last_split():
    assert compute_indices(make_traj(), ["J3"])["J3"] == pytest.approx(0.703, abs=1e-15)


def test_max_acceleration_constant_and_final_sample_excluded():
    acc = np.tile([3.0, -4.0, 0.0], (N, 1))
    acc[:10] = [0.0, 0.0, 2.0]  # climb
    acc[-1] = [100.0, 0.0, 0.0]  # the sample after the lap: not counted
    assert compute_indices(make_traj(acc=acc), ["J4"])["J4"] == pytest.approx(5.0, abs=1e-12)


def test_effort_rms_by_hand():
    # motors deviate from trim by (+0.01, −0.01, +0.02, 0) on even samples and by −that on odd
    d = np.array([0.01, -0.01, 0.02, 0.0])
    signs = np.where(np.arange(N) % 2 == 0, 1.0, -1.0)
    u = U0 + signs[:, None] * d
    u[-1] = 1.0  # after the lap: not counted
    expected = V_BATT * np.sqrt((0.01**2 + 0.01**2 + 0.02**2 + 0.0) / 4)
    J5 = compute_indices(make_traj(u=u), ["J5"])["J5"]
    np.testing.assert_allclose(J5, expected, rtol=1e-12)
    assert compute_indices(make_traj(), ["J5"])["J5"] == 0.0  # at trim: no effort


def test_max_pitch_of_a_ramp():
    x = np.zeros((N, 16))
    x[:, 10] = -np.radians(0.5 * np.arange(N))  # nose-up ramp, −0.5°/sample: |θ| counts
    x[-1, 10] = np.radians(89.0)  # after the lap: not counted
    Jp = compute_indices(make_traj(x=x), ["Jp"])["Jp"]
    np.testing.assert_allclose(Jp, 0.5 * (N_LAP - 1), rtol=1e-12)


def test_failed_lap_has_no_indices():
    tr = make_traj(status="failed", reason="ground strike at t = 0.40 s")
    with pytest.raises(ValueError, match="ground strike"):
        compute_indices(tr)
    with pytest.raises(ValueError, match="failed lap"):
        interval_table(tr)
    with pytest.raises(ValueError, match="failed lap"):
        get_index("J1")(tr)


def test_interval_table_by_hand():
    u = np.tile(U0, (N, 1))
    i2 = np.flatnonzero(SEG == 2)  # interval 2: 10 samples
    # first 5: left rotors (FL, RL = 2, 3) +0.02 → ((0.04) − 0)/2·14.8 = +0.296 V
    u[i2[:5], 1] += 0.02
    u[i2[:5], 2] += 0.02
    # last 5: right rotors (FR, RR = 1, 4) +0.05 → (0 − 0.1)/2·14.8 = −0.74 V
    u[i2[5:], 0] += 0.05
    u[i2[5:], 3] += 0.05
    x = np.zeros((N, 16))
    x[:, 12:16] = 0.8
    x[i2[2], [13, 14]] = 1.3  # left pair +0.5 N each: (T2+T3) − (T1+T4) = +1.0
    x[i2[7], 12] = 2.0  # FR +1.2 N: −1.2
    i4 = np.flatnonzero(SEG == 4)
    x[i4[3], 15] = 0.3  # RR −0.5 N: +0.5 (the interval's max); min stays 0
    tr = make_traj(x=x, u=u)
    rows = interval_table(tr)
    assert [r.waypoint for r in rows] == [1, 2, 3, 4]
    assert [r.n_samples for r in rows] == [30, 10, 20, 10]
    assert [r.straight for r in rows] == [True, False, True, False]
    np.testing.assert_allclose([r.split_time_s for r in rows], SPLITS, rtol=0, atol=0)
    np.testing.assert_allclose([r.effort_V for r in rows], [0, (0.296 - 0.74) / 2, 0, 0],
                               atol=1e-12)
    np.testing.assert_allclose([r.pair_thrust_max_N for r in rows], [0, 1.0, 0, 0.5], atol=1e-12)
    np.testing.assert_allclose([r.pair_thrust_min_N for r in rows], [0, -1.2, 0, 0], atol=1e-12)


def test_pair_thrust_is_2k_over_v_times_effort_in_steady_state():
    from casadrone.indices import pair_thrust_difference, roll_effort_voltage

    rng = np.random.default_rng(1)
    u = U0 + 0.02 * rng.standard_normal((N, 4))
    K = 9.0519
    x = np.zeros((N, 16))
    x[:, 12:16] = K * u  # steady state T_i = K δ_i
    tr = make_traj(x=x, u=u)
    # U0 is left-right symmetric (FL + RL = FR + RR) like every casadrone trim, so the pair
    # thrust needs no trim removed while the effort does
    assert (U0[1] + U0[2]) - (U0[0] + U0[3]) == pytest.approx(0.0, abs=1e-15)
    np.testing.assert_allclose(pair_thrust_difference(tr),
                               (2 * K / V_BATT) * roll_effort_voltage(tr), atol=1e-12)


def test_registry_builtins_and_metadata():
    assert tuple(INDICES)[: len(BUILTIN_NAMES)] == ("J1", "J2", "J3", "J4", "J5", "Jp")
    senses = {n: INDICES[n].sense for n in BUILTIN_NAMES}
    assert senses == {"J1": "max", "J2": "max", "J3": "min", "J4": "max", "J5": "min", "Jp": "min"}
    units = {n: INDICES[n].unit for n in BUILTIN_NAMES}
    assert units == {"J1": "m/s", "J2": "m/s", "J3": "s", "J4": "m/s²", "J5": "V", "Jp": "deg"}
    with pytest.raises(TypeError):
        INDICES["J9"] = INDICES["J1"]  # read-only view


def test_user_index_round_trip():
    def samples_in_lap(traj):
        return float(lap_mask(traj).sum())

    try:
        idx = register_index("n_lap", samples_in_lap, unit="-", sense="min",
                             description="number of lap samples")
        assert get_index("n_lap") is idx and "n_lap" in INDICES
        out = compute_indices(make_traj(), ["J3", "n_lap"])
        assert out == {"J3": pytest.approx(0.703), "n_lap": float(N_LAP)}
        assert "n_lap" in compute_indices(make_traj())  # all registered by default
        with pytest.raises(ValueError, match="already registered"):
            register_index("n_lap", samples_in_lap, unit="-", sense="min")
    finally:
        unregister_index("n_lap")
    assert "n_lap" not in INDICES


def test_registration_errors():
    with pytest.raises(ValueError, match="already registered"):
        register_index("J1", lambda tr: 0.0, unit="m/s", sense="max")
    with pytest.raises(ValueError, match="sense must be"):
        register_index("bad_sense", lambda tr: 0.0, unit="-", sense="maximise")
    with pytest.raises(ValueError, match="non-empty"):
        register_index(" ", lambda tr: 0.0, unit="-", sense="min")
    with pytest.raises(ValueError, match="built in"):
        unregister_index("J3")
    with pytest.raises(ValueError, match="unknown index 'J7'"):
        compute_indices(make_traj(), ["J7"])


def test_limit_lap_effort_by_hand():
    """effort = ∫ Σ T_i^1.5 dt by hand: thrusts held at 2 N for 1 s then 8 N for 0.5 s on every
    rotor give 4 (2^1.5 · 1 + 8^1.5 · 0.5) N^1.5 s (the δ = 0.01 N smoothing changes it by
    ~1e-5 relative); a failed limit lap has none."""
    from casadrone.indices import INDICES
    from casadrone.limit.lap import LimitLap

    t = np.array([0.0, 1.0, 1.5])
    x = np.zeros((3, 16))
    x[0, 12:16], x[1, 12:16], x[2, 12:16] = 2.0, 8.0, 5.0  # the last node holds no interval
    lap = LimitLap(status="completed", reason="", lap_time_s=1.5, t=t, x=x, u=np.zeros((2, 4)))
    expected = 4 * (2.0 ** 1.5 * 1.0 + 8.0 ** 1.5 * 0.5)
    assert INDICES["effort"](lap) == pytest.approx(expected, rel=1e-4)
    assert INDICES["effort"].source == "limit" and INDICES["effort"].sense == "min"
    with pytest.raises(ValueError, match="failed limit lap"):
        INDICES["effort"](LimitLap(status="failed", reason="no solve"))
