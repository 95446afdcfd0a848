"""Mass properties of an airframe: total mass, centre of mass and inertia tensor.

``mass_model: free`` (the paper's Table 1): the config gives them; the centre of mass is the hub,
the point λa, λb, α, β are measured from (the paper's convention: λ from the CoM).
``mass_model: components``: computed from the parts for each geometry, the open stand-in for the
paper's CAD stage (Algorithm 2, ``I, m ← extract(G_CAD)``):

- each motor with its prop, a point mass at its rotor centre (in the rotor plane, z = 0);
- each arm, a thin uniform rod from the hub to its rotor (mass λ · linear density), whose inertia
  about the hub is (m/3)(|r|² I − r rᵀ) (m l²/3 about any axis through the hub normal to it);
- the central body and the battery, uniform boxes (m/12 (b² + c²) about their own centre),
  moved to the hub by the parallel-axis theorem.

Everything is summed about the hub, then moved to the centre of mass c (parallel-axis theorem,
I_c = I_hub − m (|c|² I − c cᵀ)). The CoM moves along x when λa ≠ λb (and along z with a battery
on top); the rotor positions the model uses are referred to it (r_i − c, see
:func:`casadrone.airframe.build_airframe`), so λa, λb place the rotors from the hub, not from the
CoM, in this mode. Body axes: x nose, y left, z up; SI units out, config units (mm) in.

This module sits below :mod:`casadrone.config` (whose schema checks call it), so it takes the
configs as plain field values and imports nothing of casadrone's but the results' ``as_dict``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from casadrone.results import AsDict


def rotor_positions_mm(
    la: float, lb: float, alpha_deg: float, beta_deg: float
) -> list[list[float]]:
    """Rotor centres (mm) in the body frame (x nose, y left): FR, FL, RL, RR
    (docs/concepts/conventions.md)."""
    a, b = math.radians(alpha_deg) / 2, math.radians(beta_deg) / 2
    return [
        [la * math.cos(a), -la * math.sin(a), 0.0],
        [la * math.cos(a), la * math.sin(a), 0.0],
        [-lb * math.cos(b), lb * math.sin(b), 0.0],
        [-lb * math.cos(b), -lb * math.sin(b), 0.0],
    ]


def inertia_tensor(v: Mapping[str, Any]) -> list[list[float]]:
    """The symmetric 3×3 tensor (kg·m²) of the ``i??_kgm2`` keys of an airframe's values."""
    return [
        [v["ixx_kgm2"], v["ixy_kgm2"], v["ixz_kgm2"]],
        [v["ixy_kgm2"], v["iyy_kgm2"], v["iyz_kgm2"]],
        [v["ixz_kgm2"], v["iyz_kgm2"], v["izz_kgm2"]],
    ]



@dataclass(frozen=True)
class MassProperties(AsDict):
    """Mass (kg), centre of mass from the hub (m, body axes, 3) and inertia tensor about the
    centre of mass (kg·m², body axes, 3×3)."""

    mass_kg: float
    com_m: np.ndarray
    inertia_kgm2: np.ndarray
    mass_model: str = "free"


def point_inertia(mass: float, r: np.ndarray) -> np.ndarray:
    """Inertia (kg·m²) of a point mass at r (m) about the origin: m (|r|² I − r rᵀ)."""
    r = np.asarray(r, float)
    return mass * (r @ r * np.eye(3) - np.outer(r, r))


def rod_inertia(mass: float, end: np.ndarray) -> np.ndarray:
    """Inertia (kg·m²) about the origin of a thin uniform rod from the origin to ``end`` (m):
    (m/3)(|r|² I − r rᵀ), i.e. m l²/3 about any axis through the origin normal to the rod."""
    return point_inertia(mass, end) / 3.0


def box_inertia(mass: float, size: np.ndarray) -> np.ndarray:
    """Inertia (kg·m²) of a uniform box of edges ``size`` (m, along x, y, z) about its centre."""
    a, b, c = np.asarray(size, float) ** 2
    return mass / 12.0 * np.diag([b + c, a + c, a + b])


def components_mass_properties(parts: Any, rotors_m: np.ndarray) -> MassProperties:
    """Mass properties of the parts (a :class:`casadrone.config.airframe.ComponentsConfig`) with
    the rotors at ``rotors_m`` (4×3, m, from the hub)."""
    rotors_m = np.asarray(rotors_m, float)
    arms = parts.arm_linear_density_kgpm * np.linalg.norm(rotors_m, axis=1)
    body_at = np.asarray(parts.body_position_mm, float) / 1000
    battery_at = np.asarray(parts.battery_position_mm, float) / 1000
    masses = [parts.body_mass_kg, parts.battery_mass_kg, *[parts.motor_mass_kg] * 4, *arms]
    centres = [body_at, battery_at, *rotors_m, *(rotors_m / 2)]
    mass = float(sum(masses))
    com = sum(m * c for m, c in zip(masses, centres, strict=True)) / mass
    hub = (
        box_inertia(parts.body_mass_kg, np.asarray(parts.body_size_mm) / 1000)
        + point_inertia(parts.body_mass_kg, body_at)
        + box_inertia(parts.battery_mass_kg, np.asarray(parts.battery_size_mm) / 1000)
        + point_inertia(parts.battery_mass_kg, battery_at)
        + sum(point_inertia(parts.motor_mass_kg, r) for r in rotors_m)
        + sum(rod_inertia(m, r) for m, r in zip(arms, rotors_m, strict=True))
    )
    J = hub - point_inertia(mass, com)
    return MassProperties(mass_kg=mass, com_m=com, inertia_kgm2=0.5 * (J + J.T),
                          mass_model="components")


def mass_properties_of(values: Mapping[str, Any]) -> MassProperties:
    """Mass properties of an airframe's field values (a config as a dict, as
    :meth:`AirframeConfig.problems` sees it)."""
    if values.get("mass_model", "free") == "components":
        r = np.array(rotor_positions_mm(values["lambda_a_mm"], values["lambda_b_mm"],
                                        values["alpha_deg"], values["beta_deg"])) / 1000
        return components_mass_properties(values["components"], r)
    return MassProperties(mass_kg=float(values["mass_kg"]), com_m=np.zeros(3),
                          inertia_kgm2=np.array(inertia_tensor(values), float), mass_model="free")


def mass_properties(config: Any, theta: Mapping[str, float] | None = None) -> MassProperties:
    """Mass properties of ``config`` (a :class:`casadrone.config.airframe.AirframeConfig`) with the
    decision variables ``theta`` (config keys, e.g.
    ``{"lambda_a_mm": 140}``) replaced; a pure function, no validation (see
    :func:`casadrone.airframe.with_theta` for that)."""
    return mass_properties_of({**dict(config), **dict(theta or {})})
