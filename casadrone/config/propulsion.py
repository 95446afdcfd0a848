"""The ``propulsion:`` section of an airframe: which propulsion model flies it and its data
(the models: :mod:`casadrone.propulsion`)."""

from __future__ import annotations

import math
import re
from functools import cache, lru_cache
from typing import TYPE_CHECKING, Any, Literal

from pydantic import Field

from casadrone.config.io import Schema

if TYPE_CHECKING:  # numpy is imported where it is used: the schemas load without it
    import numpy as np

PropulsionKind = Literal["paper", "propeller"]
#: rpm/V to rad/s per V.
RPM_PER_V_TO_RAD_S_PER_V = 2 * math.pi / 60

# --------------------------------------------------------------------------------------------
# Physical bounds of the section (each refused value names its key; the argument is here)
# --------------------------------------------------------------------------------------------

#: Largest figure of merit of a rotor: momentum theory (Rankine–Froude actuator disc; Leishman,
#: Principles of Helicopter Aerodynamics, 2nd ed., §2.8) gives the least shaft power that makes a
#: thrust T, P_ideal = T^{3/2} / √(2ρA), A = πD²/4; FM = P_ideal / P ≤ 1. In this model's
#: coefficients (n in rev/s, T = C_T ρ n² D⁴, P = C_P ρ n³ D⁵) that is
#: FM = √(2/π) C_T^{3/2} / C_P (:func:`figure_of_merit`); real propellers reach 0.5-0.8 (the
#: shipped 5-inch tri-blade 0.58).
MAX_FIGURE_OF_MERIT = 1.0
#: Points of the advance-ratio range at which the axial-flight form of the same bound is checked
#: (:func:`momentum_problem`): C_T, C_P are quadratics in J, smooth on a 1000-interval grid.
MOMENTUM_GRID = 1001
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
#: The first-order motor's lag (s) when its section gives none: the middle of the 20-30 ms that
#: 5-inch racing rotors show in step tests (above; the shipped DC rotor's J_r R K_V² is 28 ms).
FIRST_ORDER_TIME_CONSTANT_S = 0.03
#: Least winding (terminal) resistance (Ω): the resistance a datasheet gives and the model's
#: current sees includes the motor's own leads, two of them phase to phase; even two 3 cm leads
#: of 12 AWG copper (3.31 mm², ρ_Cu = 1.68e-8 Ω·m; no motor of this class, 0802 whoop to 4215
#: 12S, has thicker or shorter ones) make 0.30 mΩ. The lightest-wound motors of the class measure
#: tens of mΩ (parts.csv: 38-75 mΩ).
MIN_RESISTANCE_OHM = 3e-4
#: Speed of sound in air at 20 °C (m/s). No propeller model here (C_T, C_P fitted to subsonic
#: wind-tunnel data, or the linear-inflow form) holds once the blade tips reach it: compressibility
#: and shocks change thrust and power entirely (racing propellers run at tip Mach 0.6-0.8).
SPEED_OF_SOUND_M_S = 343.0
#: Largest relative difference between the propeller's diameter and the airframe's
#: prop_diameter_mm (the rotor-overlap check, figures and exports): both describe the same
#: propeller, and 1 % is finer than any catalogue size step (5.0 vs 5.1 inch is 2 %).
DIAMETER_RTOL = 0.01
#: Width (m/s) of the smoothed max(v_a, 0) of ``inflow: positive`` when the section gives none
#: (the schema's default before it became optional; every shipped airframe and figure uses it):
#: the smoothed inflow stays within ε/2 = 0.1 m/s of max(v_a, 0).
INFLOW_SMOOTHING_M_S = 0.2
#: A ``propeller.data`` value without blanks is a dataset name (it sets the default
#: max_advance_ratio); text with blanks is a free description of where the coefficients come
#: from (what ``casadrone fit-propulsion`` writes), which sets no range.
DATASET_NAME = re.compile(r"\S+")


def figure_of_merit(ct0: float, cp0: float) -> float:
    """Static figure of merit √(2/π) C_T^{3/2} / C_P of the coefficients (n in rev/s, T = C_T ρ
    n² D⁴, P = C_P ρ n³ D⁵): the ideal power T^{3/2}/√(2ρA) over the shaft power, A = πD²/4."""
    return math.sqrt(2 / math.pi) * ct0**1.5 / cp0


