"""The ``propulsion:`` section of an airframe: which propulsion model flies it and its data
(the models: :mod:`casadrone.propulsion`)."""

from __future__ import annotations

import re
from typing import Any, Literal

from pydantic import Field, field_validator

from casadrone.config.io import Schema
from casadrone.propulsion import DEFAULT_MODEL, PROPULSION_MODELS
from casadrone.propulsion.data import (
    FIRST_ORDER_TIME_CONSTANT_S,
    RPM_PER_V_TO_RAD_S_PER_V,
    data_advance_ratio,
    momentum_problem,
    shipped_datasets,
)

#: The sub-sections of ``propulsion:``; each model reads some (its ``sections``).
SECTIONS = ("propeller", "motor", "battery")

# --------------------------------------------------------------------------------------------
# Physical bounds of the section (each refused value names its key; the argument is here)
# --------------------------------------------------------------------------------------------

#: The fastest hobby ESC's switching (PWM) frequency: BLHeli_S 24/48 kHz, BLHeli_32 16-48 kHz
#: (manual rev 32.x) and up to 128 kHz from firmware 32.8 (Hz).
ESC_MAX_PWM_HZ = 128e3
#: Shortest rotor-speed time constant (s) any model here can describe: the ESC is modelled as an
#: ideal chopper (the motor sees the PWM-averaged voltage δ·V_bat), true only while the rotor
#: speed changes little within one PWM period; ten periods of the fastest switching (a 10 %
#: change per period) is 78 µs. Real rotors are two orders above it (5-inch racing rotors
#: 20-30 ms, the shipped one 28 ms; a 1-inch whoop's tens of ms). It floors the first-order
#: motor's time_constant_s and the DC motor's mechanical time constant J_r R K_V² (the rotor
#: inertia against its back-EMF damping, :func:`casadrone.propulsion.rotor_decay_rate`).
MIN_ROTOR_TIME_CONSTANT_S = 10 / ESC_MAX_PWM_HZ
#: Least winding (terminal) resistance (Ω): the resistance a datasheet gives and the model's
#: current sees includes the motor's own leads, two of them phase to phase; even two 3 cm leads
#: of 12 AWG copper (3.31 mm², ρ_Cu = 1.68e-8 Ω·m; no motor of this class, 0802 whoop to 4215
#: 12S, has thicker or shorter ones) make 0.30 mΩ. The lightest-wound motors of the class measure
#: tens of mΩ (parts.csv: 38-75 mΩ).
MIN_RESISTANCE_OHM = 3e-4
#: A ``propeller.data`` value without blanks is a dataset name (it sets the default
#: max_advance_ratio); text with blanks is a free description of where the coefficients come
#: from (what ``casadrone fit-propulsion`` writes), which sets no range.
DATASET_NAME = re.compile(r"\S+")


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
    axial_inflow: bool = Field(True, strict=True,
                               description="false: thrust and torque ignore the inflow (true or "
                               "false only: no 0/1, no 'no')")
    # None (not written) rather than a default value, so that a key the user wrote can be told
    # from one left out and refused where the model would ignore it (ignored_inflow_key), even
    # after a model_dump round trip (an optimisation rebuilds each candidate so).
    inflow: Literal["positive", "signed"] | None = Field(
        None, description="positive (the default with ct/cp_coefficients): max(v_a, 0) (data "
        "cover J ≥ 0); signed: v_a as is (linear_inflow is always signed)")
    inflow_smoothing_m_s: float | None = Field(
        None, gt=0, le=10, description="width of the smoothed max(v_a, 0) of positive inflow "
        "(m/s); default 0.2 (INFLOW_SMOOTHING_M_S)")
    data: str | None = Field(
        None, description="the dataset the coefficients were fitted to: a shipped dataset's name "
        "(casadrone/data/propulsion, which sets the default max_advance_ratio), or a description "
        "with blanks (sets none)")
    max_advance_ratio: float | None = Field(
        None, gt=0, le=10,
        description="largest advance ratio J = v_a/(n D) the CT/CP fit holds to; the limit lap "
        "keeps every rotor at J ≤ it. Default: the largest J of the fitted points of the "
        "shipped dataset named in data; none (no bound) without one")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        ct, cp, lin = v.get("ct_coefficients"), v.get("cp_coefficients"), v.get("linear_inflow")
        ignored = ignored_inflow_key(lin is not None, v.get("inflow"),
                                     v.get("inflow_smoothing_m_s"))
        found = [ignored] if ignored is not None else []
        if lin is not None:
            if ct is not None or cp is not None:
                found.append(("linear_inflow", "give either linear_inflow or ct/cp_coefficients"))
            return found
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
        data = v.get("data")
        known: tuple[str, ...] = ()
        if isinstance(data, str) and DATASET_NAME.fullmatch(data):
            known = shipped_datasets()
            if data not in known:
                found.append(("data", f"unknown propeller dataset {data!r} (known: "
                              f"{', '.join(known) or 'none'}); a name sets the advance-ratio "
                              "range, so a misspelt one is not ignored. Free text with blanks "
                              "describes the source and sets no range"))
        if ct is not None and cp is not None and not found:
            j_max = v.get("max_advance_ratio")
            if j_max is None and data in known:
                j_max = data_advance_ratio(data)
            pad = [0.0, 0.0, 0.0]
            problem = momentum_problem((list(ct) + pad)[:3], (list(cp) + pad)[:3], j_max)
            if problem:
                found.append(("cp_coefficients", problem))
        return found


