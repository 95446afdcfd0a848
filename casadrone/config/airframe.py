"""The airframe YAML (``configs/airframes/``): geometry, mass model, drag, thrust; its loader.

Every schema is frozen and forbids unknown keys; cross-field (geometry) checks report every problem
at once. File reading, ``key=value`` overrides and the ``FILE: dotted.key: message`` error reports
live in :mod:`casadrone.config.io`. Numbers carry their unit in the key when it is not SI-obvious
(``lambda_a_mm``, ``alpha_deg``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field

from casadrone.config.io import Schema, has_keys, load, resolve_config
from casadrone.config.propulsion import PropulsionConfig
from casadrone.drag import DEFAULT_DRAG, DRAG_MODELS
from casadrone.massprops import inertia_tensor, mass_properties_of, rotor_positions_mm
from casadrone.propulsion import PROPULSION_MODELS, airframe_problems

Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Spin = Literal[-1, 1]
#: Physical ceilings of airframe values (generous: a heavy-lift multirotor stays far inside).
#: Beyond them a number is a unit slip (m for mm) and the chain's numerics lose meaning.
MAX_ARM_MM = 5000.0  # arm length or prop diameter (mm)
MAX_INERTIA = 1000.0  # any inertia-tensor element (kg·m²)
DragArea = Annotated[float, Field(ge=0, le=100)]  # C_d·A (m²)
#: Paper Table 1 bounds, in config units (mm, deg, kg·m²).
TABLE1_BOUNDS = {
    "lambda_a_mm": (100.0, 150.0),
    "lambda_b_mm": (100.0, 150.0),
    "alpha_deg": (65.0, 90.0),
    "beta_deg": (65.0, 90.0),
    "ixx_kgm2": (0.0014, 0.0030),
    "iyy_kgm2": (0.0012, 0.0021),
    "izz_kgm2": (0.0027, 0.0042),
}
#: A part's size or position (``mass_model: components``), within the arm ceiling: a part beyond
#: it would not be on the airframe (a battery 1 km out moved the centre of mass 250 m).
PartSize = Annotated[float, Field(gt=0, le=MAX_ARM_MM)]
PartOffset = Annotated[float, Field(ge=-MAX_ARM_MM, le=MAX_ARM_MM)]


# --------------------------------------------------------------------------------------------
# Airframe
# --------------------------------------------------------------------------------------------


class ThrustModelConfig(Schema):
    """Identified first-order thrust model G(s) = K / (1 + tau s) per rotor (paper Table 6)."""

    gain_n: float = Field(9.0519, gt=0, le=1e4, description="K, thrust per unit ESC command (N)")
    time_constant_s: float = Field(
        0.060538, ge=0, le=10,
        description="tau (s); 0: no lag, the idealisation of comparison studies (thrust = K x "
        "command at once; modelled by the limit lap only, casadrone.limit.lagless)")


# --------------------------------------------------------------------------------------------
# Rotor positions and the firmwares' motor numbers: the one table every figure, table and export
# labels its rotors from
# --------------------------------------------------------------------------------------------

#: The four rotors in casadrone's order, by position: the rows of ``rotor_positions``, the columns
#: of the allocation matrix, the model's thrusts T1…T4 and commands δ1…δ4 are in this order.
ROTOR_LABELS = ("FR", "FL", "RL", "RR")
#: The positions in words, in the same order.
ROTOR_NAMES = ("front-right", "front-left", "rear-left", "rear-right")


@dataclass(frozen=True)
class MotorNumbering:
    """A flight firmware's numbering of a quad-X's motors.

    Attributes:
        firmware: the firmware's name as its users write it.
        order: the casadrone rotor index (into :data:`ROTOR_LABELS`) of the firmware's motor 1,
            2, 3, 4 in turn.
        source: where the firmware defines that numbering.
    """

    firmware: str
    order: tuple[int, int, int, int]
    source: str

    def motor(self, rotor: int) -> int:
        """The firmware's motor number (1…4) of casadrone rotor ``rotor`` (0…3)."""
        return self.order.index(rotor) + 1


