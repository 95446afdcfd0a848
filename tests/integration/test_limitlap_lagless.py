"""The thrust-lag-off idealisation (``thrust.time_constant_s: 0``) against analytic climbs.

Oracle: a symmetric drag-free quadrotor (SY250 with ``drag_area_m2: [0, 0, 0]``; its rotors sit
symmetrically about the centre of mass and spin in balanced pairs, so four equal thrusts make
no moment) climbing from hover straight up to a ball of radius r centred H above it, ending at
any speed. No attitude or command beats level flight at full thrust: the vertical acceleration
is at most (Σ T_i − m g) / m and Σ T_i ≤ 4K. So the minimum time t solves z(t) = H − r with

- no lag (T_i = K δ_i at once): z(t) = (4K/m − g) t² / 2;
- the paper's lag (τ Ṫ + T = K δ, from the hover thrust m g / 4):
  z(t) = (4K/m − g) t² / 2 − 4 (K − m g / 4) / m · (τ t − τ² (1 − e^(−t/τ))),

solved here with scipy's brentq: closed forms that share no code with the model or the NLP.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.track import TrackConfig
from casadrone.limit.lap import LimitLapOptions, limit_lap

H, R = 10.0, 0.5  # ball centre above the start (m), its radius (m)
TRACK = TrackConfig(name="vertical", start_position_m=(0.0, 0.0, 2.0),
                    waypoints_m=[(0.0, 0.0, 2.0 + H)], straight=[True], acceptance_radius_m=R,
                    end="free")
OPTIONS = LimitLapOptions(intervals=20, starts=("point-mass",), sensitivities=False,
                          fallback_reference=None)


def frame_cfg(tau: float):
    return load_airframe("SY250").model_copy(update={
        "drag_area_m2": (0.0, 0.0, 0.0),
        "thrust": load_airframe("SY250").thrust.model_copy(update={"time_constant_s": tau})})


def analytic_time(cfg, tau: float) -> float:
    m, g, K = cfg.mass_kg, cfg.gravity_mps2, cfg.thrust.gain_n
    a = 4 * K / m - g

    def z(t: float) -> float:
        lag = 0.0 if tau == 0 else 4 * (K - m * g / 4) / m * (
            tau * t - tau**2 * (1 - math.exp(-t / tau)))
        return a * t**2 / 2 - lag - (H - R)

    return brentq(z, 1e-6, 10.0, xtol=1e-14)


@pytest.mark.parametrize("tau", [0.0, 0.060538])
def test_vertical_climb_takes_the_analytic_time_with_and_without_lag(tau):
    cfg = frame_cfg(tau)
    lap = limit_lap(build_airframe(cfg), TRACK, OPTIONS)
    assert lap.completed, lap.reason
    expected = analytic_time(cfg, tau)
    # observed: 3.9e-9 relative without lag (RK4 integrates a constant acceleration exactly),
    # 1.3e-8 with the lag (RK4's error on the exponential, 20 intervals)
    assert lap.lap_time_s == pytest.approx(expected, rel=1e-7)
    # the idealisation matters: the lagged climb is measurably slower
    if tau == 0:
        assert analytic_time(frame_cfg(0.060538), 0.060538) > expected * 1.02
        # the reported rotor states are the thrusts flown: K δ, full at once
        assert np.allclose(lap.x[:-1, 12:16], cfg.thrust.gain_n * lap.u, atol=1e-9)
        assert lap.x[0, 12:16].min() > 0.99 * cfg.thrust.gain_n


def test_lag_off_is_refused_for_the_propeller_model():
    from casadrone.config.airframe import AirframeConfig
    from casadrone.config.io import ConfigError

    cfg = load_airframe("SY250-propeller")
    data = cfg.model_dump()
    data["thrust"]["time_constant_s"] = 0.0
    with pytest.raises((ConfigError, ValueError), match="time_constant_s"):
        AirframeConfig.model_validate(data)


def test_the_closed_loop_refuses_a_lag_free_frame_naming_the_key():
    """The LQR-I design and the closed-loop simulation need the lagged model (its explicit form
    divides by τ): a lag-free frame is refused by name, not a singular-matrix traceback."""
    from casadrone.config.io import ConfigError
    from casadrone.linearise import linearise
    from casadrone.trim import trim

    frame = build_airframe(frame_cfg(0.0))
    with pytest.raises(ConfigError, match="thrust.time_constant_s: 0"):
        linearise(frame, trim(frame, "hover", 0.0, solver="newton"))
