"""Symbolic quadrotor model, implicit F(ẋ, x, u, p) = 0, parametric in the airframe vector p.

State (16): position x, y, z (world, m); body velocity u, v, w (m/s); body rates p, q, r
(rad/s); ZYX Euler angles φ, θ, ψ (rad; positive θ is nose-down); four rotor states: the thrusts
T1…T4 (N) with the ``paper`` propulsion model, the rotor speeds ω1…ω4 (rad/s) with ``propeller``
(what the airframe's propulsion model says they are: :mod:`casadrone.propulsion`). Input (4):
normalised ESC commands δ1…δ4 ∈ [0, 1]. Rotors FR, FL, RL, RR.

The model is built once per process and propulsion kind (:func:`quadrotor_model`); every airframe
is only a value of p, so evaluating a thousand airframes never rebuilds an expression.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Literal, cast, overload

import casadi as ca

from casadrone.airframe import PARAM_NAMES
from casadrone.drag import body_drag
from casadrone.num import Num
from casadrone.propulsion import RotorStates, appended_names, motor_currents, propulsion_model
from casadrone.propulsion.base import PaperParams
from casadrone.propulsion.propeller import PropellerParams, propeller_terms

STATE_NAMES = (
    "x", "y", "z", "u", "v", "w", "p", "q", "r", "phi", "theta", "psi", "T1", "T2", "T3", "T4",
)  # fmt: skip
INPUT_NAMES = ("delta1", "delta2", "delta3", "delta4")
NX, NU, NP = len(STATE_NAMES), len(INPUT_NAMES), len(PARAM_NAMES)  # NP: the paper's layout
IDX = {name: i for i, name in enumerate(STATE_NAMES)}
POS, VEL, RATE, EUL, THR = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 16)


def rotor_states(propulsion: str = "paper") -> RotorStates:
    """What the four rotor states of propulsion kind ``propulsion`` are (names, what, unit): thrusts
    (N) with ``paper``, rotor speeds (rad/s) with ``propeller`` (two quantities 10³ apart), so that
    no output labels a rotor speed a thrust."""
    return propulsion_model(propulsion).rotor_states


def state_names(propulsion: str = "paper") -> tuple[str, ...]:
    """The 16 state names of propulsion kind ``propulsion`` (:data:`STATE_NAMES` with the rotor
    states named by :func:`rotor_states`); the state's layout is the same for every kind."""
    return STATE_NAMES[:12] + rotor_states(propulsion).names


def rotation_matrix(phi: Num, theta: Num, psi: Num) -> Num:
    """Body → world rotation R = Rz(ψ) Ry(θ) Rx(φ) (works on CasADi symbols and floats)."""
    cph, sph = ca.cos(phi), ca.sin(phi)
    cth, sth = ca.cos(theta), ca.sin(theta)
    cps, sps = ca.cos(psi), ca.sin(psi)
    return ca.vertcat(
        ca.horzcat(cps * cth, cps * sth * sph - sps * cph, cps * sth * cph + sps * sph),
        ca.horzcat(sps * cth, sps * sth * sph + cps * cph, sps * sth * cph - cps * sph),
        ca.horzcat(-sth, cth * sph, cth * cph),
    )


def euler_rate_matrix(phi: Num, theta: Num) -> Num:
    """W with [φ̇, θ̇, ψ̇] = W ω for ZYX Euler angles (singular at θ = ±90°)."""
    cph, sph = ca.cos(phi), ca.sin(phi)
    cth, tth = ca.cos(theta), ca.tan(theta)
    return ca.vertcat(
        ca.horzcat(1, sph * tth, cph * tth),
        ca.horzcat(0, cph, -sph),
        ca.horzcat(0, sph / cth, cph / cth),
    )


def unpack_params(p: Num) -> tuple[PaperParams, Num, list[Num], list[Num], Num]:
    """Named pieces of the parameter vector p (symbolic or numeric): the paper's parameters by
    name, the inertia matrix J (3×3), the rotor positions r_i (3 each), the spin signs s_i and
    the drag areas (3)."""
    entries = {name: p[i] for i, name in enumerate(PARAM_NAMES)}
    g = cast(PaperParams, entries)
    J = ca.vertcat(
        ca.horzcat(g["Ixx"], g["Ixy"], g["Ixz"]),
        ca.horzcat(g["Ixy"], g["Iyy"], g["Iyz"]),
        ca.horzcat(g["Ixz"], g["Iyz"], g["Izz"]),
    )
    r = [ca.vertcat(entries[f"r{i}x"], entries[f"r{i}y"], entries[f"r{i}z"]) for i in range(1, 5)]
    s = [entries[f"s{i}"] for i in range(1, 5)]
    cda = ca.vertcat(g["CdA_x"], g["CdA_y"], g["CdA_z"])
    return g, J, r, s, cda


