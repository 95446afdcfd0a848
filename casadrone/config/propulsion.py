"""The ``propulsion:`` section of an airframe: which propulsion model flies it and its data
(the models: :mod:`casadrone.propulsion`)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from casadrone.config.io import Schema

PropulsionKind = Literal["paper", "propeller"]


class LinearInflowConfig(Schema):
    """The linear-inflow form T = k_η ω² − k_z ω v_a, Q = k_m ω² (signed inflow), given directly
    (ω in rad/s), as in the quadrotor aerodynamics literature."""

    k_eta_n_s2: float = Field(gt=0, le=1, description="thrust per ω² (N·s²)")
    k_z_n_s2_per_m: float = Field(0.0, ge=0, le=1,
                                  description="thrust loss per ω·v_a (N·s²/m)")
    k_m_n_m_s2: float = Field(gt=0, le=1, description="shaft torque per ω² (N·m·s²)")


class PropellerConfig(Schema):
    """A propeller: CT(J), CP(J) (or the linear-inflow form), rotor inertia and rotor drag."""

    diameter_m: float = Field(gt=0, le=5, description="propeller diameter (m)")
    ct_coefficients: tuple[float, ...] | None = Field(
        None, min_length=1, max_length=3,
        description="CT(J) = sum c_k J^k, k ≤ 2; c_0 the static CT (T = CT rho n^2 D^4, n rev/s)")
    cp_coefficients: tuple[float, ...] | None = Field(
        None, min_length=1, max_length=3,
        description="CP(J); P = CP rho n^3 D^5, shaft torque Q = P / (2 pi n)")
    linear_inflow: LinearInflowConfig | None = Field(
        None, description="instead of ct/cp_coefficients: k_eta, k_z, k_m given directly")
    rotor_inertia_kgm2: float = Field(
        7.5e-6, gt=0, le=1,
        description="propeller + motor bell about the rotor axis (kg·m²)")
    rotor_drag_n_s2_per_m: float = Field(
        0.0, ge=0, le=1, description="k_d of the H-force −k_d ω v_inplane (N·s²/m); 0: off")
    axial_inflow: bool = Field(True, description="false: thrust and torque ignore the inflow")
    inflow: Literal["positive", "signed"] = Field(
        "positive", description="positive: max(v_a, 0) (data cover J ≥ 0); signed: v_a as is")
    inflow_smoothing_m_s: float = Field(0.2, gt=0, le=10,
                                        description="width of the smoothed max(v_a, 0) (m/s)")
    data: str | None = Field(None, description="the dataset the coefficients were fitted to")
    max_advance_ratio: float | None = Field(
        None, gt=0, le=10,
        description="largest advance ratio J = v_a/(n D) the CT/CP fit holds to; the limit lap "
        "keeps every rotor at J ≤ it. Default: the largest J of the fitted points of the "
        "shipped dataset named in data; none (no bound) without one")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        ct, cp, lin = v.get("ct_coefficients"), v.get("cp_coefficients"), v.get("linear_inflow")
        if lin is not None:
            if ct is not None or cp is not None:
                return [("linear_inflow", "give either linear_inflow or ct/cp_coefficients")]
            return []
        found = []
        if "ct_coefficients" in v and ct is None:
            found.append(("ct_coefficients", "required (or give linear_inflow)"))
        if "cp_coefficients" in v and cp is None:
            found.append(("cp_coefficients", "required (or give linear_inflow)"))
        if ct is not None:
            c = list(ct) + [0.0] * (3 - len(ct))
            if c[0] <= 0:
                found.append(("ct_coefficients", f"static CT c_0 must be positive, got {c[0]}"))
            if c[1] > 0 or c[2] > 0:
                found.append(("ct_coefficients", "c_1 and c_2 must not be positive: thrust at a "
                              "given rotor speed must not grow with the inflow (J ≥ 0), which "
                              "is what the point mass's thrust bound relies on"))
        if cp is not None and cp[0] <= 0:
            found.append(("cp_coefficients", f"static CP c_0 must be positive, got {cp[0]}"))
        return found


class MotorConfig(Schema):
    """A brushless motor: Drela's DC model (``dc``) or a first-order lag (``first-order``)."""

    kind: Literal["dc", "first-order"] = Field(
        "dc", description="dc: Drela's first-order DC motor (KV, R, I0) driving the rotor "
        "inertia; first-order: a lag of time_constant_s to the command's no-load speed")
    kv_rpm_per_v: float = Field(gt=0, le=1e5, description="speed constant K_V (rpm/V)")
    resistance_ohm: float = Field(0.07, gt=0, le=100, description="winding resistance (Ω)")
    no_load_current_a: float = Field(0.0, ge=0, le=100, description="no-load current I_0 (A)")
    time_constant_s: float = Field(0.03, gt=0, le=10,
                                   description="rotor-speed lag (s), kind: first-order")
    mass_kg: float | None = Field(None, gt=0, le=10, description="datasheet mass (kg)")
    data: str | None = Field(None, description="the datasheet")


class BatteryConfig(Schema):
    """A battery pack: open-circuit voltage behind an internal resistance."""

    open_circuit_voltage_v: float = Field(gt=0, le=1000, description="V_oc (V)")
    internal_resistance_ohm: float = Field(0.0, ge=0, le=100,
                                           description="pack resistance (Ω); 0: no sag")
    mass_kg: float | None = Field(None, gt=0, le=100, description="pack mass (kg)")
    data: str | None = Field(None, description="where the figures come from")


class PropulsionConfig(Schema):
    """The ``propulsion:`` section of an airframe (module docstring: the models)."""

    model: PropulsionKind = Field("paper", description="paper (Table 6 thrust model) | propeller")
    propeller: PropellerConfig | None = Field(
        None, description="the propeller (model: propeller)")
    motor: MotorConfig | None = Field(None, description="the motor (model: propeller)")
    battery: BatteryConfig | None = Field(None, description="the battery pack (model: "
                                          "propeller)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        if v.get("model") != "propeller":
            return []
        return [(key, "required when model is 'propeller'")
                for key in ("propeller", "motor", "battery") if key in v and v[key] is None]