#: The firmwares casadrone writes for (:mod:`casadrone.export.mixers`), by export format family.
MOTOR_NUMBERING: dict[str, MotorNumbering] = {
    "betaflight": MotorNumbering(
        "Betaflight", (3, 0, 2, 1),
        "QUADX in src/main/flight/mixer_init.c: motor 1 REAR_R, 2 FRONT_R, 3 REAR_L, 4 FRONT_L"),
    "px4": MotorNumbering(
        "PX4", (0, 2, 1, 3),
        "the 'Quadrotor x' geometry of PX4's airframe reference: CA_ROTOR0…3 = motors 1…4, "
        "front-right, rear-left, front-left, rear-right"),
}


def rotor_label(rotor: int, *firmwares: str) -> str:
    """A rotor's label: its position (``"RR"``), and for each firmware named (keys of
    :data:`MOTOR_NUMBERING`) that firmware's motor number, e.g. ``"RR (Betaflight motor 1)"``."""
    numbers = [f"{MOTOR_NUMBERING[f].firmware} motor {MOTOR_NUMBERING[f].motor(rotor)}"
               for f in firmwares]
    return ROTOR_LABELS[rotor] + (f" ({', '.join(numbers)})" if numbers else "")


def position_of(x: float, y: float) -> str:
    """The position label of a rotor at body ``x`` (forward) and ``y`` (left) from the centre:
    ``"F"`` or ``"R"`` by the sign of x, then ``"L"`` or ``"R"`` by the sign of y."""
    return ("F" if x > 0 else "R") + ("L" if y > 0 else "R")


#: The keys of an airframe's mass properties: given in ``mass_model: free``, computed from the
#: ``components`` (:mod:`casadrone.massprops`) in ``mass_model: components``.
MASS_KEYS = ("mass_kg", "ixx_kgm2", "iyy_kgm2", "izz_kgm2", "ixy_kgm2", "ixz_kgm2", "iyz_kgm2")
INERTIA_KEYS = ("ixx_kgm2", "iyy_kgm2", "izz_kgm2")


class ComponentsConfig(Schema):
    """The parts of an airframe (``mass_model: components``, :mod:`casadrone.massprops`).

    Sizes and positions are at most :data:`MAX_ARM_MM` (5 m) and masses at most 1000 kg, the
    ceilings of ``mass_model: free``. Positions are body axes (x nose, y left, z up) from the arm
    hub, the point where the arms meet and from which λa, λb, α, β place the rotors; the rotor
    plane is z = 0. The centre of mass follows from the parts (it moves forward when λa > λb).
    """

    body_mass_kg: float = Field(gt=0, le=1000, description="central body: plates, standoffs, "
                                "flight controller and ESC stack, camera, video transmitter, "
                                "receiver, wiring (a uniform box)")
    body_size_mm: tuple[PartSize, PartSize, PartSize] = Field(
        description="central body box along body x, y, z (mm)")
    body_position_mm: tuple[PartOffset, PartOffset, PartOffset] = Field(
        (0.0, 0.0, 0.0), description="centre of the body box from the hub (mm)")
    motor_mass_kg: float = Field(gt=0, le=1000, description="one motor with its prop and "
                                 "screws, a point mass at the rotor centre (kg)")
    arm_linear_density_kgpm: float = Field(ge=0, le=1000, description="arm mass per metre: a "
                                           "thin rod from the hub to each rotor (kg/m)")
    battery_mass_kg: float = Field(gt=0, le=1000, description="battery pack, a uniform box (kg)")
    battery_size_mm: tuple[PartSize, PartSize, PartSize] = Field(
        description="battery box along body x, y, z (mm)")
    battery_position_mm: tuple[PartOffset, PartOffset, PartOffset] = Field(
        description="centre of the battery from the hub (mm)")