@dataclass(frozen=True)
class QuadrotorModel:
    """The symbolic model and its compiled-once CasADi Functions.

    Attributes:
        F: implicit residual ``F(xdot, x, u, p) -> res`` (16).
        f: explicit dynamics ``f(x, u, p) -> xdot`` derived from F.
        jacobians: ``jacobians(xdot, x, u, p) -> (E, A_prime, B_prime)``, exact Jacobians of F.
        linear_parts: ``linear_parts(x, u, p) -> (xdot, E, A_prime, B_prime)``, dense: ẋ = f and
            the Jacobians of F there in one call (F is affine in ẋ with E(p), so A′ and B′ do
            not depend on ẋ).
    """

    F: ca.Function
    f: ca.Function
    jacobians: ca.Function
    linear_parts: ca.Function
    state_names: tuple[str, ...] = STATE_NAMES
    input_names: tuple[str, ...] = INPUT_NAMES
    param_names: tuple[str, ...] = PARAM_NAMES


@dataclass(frozen=True)
class AirframeTerms:
    """The airframe's forces, torques and rotor dynamics in the body frame, gravity excluded: the
    part of the model that does not depend on how attitude is represented (symbolic or numeric).

    Attributes:
        thrust: rotor force on the body (N, body frame; the paper's model: Σ T_i along body z).
        drag: airframe drag (N, body frame; the airframe's form, :func:`casadrone.drag.body_drag`:
            −½ ρ CdA_i |v_i| v_i per body axis with the paper's model).
        torque: rotor torque on the body (N·m; thrust moments r_i × T_i e_z and yaw reaction
            torques s_i κ T_i e_z).
        rotor_residual: the rotor states' implicit dynamics, zero along a flight (the paper's
            model: τ Ṫ_i + T_i − K δ_i).
    """

    thrust: Num
    drag: Num
    torque: Num
    rotor_residual: Num


def param_names(kind: str = "paper") -> tuple[str, ...]:
    """The names of the parameter vector p of propulsion ``kind``: the paper's first, then the
    model's own and its body-drag switch if it has one
    (:func:`casadrone.propulsion.appended_names`)."""
    return PARAM_NAMES + appended_names(propulsion_model(kind))


@overload
def named(p: Num, kind: Literal["propeller"] = ...) -> PropellerParams: ...


@overload
def named(p: Num, kind: str) -> PaperParams: ...


def named(p: Num, kind: str = "propeller") -> PaperParams:
    """The entries of p (symbolic or numeric) by name: the typed record of the paper's
    parameters (:class:`~casadrone.propulsion.base.PaperParams`) with those of propulsion
    ``kind`` after them (:class:`~casadrone.propulsion.propeller.PropellerParams` for
    ``propeller``)."""
    return cast(PaperParams, {name: p[i] for i, name in enumerate(param_names(kind))})


def n_params(propulsion: str = "paper") -> int:
    """Length of the parameter vector p of propulsion kind ``propulsion``."""
    return len(param_names(propulsion))


def airframe_terms(vel: Num, omega: Num, rotor: Num, rotor_dot: Num, u: Num, p: Num,
                   propulsion: str = "paper") -> AirframeTerms:
    """:class:`AirframeTerms` at body velocity ``vel`` (m/s), body rates ``omega`` (rad/s), rotor
    states ``rotor`` and their derivative ``rotor_dot``, ESC commands ``u`` and airframe vector
    ``p`` (in the layout of ``propulsion``, :func:`param_names`). Every
    attitude representation (the Euler model below, the limit lap's) is built on it; the rotor
    force, torque and residual are the propulsion model's
    (:meth:`casadrone.propulsion.base.PropulsionModel.terms`), the drag the airframe's.
    """
    model = propulsion_model(propulsion)
    g, _, r, s, cda = unpack_params(p)
    q = named(p, propulsion)
    force, torque, residual = model.terms(vel, omega, rotor, rotor_dot, u, q, r, s)
    return AirframeTerms(thrust=force, drag=body_drag(vel, g["rho"], cda, q),
                         torque=torque, rotor_residual=residual)


def rotor_thrusts(vel: Num, omega: Num, rotor: Num, p: Num, propulsion: str = "paper") -> Num:
    """Each rotor's thrust (N, 4) along its axis at body velocity ``vel`` (m/s), body rates
    ``omega`` (rad/s) and rotor states ``rotor``: the states themselves with ``paper`` (they are
    the thrusts); with ``propeller`` T_i = CT(J_i) ρ n_i² D⁴ at the rotor's own axial inflow, the
    thrust :func:`casadrone.propulsion.propeller_terms` gives the model (the same expression, not
    a second copy; commands and rotor accelerations do not enter it)."""
    _, _, r, s, _ = unpack_params(p)
    return propulsion_model(propulsion).thrusts(vel, omega, rotor, named(p, propulsion), r, s)


