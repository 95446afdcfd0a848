"""YAML configuration of airframes and controllers: pydantic v2 schemas and their loaders.

Every schema is frozen and forbids unknown keys; cross-field (geometry) checks report every problem
at once. File reading, ``key=value`` overrides and the ``FILE: dotted.key: message`` error reports
live in :mod:`casadrone.configio`, the problem schemas in :mod:`casadrone.problemconfig`, the check
of any config file (``casadrone validate``) in :mod:`casadrone.validation`. Numbers carry their unit
in the key when it is not SI-obvious (``lambda_a_mm``, ``alpha_deg``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import Field

from casadrone.configio import Schema, has_keys, load, resolve_config

Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Spin = Literal[-1, 1]


# --------------------------------------------------------------------------------------------
# Airframe
# --------------------------------------------------------------------------------------------


class ThrustModelConfig(Schema):
    """Identified first-order thrust model G(s) = K / (1 + tau s) per rotor (paper Table 6)."""

    gain_n: float = Field(9.0519, gt=0, description="K, thrust per unit ESC command (N)")
    time_constant_s: float = Field(0.060538, gt=0, description="tau (s)")


ROTOR_LABELS = ("FR", "FL", "RL", "RR")


class AirframeConfig(Schema):
    """An airframe: geometry θ = (λa, λb, α, β, Ixx, Iyy, Izz) plus mass, drag and propulsion."""

    name: str
    lambda_a_mm: float = Field(gt=0, description="CoM to front motors (mm)")
    lambda_b_mm: float = Field(gt=0, description="CoM to rear motors (mm)")
    alpha_deg: float = Field(gt=0, lt=180, description="angle between the nose arms (deg)")
    beta_deg: float = Field(gt=0, lt=180, description="angle between the tail arms (deg)")
    ixx_kgm2: float = Field(gt=0, description="roll inertia, about the nose axis (kg·m²)")
    iyy_kgm2: float = Field(gt=0, description="pitch inertia (kg·m²)")
    izz_kgm2: float = Field(gt=0, description="yaw inertia (kg·m²)")
    ixy_kgm2: float = 0.0
    ixz_kgm2: float = 0.0
    iyz_kgm2: float = 0.0
    mass_kg: float = Field(gt=0)
    drag_area_m2: tuple[NonNegative, NonNegative, NonNegative] = Field(
        (0.012, 0.012, 0.025), description="C_d·A along body x, y, z (m²)"
    )
    kappa_m: float = Field(0.016, gt=0, description="rotor yaw torque per unit thrust (m)")
    battery_voltage_v: float = Field(14.8, gt=0)
    prop_diameter_mm: float = Field(127.0, gt=0)
    rotor_spins: tuple[Spin, Spin, Spin, Spin] = Field(
        (-1, 1, -1, 1),
        description="sign of each rotor's reaction yaw torque about body +z, rotors FR, FL, RL, RR",
    )
    thrust: ThrustModelConfig = ThrustModelConfig()
    air_density_kgm3: float = Field(1.225, gt=0)
    gravity_mps2: float = Field(9.81, gt=0)

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found: list[tuple[str, str]] = []
        s = v.get("rotor_spins")
        if s is not None and not (s[0] == s[2] and s[1] == s[3] and s[0] == -s[1]):
            found.append(
                ("rotor_spins", "diagonal rotors must spin alike and the two pairs opposite "
                 f"(FR with RL, FL with RR), e.g. [-1, 1, -1, 1]; got {list(s)}")
            )
        if has_keys(v, "lambda_a_mm", "lambda_b_mm", "alpha_deg", "beta_deg", "prop_diameter_mm"):
            found += _overlaps(v)
        if has_keys(v, "ixx_kgm2", "iyy_kgm2", "izz_kgm2", "ixy_kgm2", "ixz_kgm2", "iyz_kgm2"):
            J = [
                [v["ixx_kgm2"], v["ixy_kgm2"], v["ixz_kgm2"]],
                [v["ixy_kgm2"], v["iyy_kgm2"], v["iyz_kgm2"]],
                [v["ixz_kgm2"], v["iyz_kgm2"], v["izz_kgm2"]],
            ]
            if not _positive_definite(J):
                key = next(k for k in ("ixy_kgm2", "ixz_kgm2", "iyz_kgm2") if v[k] != 0)
                found.append((key, "inertia tensor is not positive definite: the products of "
                              "inertia are too large for the principal moments"))
        if has_keys(v, "mass_kg", "gravity_mps2", "thrust"):
            weight, full = v["mass_kg"] * v["gravity_mps2"], 4 * v["thrust"].gain_n
            if weight >= full:
                found.append(("mass_kg", f"cannot hover: weight {weight:.2f} N is not below the "
                              f"full thrust of four rotors {full:.2f} N (4 × thrust.gain_n)"))
        return found


def _overlaps(v: dict[str, Any]) -> list[tuple[str, str]]:
    """One problem per pair of rotors whose discs (prop diameter) overlap."""
    r = rotor_positions_mm(v["lambda_a_mm"], v["lambda_b_mm"], v["alpha_deg"], v["beta_deg"])
    d = v["prop_diameter_mm"]
    found = []
    for i in range(4):
        for j in range(i + 1, 4):
            gap = math.dist(r[i], r[j])
            if gap >= d:
                continue
            pair = f"rotors {ROTOR_LABELS[i]} and {ROTOR_LABELS[j]} overlap: centres {gap:.1f} mm"
            msg = f"{pair} apart, less than the prop diameter {d:.1f} mm"
            if (i, j) == (0, 1):
                key, arm = "alpha_deg", v["lambda_a_mm"]
            elif (i, j) == (2, 3):
                key, arm = "beta_deg", v["lambda_b_mm"]
            else:
                key, arm = "prop_diameter_mm", None
            if arm is not None and d < 2 * arm:
                msg += f" (needs at least {math.degrees(2 * math.asin(d / (2 * arm))):.1f} deg)"
            found.append((key, msg))
    return found


def _positive_definite(J: list[list[float]]) -> bool:
    """Sylvester's criterion for a symmetric 3×3 matrix."""
    m1 = J[0][0]
    m2 = J[0][0] * J[1][1] - J[0][1] ** 2
    m3 = (
        J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1])
        - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0])
        + J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0])
    )
    return m1 > 0 and m2 > 0 and m3 > 0