class AirframeConfig(Schema):
    """An airframe: geometry θ = (λa, λb, α, β, Ixx, Iyy, Izz) plus mass, drag and propulsion.

    ``mass_model: free`` (the paper's Table 1): mass and inertia are given (Ixx, Iyy, Izz are
    decision variables). ``mass_model: components``: they are computed from ``components`` for
    each geometry (:mod:`casadrone.massprops`) and must not be given. Either way the inertia tensor
    must be a possible rigid body: positive definite and its principal moments obeying the
    triangle inequalities.
    """

    name: str = Field(description="name of the airframe, shown in tables, figures and exports")
    lambda_a_mm: float = Field(gt=0, le=MAX_ARM_MM,
                               description="hub (free: CoM) to front motors (mm)")
    lambda_b_mm: float = Field(gt=0, le=MAX_ARM_MM,
                               description="hub (free: CoM) to rear motors (mm)")
    alpha_deg: float = Field(gt=0, lt=180, description="angle between the nose arms (deg)")
    beta_deg: float = Field(gt=0, lt=180, description="angle between the tail arms (deg)")
    mass_model: Literal["free", "components"] = Field(
        "free", description="free: mass and inertia given; components: computed from the parts")
    ixx_kgm2: float | None = Field(None, gt=0, le=MAX_INERTIA,
                                   description="roll inertia, about the nose axis "
                                   "(kg·m²); mass_model free only")
    iyy_kgm2: float | None = Field(None, gt=0, le=MAX_INERTIA,
                                   description="pitch inertia (kg·m²); free only")
    izz_kgm2: float | None = Field(None, gt=0, le=MAX_INERTIA,
                                   description="yaw inertia (kg·m²); free only")
    ixy_kgm2: float = Field(
        0.0, ge=-MAX_INERTIA, le=MAX_INERTIA,
        description="product of inertia xy about the centre of mass (kg·m²); mass_model free only",
    )
    ixz_kgm2: float = Field(
        0.0, ge=-MAX_INERTIA, le=MAX_INERTIA,
        description="product of inertia xz about the centre of mass (kg·m²); mass_model free only",
    )
    iyz_kgm2: float = Field(
        0.0, ge=-MAX_INERTIA, le=MAX_INERTIA,
        description="product of inertia yz about the centre of mass (kg·m²); mass_model free only",
    )
    mass_kg: float | None = Field(None, gt=0, le=1000, description="total mass (kg); free only")
    components: ComponentsConfig | None = Field(
        None, description="the parts (mass_model: components only)")
    drag_area_m2: tuple[DragArea, DragArea, DragArea] = Field(
        (0.012, 0.012, 0.025), description="C_d·A along body x, y, z (m²)"
    )
    drag_model: Literal[tuple(DRAG_MODELS)] = Field(  # type: ignore[valid-type]
        DEFAULT_DRAG, description="body-drag form on drag_area_m2 (casadrone.drag): "
        + "; ".join(f"{m.name}: {m.description}" for m in DRAG_MODELS.values())
        + "; isotropic needs a propulsion model with drag forms (propeller)")
    kappa_m: float = Field(0.016, gt=0, le=1, description="rotor yaw torque per unit thrust (m)")
    battery_voltage_v: float = Field(
        14.8, gt=0, le=1000,
        description="battery voltage the ESC commands scale: ESC voltage = δ · this (V; 4S: 14.8)",
    )
    prop_diameter_mm: float = Field(
        127.0, gt=0, le=MAX_ARM_MM,
        description="propeller diameter (mm): the rotor-overlap check, figures and exports",
    )
    rotor_spins: tuple[Spin, Spin, Spin, Spin] = Field(
        (-1, 1, -1, 1),
        description="sign of each rotor's reaction yaw torque about body +z, rotors FR, FL, RL, RR",
    )
    thrust: ThrustModelConfig = Field(
        ThrustModelConfig(),
        description="the paper's identified first-order thrust model of one rotor",
    )
    propulsion: PropulsionConfig = Field(
        PropulsionConfig(), description="propulsion model: paper (the thrust section) or "
        "propeller (rotor speed, inflow, rotor drag, motor and battery; casadrone.propulsion)")
    air_density_kgm3: float = Field(
        1.225, gt=0, le=2,
        description="air density ρ of the drag model (kg/m³; sea level 1.225)",
    )
    gravity_mps2: float = Field(
        9.81, ge=0.1, le=30,
        description="gravitational acceleration g (m/s²)",
    )

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found: list[tuple[str, str]] = []
        s = v.get("rotor_spins")
        if s is not None and not (s[0] == s[2] and s[1] == s[3] and s[0] == -s[1]):
            found.append(
                ("rotor_spins", "diagonal rotors must spin alike and the two pairs opposite "
                 f"(FR with RL, FL with RR), e.g. [-1, 1, -1, 1]; got {list(s)}")
            )
        geometry = has_keys(v, "lambda_a_mm", "lambda_b_mm", "alpha_deg", "beta_deg")
        if geometry and "prop_diameter_mm" in v:
            found += _overlaps(v)
        mass_problems = _mass_model_problems(v)
        found += mass_problems
        mass = v.get("mass_kg")
        if (v.get("mass_model") == "components" and v.get("components") is not None
                and not mass_problems and geometry):
            mp = mass_properties_of(v)
            mass = mp.mass_kg
            found += [("components", f"computed {m}") for _, m in inertia_problems(mp.inertia_kgm2)]
        elif v.get("mass_model") == "free" and has_keys(v, *MASS_KEYS[1:]) and not mass_problems:
            found += inertia_problems(inertia_tensor(v))
        prop = v.get("propulsion")
        if prop is not None:  # the section against the vehicle's mass, air and prop diameter
            found += airframe_problems(
                prop, mass_kg=mass, rho=v.get("air_density_kgm3"),
                prop_diameter_mm=v.get("prop_diameter_mm"),
                mass_key="mass_kg" if v.get("mass_model") == "free" else "components")
        if (prop is not None and v.get("drag_model", DEFAULT_DRAG) != DEFAULT_DRAG
                and not getattr(PROPULSION_MODELS[prop.model], "drag_forms", False)):
            found.append(("drag_model", f"{v['drag_model']} needs a propulsion model with drag "
                          f"forms (propeller); the {prop.model} model keeps the paper's "
                          f"{DEFAULT_DRAG} drag"))
        thrust = v.get("thrust")
        if (thrust is not None and thrust.time_constant_s == 0 and prop is not None
                and not PROPULSION_MODELS[prop.model].lagless):
            found.append(("thrust.time_constant_s", "0 (no thrust lag) is an idealisation of "
                          f"the paper's thrust model; the {prop.model} model's lag is its "
                          "motor's"))
        if mass is not None and has_keys(v, "gravity_mps2", "thrust"):
            weight, full = mass * v["gravity_mps2"], 4 * v["thrust"].gain_n
            what = "4 × thrust.gain_n"
            prop = v.get("propulsion")
            own = (PROPULSION_MODELS[prop.model].full_static_thrust(prop, v["air_density_kgm3"])
                   if prop is not None and "air_density_kgm3" in v else None)
            if own is not None:  # the model's own full thrust, not K
                full, what = 4 * own, "propulsion"
            if weight >= full:
                key = "mass_kg" if v.get("mass_model") == "free" else "components"
                found.append((key, f"cannot hover: weight {weight:.2f} N is not below the "
                              f"full thrust of four rotors {full:.2f} N ({what})"))
        return found