@lru_cache(maxsize=2)
def rotor_thrust_function(propulsion: str = "paper") -> ca.Function:
    """``rotor_thrusts(vel, omega, rotor, p) -> thrust`` (:func:`rotor_thrusts`) as a Function,
    built once per process and propulsion kind."""
    vel, omega, rotor = ca.SX.sym("vel", 3), ca.SX.sym("omega", 3), ca.SX.sym("rotor", 4)
    p = ca.SX.sym("p", n_params(propulsion))
    return ca.Function("rotor_thrusts", [vel, omega, rotor, p],
                       [rotor_thrusts(vel, omega, rotor, p, propulsion)],
                       ["vel", "omega", "rotor", "p"], ["thrust"])


def implicit_residual(xdot: Num, x: Num, u: Num, p: Num, propulsion: str = "paper") -> Num:
    """F(ẋ, x, u, p) of docs/concepts/chain.md#model as an SX/MX expression (16 rows)."""
    g, J, _, _, _ = unpack_params(p)
    m, grav = g["mass"], g["g"]
    vel, omega, eul, T = x[VEL], x[RATE], x[EUL], x[THR]
    R = rotation_matrix(eul[0], eul[1], eul[2])
    terms = airframe_terms(vel, omega, T, xdot[THR], u, p, propulsion)
    gravity_body = R.T @ ca.vertcat(0, 0, -m * grav)

    res_pos = xdot[POS] - R @ vel
    res_vel = m * xdot[VEL] + m * ca.cross(omega, vel) - terms.thrust - gravity_body - terms.drag
    res_rate = J @ xdot[RATE] + ca.cross(omega, J @ omega) - terms.torque
    res_eul = xdot[EUL] - euler_rate_matrix(eul[0], eul[1]) @ omega
    return ca.vertcat(res_pos, res_vel, res_rate, res_eul, terms.rotor_residual)


@lru_cache(maxsize=4)
def quadrotor_model(propulsion: str = "paper") -> QuadrotorModel:
    """Build the model of propulsion kind ``propulsion`` once per process; its Functions."""
    xdot = ca.SX.sym("xdot", NX)
    x = ca.SX.sym("x", NX)
    u = ca.SX.sym("u", NU)
    p = ca.SX.sym("p", n_params(propulsion))
    res = implicit_residual(xdot, x, u, p, propulsion)
    F = ca.Function("F", [xdot, x, u, p], [res], ["xdot", "x", "u", "p"], ["res"])

    # F is affine in ẋ: F = E ẋ + F(0, x, u, p), so ẋ = -E⁻¹ F(0, x, u, p). E is block diagonal
    # (I, m I, J, I, τ I); solve block by block so the explicit expression stays small.
    E = ca.jacobian(res, xdot)
    F0 = ca.substitute(res, xdot, ca.SX.zeros(NX))
    blocks = [POS, VEL, RATE, EUL, THR]
    xdot_expr = ca.vertcat(*[-ca.solve(E[b, b], F0[b]) for b in blocks])
    f = ca.Function("f", [x, u, p], [ca.simplify(xdot_expr)], ["x", "u", "p"], ["xdot"])

    jacobians = ca.Function(
        "jacobians",
        [xdot, x, u, p],
        [E, ca.jacobian(res, x), ca.jacobian(res, u)],
        ["xdot", "x", "u", "p"],
        ["E", "A_prime", "B_prime"],
    )
    xdot_at = f(x, u, p)
    linear_parts = ca.Function(
        "linear_parts",
        [x, u, p],
        [xdot_at, *(ca.densify(J) for J in jacobians(xdot_at, x, u, p))],
        ["x", "u", "p"],
        ["xdot", "E", "A_prime", "B_prime"],
    )
    return QuadrotorModel(F=F, f=f, jacobians=jacobians, linear_parts=linear_parts,
                          state_names=state_names(propulsion),
                          param_names=param_names(propulsion))


@lru_cache(maxsize=1)
def propeller_outputs() -> ca.Function:
    """``rotor_outputs(x, u, p) -> (thrust (4, N), inflow (4, m/s), advance_ratio (4),
    battery_voltage (V), battery_current (A))`` of the ``propeller`` kind: what a lap reports
    (the effective axial inflow v_a that enters CT and CP, J = v_a / (n D))."""
    x, u = ca.SX.sym("x", NX), ca.SX.sym("u", NU)
    p = ca.SX.sym("p", n_params("propeller"))
    w = x[THR]
    q = named(p)
    _, _, r, s, _ = unpack_params(p)
    _, _, _, thrust, inflow = propeller_terms(x[VEL], x[RATE], w, ca.SX.zeros(4), u, q, r, s)
    V, current = motor_currents(w, u, q)
    J = inflow / (w / (2 * ca.pi) * q["prop_D"])
    return ca.Function("rotor_outputs", [x, u, p],
                       [thrust, inflow, J, V, ca.dot(u, current)], ["x", "u", "p"],
                       ["thrust", "inflow", "advance_ratio", "battery_voltage",
                        "battery_current"])
