"""The propeller model (``propulsion.model: propeller``): the rotor states are the rotor speeds
ω_i (rad/s) and

- thrust and shaft torque from the propeller's coefficients, T = CT(J) ρ n² D⁴,
  Q = CP(J) ρ n² D⁵ / (2π), n = ω/2π (rev/s), with CT, CP quadratic in the advance ratio
  J = v_a/(n D). Multiplied out, T = ρ (c₀ D⁴ n² + c₁ D³ n v_a + c₂ D² v_a²) and likewise Q:
  polynomials in n and v_a, smooth and finite at n = 0 (no division by the rotor speed), which
  is why the coefficients stop at J²;
- v_a is each rotor's own axial inflow, the component along the rotor axis (body +z) of
  v + Ω × r_i (body velocity plus body rate crossed with the rotor's position from the centre of
  mass). ``inflow: positive`` (default) takes max(v_a, 0), smoothed over ``inflow_smoothing_m_s``
  and exactly 0 at v_a = 0: the wind-tunnel data cover J ≥ 0 only, and descending or braking
  through the own wake (vortex-ring state) is where momentum theory and the data both fail, so
  the static coefficients are used there (an under-estimate of braking thrust).
  ``inflow: signed`` uses v_a as is (the linear-inflow form of the literature);
- rotor drag, the in-plane H-force of edgewise flow, H_i = −k_d ω_i v_∥,i (v_∥ the in-plane part
  of the rotor's velocity), acting at the rotor (its moment about the centre of mass included);
- the motor: ``dc``, Drela's first-order DC motor (QPROP's motor model 1: I = (V − ω/K_V)/R,
  shaft torque (I − I₀)/K_V), driving the rotor inertia J_r ω̇ = Q_motor − Q_prop; or
  ``first-order``, τ_m ω̇ = K_V δ V_oc − ω (a lag to the no-load speed of the command, what a
  thrust stand's step test identifies). ``dc`` is the default: it is the model that makes the
  rotor slow down under load and speed up as the inflow unloads the propeller, which a racing
  lap exercises, and its three constants are on every motor's datasheet;
- the ESC as an ideal chopper (motor voltage δ V_bat, battery current Σ δ_i I_i) and the battery
  as an open-circuit voltage behind an internal resistance; the sag V_bat = V_oc − R_b I_bat is
  solved in closed form (it is linear in V_bat):
  V_bat = (V_oc + (R_b/R) Σ δ_i ω_i/K_V) / (1 + (R_b/R) Σ δ_i²);
- the yaw reaction of rotor i on the body is s_i Q_motor,i (the stator's reaction).

Not modelled: rotor gyroscopic moments, blade flapping, ground effect, vortex-ring state,
ESC losses, the battery's state of charge. Each term can be switched off: ``axial_inflow:
false``, ``rotor_drag_n_s2_per_m: 0``, ``internal_resistance_ohm: 0`` (no sag).

**The data's range.** CT(J), CP(J) are fits to wind-tunnel points that end at a largest
advance ratio J_max (``propeller.max_advance_ratio``; default, for a shipped dataset named in
``propeller.data``, the largest J of the points its fit uses: 0.618 for the shipped
propeller, :func:`data_advance_ratio`). Beyond it the quadratics are extrapolated, and near a
stopped rotor in axial inflow (J → ∞) the extrapolated CT is negative: T = ρ c₂ D² v_a², an
air brake of −3 N at 27 m/s that no data support. The model itself stays the polynomial in
(n, v_a) everywhere (a clamp of CT at J_max would divide by n and lose smoothness at n = 0,
and every stage shares this one model and its compiled blocks). Instead:

- the **limit lap**, the one stage that optimises into the extrapolation (without a bound its
  optimum flew 4–6 % of the paper track's rotor-nodes beyond the data, braking with negative
  thrust), keeps every rotor inside it: one row per rotor and node,
  J_max n_i D − v_a,i ≥ 0 (:func:`advance_margins`), linear in n and v_a, at n = 0 no inflow
  through the stopped rotor (:func:`casadrone.limit.nlp.advance_rows`). Inside the range
  CT(J) ≥ CT(J_max) > 0, so no thrust is negative (but for the smoothing's −ε/2 at a stopped
  rotor: ρ |c₂| D² ε²/4 ≈ 2e-5 N). The point mass's thrust bound is unchanged: it bounds a
  superset of these flights;
- the **closed-loop lap and the trim** use the model as it is: they simulate or solve a given
  flight, they do not seek the extrapolation. Measured (benchmarks/RESULTS-propulsion.md),
  the five reference frames' closed-loop laps stay inside the data but for momentary idle
  rotors (≤ 0.1 % of rotor-samples, |T| ≤ 0.01 N), and level trims to 30 m/s reach J = 0.59;
  the trim's message says when a rotor is beyond the range
  (:func:`casadrone.trim.beyond_data_note`), and ``limit-lap --json`` reports
  ``max_advance_ratio``, ``data_advance_ratio`` and ``beyond_data_share``.

The linear-inflow form of the quadrotor literature, T = k_η ω² − k_z ω v_a, Q = k_m ω²,
H = −k_d ω v_∥, is the special case c₀ = 4π² k_η/(ρ D⁴), c₁ = −2π k_z/(ρ D³), c₂ = 0,
CP = 8π³ k_m/(ρ D⁵) with signed inflow (``propeller.linear_inflow``).

The parameter vector of an airframe is the paper's (:data:`casadrone.airframe.PARAM_NAMES`) with
:data:`PROPELLER_PARAM_NAMES` appended (:func:`casadrone.model.param_names`). The section's
schema is :mod:`casadrone.config.propulsion`. This module sits below the airframe schema (whose
hover check uses :func:`full_static_thrust`) and imports CasADi only inside the symbolic
functions; its airframe-level helpers take any object with the
:class:`casadrone.airframe.Airframe` attributes. The entry of the registry is :data:`PROPELLER`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import cache
from typing import Any, TypedDict, cast

from casadrone.drag import DRAG_PARAM_NAMES
from casadrone.num import Num
from casadrone.propulsion.base import PaperParams, RotorStates, register_propulsion_model
from casadrone.propulsion.data import (
    DIAMETER_RTOL,
    FIRST_ORDER_TIME_CONSTANT_S,
    INFLOW_SMOOTHING_M_S,
    MAX_FIGURE_OF_MERIT,
    RPM_PER_V_TO_RAD_S_PER_V,
    SPEED_OF_SOUND_M_S,
    data_advance_ratio,
    figure_of_merit,
    momentum_problem,
    shipped_datasets,
)
from casadrone.propulsion.electric import pack_current

#: A ``propulsion:`` section, :class:`casadrone.config.propulsion.PropulsionConfig` (the schema
#: sits above this package, so it is not imported here).
PropulsionConfig = Any

class PropellerTail(TypedDict):
    """What the ``propeller`` kind appends to the paper's parameter vector, in its order (SI
    units; switches are 0 or 1), symbolic or numeric."""

    prop_D: Num  # propeller diameter (m)
    ct0: Num  # CT(J) = ct0 + ct1 J + ct2 J²
    ct1: Num
    ct2: Num
    cp0: Num  # CP(J)
    cp1: Num
    cp2: Num
    rotor_J: Num  # rotor (propeller + motor bell) inertia about its axis (kg·m²)
    rotor_kd: Num  # rotor drag k_d (N·s²/m): H = −k_d ω v_∥
    inflow_on: Num  # 1: thrust and torque depend on the axial inflow
    inflow_positive: Num  # 1: v_a taken as max(v_a, 0) (smoothed); 0: signed
    inflow_eps: Num  # smoothing width of max(v_a, 0) (m/s)
    motor_dc: Num  # 1: DC motor; 0: first-order lag
    motor_kv: Num  # K_V (rad/s per V)
    motor_R: Num  # winding resistance (Ω)
    motor_I0: Num  # no-load current (A)
    motor_tau: Num  # first-order time constant (s)
    batt_Voc: Num  # battery open-circuit voltage (V)
    batt_R: Num  # battery internal resistance (Ω)


class DragSwitch(TypedDict):
    """The body-drag switch a model with ``drag_forms`` appends after its own parameters
    (:data:`casadrone.drag.DRAG_PARAM_NAMES`)."""

    drag_isotropic: Num  # 1: isotropic body drag, 0: the paper's per-axis form (casadrone.drag)


class PropellerParams(PaperParams, PropellerTail, DragSwitch):
    """The airframe vector p of the ``propeller`` kind by name (:func:`casadrone.model.named`):
    the paper's parameters, then :class:`PropellerTail`'s, then the :class:`DragSwitch`."""


#: Appended to the paper's parameter vector: the fields of :class:`PropellerTail`, in order.
PROPELLER_PARAM_NAMES: tuple[str, ...] = tuple(PropellerTail.__annotations__)


# --------------------------------------------------------------------------------------------
# Parameter vector
# --------------------------------------------------------------------------------------------


def coefficients(cfg: PropulsionConfig, rho: float) -> tuple[list[float], list[float]]:
    """(CT, CP) coefficients (three each) of a propeller section; the linear-inflow form is
    converted at air density ``rho`` (kg/m³)."""
    prop = cfg.propeller
    assert prop is not None
    lin, D = prop.linear_inflow, prop.diameter_m
    if lin is not None:
        ct = [4 * math.pi**2 * lin.k_eta_n_s2 / (rho * D**4),
              -2 * math.pi * lin.k_z_n_s2_per_m / (rho * D**3), 0.0]
        cp = [8 * math.pi**3 * lin.k_m_n_m_s2 / (rho * D**5), 0.0, 0.0]
        return ct, cp
    assert prop.ct_coefficients is not None and prop.cp_coefficients is not None
    pad = [0.0, 0.0, 0.0]
    return ((list(prop.ct_coefficients) + pad)[:3], (list(prop.cp_coefficients) + pad)[:3])


def propeller_params(cfg: PropulsionConfig, rho: float) -> list[float]:
    """The :data:`PROPELLER_PARAM_NAMES` values of a ``propeller`` section (SI)."""
    prop, motor, batt = cfg.propeller, cfg.motor, cfg.battery
    assert prop is not None and motor is not None and batt is not None
    ct, cp = coefficients(cfg, rho)
    signed = prop.linear_inflow is not None or prop.inflow == "signed"
    eps = INFLOW_SMOOTHING_M_S if prop.inflow_smoothing_m_s is None else prop.inflow_smoothing_m_s
    return [
        prop.diameter_m, *ct, *cp, prop.rotor_inertia_kgm2, prop.rotor_drag_n_s2_per_m,
        float(prop.axial_inflow), 0.0 if signed else 1.0, eps,
        1.0 if motor.kind == "dc" else 0.0, motor.kv_rpm_per_v * RPM_PER_V_TO_RAD_S_PER_V,
        motor.resistance_ohm, motor.no_load_current_a,
        FIRST_ORDER_TIME_CONSTANT_S if motor.time_constant_s is None else motor.time_constant_s,
        batt.open_circuit_voltage_v, batt.internal_resistance_ohm,
    ]


# --------------------------------------------------------------------------------------------
# Symbolic propeller model
# --------------------------------------------------------------------------------------------


def axial_inflow(v_axial: Num, q: PropellerParams) -> Num:
    """The axial inflow (m/s) that enters CT and CP: v_a, or max(v_a, 0) smoothed as
    ½(v + √(v² + ε²)) − ε/2 (exactly 0 at v = 0, ≥ −ε/2 everywhere), times the inflow switch."""
    import casadi as ca

    eps = q["inflow_eps"]
    positive = 0.5 * (v_axial + ca.sqrt(v_axial**2 + eps**2)) - 0.5 * eps
    pos = q["inflow_positive"]
    return q["inflow_on"] * (pos * positive + (1 - pos) * v_axial)


def rotor_loads(w: Num, v_a: Num, q: PropellerParams) -> tuple[Num, Num]:
    """Thrust (N) and shaft torque (N·m) of one rotor at speed w (rad/s) and effective axial
    inflow v_a (m/s): T = ρ (c₀ D⁴ n² + c₁ D³ n v + c₂ D² v²), Q = ρ/(2π) (cp₀ D⁵ n² + …)."""
    rho, D = q["rho"], q["prop_D"]
    n = w / (2 * math.pi)
    T = rho * (q["ct0"] * D**4 * n**2 + q["ct1"] * D**3 * n * v_a + q["ct2"] * D**2 * v_a**2)
    Q = rho / (2 * math.pi) * (q["cp0"] * D**5 * n**2 + q["cp1"] * D**4 * n * v_a
                               + q["cp2"] * D**3 * v_a**2)
    return T, Q


def battery_voltage(w: Num, u: Num, q: PropellerParams) -> Num:
    """V_bat (V) under load, the closed-form sag (module docstring); w, u of all four rotors."""
    import casadi as ca

    k = q["batt_R"] / q["motor_R"]
    return (q["batt_Voc"] + k * ca.dot(u, w) / q["motor_kv"]) / (1 + k * ca.dot(u, u))


def motor_currents(w: Num, u: Num, q: PropellerParams) -> tuple[Num, Num]:
    """(V_bat (V), motor currents I_i (A, 4)) of the DC motor model."""
    V = battery_voltage(w, u, q)
    return V, (u * V - w / q["motor_kv"]) / q["motor_R"]


def propeller_terms(vel: Num, omega: Num, w: Num, w_dot: Num, u: Num, q: PropellerParams,
                    r: list[Num], s: list[Num]) -> tuple[Num, Num, Num, Num, Num]:
    """Rotor force, torque and rotor residual of the ``propeller`` kind (see module docstring)
    as (force (3), torque (3), rotor residual (4), thrusts (4), axial inflows (4)); ``q`` the
    named parameters (:func:`casadrone.model.named`), ``r`` the rotor positions from the centre
    of mass, ``s`` the spin signs."""
    import casadi as ca

    ez = ca.DM([0, 0, 1])
    _, current = motor_currents(w, u, q)
    q_motor_dc = (current - q["motor_I0"]) / q["motor_kv"]
    target = q["motor_kv"] * u * q["batt_Voc"]  # first-order: no-load speed of the command
    dc = q["motor_dc"]
    force, torque, residual, thrusts, inflows = ca.DM.zeros(3), ca.DM.zeros(3), [], [], []
    for i in range(4):
        v_i = vel + ca.cross(omega, r[i])
        v_ax = v_i[2]
        v_a = axial_inflow(v_ax, q)
        T, Q = rotor_loads(w[i], v_a, q)
        q_motor = dc * q_motor_dc[i] + (1 - dc) * (Q + q["rotor_J"] * (target[i] - w[i])
                                                   / q["motor_tau"])
        H = -q["rotor_kd"] * w[i] * ca.vertcat(v_i[0], v_i[1], 0)
        f_i = T * ez + H
        force = force + f_i
        torque = torque + ca.cross(r[i], f_i) + s[i] * q_motor * ez
        residual.append(dc * (q["rotor_J"] * w_dot[i] - q_motor_dc[i] + Q)
                        + (1 - dc) * (q["motor_tau"] * w_dot[i] + w[i] - target[i]))
        thrusts.append(T)
        inflows.append(v_a)
    return force, torque, ca.vertcat(*residual), ca.vertcat(*thrusts), ca.vertcat(*inflows)


def rotor_decay_rate(q: PropellerParams) -> Num:
    """The rotor speeds' linear decay rate λ (1/s) that depends on the parameters only, the
    linear part −λ ω of ω̇ that the exponential step integrates exactly
    (:func:`casadrone.limit.nlp.etdrk4_step`): with the DC motor the back-EMF damping
    1/(J_r R K_V²) (the current's −ω/(K_V R) term through the torque (I − I₀)/K_V over the rotor
    inertia; the propeller's load and the pack's sag are left to the step's nonlinear part), with
    the first-order motor 1/τ_m. SY250-propeller: 35.9 1/s (27.8 ms), against 46 1/s (median;
    55.5 largest) of the full linearisation along its limit lap
    (benchmarks/RESULTS-propulsion.md)."""
    dc = q["motor_dc"]
    return dc / (q["rotor_J"] * q["motor_R"] * q["motor_kv"] ** 2) + (1 - dc) / q["motor_tau"]


def advance_margins(vel: Num, omega: Num, w: Num, q: PropellerParams, r: list[Num],
                    j_max: float) -> Num:
    """The four rows J_max n_i D − v_a,i (m/s) that keep each rotor inside its data,
    J = v_a/(n D) ≤ J_max: ``vel``, ``omega`` the body velocity (m/s) and rates (rad/s), ``w``
    the rotor speeds (rad/s), v_a the effective axial inflow of :func:`axial_inflow` (the one
    CT and CP see). Linear in n and v_a, no division: at n = 0 it asks v_a ≤ 0 (no inflow
    through a stopped rotor) instead of dividing by zero."""
    import casadi as ca

    rows = [j_max * w[i] / (2 * math.pi) * q["prop_D"]
            - axial_inflow((vel + ca.cross(omega, r[i]))[2], q) for i in range(4)]
    return ca.vertcat(*rows)


# --------------------------------------------------------------------------------------------
# Steady states at zero airspeed (closed form, numeric)
# --------------------------------------------------------------------------------------------


def static_speed(q: dict[str, float], delta: float) -> float:
    """Steady rotor speed (rad/s) of all four rotors at the same command ``delta`` and zero
    airspeed. DC motor: the motor torque is linear in ω (with the sag), the propeller's c ω², so
    Q_motor = Q_prop is a quadratic with one positive root. First-order: K_V δ V_oc."""
    if q["motor_dc"] < 0.5:
        return q["motor_kv"] * delta * q["batt_Voc"]
    kv, R, k = q["motor_kv"], q["motor_R"], q["batt_R"] / q["motor_R"]
    den = 1 + 4 * k * delta**2
    # V = (Voc + 4 k δ ω / kv) / den;  I = (δ V − ω/kv)/R = a0 + a1 ω;  Q_m = (I − I0)/kv
    a0 = delta * q["batt_Voc"] / den / R
    a1 = (delta * 4 * k * delta / kv / den - 1 / kv) / R
    c = q["rho"] * q["cp0"] * q["prop_D"] ** 5 / (2 * math.pi) / (2 * math.pi) ** 2
    A, B, C = c, -a1 / kv, -(a0 - q["motor_I0"]) / kv  # c ω² − Q_m(ω) = 0
    if C >= 0:
        return 0.0  # the command does not overcome the no-load current
    return (-B + math.sqrt(B * B - 4 * A * C)) / (2 * A)


def static_thrust(q: dict[str, float], w: float) -> float:
    """Thrust (N) of one rotor at speed w (rad/s) and zero inflow."""
    return q["rho"] * q["ct0"] * q["prop_D"] ** 4 * (w / (2 * math.pi)) ** 2


def speed_for_thrust(q: dict[str, float], thrust: float) -> float:
    """Rotor speed (rad/s) giving ``thrust`` (N) at zero inflow."""
    return 2 * math.pi * math.sqrt(max(thrust, 0.0) / (q["rho"] * q["ct0"] * q["prop_D"] ** 4))


def hover_commands(q: dict[str, float], thrusts) -> tuple[list[float], list[float]]:
    """(rotor speeds (rad/s), commands) holding each rotor at its thrust (N) at zero airspeed.

    DC motor: I_i = I₀ + K_V Q_prop,i, δ_i V = R I_i + ω_i/K_V =: e_i and V = V_oc − R_b Σ δ_i I_i
    give V² − V_oc V + R_b Σ e_i I_i = 0 (the larger root). First-order: δ = ω/(K_V V_oc)."""
    w = [speed_for_thrust(q, t) for t in thrusts]
    if q["motor_dc"] < 0.5:
        return w, [wi / (q["motor_kv"] * q["batt_Voc"]) for wi in w]
    kv, R = q["motor_kv"], q["motor_R"]
    c = q["rho"] * q["cp0"] * q["prop_D"] ** 5 / (2 * math.pi) / (2 * math.pi) ** 2
    current = [q["motor_I0"] + kv * c * wi**2 for wi in w]
    e = [R * i + wi / kv for i, wi in zip(current, w, strict=True)]
    disc = q["batt_Voc"] ** 2 - 4 * q["batt_R"] * sum(a * b for a, b in zip(e, current,
                                                                           strict=True))
    V = 0.5 * (q["batt_Voc"] + math.sqrt(max(disc, 0.0)))
    return w, [ei / V for ei in e]


def max_speed(q: dict[str, float]) -> float:
    """Upper bound of the rotor speed (rad/s) used by the limit lap: the no-load speed at the
    open-circuit voltage, K_V V_oc. A motor at δ ≤ 1 driving a propeller that absorbs power
    (CP > 0) cannot exceed it: the battery voltage under a positive load is below V_oc and the
    motor torque at ω ≥ K_V V_oc is negative."""
    return q["motor_kv"] * q["batt_Voc"]


def box_thrust_bound(q: dict[str, float]) -> float:
    """An upper bound (N) of one rotor's thrust over the limit lap's whole box, every airspeed
    and every rotor speed 0 ≤ ω ≤ :func:`max_speed`: T = ρ (c₀ D⁴ n² + c₁ D³ n v + c₂ D² v²) with
    c₁, c₂ ≤ 0 (the schema refuses others) is largest at the smallest effective inflow, v = 0
    with ``positive`` inflow up to the smoothing's −ε/2; so T ≤ ρ (c₀ D⁴ n² + |c₁| D³ n ε/2).
    Rigorous but loose (3× the static full thrust of SY250-propeller: the no-load speed at the
    open-circuit voltage is far above any speed the loaded rotor reaches)."""
    n = max_speed(q) / (2 * math.pi)
    D = q["prop_D"]
    return q["rho"] * (q["ct0"] * D**4 * n**2 + abs(q["ct1"]) * D**3 * n * q["inflow_eps"] / 2)


def full_command_speed(q: dict[str, float], v_axial):
    """Steady rotor speed (rad/s) of all four rotors at full command (δ = 1) with the same
    effective axial inflow ``v_axial`` (m/s, array), the pack sagging under the four motors'
    current. DC motor: the motor torque is linear in ω (with the sag), the propeller's torque
    A ω² + B ω + C (B, C from the inflow), one positive root. First-order: K_V V_oc."""
    import numpy as np

    v = np.asarray(v_axial, float)
    if q["motor_dc"] < 0.5:
        return np.full_like(v, q["motor_kv"] * q["batt_Voc"])
    kv, R, k, D, rho = q["motor_kv"], q["motor_R"], q["batt_R"] / q["motor_R"], q["prop_D"], \
        q["rho"]
    # Q_m = a0 + a1 ω (static_speed with δ = 1)
    a0 = (q["batt_Voc"] / (1 + 4 * k) / R - q["motor_I0"]) / kv
    a1 = (4 * k / kv / (1 + 4 * k) - 1 / kv) / R / kv
    c = rho / (2 * math.pi)
    A = c * q["cp0"] * D**5 / (2 * math.pi) ** 2
    B = c * q["cp1"] * D**4 * v / (2 * math.pi) - a1
    C = c * q["cp2"] * D**3 * v**2 - a0
    return (-B + np.sqrt(np.maximum(B * B - 4 * A * C, 0.0))) / (2 * A)


#: Axial inflows (m/s) over which :func:`thrust_bound` maximises the steady full-command thrust:
#: from the smoothing's −ε/2 to 150 m/s (three times the fastest lap flown), 0.05 m/s apart.
BOUND_INFLOW_MAX_M_S, BOUND_INFLOW_STEP_M_S = 150.0, 0.05


def thrust_bound(q: dict[str, float]) -> float:
    """The point mass's thrust bound per rotor (N): the largest steady thrust of a rotor at
    full command over every effective axial inflow v ≥ −ε/2, all four rotors at full command
    with the pack's sag (:func:`full_command_speed`, maximised on a grid to
    :data:`BOUND_INFLOW_MAX_M_S`).

    Why it bounds the total thrust of every steady flight, at every speed:

    - inflow: at a fixed rotor speed T falls with v ≥ 0 (c₁, c₂ ≤ 0, enforced by the schema);
      the inflow also unloads the propeller, so the rotor speeds up, but for the shipped data
      that never wins: the maximum is at v = 0 (less than 0.1 % above the static full thrust,
      from the smoothing's −ε/2). Descent, braking or flight backwards through the disc (J < 0)
      gives v = 0 with ``inflow: positive``: the static thrust again. With ``inflow: signed``
      (the linear-inflow form) descent raises the thrust without bound, and
      :func:`rotor_thrust_bound` is then inf;
    - commands: the point mass bounds the *sum* ΣT ≤ 4 T_b. One rotor alone can exceed T_b (the
      others draw less current, so the pack sags less), but then the others give less, and all
      four at full command draws the most power from the pack below its maximum-power current
      V_oc/(2 R_b); checked by maximising ΣT over unequal commands and inflows
      (tests/unit/test_propulsion.py);
    - rotor drag (the H-force) is in the rotor plane, not along the thrust: it has no
      counterpart in the point mass (:func:`casadrone.limit.nlp.point_mass_ocp_model`).

    Not covered: transients. The rotor speed is a state with a time constant of 20–30 ms; a
    rotor unloaded by a large inflow that then drops (the frame pitching up to brake) spins
    above its new steady speed for that long and can give more than T_b. The rigorous bound
    over the limit lap's whole box is :func:`box_thrust_bound` (3× looser); how far a lap's
    total thrust comes to 4 T_b is measured in benchmarks/RESULTS-propulsion.md.
    """
    v = bound_inflows(q)
    return float(rotor_loads(full_command_speed(q, v), v, cast(PropellerParams, q))[0].max())


def bound_inflows(q: dict[str, float]):
    """The effective axial inflows (m/s) over which the thrust bounds are maximised: the
    smoothing's −ε/2, then 0 to :data:`BOUND_INFLOW_MAX_M_S` every
    :data:`BOUND_INFLOW_STEP_M_S`."""
    import numpy as np

    return np.concatenate([[-q["inflow_eps"] / 2],
                           np.arange(0.0, BOUND_INFLOW_MAX_M_S, BOUND_INFLOW_STEP_M_S)])


def pack_power(q: dict[str, float], pack_a: float) -> float:
    """The largest power (W) the pack gives at currents up to ``pack_a`` (A):
    I (V_oc − R_b I) at I = min(``pack_a``, V_oc / (2 R_b)), the current of its largest power
    (more current gives less)."""
    voc, rb = q["batt_Voc"], q["batt_R"]
    current = pack_a if rb <= 0 else min(pack_a, voc / (2 * rb))
    return current * (voc - rb * current)


def electric_thrust_bound(q: dict[str, float], motor_a: float | None,
                          rotor_power_w: float | None) -> float:
    """The largest steady thrust (N) of one rotor over every effective axial inflow
    (:func:`bound_inflows`) when the motor's current is at most ``motor_a`` (A) and the rotor
    draws at most ``rotor_power_w`` (W) at the motor's terminals, at or below full command: at
    each inflow the rotor speed is the least of the full-command speed
    (:func:`full_command_speed`), the speed whose shaft torque draws ``motor_a``
    (I = I₀ + K_V Q, Q quadratic in ω: its positive root) and the speed whose terminal power
    (R I + ω/K_V) I reaches ``rotor_power_w`` (increasing in ω: bisection); the thrust is CT's
    at that speed (:func:`rotor_loads`). None for either limit leaves it out; neither:
    :func:`thrust_bound`. The DC motor's (the first-order motor has no current:
    :func:`thrust_bound`).

    Why a quarter of the pack's power (:func:`pack_power`) bounds a rotor's share
    (:mod:`casadrone.build.bound`): the four motors together draw at most the pack's power at
    its current limit, and a rotor's largest thrust grows slower than its power (≈ P^(2/3) at
    rest, and each inflow's less), so four rotors sharing a power give the most thrust sharing
    it equally; checked against random steady states of the model under the limits
    (tests/unit/test_propulsion.py)."""
    import numpy as np

    if q["motor_dc"] < 0.5 or (motor_a is None and rotor_power_w is None):
        return thrust_bound(q)
    v = bound_inflows(q)
    kv, R = q["motor_kv"], q["motor_R"]
    w = full_command_speed(q, v)
    pq = cast(PropellerParams, q)

    def torque(w_):  # shaft torque (N·m) at rotor speed w_ (rad/s), quadratic in it
        return rotor_loads(w_, v, pq)[1]

    def current(w_):  # the DC motor's steady current (A)
        return q["motor_I0"] + kv * torque(w_)

    if motor_a is not None:  # Q(ω) = A ω² + B ω + C = (I_max − I₀)/K_V: the positive root
        up, down, rest = torque(1.0), torque(-1.0), torque(0.0)
        A, B = (up + down) / 2 - rest, (up - down) / 2
        C = rest - (motor_a - q["motor_I0"]) / kv
        w = np.minimum(w, (-B + np.sqrt(np.maximum(B * B - 4 * A * C, 0.0))) / (2 * A))
    if rotor_power_w is not None:
        def power(w_):
            return (R * current(w_) + w_ / kv) * current(w_)

        lo, hi = np.zeros_like(w), w.copy()
        for _ in range(60):  # bisection to machine precision of ω (2^-60 of its range)
            mid = 0.5 * (lo + hi)
            over = power(mid) > rotor_power_w
            hi, lo = np.where(over, mid, hi), np.where(over, lo, mid)
        w = np.where(power(w) > rotor_power_w, lo, w)
    return float(rotor_loads(w, v, pq)[0].max())


def values(cfg: PropulsionConfig, rho: float) -> dict[str, float]:
    """The named propeller parameters of a section (air density ``rho``, kg/m³) as floats."""
    return {"rho": rho, **dict(zip(PROPELLER_PARAM_NAMES, propeller_params(cfg, rho),
                                   strict=True))}


def full_static_thrust(cfg: PropulsionConfig, rho: float) -> float:
    """Thrust (N) of one rotor at full command, all four at full command, zero airspeed."""
    q = values(cfg, rho)
    return static_thrust(q, static_speed(q, 1.0))


# --------------------------------------------------------------------------------------------
# What other stages ask of an airframe's propulsion (one place for "the maximum thrust")
# --------------------------------------------------------------------------------------------


def airframe_values(airframe) -> dict[str, float]:
    """The propeller parameters of a ``propeller`` airframe (its p after the paper's names, before
    the body-drag switch) and the air density, as floats."""
    start = len(airframe.p) - len(PROPELLER_PARAM_NAMES) - len(DRAG_PARAM_NAMES)
    tail = airframe.p[start:start + len(PROPELLER_PARAM_NAMES)]
    return {"rho": float(airframe.air_density),
            **{k: float(v) for k, v in zip(PROPELLER_PARAM_NAMES, tail, strict=True)}}


# --------------------------------------------------------------------------------------------
# Shipped propeller data and the fit behind the shipped coefficients
# --------------------------------------------------------------------------------------------

def advance_ratio_limit(cfg: PropulsionConfig) -> float | None:
    """The largest advance ratio the limit lap may fly (dimensionless), None for none: the
    section's ``propeller.max_advance_ratio``; else, when ``propeller.data`` names a shipped
    dataset, its :func:`data_advance_ratio`; else None (coefficients given without data, the
    linear-inflow form: no range is known, so none is imposed)."""
    prop = cfg.propeller
    if prop is None:
        return None
    if prop.max_advance_ratio is not None:
        return float(prop.max_advance_ratio)
    if prop.data is not None and prop.data in shipped_datasets():
        return data_advance_ratio(prop.data)
    return None


def fit_coefficients(J, y, degree: int = 2, relative: bool = False) -> list[float]:
    """Least-squares polynomial coefficients c_0…c_degree of y(J), every point weighted alike
    (absolute residuals: a sweep to its end crosses C_T = 0, where weights 1/|y| would fit that
    one point and nothing else), or with ``relative=True`` relative residuals weighted equally
    (each point weighted by 1/|y|: data that stay away from zero)."""
    import numpy as np

    y = np.asarray(y)
    c = np.polynomial.polynomial.polyfit(np.asarray(J), y, degree,
                                         w=1 / np.abs(y) if relative else None)
    return [float(v) for v in c]


def airframe_problems(prop: PropulsionConfig, *, mass_kg: float | None, rho: float | None,
                      prop_diameter_mm: float | None, mass_key: str) -> list[tuple[str, str]]:
    """Problems of a valid ``propeller`` section against the rest of its airframe, as (airframe
    key, message): those that need the vehicle's mass, the air density or the airframe's own
    propeller diameter. Checks whose input is absent (None) are skipped."""
    if prop.propeller is None:
        return []
    found: list[tuple[str, str]] = []
    p, motor, batt = prop.propeller, prop.motor, prop.battery
    D = p.diameter_m
    if prop_diameter_mm is not None and abs(D - prop_diameter_mm / 1000) > DIAMETER_RTOL * D:
        found.append(("propulsion.propeller.diameter_m", (
            f"{D:g} m disagrees with prop_diameter_mm {prop_diameter_mm:g} (the rotor-overlap "
            f"check's; more than {DIAMETER_RTOL:.0%} apart): one propeller has one diameter")))
    if mass_kg is not None:
        # Each rotor's mass lies within D/2 of its axis, so J_r ≤ m_r (D/2)²; four rotors weigh
        # at most the vehicle, m_r ≤ m/4: J_r ≤ m D²/16 (the whole quarter mass at the tips).
        most = mass_kg * D**2 / 16
        if p.rotor_inertia_kgm2 > most:
            found.append(("propulsion.propeller.rotor_inertia_kgm2", (
                f"{p.rotor_inertia_kgm2:g} kg·m² exceeds m D²/16 = {most:.3g} kg·m², a quarter of "
                f"the vehicle's {mass_kg:g} kg all at the propeller tips (diameter {D:g} m)")))
        # The parts are within the whole, and the rest (frame, propellers, electronics) weighs
        # more than nothing.
        m_motors = 4 * motor.mass_kg if motor is not None and motor.mass_kg else 0.0
        m_batt = batt.mass_kg if batt is not None and batt.mass_kg else 0.0
        if m_motors + m_batt >= mass_kg:
            key = ("propulsion.battery.mass_kg" if m_batt >= mass_kg else
                   "propulsion.motor.mass_kg" if m_motors >= mass_kg else mass_key)
            found.append((key, f"four motors ({m_motors:g} kg) and the battery ({m_batt:g} kg) "
                          f"weigh at least the whole vehicle ({mass_kg:g} kg): the parts cannot "
                          "outweigh the airframe they are part of"))
    if rho is not None:
        found += _air_problems(prop, rho)
    return found


@cache
def _air_problems(prop: PropulsionConfig, rho: float) -> tuple[tuple[str, str], ...]:
    """The checks of :func:`airframe_problems` that need only the section and the air (momentum
    theory of the linear-inflow form, subsonic tips): the same for every candidate of a study,
    so worked out once per (section, density), not per candidate (the section is frozen,
    hashable)."""
    p, motor, batt = prop.propeller, prop.motor, prop.battery
    if p is None or motor is None or batt is None:
        return ()
    D = p.diameter_m
    if p.linear_inflow is not None:
        ct, cp = coefficients(prop, rho)
        fm = figure_of_merit(ct[0], cp[0])
        if fm > MAX_FIGURE_OF_MERIT:
            lin = p.linear_inflow
            return (("propulsion.propeller.linear_inflow.k_m_n_m_s2", (
                f"static figure of merit k_η^1.5 / (k_m √(ρπ/2) D) = {fm:.3g} exceeds 1 "
                f"(k_eta_n_s2 = {lin.k_eta_n_s2:g}, D = {D:g} m, ρ = {rho:g} kg/m³): "
                "momentum theory needs a shaft power of at least the ideal T^1.5/√(2ρA), "
                f"k_m ≥ {fm * lin.k_m_n_m_s2:.4g} N·m·s² for this k_eta")),)
        # The climbing actuator disc over the range the limit lap flies (the section's
        # max_advance_ratio, else its dataset's: advance_ratio_limit), as for CT/CP
        # coefficients (casadrone.config.propulsion.momentum_problem): the linear form is the
        # same propeller in other units, and with k_z small its thrust holds up in climb at a
        # power momentum theory does not allow.
        j_max = advance_ratio_limit(prop)
        problem = momentum_problem(ct, cp, j_max) if j_max is not None else None
        if problem is not None:
            return (("propulsion.propeller.linear_inflow.k_m_n_m_s2", (
                f"{problem} (C_T, C_P of the linear-inflow form at ρ = {rho:g} kg/m³: "
                "c₀ = 4π²k_η/(ρD⁴), c₁ = −2πk_z/(ρD³), C_P = 8π³k_m/(ρD⁵))")),)
    w = static_speed(values(prop, rho), 1.0)
    tip = w * D / 2
    if tip < SPEED_OF_SOUND_M_S:
        return ()
    return (("propulsion.battery.open_circuit_voltage_v", (
        f"{batt.open_circuit_voltage_v:g} V drives the propeller at full command at rest "
        f"to {w * 60 / (2 * math.pi):.4g} rpm (K_V {motor.kv_rpm_per_v:g} rpm/V, "
        f"{motor.kind} motor): tip speed {tip:.4g} m/s, at or above the speed of sound "
        f"{SPEED_OF_SOUND_M_S:g} m/s, where no propeller model here holds")),)


# --------------------------------------------------------------------------------------------
# The registry's entry
# --------------------------------------------------------------------------------------------

#: The unit of the rotor states in the limit lap's NLP (rad/s): krad/s. In rad/s the rotor speeds
#: (~2·10³) and their rates (~10⁵ rad/s² in a full-command step) are three to five orders above
#: the other states (m, m/s, rad, rad/s ~ 1–50); IPOPT scales constraints by their gradients but
#: never the variables, so its steps, bound pushes and restoration phase then act on badly
#: scaled unknowns. Measured (benchmarks/RESULTS-propulsion.md): unscaled, SY250-propeller on
#: the paper track ended in Restoration_Failed from both starts.
ROTOR_SPEED_UNIT_RAD_S = 1000.0


class Propeller:
    """The propeller, DC motor and battery model (module docstring;
    :class:`casadrone.propulsion.base.PropulsionModel`)."""

    name = "propeller"
    description = "propeller"
    sections: tuple[str, ...] = ("propeller", "motor", "battery")
    no_sections = "its rotors are the propeller, motor and battery sections"
    param_names: tuple[str, ...] = PROPELLER_PARAM_NAMES
    #: rotor speeds (rad/s), 10³ from the paper's thrusts: no output labels one a thrust
    rotor_states = RotorStates(("omega1", "omega2", "omega3", "omega4"), "rotor speeds", "rad/s")
    thrust_is_state = False
    command_linear = False
    trim_unknowns = 10
    #: The rotor speed's time constant (~20 ms with the DC motor and rotor inertia) is shorter
    #: than the paper's thrust lag (61 ms), and RK4 steps of ~14 ms (40 intervals, 3 steps each, a
    #: 4.3 s lap over 5 legs) follow it badly: SY250-propeller's paper-track lap re-simulated
    #: 0.30 m off on 40 intervals and 2.1 cm off on 80, the lap itself the same to 0.01 %
    #: (4.3094 / 4.3090 s; benchmarks/RESULTS-propulsion.md).
    default_intervals = 80
    rotor_scale: float | None = ROTOR_SPEED_UNIT_RAD_S
    lagless = False  # the lag is the motor's (its section), not thrust.time_constant_s
    suffix = "-propeller"
    #: ``sigma_min``, the smallest centring parameter of IPOPT's adaptive μ (μ = σ × the average
    #: complementarity; IPOPT's default 1e-6), for a far warm start. Why: from a neighbouring
    #: frame's lap the adaptive μ fell at the first iteration to 10^-9.2 (``paper``: 10^-5.4), and
    #: with so small a barrier the Newton steps ran into the commands' and the tilt bounds
    #: (fraction to the boundary) for 40 iterations before the first full step. Measured on
    #: SY250-propeller's two neighbours of bench_propulsion_warm (80 intervals;
    #: benchmarks/RESULTS-propulsion.md, "Closing the warm gap"): σ_min 1e-3 35 and 26 iterations
    #: instead of 66 and 67 (four neighbours: 26–35 against 41–67), the same laps to 8 digits (it
    #: changes the path, not the convergence test); 1e-4 42 and 33, 1e-2 32 and 49. A floor on μ
    #: instead (``mu_min`` 1e-7) took 25 and 15 but stops on the barrier's bias (laps 0.003 %
    #: slower; 3e-7: 0.009 %). ``paper`` keeps IPOPT's default: its results stay bit-identical.
    warm_ipopt: Mapping[str, float] = {"sigma_min": 1e-3}
    #: the airframe's drag_model chooses the body-drag form (casadrone.drag)
    drag_forms = True

    def pack(self, section: PropulsionConfig, rho: float) -> list[float]:
        return propeller_params(section, rho)

    def section_problems(self, section: PropulsionConfig, *, mass_kg: float | None,
                         rho: float | None, prop_diameter_mm: float | None, mass_key: str
                         ) -> list[tuple[str, str]]:
        return airframe_problems(section, mass_kg=mass_kg, rho=rho,
                                 prop_diameter_mm=prop_diameter_mm, mass_key=mass_key)

    def full_static_thrust(self, section: PropulsionConfig, rho: float) -> float | None:
        """None while a section is missing (the schema reports it)."""
        if None in (section.propeller, section.motor, section.battery):
            return None
        return full_static_thrust(section, rho)

    def advance_ratio_limit(self, section: PropulsionConfig) -> float | None:
        return advance_ratio_limit(section)

    def terms(self, vel, omega, rotor, rotor_dot, u, q, r, s):
        return propeller_terms(vel, omega, rotor, rotor_dot, u, q, r, s)[:3]

    def thrusts(self, vel, omega, rotor, q, r, s):
        """T_i = CT(J_i) ρ n_i² D⁴ at the rotor's own axial inflow, the thrust
        :func:`propeller_terms` gives the model (commands and rotor accelerations do not enter
        it)."""
        import casadi as ca

        zero = ca.DM.zeros(4)
        return propeller_terms(vel, omega, rotor, zero, zero, q, r, s)[3]

    def steady_rotors(self, delta, q):
        return None  # the rotor speeds at rest solve the motor-propeller balance: trim unknowns

    def static_rotors(self, thrust, q):
        """ω = 2π √(T / (ρ c_T0 D⁴)) (:func:`speed_for_thrust`, symbolic)."""
        import casadi as ca
        import numpy as np

        return 2 * np.pi * ca.sqrt(thrust / (q["rho"] * q["ct0"] * q["prop_D"] ** 4))

    def decay_rate(self, q):
        return rotor_decay_rate(q)

    def currents(self, rotor, u, q):
        """(pack current Σ δ_i I_i, motor currents I_i) (A) of the DC motor model
        (:func:`motor_currents`, :func:`casadrone.propulsion.electric.pack_current`)."""
        _, current = motor_currents(rotor, u, q)
        return pack_current(u, current), current

    def max_static_thrust(self, airframe) -> float:
        """The steady DC-motor/propeller balance with the battery's sag."""
        q = airframe_values(airframe)
        return static_thrust(q, static_speed(q, 1.0))

    def rotor_thrust_bound(self, airframe) -> float:
        """:func:`thrust_bound`, the largest steady full-command thrust over every airspeed
        (exceeded only in rotor-speed transients; its docstring argues it); inf with signed
        inflow, where descent raises the thrust without bound."""
        q = airframe_values(airframe)
        if q["inflow_positive"] < 0.5 and q["inflow_on"] > 0.5:
            return math.inf
        return thrust_bound(q)

    def rotor_state_bounds(self, airframe) -> tuple[float, float]:
        """Rotor speed in [0, K_V V_oc] (:func:`max_speed`)."""
        return 0.0, max_speed(airframe_values(airframe))

    def hover_rotors(self, airframe, thrusts) -> tuple[list[float], list[float]]:
        """(ω, δ) of :func:`hover_commands`."""
        return hover_commands(airframe_values(airframe), list(thrusts))

    def static_thrusts(self, airframe, rotor_states):
        """ρ c₀ D⁴ n² of the rotor speeds."""
        import numpy as np

        r = np.asarray(rotor_states, float)
        q = airframe_values(airframe)
        return q["rho"] * q["ct0"] * q["prop_D"] ** 4 * (r / (2 * math.pi)) ** 2


PROPELLER = register_propulsion_model(Propeller())