def _poly(c: list[float], J: float) -> float:
    return c[0] + c[1] * J + c[2] * J * J


def _quadratic_min(c: list[float], hi: float) -> tuple[float, float]:
    """(J, value) of the least c₀ + c₁J + c₂J² on 0 ≤ J ≤ hi (hi may be inf)."""
    if math.isinf(hi):
        if c[2] < 0 or (c[2] == 0 and c[1] < 0):
            return math.inf, -math.inf
        hi = 0.0 if c[2] == 0 else max(0.0, -c[1] / (2 * c[2]))
    candidates = [0.0, hi]
    if c[2] > 0 and 0 < -c[1] / (2 * c[2]) < hi:
        candidates.append(-c[1] / (2 * c[2]))
    return min(((J, _poly(c, J)) for J in candidates), key=lambda t: t[1])


def _first_zero(c: list[float], hi: float) -> float:
    """The least J in [0, hi] where c₀ + c₁J + c₂J² ≤ 0 (c₀ > 0 and such a J exists)."""
    c0, c1, c2 = c
    if c2 == 0:
        return -c0 / c1
    d = math.sqrt(max(c1 * c1 - 4 * c2 * c0, 0.0))
    roots = sorted(r for r in ((-c1 - d) / (2 * c2), (-c1 + d) / (2 * c2)) if 0 <= r <= hi)
    return roots[0] if roots else hi


def thrust_root(ct: list[float]) -> float:
    """The advance ratio where C_T(J) falls to 0 (the zero-thrust, windmill point), inf if it
    never does (c₀ > 0, c₁, c₂ ≤ 0: one root at most)."""
    c0, c1, c2 = ct
    if c2 < 0:
        return (-c1 - math.sqrt(c1 * c1 - 4 * c2 * c0)) / (2 * c2)
    return -c0 / c1 if c1 < 0 else math.inf


def momentum_problem(ct: list[float], cp: list[float], j_max: float | None) -> str | None:
    """Why C_T(J), C_P(J) (three coefficients each, c₀ > 0) break momentum theory in axial flight
    over the advance ratios the model uses, or None.

    At J = 0: the figure of merit (:data:`MAX_FIGURE_OF_MERIT`). With a known range 0 ≤ J ≤ J_max
    (the data's, or max_advance_ratio): C_P > 0 throughout (the rotor-speed bound K_V V_oc of
    :func:`casadrone.propulsion.max_speed` needs a propeller that absorbs power), and where
    C_T > 0 the actuator disc in climb, P ≥ T (V + v_i), v_i = −V/2 + √(V²/4 + T/(2ρA)), i.e.
    C_P ≥ C_T (J/2 + √(J²/4 + 2 C_T/π)) (its J = 0 case is FM ≤ 1). Without a range (coefficients
    without data, a static fit) only the necessary part: C_P > 0 wherever C_T > 0, since a rotor
    that makes thrust absorbs power; the full inequality is not asked there, as constant
    (static-only) coefficients of a stand's fit break it at large J by construction.
    """
    fm = figure_of_merit(ct[0], cp[0])
    if fm > MAX_FIGURE_OF_MERIT:
        return (f"static figure of merit √(2/π)·C_T0^1.5/C_P0 = {fm:.3g} exceeds 1 (C_T0 = "
                f"{ct[0]:g} of ct_coefficients, C_P0 = {cp[0]:g}): momentum theory needs a shaft "
                f"power of at least the ideal T^1.5/√(2ρA), C_P0 ≥ {fm * cp[0]:.4g} for this C_T0")
    hi = j_max if j_max is not None else thrust_root(ct)
    J, least = _quadratic_min(cp, hi)
    if least <= 0:
        at = "as J grows" if math.isinf(J) else f"at J = {J:.3g}"
        where = (f"over the advance ratios the model uses (0 ≤ J ≤ {j_max:g})"
                 if j_max is not None else "while the propeller makes thrust (C_T > 0)")
        return (f"C_P(J) must stay positive {where}, but is ≤ 0 from J = "
                f"{_first_zero(cp, hi):.3g} (least {least:.3g} {at}), the propeller giving "
                "shaft power back while it makes thrust C_T(J) > 0: momentum theory has a rotor "
                "that makes thrust absorb power")
    if j_max is None:
        return None
    for k in range(1, MOMENTUM_GRID):
        J = j_max * k / (MOMENTUM_GRID - 1)
        ctj, cpj = _poly(ct, J), _poly(cp, J)
        if ctj <= 0:
            continue
        ideal = ctj * (J / 2 + math.sqrt(J * J / 4 + 2 * ctj / math.pi))
        if cpj < ideal:
            return (f"at J = {J:.3g} (within 0 ≤ J ≤ {j_max:g}) C_P = {cpj:.4g} is below the "
                    f"ideal power of its thrust C_T = {ctj:.4g}, C_T (J/2 + √(J²/4 + 2C_T/π)) = "
                    f"{ideal:.4g}: momentum theory in climb (P ≥ T (V + v_i)) is broken")
    return None


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

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        if v.get("kind", "dc") == "dc" and v.get("time_constant_s") is not None:
            return [("time_constant_s", "unused by kind: dc, whose rotor lag follows from the "
                     "rotor inertia, the winding resistance and K_V (J_r R K_V²); remove it, or "
                     "set kind: first-order")]
        return []


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
        sections = ("propeller", "motor", "battery")
        if v.get("model") == "paper":
            given = [key for key in sections if v.get(key) is not None]
            if given:  # one line: the choice of model is the one key that explains them all
                return [("model", f"paper uses no {', '.join(given)} section (its thrust is the "
                         "airframe's thrust section); remove them or set model: propeller")]
        if v.get("model") != "propeller":
            return []
        found = [(key, "required when model is 'propeller'")
                 for key in sections if key in v and v[key] is None]
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


