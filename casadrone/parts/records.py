"""The records of the parts catalogue: one frozen record per propeller, motor and pack, with the
figures a ``propulsion:`` section and a race need, and where each figure comes from.

Numbers only (no schema, no CasADi): :mod:`casadrone.config.parts` turns a record into the
``propulsion.propeller`` / ``motor`` / ``battery`` section an airframe uses, and reads the
user's own parts.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar, Literal

from casadrone.results import AsDict

#: Where a figure comes from: the maker's published specification or test sheet (``datasheet``),
#: a published test of the part (``measured``), or no source (``assumed``: a typical value, the
#: row's source says which).
Basis = Literal["datasheet", "measured", "assumed"]
BASES: tuple[str, ...] = ("datasheet", "measured", "assumed")
#: The kinds of part, each a table of the catalogue.
Kind = Literal["propeller", "motor", "pack"]
KINDS: tuple[str, ...] = ("propeller", "motor", "pack")

#: Air at the ISA sea-level state, for the Reynolds number of a blade section: density (kg/m³)
#: and dynamic viscosity (Pa·s, Sutherland's law at 288.15 K).
AIR_DENSITY_KG_M3 = 1.225
AIR_VISCOSITY_PA_S = 1.789e-5
#: Radius fraction of the reference blade section (the UIUC database quotes its Reynolds numbers
#: at 75 % of the radius).
REFERENCE_RADIUS = 0.75


def blade_reynolds(rpm: float, diameter_m: float, chord_over_radius: float) -> float:
    """Reynolds number ρ V c / μ of the blade section at 75 % radius in static air: V = ω·0.75R
    (the rotational speed of the section, which dominates it at the advance ratios of the
    database, J ≤ 1.2: √(1 + (J/(0.75π))²) ≤ 1.11), c = (c/R)·R."""
    radius = diameter_m / 2
    speed = 2 * math.pi * rpm / 60 * REFERENCE_RADIUS * radius
    return AIR_DENSITY_KG_M3 * speed * chord_over_radius * radius / AIR_VISCOSITY_PA_S


@dataclass(frozen=True)
class PropellerPart(AsDict):
    """A propeller: C_T(J), C_P(J) fitted to its measured points (three coefficients each, c₀ +
    c₁J + c₂J², n in rev/s: T = C_T ρ n² D⁴, P = C_P ρ n³ D⁵) over 0 ≤ J ≤ ``j_max_measured``,
    the end of the fitted sweep. The points were measured at ``rpm_min``–``rpm_max``; the blade
    Reynolds number at 75 % radius of the lowest-rpm sweep (``reynolds_075_min``) and of the
    fitted one (``reynolds_075_fit``) say how far below a racing rotor's (:meth:`reynolds_at`)
    they lie: small-propeller coefficients rise with the Reynolds number (thrust) and fall
    (power) — the data's low-rpm caveat. None where the database gives no blade geometry.

    Beside them: ``sweep_rpm`` (the fitted sweep's rpm), ``ct_rms``/``cp_rms`` (RMS residual of
    each fit over its ``points_fitted`` points), ``static_measured`` (C_T0, C_P0 rest on static
    points, not on the sweep extrapolated to J = 0; False for a user's entry: unknown),
    ``chord_075`` (blade chord over radius at 75 % radius), ``mass_kg`` (None: the database
    weighs no propeller)."""

    name: str
    diameter_m: float
    pitch_m: float | None
    blades: int
    ct_coefficients: tuple[float, float, float]
    cp_coefficients: tuple[float, float, float]
    j_max_measured: float
    rpm_min: float
    rpm_max: float
    sweep_rpm: float | None
    reynolds_075_min: float | None
    reynolds_075_fit: float | None
    ct_rms: float
    cp_rms: float
    points_fitted: int
    static_measured: bool
    mass_kg: float | None
    chord_075: float | None
    source: str
    kind: ClassVar[str] = "propeller"
    _properties: ClassVar[tuple[str, ...]] = ("caveat",)

    def ct(self, J: float) -> float:
        """C_T of the fit at advance ratio J."""
        return _poly(self.ct_coefficients, J)

    def cp(self, J: float) -> float:
        """C_P of the fit at advance ratio J."""
        return _poly(self.cp_coefficients, J)

    def reynolds_at(self, rpm: float) -> float | None:
        """Blade Reynolds number at 75 % radius at ``rpm`` (None without blade geometry)."""
        if self.chord_075 is None:
            return None
        return blade_reynolds(rpm, self.diameter_m, self.chord_075)

    @property
    def caveat(self) -> str:
        """The low-rpm caveat in words: the Reynolds numbers measured against a racing rotor's."""
        if not self.rpm_max:  # a user's propeller given without its rpm range
            return "no rpm range given: the Reynolds number of its data is unknown"
        if self.reynolds_075_min is None or self.reynolds_075_fit is None:
            return (f"measured at {self.rpm_min:.0f}-{self.rpm_max:.0f} rpm; the database gives no "
                    "blade geometry, so no Reynolds number")
        racing = self.reynolds_at(RACING_RPM)
        return (f"measured at {self.rpm_min:.0f}-{self.rpm_max:.0f} rpm: Re(0.75R) "
                f"{self.reynolds_075_min:.3g} in the lowest-rpm sweep, {self.reynolds_075_fit:.3g} "
                f"in the fitted one; {racing:.3g} at {RACING_RPM:.0f} rpm")


#: A racing rotor's speed for the caveat's comparison (rpm): a 5-inch propeller on a 2207 motor
#: turns 25 000-35 000 rpm at full throttle (the motors' own test tables, motors.csv).
RACING_RPM = 30000.0


@dataclass(frozen=True)
class MotorPart(AsDict):
    """A brushless motor, Drela's first-order DC model: speed constant K_V (rpm/V), winding
    resistance R (Ω, terminal to terminal), no-load current I₀ (A) at ``no_load_voltage_v``, the
    largest current the maker allows (A) and the mass (kg, with leads where given). ``basis``
    maps each figure (``kv``, ``resistance``, ``no_load_current``, ``no_load_voltage``,
    ``max_current``, ``mass``) to where it comes from (:data:`Basis`)."""

    name: str
    kv_rpm_per_v: float
    resistance_ohm: float
    no_load_current_a: float
    no_load_voltage_v: float
    max_current_a: float
    mass_kg: float
    basis: Mapping[str, str] = field(hash=False)
    source: str
    kind: ClassVar[str] = "motor"

    def no_load_speed_rpm(self, volts: float) -> float:
        """K_V·V: the unloaded speed at ``volts`` (rpm)."""
        return self.kv_rpm_per_v * volts


#: The figures of a motor row and of a pack row that carry a basis.
MOTOR_FIGURES = ("kv", "resistance", "no_load_current", "no_load_voltage", "max_current", "mass")
PACK_FIGURES = ("capacity", "c_rating", "mass", "resistance")


@dataclass(frozen=True)
class PackPart(AsDict):
    """A LiPo pack of ``cells`` cells in series: capacity (Ah), whole-pack internal resistance
    (Ω), C rating (its largest current is C·capacity), mass (kg), and the open-circuit voltage of
    one cell (V, ``ocv``) at the states of charge ``ocv_soc`` (0 empty, 1 full, increasing),
    from the curve named ``ocv_curve``. ``basis`` maps ``capacity``, ``c_rating``, ``mass``,
    ``resistance`` to where each comes from."""

    name: str
    cells: int
    capacity_ah: float
    resistance_ohm: float
    c_rating: float
    mass_kg: float
    ocv_soc: tuple[float, ...]
    ocv: tuple[float, ...]
    ocv_curve: str
    basis: Mapping[str, str] = field(hash=False)
    source: str
    kind: ClassVar[str] = "pack"
    _properties: ClassVar[tuple[str, ...]] = ("max_current_a", "full_voltage_v")

    @property
    def max_current_a(self) -> float:
        """C rating × capacity (A)."""
        return self.c_rating * self.capacity_ah

    @property
    def full_voltage_v(self) -> float:
        """Open-circuit voltage of the full pack (V)."""
        return self.open_circuit_voltage_v(1.0)

    def open_circuit_voltage_v(self, soc: float) -> float:
        """Open-circuit voltage of the pack at state of charge ``soc`` (V): ``cells`` × the cell
        curve, linear between its points, held at its ends outside them."""
        return self.cells * interpolate(self.ocv_soc, self.ocv, soc)


def interpolate(xs: tuple[float, ...], ys: tuple[float, ...], x: float) -> float:
    """Piecewise-linear y(x) through increasing ``xs``, constant beyond the ends."""
    if x <= xs[0]:
        return ys[0]
    if x >= xs[-1]:
        return ys[-1]
    k = bisect.bisect_right(xs, x)
    t = (x - xs[k - 1]) / (xs[k] - xs[k - 1])
    return ys[k - 1] + t * (ys[k] - ys[k - 1])


def _poly(c: tuple[float, ...], J: float) -> float:
    return sum(ck * J**k for k, ck in enumerate(c))


Part = PropellerPart | MotorPart | PackPart