def _mass_model_problems(v: dict[str, Any]) -> list[tuple[str, str]]:
    """Mass keys missing in ``mass_model: free``, given in ``components`` (or components absent)."""
    model = v.get("mass_model")
    found = []
    if model == "free":
        for key in ("mass_kg", *INERTIA_KEYS):
            if key in v and v[key] is None:
                found.append((key, "required key missing (mass_model: free; or set mass_model: "
                              "components and give a components section)"))
        if v.get("components") is not None:
            found.append(("components", "only used with mass_model: components; remove it or "
                          "set mass_model: components"))
    elif model == "components":
        if "components" in v and v["components"] is None:
            found.append(("components", "required when mass_model is 'components'"))
        for key in MASS_KEYS:
            if v.get(key) not in (None, 0.0):
                found.append((key, "computed from the components with mass_model: components; "
                              "remove it"))
    return found


#: Relative slack on the triangle inequalities (of the trace): a flat body meets Ixx + Iyy = Izz
#: exactly, which round-off must not turn into a refusal.
TRIANGLE_RTOL = 1e-9


def inertia_problems(J: np.ndarray | list[list[float]]) -> list[tuple[str, str]]:
    """Why a 3×3 inertia tensor (kg·m², about the CoM) is no rigid body, as (key, message).

    A rigid body's tensor is positive definite and each principal moment is at most the sum of
    the other two: Ixx + Iyy − Izz = 2 Σ m z² ≥ 0, and likewise about the other axes (equality for
    a body flat in one plane). A diagonal tensor is checked on its own moments (the message names
    Ixx, Iyy, Izz); a full one on its principal moments, reported on the body axis nearest the
    offending principal axis.
    """
    keys = (("ixx_kgm2", "ixy_kgm2", "ixz_kgm2"), ("ixy_kgm2", "iyy_kgm2", "iyz_kgm2"),
            ("ixz_kgm2", "iyz_kgm2", "izz_kgm2"))
    for i, j in ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)):
        if not math.isfinite(J[i][j]):
            return [(keys[i][j], f"inertia must be a finite number (got {J[i][j]})")]
    offdiag = (J[0][1], J[0][2], J[1][2])
    if not _positive_definite(J):
        if any(offdiag):
            key = ("ixy_kgm2", "ixz_kgm2", "iyz_kgm2")[[c != 0 for c in offdiag].index(True)]
            return [(key, "inertia tensor is not positive definite: the products of inertia are "
                     "too large for the principal moments")]
        return [("ixx_kgm2", "inertia tensor is not positive definite")]
    names = ("Ixx", "Iyy", "Izz")
    if any(offdiag):
        moments, axes = np.linalg.eigh(np.asarray(J, float))
        nearest = [int(np.argmax(np.abs(axes[:, i]))) for i in range(3)]
        label = "principal moment"
    else:
        moments, nearest, label = np.array([J[i][i] for i in range(3)]), [0, 1, 2], ""
    slack = TRIANGLE_RTOL * float(sum(moments))
    found = []
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        others = float(moments[j] + moments[k])
        if float(moments[i]) <= others + slack:
            continue
        if label:
            what = (f"principal moments violate the triangle inequality: {float(moments[i]):.6g} "
                    f"kg·m² (principal axis nearest body {'xyz'[nearest[i]]}) exceeds the sum of "
                    f"the other two {others:.6g} kg·m²")
        else:
            a, b = sorted((names[j], names[k]))
            what = (f"{a} + {b} ≥ {names[i]} violated: {names[i]} = {float(moments[i]):.6g} "
                    f"kg·m² exceeds {a} + {b} = {others:.6g} kg·m²")
        found.append((INERTIA_KEYS[nearest[i]], what + "; no rigid body has these moments (each "
                      "principal moment is at most the sum of the other two)"))
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


def _positive_definite(J: np.ndarray | list[list[float]]) -> bool:
    """Sylvester's criterion for a symmetric 3×3 matrix."""
    m1 = J[0][0]
    m2 = J[0][0] * J[1][1] - J[0][1] ** 2
    m3 = (
        J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1])
        - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0])
        + J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0])
    )
    return m1 > 0 and m2 > 0 and m3 > 0


def min_rotor_gap_mm(la: float, lb: float, alpha_deg: float, beta_deg: float) -> float:
    """Smallest centre-to-centre distance between any two rotors (mm)."""
    r = rotor_positions_mm(la, lb, alpha_deg, beta_deg)
    return min(math.dist(r[i], r[j]) for i in range(4) for j in range(i + 1, 4))


def load_airframe(path: str | Path, overrides: list[str] | None = None) -> AirframeConfig:
    """Load an airframe: a YAML path or a reference name (``SY250``), with ``key=value``
    overrides (``alpha_deg=75``) validated like the file."""
    return load(AirframeConfig, resolve_config(path, "airframes"), overrides)