# --------------------------------------------------------------------------------------------
# Shipped propeller data (package data: the section's ``data`` names one)
# --------------------------------------------------------------------------------------------

#: The shipped 5-inch propeller: UIUC Propeller Database, Vol. 2, DA4022 5.0x3.75, 3 blades.
SHIPPED_PROPELLER = "uiuc-da4022-5x3.75-3blade"
#: The points the shipped fit uses: the static points at ≥ 5000 rpm and the wind-tunnel sweep
#: at the highest rpm (6034), the nearest the database comes to a racing propeller's Reynolds
#: number, over J ≤ 0.62 (CT down to a third of its static value: 40 m/s of axial inflow at
#: 30 000 rpm is J = 0.63).
FIT_MIN_STATIC_RPM, FIT_SWEEP_RPM, FIT_MAX_J = 5000.0, 6034.0, 0.62


def propeller_data(name: str = SHIPPED_PROPELLER) -> np.ndarray:
    """The raw points (J, rpm, CT, CP) of a shipped propeller dataset (numpy array, 4 columns)."""
    from importlib import resources

    import numpy as np

    path = resources.files("casadrone") / "data" / "propulsion" / f"{name}.csv"
    with path.open() as fh:
        return np.loadtxt(fh, delimiter=",", comments="#", skiprows=7)


def fit_points(data: np.ndarray) -> np.ndarray:
    """The rows of :func:`propeller_data` the shipped fit uses (see :data:`FIT_MAX_J`)."""
    J, rpm = data[:, 0], data[:, 1]
    return data[((J == 0) & (rpm >= FIT_MIN_STATIC_RPM))
                | ((rpm == FIT_SWEEP_RPM) & (J > 0) & (J <= FIT_MAX_J))]


@cache
def data_advance_ratio(name: str = SHIPPED_PROPELLER) -> float:
    """The largest advance ratio of the points a shipped dataset's fit uses
    (:func:`fit_points`): where its CT(J), CP(J) are measured, 0.618 for the shipped propeller.
    Read once per process (package data; every propeller airframe build asks for it)."""
    return float(fit_points(propeller_data(name))[:, 0].max())


@lru_cache(maxsize=1)
def shipped_datasets() -> tuple[str, ...]:
    """Names of the propeller datasets shipped in the package data."""
    from importlib import resources

    folder = resources.files("casadrone") / "data" / "propulsion"
    return tuple(sorted(f.name[:-4] for f in folder.iterdir()
                        if f.name.endswith(".csv") and f.name != "parts.csv"))
