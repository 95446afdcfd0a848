"""A user's own parts (a YAML file of ``propellers:``, ``motors:``, ``packs:``, validated like
every config) and every part turned into the ``propulsion:`` section an airframe uses.

A user file is checked for what no real part can have: a negative or zero mass, resistance or
capacity; a speed constant outside every brushless motor made; an open-circuit voltage curve
that does not rise with the state of charge, or leaves the lithium cell's window; a pack whose
rated current C·capacity is more than it can deliver through its own resistance, or whose
energy per kilogram beats every lithium cell made; propeller coefficients that break momentum
theory (the ``propulsion.propeller`` checks, :class:`casadrone.config.propulsion.PropellerConfig`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import Field

from casadrone.config.airframe import AirframeConfig
from casadrone.config.io import ConfigError, Schema, has_keys, load
from casadrone.config.propulsion import (
    MIN_RESISTANCE_OHM,
    BatteryConfig,
    MotorConfig,
    PropellerConfig,
)
from casadrone.parts.catalogue import Catalogue, ocv_curves, shipped_catalogue
from casadrone.parts.records import (
    MOTOR_FIGURES,
    PACK_FIGURES,
    Basis,
    MotorPart,
    PackPart,
    PropellerPart,
    interpolate,
)

# --------------------------------------------------------------------------------------------
# Physical bounds of a part (each refused value names its key; the argument is here)
# --------------------------------------------------------------------------------------------

#: Speed constants of brushless motors made (rpm/V): from the 20-100 KV of heavy-lift and
#: gimbal motors (T-Motor U15 80 KV, GBM gimbal motors ~20 KV) to the 30 000+ KV of 1S whoop
#: motors (0702/0802: 19 000-30 000 KV); outside it a figure is a typing slip.
KV_RANGE_RPM_PER_V = (10.0, 60000.0)
#: Cell open-circuit voltage window of a lithium cell (V): no lithium-ion or lithium-polymer
#: chemistry rests below 2.0 V (LiPo cut-off 3.0 V, LTO's lowest OCV ~1.5-2.4 V is not a LiPo) or
#: above 4.45 V (LiHV full charge 4.35 V).
CELL_OCV_RANGE_V = (2.0, 4.45)
#: Largest specific energy of a lithium cell (Wh/kg): the best shipping lithium-ion cells reach
#: 250-300 Wh/kg at the cell level, high-C racing LiPos 120-170 Wh/kg (packs.csv); a pack
#: above it (nominal 3.7 V per cell × capacity over its mass) has a wrong mass or capacity.
MAX_SPECIFIC_ENERGY_WH_KG = 300.0
#: Nominal cell voltage of a lithium polymer cell (V), for the specific-energy check.
NOMINAL_CELL_V = 3.7
#: Default cell OCV curve of a pack that names none (lipo-ocv.csv).
DEFAULT_OCV_CURVE = "chen-rincon-mora-2006"

NAME = r"^[a-z0-9][a-z0-9.+_-]*$"


class _PartEntry(Schema):
    name: str = Field(pattern=NAME, max_length=80,
                      description="the part's name: lower case, digits and . + _ - (unique "
                      "across the catalogue)")
    basis: Basis = Field(description="where the figures come from: datasheet, measured or "
                         "assumed (every figure of the entry)")
    source: str = Field(min_length=1, max_length=2000,
                        description="where the figures come from (datasheet title or URL, test)")


class PropellerEntry(_PartEntry):
    """A propeller: C_T(J), C_P(J) as the ``propulsion.propeller`` section takes them, and the
    advance ratio the data end at."""

    diameter_m: float = Field(gt=0, le=5, description="propeller diameter (m)")
    pitch_m: float | None = Field(None, gt=0, le=10, description="propeller pitch (m)")
    blades: int = Field(ge=1, le=12, description="number of blades")
    ct_coefficients: tuple[float, ...] = Field(min_length=1, max_length=3,
                                               description="CT(J) = sum c_k J^k, k ≤ 2")
    cp_coefficients: tuple[float, ...] = Field(min_length=1, max_length=3,
                                               description="CP(J) = sum c_k J^k, k ≤ 2")
    j_max_measured: float = Field(gt=0, le=10, description="largest advance ratio measured")
    rpm_min: float | None = Field(None, gt=0, le=1e6, description="lowest rpm measured")
    rpm_max: float | None = Field(None, gt=0, le=1e6, description="highest rpm measured")
    reynolds_075: float | None = Field(None, gt=0, le=1e8,
                                       description="blade Reynolds number at 75 % radius of the "
                                       "lowest-rpm measurement")
    mass_kg: float | None = Field(None, gt=0, le=10, description="propeller mass (kg)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found = PropellerConfig.problems({
            "ct_coefficients": v.get("ct_coefficients"), "cp_coefficients":
            v.get("cp_coefficients"), "max_advance_ratio": v.get("j_max_measured")})
        lo, hi = v.get("rpm_min"), v.get("rpm_max")
        if lo is not None and hi is not None and lo > hi:
            found.append(("rpm_min", f"{lo:g} is above rpm_max {hi:g}"))
        return found


class MotorEntry(_PartEntry):
    """A brushless motor (Drela's DC model), as the catalogue's motors.csv rows."""

    kv_rpm_per_v: float = Field(ge=KV_RANGE_RPM_PER_V[0], le=KV_RANGE_RPM_PER_V[1],
                                description="speed constant K_V (rpm/V; KV_RANGE_RPM_PER_V)")
    resistance_ohm: float = Field(ge=MIN_RESISTANCE_OHM, le=100,
                                  description="winding resistance, terminal to terminal (Ω)")
    no_load_current_a: float = Field(gt=0, le=100, description="no-load current I_0 (A)")
    no_load_voltage_v: float = Field(gt=0, le=100, description="voltage of the no-load test (V)")
    max_current_a: float = Field(gt=0, le=1000, description="largest current allowed (A)")
    mass_kg: float = Field(gt=0, le=10, description="motor mass (kg)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        i0, imax = v.get("no_load_current_a"), v.get("max_current_a")
        if i0 is not None and imax is not None and i0 >= imax:
            return [("no_load_current_a", f"{i0:g} A is not below max_current_a {imax:g} A: a "
                     "motor draws least current unloaded")]
        return []


class PackEntry(_PartEntry):
    """A lithium pack: cells in series, capacity, whole-pack resistance, C rating, mass and its
    cell open-circuit voltage curve (a shipped curve's name, or points of its own)."""

    cells: int = Field(ge=1, le=24, description="cells in series")
    capacity_ah: float = Field(gt=0, le=100, description="capacity (Ah)")
    resistance_ohm: float = Field(gt=0, le=10, description="whole-pack internal resistance (Ω)")
    c_rating: float = Field(gt=0, le=1000, description="continuous C rating (1/h)")
    mass_kg: float = Field(gt=0, le=100, description="pack mass (kg)")
    ocv_curve: str | None = Field(None, description="a shipped cell OCV curve (lipo-ocv.csv; "
                                  f"default {DEFAULT_OCV_CURVE}), or give ocv_soc and ocv")
    ocv_soc: tuple[float, ...] | None = Field(None, min_length=2, max_length=200,
                                              description="states of charge of the cell OCV "
                                              "points, 0 to 1, increasing")
    ocv: tuple[float, ...] | None = Field(None, min_length=2, max_length=200,
                                          description="cell open-circuit voltage at ocv_soc (V)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        return _ocv_problems(v) + _pack_rating_problems(v)


def _ocv_problems(v: dict[str, Any]) -> list[tuple[str, str]]:
    soc, volts, curve = v.get("ocv_soc"), v.get("ocv"), v.get("ocv_curve")
    if soc is None or volts is None:
        if (soc is None) != (volts is None):
            return [("ocv" if volts is None else "ocv_soc", "give ocv_soc and ocv together")]
        known = ocv_curves()
        if curve is not None and curve not in known:
            return [("ocv_curve", f"unknown OCV curve {curve!r} (known: {', '.join(known)})")]
        return []
    if curve is not None:
        return [("ocv_curve", "give either ocv_curve or the points ocv_soc, ocv")]
    if len(soc) != len(volts):
        return [("ocv", f"{len(volts)} voltages for {len(soc)} ocv_soc points")]
    if soc[0] != 0 or soc[-1] != 1 or any(b <= a for a, b in zip(soc, soc[1:], strict=False)):
        return [("ocv_soc", "must run from 0 to 1, strictly increasing")]
    if any(b <= a for a, b in zip(volts, volts[1:], strict=False)):
        return [("ocv", "must rise with the state of charge (a cell's open-circuit voltage "
                 "grows as it charges)")]
    lo, hi = CELL_OCV_RANGE_V
    if volts[0] < lo or volts[-1] > hi:
        return [("ocv", f"{volts[0]:g}-{volts[-1]:g} V leaves the lithium cell's "
                 f"{lo:g}-{hi:g} V (CELL_OCV_RANGE_V)")]
    return []


def _pack_rating_problems(v: dict[str, Any]) -> list[tuple[str, str]]:
    """The pack's rated current against what its resistance lets through, and its specific
    energy against the best lithium cells'."""
    found: list[tuple[str, str]] = []
    if not has_keys(v, "cells", "capacity_ah", "resistance_ohm", "c_rating"):
        return found
    cells, q, r, c = v["cells"], v["capacity_ah"], v["resistance_ohm"], v["c_rating"]
    m = v.get("mass_kg")
    full = cells * _full_cell_voltage(v)
    # a source of V_oc behind R gives its largest power at I = V_oc/(2R), the terminal voltage
    # then half the open-circuit one: a rating above it is beyond any use of the pack
    most = full / (2 * r)
    if c * q > most:
        found.append(("c_rating", f"{c:g}C × {q:g} Ah = {c * q:.4g} A is above the "
                      f"{most:.4g} A of the pack's largest power (V_oc/2R = {full:.3g} V / "
                      f"2·{r:g} Ω): lower c_rating, or check resistance_ohm"))
    if m is not None and cells * NOMINAL_CELL_V * q / m > MAX_SPECIFIC_ENERGY_WH_KG:
        found.append(("mass_kg", f"{m:g} kg for {cells * NOMINAL_CELL_V * q:.3g} Wh is "
                      f"{cells * NOMINAL_CELL_V * q / m:.0f} Wh/kg, above any lithium cell's "
                      f"{MAX_SPECIFIC_ENERGY_WH_KG:.0f} Wh/kg (MAX_SPECIFIC_ENERGY_WH_KG)"))
    return found


def _full_cell_voltage(v: dict[str, Any]) -> float:
    volts = v.get("ocv")
    if volts:
        return float(volts[-1])
    curve = ocv_curves().get(v.get("ocv_curve") or DEFAULT_OCV_CURVE)
    return curve[1][-1] if curve else CELL_OCV_RANGE_V[1]


class PartsConfig(Schema):
    """A file of a user's own parts: ``propellers:``, ``motors:`` and ``packs:`` lists, each
    entry with its name, basis and source; names unique across the file and the catalogue."""

    propellers: tuple[PropellerEntry, ...] = Field((), description="propellers")
    motors: tuple[MotorEntry, ...] = Field((), description="motors")
    packs: tuple[PackEntry, ...] = Field((), description="LiPo packs")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        seen: set[str] = set()
        found = []
        for key in ("propellers", "motors", "packs"):
            for i, entry in enumerate(v.get(key) or ()):
                if entry.name in seen:
                    found.append((f"{key}.{i}.name", f"{entry.name!r} is given twice"))
                seen.add(entry.name)
        return found


# --------------------------------------------------------------------------------------------
# Entries to parts, parts to sections
# --------------------------------------------------------------------------------------------


def propeller_part(e: PropellerEntry) -> PropellerPart:
    """The :class:`PropellerPart` of a user entry (coefficients padded to three)."""
    return PropellerPart(
        name=e.name, diameter_m=e.diameter_m, pitch_m=e.pitch_m, blades=e.blades,
        ct_coefficients=_three(e.ct_coefficients), cp_coefficients=_three(e.cp_coefficients),
        j_max_measured=e.j_max_measured,
        rpm_min=e.rpm_min or 0.0, rpm_max=e.rpm_max or 0.0, sweep_rpm=None,
        reynolds_075_min=e.reynolds_075, reynolds_075_fit=None, ct_rms=0.0, cp_rms=0.0,
        points_fitted=0, static_measured=False, mass_kg=e.mass_kg, chord_075=None,
        source=e.source)


def _three(c: tuple[float, ...]) -> tuple[float, float, float]:
    """Polynomial coefficients padded with zeros to c₀, c₁, c₂."""
    padded = [*c, 0.0, 0.0]
    return (padded[0], padded[1], padded[2])


def motor_part(e: MotorEntry) -> MotorPart:
    """The :class:`MotorPart` of a user entry."""
    return MotorPart(
        name=e.name, kv_rpm_per_v=e.kv_rpm_per_v, resistance_ohm=e.resistance_ohm,
        no_load_current_a=e.no_load_current_a, no_load_voltage_v=e.no_load_voltage_v,
        max_current_a=e.max_current_a, mass_kg=e.mass_kg,
        basis=dict.fromkeys(MOTOR_FIGURES, e.basis), source=e.source)


def pack_part(e: PackEntry) -> PackPart:
    """The :class:`PackPart` of a user entry (its OCV points, or the named curve's)."""
    if e.ocv_soc is not None and e.ocv is not None:
        soc, volts, curve = e.ocv_soc, e.ocv, f"{e.name} (own points)"
    else:
        curve = e.ocv_curve or DEFAULT_OCV_CURVE
        soc, volts = ocv_curves()[curve]
    return PackPart(
        name=e.name, cells=e.cells, capacity_ah=e.capacity_ah, resistance_ohm=e.resistance_ohm,
        c_rating=e.c_rating, mass_kg=e.mass_kg, ocv_soc=tuple(soc), ocv=tuple(volts),
        ocv_curve=curve, basis=dict.fromkeys(PACK_FIGURES, e.basis), source=e.source)


def user_catalogue(cfg: PartsConfig) -> Catalogue:
    """The parts of a validated user file."""
    return Catalogue(tuple(propeller_part(e) for e in cfg.propellers),
                     tuple(motor_part(e) for e in cfg.motors),
                     tuple(pack_part(e) for e in cfg.packs))


def load_parts(path: str | Path | None = None) -> Catalogue:
    """The shipped catalogue, with the parts of a user file added when given; a bad file (or a
    name the catalogue has already) raises ConfigError, one ``FILE: key: message`` line each."""
    shipped = shipped_catalogue()
    if path is None:
        return shipped
    cfg = load(PartsConfig, path)
    taken = set(shipped.names())
    clashes = [f"{path}: {key}.{i}.name: {e.name!r} is already a part of the shipped catalogue"
               for key in ("propellers", "motors", "packs")
               for i, e in enumerate(getattr(cfg, key)) if e.name in taken]
    if clashes:
        raise ConfigError(clashes)
    return shipped.joined(user_catalogue(cfg))


def propeller_section(p: PropellerPart, **extra: Any) -> PropellerConfig:
    """The ``propulsion.propeller`` section of a catalogue propeller: its fit, valid to the end
    of its measured sweep (``max_advance_ratio``); ``extra`` sets other keys (rotor inertia)."""
    return PropellerConfig(
        diameter_m=p.diameter_m, ct_coefficients=p.ct_coefficients,
        cp_coefficients=p.cp_coefficients, max_advance_ratio=p.j_max_measured,
        data=f"parts catalogue {p.name}: {p.source}"[:2000], **extra)


def motor_section(m: MotorPart) -> MotorConfig:
    """The ``propulsion.motor`` section (kind: dc) of a catalogue motor."""
    return MotorConfig(kind="dc", kv_rpm_per_v=m.kv_rpm_per_v, resistance_ohm=m.resistance_ohm,
                       no_load_current_a=m.no_load_current_a, mass_kg=m.mass_kg,
                       data=f"parts catalogue {m.name}: {m.source}")


def battery_section(b: PackPart, soc: float = 1.0) -> BatteryConfig:
    """The ``propulsion.battery`` section of a catalogue pack at state of charge ``soc`` (its
    open-circuit voltage there, cells × the cell curve; full by default)."""
    return BatteryConfig(open_circuit_voltage_v=b.cells * interpolate(b.ocv_soc, b.ocv, soc),
                         internal_resistance_ohm=b.resistance_ohm, mass_kg=b.mass_kg,
                         data=f"parts catalogue {b.name}: {b.source}")


def airframe_with_parts(cfg: AirframeConfig, propeller: PropellerPart | None = None,
                        motor: MotorPart | None = None, pack: PackPart | None = None
                        ) -> AirframeConfig:
    """``cfg`` (an airframe of the ``propeller`` model) flying the given parts: each given part's
    section replaces the airframe's, the propeller keeping the airframe's rotor inertia and
    rotor drag (the catalogue has none of its own), validated again as a whole (a propeller
    whose diameter disagrees with ``prop_diameter_mm`` is refused as in a file). The airframe's
    mass stays its own: the parts' masses ride in their sections for a build to add up."""
    data = cfg.model_dump(exclude_none=True)
    sections = data.setdefault("propulsion", {})
    if propeller is not None:
        old = sections.get("propeller", {})
        kept = {k: old[k] for k in ("rotor_inertia_kgm2", "rotor_drag_n_s2_per_m") if k in old}
        sections["propeller"] = propeller_section(propeller, **kept).model_dump(exclude_none=True)
    if motor is not None:
        sections["motor"] = motor_section(motor).model_dump(exclude_none=True)
    if pack is not None:
        sections["battery"] = battery_section(pack).model_dump(exclude_none=True)
    return AirframeConfig.model_validate(data)
