"""The limit lap with the ``propeller`` propulsion model (slow: one cold solve of SY250-propeller
on a short track, its 80 default intervals per leg, about a minute of CPU).

Checked by oracles that share no code with the solver:

- the optimal commands, held on each interval and flown open loop by scipy's DOP853 on the
  model's explicit dynamics, follow the lap's nodes within 5 cm and pass every target (the
  issue's re-simulation acceptance); this is what the rotor-speed scaling and the finer grid
  are for: on 40 intervals RK4 follows the ~20 ms rotor-speed time constant badly;
- the point-mass reference, whose thrust bound is the largest steady full-command thrust
  (propulsion.thrust_bound), is below the lap (it is the relaxation's best local optimum);
- on the straight the rotors run at full command (bang-bang) and their thrust stays below the
  static full thrust at every node (the inflow only takes thrust away at steady state);
- the opt-in exponential rotor step (ETDRK4) on half the intervals (40 × 4 steps), flown the
  same way by DOP853, follows its lap within 5 cm as well;
- recomputed with numpy from the returned nodes, every rotor stays inside the propeller data
  (J ≤ J_max) and no thrust is below the data's C_T(J_max), with the shipped range and with a
  tighter one that binds.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.track import TrackConfig
from casadrone.limit.check import lap_propulsion
from casadrone.limit.lap import LimitLapOptions, design_limit_lap
from casadrone.limit.result import DEFAULT_INTERVALS
from casadrone.model import quadrotor_model
from casadrone.propulsion import max_static_thrust, rotor_thrust_bound

pytestmark = pytest.mark.slow

TRACK = TrackConfig(name="straight-and-curve", start_position_m=(0.0, 0.0, 2.0),
                    waypoints_m=[(30.0, 0.0, 2.0), (30.0, 2.5, 2.0)], straight=[True, False],
                    acceptance_radius_m=1.0)
RESIM_M = 0.05  # the acceptance


@pytest.fixture(scope="module")
def frame():
    return build_airframe(load_airframe("SY250-propeller"))


@pytest.fixture(scope="module")
def lap():
    return design_limit_lap(load_airframe("SY250-propeller"), TRACK,
                            LimitLapOptions(sensitivities=False))


def test_propeller_lap_converges_on_its_default_grid(lap):
    assert lap.completed, lap.reason
    assert lap.layout is not None and lap.layout.intervals == DEFAULT_INTERVALS["propeller"]
    assert lap.point_mass_reference_s < lap.lap_time_s
    assert lap.resimulation_miss_m <= RESIM_M


def flown_by_dop853(lap, frame) -> np.ndarray:
    """The lap's commands held on each interval, flown open loop from its start by DOP853."""
    f = quadrotor_model("propeller").f
    x = lap.x[0].copy()
    nodes = [x]
    for i, u in enumerate(lap.u):
        sol = solve_ivp(lambda _t, s, u=u: np.asarray(f(s, u, frame.p)).ravel(),
                        (lap.t[i], lap.t[i + 1]), x, method="DOP853", rtol=1e-9, atol=1e-9)
        x = sol.y[:, -1]
        nodes.append(x)
    return np.array(nodes)


def test_commands_flown_by_an_independent_integrator_follow_the_lap(lap, frame):
    nodes = flown_by_dop853(lap, frame)
    assert np.max(np.linalg.norm(nodes[:, 0:3] - lap.x[:, 0:3], axis=1)) <= RESIM_M
    N, L = lap.layout.intervals, len(lap.leg_times_s)
    for k, target in zip((L - 2, L - 1), TRACK.waypoints_m, strict=True):  # legs to the balls
        assert np.linalg.norm(nodes[(k + 1) * N, 0:3] - np.asarray(target)) <= 1.0 + RESIM_M


def test_straight_is_flown_at_full_command_below_the_static_thrust(lap, frame):
    prop = lap_propulsion(frame, lap.x_euler, lap.u)
    N = lap.layout.intervals
    straight = slice(len(lap.u) - 2 * N, len(lap.u) - N)
    assert np.mean(lap.u[straight] >= 0.98) >= 0.5  # mostly full command
    thrust = prop["thrust_n"][straight]
    assert thrust.max() <= max_static_thrust(frame) * 1.01
    assert thrust.sum(axis=1).max() <= 4 * rotor_thrust_bound(frame) * 1.01


