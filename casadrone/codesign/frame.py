"""The airframe as a function of the decision variables θ, written once for numbers and symbols.

Co-design puts θ (config keys and units: ``lambda_a_mm``, ``alpha_deg``, … , and the inertia keys
under ``mass_model: free``) inside the limit-lap NLP, so the model parameter vector p, the hover
thrusts of the start state and the feasibility rules must be CasADi expressions of θ. Every
formula here uses CasADi operations only, so the same function takes floats (returns numbers)
or symbols (returns expressions), as AeroSandbox writes its models; the numbers are those of
:mod:`casadrone.massprops` and :mod:`casadrone.airframe` (tests/unit/test_codesign_frame.py
compares them at random θ).

The mass model ``components`` is :func:`casadrone.massprops.components_mass_properties`: motors
as point masses at the rotors, arms as thin rods from the hub, body and battery as boxes moved
by the parallel-axis theorem, everything moved to the centre of mass, rotor positions referred to
it. ``free``: mass given, inertia from θ (or the config), centre of mass at the hub.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import casadi as ca
import numpy as np

from casadrone.airframe import PARAM_NAMES, THETA_KEYS, build_airframe
from casadrone.config.airframe import ROTOR_LABELS, AirframeConfig
from casadrone.model import named
from casadrone.propulsion import max_static_thrust, propulsion_model

#: θ keys co-design can vary: the geometry and (``free`` mass model) the principal inertias.
CODESIGN_KEYS = THETA_KEYS


def rotor_positions(la, lb, alpha_deg, beta_deg):
    """Rotor centres (4×3, units of la and lb) FR, FL, RL, RR: :func:`casadrone.massprops.
    rotor_positions_mm` in CasADi operations."""
    a, b = alpha_deg * (np.pi / 360.0), beta_deg * (np.pi / 360.0)
    ca_, sa, cb, sb = ca.cos(a), ca.sin(a), ca.cos(b), ca.sin(b)
    return ca.vertcat(
        ca.horzcat(la * ca_, -la * sa, 0.0), ca.horzcat(la * ca_, la * sa, 0.0),
        ca.horzcat(-lb * cb, lb * sb, 0.0), ca.horzcat(-lb * cb, -lb * sb, 0.0))


#: The θ keys that place each rotor (:func:`rotor_positions`): the front rotors sit on the nose
#: arms (λa, α), the rear rotors on the tail arms (λb, β). A row of two rotors (a propeller gap)
#: depends on the keys of both and on no other (a gap is the same from any origin).
ROTOR_KEYS = {"FR": ("lambda_a_mm", "alpha_deg"), "FL": ("lambda_a_mm", "alpha_deg"),
              "RL": ("lambda_b_mm", "beta_deg"), "RR": ("lambda_b_mm", "beta_deg")}


def point_inertia(mass, r):
    """m (|r|² I − r rᵀ) (kg·m²), r a 3-vector (m)."""
    return mass * (ca.dot(r, r) * ca.DM.eye(3) - ca.mtimes(r, r.T))


def box_inertia(mass, size) -> ca.DM:
    """Uniform box of edges ``size`` (m) about its centre (numbers only: the parts are fixed)."""
    a, b, c = np.asarray(size, float) ** 2
    return ca.DM(mass / 12.0 * np.diag([b + c, a + c, a + b]))


def components_mass(parts: Any, rotors_m):
    """(mass (kg), centre of mass from the hub (m, 3), inertia about it (kg·m², 3×3)) of the
    parts (a :class:`casadrone.config.ComponentsConfig`) with rotors at ``rotors_m`` (4×3, m)."""
    body_at = ca.DM(np.asarray(parts.body_position_mm, float) / 1000)
    battery_at = ca.DM(np.asarray(parts.battery_position_mm, float) / 1000)
    r = [rotors_m[i, :].T for i in range(4)]
    arms = [parts.arm_linear_density_kgpm * ca.norm_2(ri) for ri in r]
    masses = [parts.body_mass_kg, parts.battery_mass_kg, *[parts.motor_mass_kg] * 4, *arms]
    centres = [body_at, battery_at, *r, *[ri / 2 for ri in r]]
    mass = sum(masses)
    com = sum(m * c for m, c in zip(masses, centres, strict=True)) / mass
    hub = (box_inertia(parts.body_mass_kg, np.asarray(parts.body_size_mm) / 1000)
           + point_inertia(parts.body_mass_kg, body_at)
           + box_inertia(parts.battery_mass_kg, np.asarray(parts.battery_size_mm) / 1000)
           + point_inertia(parts.battery_mass_kg, battery_at)
           + sum(point_inertia(parts.motor_mass_kg, ri) for ri in r)
           + sum(point_inertia(m, ri) / 3.0 for m, ri in zip(arms, r, strict=True)))
    return mass, com, hub - point_inertia(mass, com)


def _values(cfg: AirframeConfig, theta: Mapping[str, Any]) -> dict[str, Any]:
    return {**{k: getattr(cfg, k) for k in CODESIGN_KEYS}, **dict(theta)}


def mass_and_layout(cfg: AirframeConfig, theta: Mapping[str, Any]):
    """(mass, inertia about the CoM (3×3), rotor positions from the CoM (4×3, m), rotor
    positions from the hub (4×3, mm)) of ``cfg`` with the keys of ``theta`` replaced; numbers or
    CasADi expressions alike."""
    v = _values(cfg, theta)
    r_mm = rotor_positions(v["lambda_a_mm"], v["lambda_b_mm"], v["alpha_deg"], v["beta_deg"])
    if cfg.mass_model == "components":
        mass, com, J = components_mass(cfg.components, r_mm / 1000)
        return mass, J, r_mm / 1000 - ca.repmat(com.T, 4, 1), r_mm
    J = ca.vertcat(ca.horzcat(v["ixx_kgm2"], cfg.ixy_kgm2, cfg.ixz_kgm2),
                   ca.horzcat(cfg.ixy_kgm2, v["iyy_kgm2"], cfg.iyz_kgm2),
                   ca.horzcat(cfg.ixz_kgm2, cfg.iyz_kgm2, v["izz_kgm2"]))
    return cfg.mass_kg, J, r_mm / 1000, r_mm


def param_vector(cfg: AirframeConfig, theta: Mapping[str, Any], base_p: np.ndarray):
    """The model parameter vector p (PARAM_NAMES order) of ``cfg`` with ``theta`` replaced:
    ``base_p`` (``build_airframe(cfg).p``) with mass, inertia and rotor positions recomputed."""
    mass, J, r, _ = mass_and_layout(cfg, theta)
    new = {"mass": mass, "Ixx": J[0, 0], "Iyy": J[1, 1], "Izz": J[2, 2], "Ixy": J[0, 1],
           "Ixz": J[0, 2], "Iyz": J[1, 2]}
    new |= {f"r{i + 1}{c}": r[i, j] for i in range(4) for j, c in enumerate("xyz")}
    head = [new.get(name, float(base_p[k])) for k, name in enumerate(PARAM_NAMES)]
    return ca.vertcat(*head, ca.DM(np.asarray(base_p[len(PARAM_NAMES):], float)))


def hover_thrusts(p):
    """Rotor thrusts (N) of hover (Σ T = m g, no moment) from p: the allocation solved."""
    i = {n: k for k, n in enumerate(PARAM_NAMES)}
    rx = ca.vertcat(*[p[i[f"r{k}x"]] for k in range(1, 5)])
    ry = ca.vertcat(*[p[i[f"r{k}y"]] for k in range(1, 5)])
    s = ca.vertcat(*[p[i[f"s{k}"]] for k in range(1, 5)])
    A = ca.vertcat(ca.DM.ones(1, 4), ry.T, -rx.T, (s * p[i["kappa"]]).T)
    return ca.solve(A, ca.vertcat(p[i["mass"]] * p[i["g"]], 0, 0, 0))


def hover_rotor_states(p, propulsion: str = "paper"):
    """The rotor states of hover from p: the thrusts of :func:`hover_thrusts` (``paper``), or
    the rotor speeds (rad/s) giving them at zero inflow, ω = 2π √(T / (ρ c_T0 D⁴))
    (``propeller``: :func:`casadrone.propulsion.speed_for_thrust`, the limit lap's own start,
    :func:`casadrone.propulsion.hover_rotors`)."""
    T = hover_thrusts(p)

    return propulsion_model(propulsion).static_rotors(T, named(p, propulsion))


@dataclass(frozen=True)
class FeasibilityRow:
    """One rule a frame must meet, as ``expression ≥ 0`` in θ (scaled to order one)."""

    name: str
    expression: Any


def feasibility_rows(cfg: AirframeConfig, theta: Mapping[str, Any]) -> list[FeasibilityRow]:
    """The airframe schema's rules on θ as smooth inequalities g(θ) ≥ 0:

    - no propeller overlap: each pair of rotor centres at least a prop diameter apart,
      (|r_i − r_j|² − d²) / d² ≥ 0 (:func:`casadrone.config._overlaps`);
    - a possible body (``free``): Ixx + Iyy ≥ Izz and its two companions, scaled by the trace
      (:func:`casadrone.config.inertia_problems`; a ``components`` body is a sum of physical parts
      and always possible);
    - able to hover: the weight below the full thrust of four rotors, 1 − m g / (4 T_max) ≥ 0,
      T_max one rotor's full-command static thrust (:func:`casadrone.propulsion.
      max_static_thrust`: K with ``paper``; it does not depend on θ).
    """
    mass, J, _, r_mm = mass_and_layout(cfg, theta)
    d2 = cfg.prop_diameter_mm ** 2
    rows = [FeasibilityRow(f"gap {ROTOR_LABELS[i]}-{ROTOR_LABELS[j]}",
                           (ca.sumsqr(r_mm[i, :] - r_mm[j, :]) - d2) / d2)
            for i in range(4) for j in range(i + 1, 4)]
    if cfg.mass_model == "free":
        tr = J[0, 0] + J[1, 1] + J[2, 2]
        for a, b, c in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):
            rows.append(FeasibilityRow(f"rigid body I{'xyz'[a]}+I{'xyz'[b]}>=I{'xyz'[c]}",
                                       (J[a, a] + J[b, b] - J[c, c]) / tr))
    t_max = max_static_thrust(build_airframe(cfg))
    rows.append(FeasibilityRow("hover", 1 - mass * cfg.gravity_mps2 / (4 * t_max)))
    return rows


@dataclass(frozen=True)
class SymbolicFrame:
    """θ (normalised to [0, 1] in its box) → p, the rotor states of hover
    (:func:`hover_rotor_states`), feasibility rows, mass, span; one CasADi Function built once per
    problem."""

    cfg: AirframeConfig
    keys: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray

    def theta(self, s) -> dict[str, Any]:
        """Config-unit θ of normalised ``s`` (numbers or a symbol)."""
        return {k: self.lower[i] + (self.upper[i] - self.lower[i]) * s[i]
                for i, k in enumerate(self.keys)}

    def normalise(self, theta: Mapping[str, float]) -> np.ndarray:
        x = np.array([theta[k] for k in self.keys], float)
        return (x - self.lower) / (self.upper - self.lower)

    @cached_property
    def row_names(self) -> tuple[str, ...]:
        return tuple(r.name for r in feasibility_rows(self.cfg, {}))

    @cached_property
    def function(self) -> ca.Function:
        """``frame(s) -> (p, hover, feas, mass, diagonals)``; diagonals: FR–RL and FL–RR, tip
        to tip (m: rotor centres apart plus one prop diameter); the span is the larger."""
        s = ca.SX.sym("s", len(self.keys))
        th = self.theta(s)
        p = param_vector(self.cfg, th, build_airframe(self.cfg).p)
        feas = ca.vertcat(*[r.expression for r in feasibility_rows(self.cfg, th)])
        mass = p[PARAM_NAMES.index("mass")]
        _, _, _, r_mm = mass_and_layout(self.cfg, th)
        diag = ca.vertcat(ca.norm_2(r_mm[0, :] - r_mm[2, :]), ca.norm_2(r_mm[1, :] - r_mm[3, :]))
        tips = (diag + self.cfg.prop_diameter_mm) / 1000
        hover = hover_rotor_states(p, self.cfg.propulsion.model)
        return ca.Function("codesign_frame", [s], [p, hover, feas, mass, tips],
                           ["s"], ["p", "hover", "feas", "mass", "diagonals"])
