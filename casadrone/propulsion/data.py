"""The static propeller physics and data every floor may ask for: unit conversions, the physical
limits the ``propulsion:`` schema checks (momentum theory, the speed of sound), the defaults the
model fills in, and the shipped propeller datasets with the points of their fit. Numbers only:
no CasADi, no schema (the schema, :mod:`casadrone.config.propulsion`, sits above and imports
these)."""

from __future__ import annotations

import math
from functools import cache, lru_cache

#: rpm/V to rad/s per V.
RPM_PER_V_TO_RAD_S_PER_V = 2 * math.pi / 60

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

#: The first-order motor's lag (s) when its section gives none: the middle of the 20-30 ms that
#: 5-inch racing rotors show in step tests (the shipped DC rotor's J_r R K_V² is 28 ms).
FIRST_ORDER_TIME_CONSTANT_S = 0.03

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



# --------------------------------------------------------------------------------------------
# Shipped propeller data (package data: the section's ``data`` names one)
# --------------------------------------------------------------------------------------------

#: The shipped 5-inch propeller: UIUC Propeller Database, Vol. 2, DA4022 5.0x3.75, 3 blades.
SHIPPED_PROPELLER = "uiuc-da4022-5x3.75-3blade"
#: The points the shipped fit uses: the static points at ≥ 5000 rpm and the whole wind-tunnel
#: sweep at the highest rpm (6034), the nearest the database comes to a racing propeller's
#: Reynolds number, to its last point (J = 0.854, where C_T is already negative: the fit's
#: zero-thrust J is 0.815; 40 m/s of axial inflow at 30 000 rpm is J = 0.63).
FIT_MIN_STATIC_RPM, FIT_SWEEP_RPM = 5000.0, 6034.0


def propeller_data(name: str = SHIPPED_PROPELLER):
    """The raw points (J, rpm, CT, CP) of a shipped propeller dataset (numpy array, 4 columns)."""
    from importlib import resources

    import numpy as np

    path = resources.files("casadrone") / "data" / "propulsion" / f"{name}.csv"
    with path.open() as fh:
        return np.loadtxt(fh, delimiter=",", comments="#", skiprows=7)


def fit_points(data):
    """The rows of :func:`propeller_data` the shipped fit uses (see :data:`FIT_SWEEP_RPM`)."""
    J, rpm = data[:, 0], data[:, 1]
    return data[((J == 0) & (rpm >= FIT_MIN_STATIC_RPM)) | ((rpm == FIT_SWEEP_RPM) & (J > 0))]


@cache
def data_advance_ratio(name: str = SHIPPED_PROPELLER) -> float:
    """The largest advance ratio of the points a shipped dataset's fit uses
    (:func:`fit_points`): the end of its measured sweep, 0.854 for the shipped propeller.
    Read once per process (package data; every propeller airframe build asks for it)."""
    return float(fit_points(propeller_data(name))[:, 0].max())


@lru_cache(maxsize=1)
def shipped_datasets() -> tuple[str, ...]:
    """Names of the propeller datasets shipped in the package data."""
    from importlib import resources

    folder = resources.files("casadrone") / "data" / "propulsion"
    return tuple(sorted(f.name[:-4] for f in folder.iterdir()
                        if f.name.endswith(".csv") and f.name != "parts.csv"))