def ignored_inflow_key(linear: bool, inflow: str | None, smoothing: float | None
                       ) -> tuple[str, str] | None:
    """(key, message) for an inflow key written in the section that the model would ignore, or
    None (``inflow``, ``smoothing``: the keys' values, None where not written). The linear-inflow
    form is defined with signed inflow (T = k_η ω² − k_z ω v_a for either sign of v_a,
    :func:`casadrone.propulsion.propeller_params`), so ``inflow: positive`` beside it would be
    silently overruled; the smoothing width only shapes max(v_a, 0), so with signed inflow it
    does nothing. A key the user wrote is either used or refused."""
    if linear and inflow == "positive":
        return ("inflow", "'positive' cannot apply to linear_inflow, which is the signed-inflow "
                "form (T = k_η ω² − k_z ω v_a for either sign of v_a); remove inflow, or give "
                "ct/cp_coefficients for max(v_a, 0)")
    if smoothing is not None and (linear or inflow == "signed"):
        return ("inflow_smoothing_m_s", "only shapes the smoothed max(v_a, 0) of inflow: "
                "positive; with signed inflow (or linear_inflow) it is unused: remove it")
    return None


class MotorConfig(Schema):
    """A brushless motor: Drela's DC model (``dc``) or a first-order lag (``first-order``)."""

    kind: Literal["dc", "first-order"] = Field(
        "dc", description="dc: Drela's first-order DC motor (KV, R, I0) driving the rotor "
        "inertia; first-order: a lag of time_constant_s to the command's no-load speed")
    kv_rpm_per_v: float = Field(gt=0, le=1e5, description="speed constant K_V (rpm/V)")
    resistance_ohm: float = Field(0.07, ge=MIN_RESISTANCE_OHM, le=100,
                                  description="winding resistance (Ω; at least the 0.3 mΩ of "
                                  "the leads, MIN_RESISTANCE_OHM)")
    no_load_current_a: float = Field(0.0, ge=0, le=100, description="no-load current I_0 (A)")
    # None (not written) rather than a default value, so that a lag written beside kind: dc,
    # which the DC model never reads, is refused instead of silently ignored (as the inflow keys)
    time_constant_s: float | None = Field(
        None, ge=MIN_ROTOR_TIME_CONSTANT_S, le=10,
        description="rotor-speed lag (s) of kind: first-order (default "
        f"{FIRST_ORDER_TIME_CONSTANT_S} s, FIRST_ORDER_TIME_CONSTANT_S); at least ten PWM periods "
        "of the fastest ESC (MIN_ROTOR_TIME_CONSTANT_S); refused with kind: dc, whose lag is "
        "J_r R K_V²")
    mass_kg: float | None = Field(None, gt=0, le=10, description="datasheet mass (kg)")
    data: str | None = Field(None, description="the datasheet")
    max_current_a: float | None = Field(
        None, gt=0, le=1000, description="largest motor current (A, the datasheet's maximum); "
        "the limit lap keeps every motor at or below it (kind: dc); none: unlimited")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        if v.get("kind", "dc") != "dc" and v.get("max_current_a") is not None:
            return [("max_current_a", "a current limit needs the motor's current: kind: dc "
                     "(the first-order lag has no current); remove it or set kind: dc")]
        if v.get("kind", "dc") == "dc" and v.get("time_constant_s") is not None:
            return [("time_constant_s", "unused by kind: dc, whose rotor lag follows from the "
                     "rotor inertia, the winding resistance and K_V (J_r R K_V²); remove it, or "
                     "set kind: first-order")]
        return []