#: A data range below the J the default lap flies on this track (0.607 with the range at
#: 0.618), so that the rows bind.
TIGHT_J = 0.45


@pytest.fixture(scope="module")
def tight_lap():
    cfg = load_airframe("SY250-propeller", [f"propulsion.propeller.max_advance_ratio={TIGHT_J}"])
    return build_airframe(cfg), design_limit_lap(cfg, TRACK, LimitLapOptions(sensitivities=False))


def _recomputed(frame, lap):
    """(v_a − J_max n D, J, T) of every rotor at every node after the start, with numpy from
    the returned nodes (rotor positions, the positive-inflow smoothing, CT(J) written out)."""
    from casadrone.propulsion import airframe_values

    q = airframe_values(frame)
    D, eps = q["prop_D"], q["inflow_eps"]
    j_max = frame.max_advance_ratio
    ct_end = q["ct0"] + q["ct1"] * j_max + q["ct2"] * j_max**2  # C_T falls with J: its least
    excess, J, T = [], [], []
    for x in lap.x_euler[1:]:
        for i in range(4):
            v = (x[3:6] + np.cross(x[6:9], frame.rotor_positions[i]))[2]
            v_a = 0.5 * (v + np.sqrt(v * v + eps**2)) - eps / 2
            nD = x[12 + i] / (2 * np.pi) * D
            excess.append(v_a - j_max * nD)
            J.append(v_a / nD if nD > 0 else 0.0)
            # the thrust less the least the data allow at this rotor speed (C_T at J_max)
            T.append(q["rho"] * D**2 * (q["ct0"] * nD**2 + q["ct1"] * nD * v_a
                                        + q["ct2"] * v_a**2 - min(ct_end, 0.0) * nD**2))
    return np.array(excess), np.array(J), np.array(T)


def test_every_rotor_stays_inside_the_propeller_data(lap, frame, tight_lap):
    """At every node after the start and every rotor, J ≤ J_max within the solver's tolerance
    and no thrust is below what the data allow (C_T(J_max) ρ n² D⁴, negative at the shipped
    range's end 0.854, where the measured C_T is): with the shipped range and with a range of
    0.45 that binds (some rotor-nodes at it, no thrust negative), the lap then slower (observed
    with the range at 0.618: 1.1917 s against 1.1711 s)."""
    excess, J, T = _recomputed(frame, lap)
    assert excess.max() <= 1e-8 and J.max() <= frame.max_advance_ratio + 1e-9
    assert T.min() > -1e-6
    tight, tlap = tight_lap
    assert tlap.completed and tlap.resimulation_miss_m <= RESIM_M, tlap.reason
    excess, J, T = _recomputed(tight, tlap)
    assert tight.max_advance_ratio == TIGHT_J
    # observed: v_a − J_max n D ≤ 3.5e-9 m/s, J ≤ J_max + 7e-11 (IPOPT's feasibility)
    assert excess.max() <= 4e-8 and J.max() <= TIGHT_J + 1e-9
    assert np.mean(J >= TIGHT_J - 1e-3) > 0.01  # the rows bind (observed 8.9 % of rotor-nodes)
    assert T.min() > 0  # observed 0.19 N
    assert tlap.lap_time_s > lap.lap_time_s


def test_exponential_rotor_step_on_half_the_intervals_follows_the_lap(frame):
    """LimitLapOptions(rotor_step="exponential") on 40 intervals of 4 steps: the lap converges
    and DOP853 flying its commands stays within the issue's 5 cm of its nodes (observed 0.5 mm
    here; on the paper track SY250-propeller missed by 2.1 cm, classical RK4 on 40 × 3 by
    0.30 m)."""
    lap = design_limit_lap(load_airframe("SY250-propeller"), TRACK,
                           LimitLapOptions(sensitivities=False, intervals=40, substeps=4,
                                           rotor_step="exponential", starts=("point-mass",)))
    assert lap.completed, lap.reason
    nodes = flown_by_dop853(lap, frame)
    assert np.max(np.linalg.norm(nodes[:, 0:3] - lap.x[:, 0:3], axis=1)) <= RESIM_M