def rotor_positions_mm(
    la: float, lb: float, alpha_deg: float, beta_deg: float
) -> list[list[float]]:
    """Rotor centres (mm) in the body frame (x nose, y left): FR, FL, RL, RR (DESIGN.md §4)."""
    a, b = math.radians(alpha_deg) / 2, math.radians(beta_deg) / 2
    return [
        [la * math.cos(a), -la * math.sin(a), 0.0],
        [la * math.cos(a), la * math.sin(a), 0.0],
        [-lb * math.cos(b), lb * math.sin(b), 0.0],
        [-lb * math.cos(b), -lb * math.sin(b), 0.0],
    ]


def min_rotor_gap_mm(la: float, lb: float, alpha_deg: float, beta_deg: float) -> float:
    """Smallest centre-to-centre distance between any two rotors (mm)."""
    r = rotor_positions_mm(la, lb, alpha_deg, beta_deg)
    return min(math.dist(r[i], r[j]) for i in range(4) for j in range(i + 1, 4))


# --------------------------------------------------------------------------------------------
# Controller
# --------------------------------------------------------------------------------------------


class StateWeights(Schema):
    """Diagonal LQR state weights, one per state group (units: 1/unit² of the state)."""

    position: tuple[NonNegative, NonNegative, NonNegative] = (0.5, 0.5, 1.0)
    velocity: tuple[NonNegative, NonNegative, NonNegative] = (0.2, 0.2, 0.2)
    rates: tuple[NonNegative, NonNegative, NonNegative] = (0.05, 0.05, 0.05)
    attitude: tuple[NonNegative, NonNegative, NonNegative] = (2.0, 2.0, 4.0)
    thrust: tuple[NonNegative, NonNegative, NonNegative, NonNegative] = (0.0, 0.0, 0.0, 0.0)


class RobustnessConfig(Schema):
    """Perturbed-plant ensemble of paper Appendix B."""

    n_plants: int = Field(50, ge=1)
    dynamics_pct: float = Field(30.0, ge=0, lt=100, description="mass, inertia, drag spread (%)")
    coupling_pct: float = Field(
        20.0, ge=0, lt=100, description="thrust gain, time constant, arm geometry, κ spread (%)"
    )
    seed: int = 0


class ControllerConfig(Schema):
    """LQR-I controller: discrete design at ``sample_time_s``, identical for every candidate."""

    name: str = "default"
    sample_time_s: float = Field(0.01, gt=0, le=0.1)
    q: StateWeights = StateWeights()
    q_integral: tuple[NonNegative, NonNegative, NonNegative, NonNegative] = Field(
        (0.05, 0.05, 0.1, 0.05), description="weights of ∫e for x, y, z, yaw"
    )
    r: tuple[Positive, Positive, Positive, Positive] = Field((10.0, 10.0, 10.0, 10.0))
    gain_policy: Literal["redesign", "frozen"] = "redesign"
    reference_airframe: Path | None = Field(
        None, description="airframe YAML whose gain is frozen for all (gain_policy: frozen)"
    )
    robustness: RobustnessConfig = RobustnessConfig()

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        if v.get("gain_policy") == "frozen" and v.get("reference_airframe", 0) is None:
            return [("reference_airframe", "required when gain_policy is 'frozen'")]
        return []


# --------------------------------------------------------------------------------------------
# Loading by kind
# --------------------------------------------------------------------------------------------


def load_airframe(path: str | Path, overrides: list[str] | None = None) -> AirframeConfig:
    """Load an airframe: a YAML path or a reference name (``SY250``), with ``key=value``
    overrides (``alpha_deg=75``) validated like the file."""
    return load(AirframeConfig, resolve_config(path, "airframes"), overrides)


def load_controller(
    path: str | Path | None = None, overrides: list[str] | None = None
) -> ControllerConfig:
    """Load a controller YAML or name; ``None`` gives ``configs/controllers/default.yaml``."""
    return load(ControllerConfig, resolve_config(path or "default", "controllers"), overrides)