class BatteryConfig(Schema):
    """A battery pack: open-circuit voltage behind an internal resistance; with ``capacity_ah``
    also its state of charge, the open-circuit voltage from it (``cells``, ``ocv_curve``) and
    its current limit (``c_rating``): :mod:`casadrone.propulsion.electric`. Without
    ``capacity_ah`` the open-circuit voltage is constant and nothing is limited."""

    open_circuit_voltage_v: float = Field(gt=0, le=1000, description="V_oc (V) at the start "
                                          "(with ocv_curve: sets the start's state of charge)")
    internal_resistance_ohm: float = Field(0.0, ge=0, le=100,
                                           description="pack resistance (Ω); 0: no sag")
    mass_kg: float | None = Field(None, gt=0, le=100, description="pack mass (kg)")
    data: str | None = Field(None, description="where the figures come from")
    capacity_ah: float | None = Field(
        None, gt=0, le=1000, description="capacity (Ah): the state of charge falls by "
        "I/(3600 capacity) per second; none: no energy model")
    c_rating: float | None = Field(
        None, gt=0, le=1000, description="continuous C rating: the pack current stays at or "
        "below c_rating x capacity_ah (A); none: unlimited")
    cells: int | None = Field(None, ge=1, le=100, strict=True,
                              description="cells in series (the S of 4S); needed by ocv_curve")
    ocv_curve: tuple[tuple[float, float], ...] | None = Field(
        None, min_length=2, description="the cell's open-circuit voltage against state of "
        "charge, [[soc, volts], ...], soc from 0 to 1 and volts increasing; the pack's is cells "
        "times it; none: open_circuit_voltage_v throughout")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        curve, cells = v.get("ocv_curve"), v.get("cells")
        found = [(key, "needs capacity_ah (the pack's energy model)")
                 for key in ("c_rating", "ocv_curve") if v.get(key) is not None
                 and v.get("capacity_ah") is None]
        if curve is None:
            return found
        if cells is None:
            found.append(("cells", "required with ocv_curve (the pack's voltage is cells x the "
                          "cell's)"))
        soc, volts = [p[0] for p in curve], [p[1] for p in curve]
        if soc[0] != 0 or soc[-1] != 1 or any(b <= a for a, b in zip(soc, soc[1:],
                                                                     strict=False)):
            found.append(("ocv_curve", f"state of charge must rise from 0 to 1, got {soc}"))
        elif any(b <= a for a, b in zip(volts, volts[1:], strict=False)) or volts[0] <= 0:
            found.append(("ocv_curve", f"cell volts must be positive and increasing with the "
                          f"state of charge, got {volts}"))
        elif cells is not None:
            lo, hi = cells * volts[0], cells * volts[-1]
            voc = v.get("open_circuit_voltage_v")
            if voc is not None and not lo <= voc <= hi:
                found.append(("open_circuit_voltage_v", f"{voc:g} V is outside the pack's "
                              f"open-circuit voltages {lo:g}-{hi:g} V (cells x ocv_curve): it "
                              "sets the start's state of charge"))
        return found


class PropulsionConfig(Schema):
    """The ``propulsion:`` section of an airframe (module docstring: the models)."""

    model: str = Field(DEFAULT_MODEL, description=" | ".join(
        m.description for m in PROPULSION_MODELS.values()),
        json_schema_extra={"enum": list(PROPULSION_MODELS)})  # the shipped models
    propeller: PropellerConfig | None = Field(
        None, description="the propeller (model: propeller)")
    motor: MotorConfig | None = Field(None, description="the motor (model: propeller)")
    battery: BatteryConfig | None = Field(None, description="the battery pack (model: "
                                          "propeller)")

    @field_validator("model")
    @classmethod
    def _a_registered_model(cls, model: str) -> str:
        if model not in PROPULSION_MODELS:
            raise ValueError(f"{model!r} is not a propulsion model; known: "
                             f"{', '.join(PROPULSION_MODELS)}")
        return model

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        model = PROPULSION_MODELS.get(v.get("model", ""))
        if model is None:
            return []
        given = [key for key in SECTIONS if key not in model.sections and v.get(key) is not None]
        if given:  # one line: the choice of model is the one key that explains them all
            users = [m.name for m in PROPULSION_MODELS.values() if set(given) <= set(m.sections)]
            return [("model", f"{model.name} uses no {', '.join(given)} section "
                     f"({model.no_sections}); remove them"
                     + (f" or set model: {users[0]}" if users else ""))]
        found = [(key, f"required when model is '{model.name}'")
                 for key in model.sections if key in v and v[key] is None]
        prop, motor = v.get("propeller"), v.get("motor")
        if prop is not None and motor is not None and motor.kind == "dc":
            kv = motor.kv_rpm_per_v * RPM_PER_V_TO_RAD_S_PER_V
            tau = prop.rotor_inertia_kgm2 * motor.resistance_ohm * kv**2
            if tau < MIN_ROTOR_TIME_CONSTANT_S:
                found.append(("propeller.rotor_inertia_kgm2", (
                    f"{prop.rotor_inertia_kgm2:g} kg·m² gives the DC motor a mechanical time "
                    f"constant J_r R K_V² = {tau:.3g} s, below "
                    f"{MIN_ROTOR_TIME_CONSTANT_S * 1e6:.0f} µs (ten PWM periods of a "
                    f"{ESC_MAX_PWM_HZ / 1e3:.0f} kHz ESC: the averaged ESC model no longer "
                    "holds); at least "
                    f"{MIN_ROTOR_TIME_CONSTANT_S / (motor.resistance_ohm * kv**2):.3g} kg·m² with "
                    "this motor")))
        return found


