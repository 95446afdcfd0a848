"""The combinations of a build: propeller × motor × pack from the catalogue, each turned into the
template airframe flying those parts, and the ones no frame of the box can fly refused before
any solve, with the reason.

A combination's airframe (:func:`combination_airframe`) is the template with

- the propeller's, motor's and pack's ``propulsion:`` sections
  (:func:`casadrone.config.parts.airframe_with_parts`), ``prop_diameter_mm`` the propeller's;
- the pack's energy model: capacity, C rating, cells and cell OCV curve, charged full
  (open-circuit voltage cells × the curve's top), and the motor's largest current: the race's
  state of charge and current limits (:mod:`casadrone.propulsion.electric`);
- the components mass model's motor (motor + propeller, at the rotor) and battery masses the
  parts' own, so the build's mass is the frame's plus the parts'.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from casadrone.airframe import build_airframe, with_theta
from casadrone.config.airframe import AirframeConfig
from casadrone.config.build import SPEED_OF_SOUND_M_S, BuildSettings
from casadrone.config.io import ConfigError
from casadrone.config.parts import airframe_with_parts
from casadrone.parts import Catalogue, MotorPart, PackPart, PropellerPart
from casadrone.propulsion import (
    airframe_values,
    full_static_thrust,
    hover_commands,
    motor_currents,
)
from casadrone.propulsion.propeller import PropellerParams
from casadrone.results import AsDict

#: Metres per inch, for the propeller diameter filter.
M_PER_INCH = 0.0254


@dataclass(frozen=True)
class Combination(AsDict):
    """One propeller, one motor, one pack (four of each of the first two on the frame)."""

    propeller: PropellerPart
    motor: MotorPart
    pack: PackPart

    @property
    def label(self) -> str:
        return f"{self.propeller.name} + {self.motor.name} + {self.pack.name}"

    def as_dict(self) -> dict[str, Any]:
        return {"propeller": self.propeller.name, "motor": self.motor.name,
                "pack": self.pack.name}


def chosen(catalogue: Catalogue, settings: BuildSettings, kind: str) -> tuple[Any, ...]:
    """The parts of ``kind`` the build considers: the named ones (KeyError naming an unknown
    name), or all of the kind filtered by the settings (diameter and blades, cells)."""
    names = {"propeller": settings.propellers, "motor": settings.motors,
             "pack": settings.packs}[kind]
    if names != "all":
        return tuple(catalogue.get(n, kind) for n in names)
    if kind == "propeller":
        lo, hi = settings.diameter_in or (0.0, math.inf)
        return tuple(p for p in catalogue.propellers
                     if lo <= p.diameter_m / M_PER_INCH + 1e-9
                     and p.diameter_m / M_PER_INCH - 1e-9 <= hi
                     and (settings.blades is None or p.blades == settings.blades))
    if kind == "pack":
        return tuple(p for p in catalogue.packs
                     if settings.cells is None or p.cells == settings.cells)
    return catalogue.motors


def combinations(catalogue: Catalogue, settings: BuildSettings) -> list[Combination]:
    """Every propeller × motor × pack the settings name, in catalogue order."""
    return [Combination(*c) for c in itertools.product(
        chosen(catalogue, settings, "propeller"), chosen(catalogue, settings, "motor"),
        chosen(catalogue, settings, "pack"))]


def combination_airframe(template: AirframeConfig, combo: Combination,
                         propeller_mass_kg: float) -> AirframeConfig:
    """The template flying ``combo`` (module docstring); ConfigError where the airframe is
    invalid (a propeller that overlaps its neighbours at the template's geometry)."""
    data = template.model_dump(exclude_none=True)
    data["prop_diameter_mm"] = combo.propeller.diameter_m * 1000
    data["propulsion"]["propeller"]["diameter_m"] = combo.propeller.diameter_m
    prop_kg = combo.propeller.mass_kg or propeller_mass_kg
    parts = data.get("components")
    if parts is not None:
        parts["motor_mass_kg"] = combo.motor.mass_kg + prop_kg
        parts["battery_mass_kg"] = combo.pack.mass_kg
    try:
        cfg = airframe_with_parts(AirframeConfig.model_validate(data), combo.propeller,
                                  combo.motor, combo.pack)
    except ValueError as exc:  # pydantic's ValidationError: the airframe's own checks
        errors = getattr(exc, "errors", None)
        first = errors()[0]["msg"] if callable(errors) else str(exc)
        raise ConfigError([f"{combo.label}: {first}"]) from exc
    data = cfg.model_dump(exclude_none=True)
    pack = combo.pack
    data["battery_voltage_v"] = pack.full_voltage_v
    data["propulsion"]["battery"].update(
        open_circuit_voltage_v=pack.full_voltage_v, capacity_ah=pack.capacity_ah,
        c_rating=pack.c_rating, cells=pack.cells,
        ocv_curve=[[s, v] for s, v in zip(pack.ocv_soc, pack.ocv, strict=True)])
    data["propulsion"]["motor"]["max_current_a"] = combo.motor.max_current_a
    return AirframeConfig.model_validate(data)


def box_grid(keys: tuple[str, ...], lower: np.ndarray, upper: np.ndarray, n: int = 2
             ) -> list[dict[str, float]]:
    """θ on an ``n``-point grid per key of the geometry box, its bounds included (``n`` = 2:
    the box's corners)."""
    axes = [np.linspace(lo, hi, n) for lo, hi in zip(lower, upper, strict=True)]
    return [dict(zip(keys, (float(v) for v in point), strict=True))
            for point in itertools.product(*axes)]


def valid_frames(cfg: AirframeConfig, keys: tuple[str, ...], lower: np.ndarray,
                 upper: np.ndarray, n: int = 2) -> list[AirframeConfig]:
    """``cfg`` at each point of the box's :func:`box_grid` (its corners by default) where it is
    a valid airframe (no propeller overlap)."""
    out = []
    for theta in box_grid(keys, lower, upper, n):
        try:
            out.append(with_theta(cfg, theta))
        except ConfigError:
            continue
    return out


def least_mass_kg(frames: list[AirframeConfig]) -> float:
    """The least mass (kg) among ``frames`` (the components mass model grows with the arms:
    its least over the box is at a corner)."""
    return min(build_airframe(f).mass for f in frames)


@dataclass(frozen=True)
class Hover(AsDict):
    """A frame at hover: throttle (command δ), currents, and its full-command thrust-to-weight."""

    throttle: float
    pack_current_a: float
    motor_current_a: float
    thrust_to_weight: float


def hover_of(cfg: AirframeConfig, mass_kg: float | None = None) -> Hover:
    """The hover of ``cfg`` at its own mass, or at ``mass_kg``: each rotor holding a quarter of
    m·g at rest (:func:`casadrone.propulsion.hover_commands`, the DC motor and the pack's sag),
    the motor currents (:func:`casadrone.propulsion.motor_currents`), and the static thrust of
    all four rotors at full command over m·g (:func:`casadrone.propulsion.full_static_thrust`).
    Throttle NaN where the motor cannot hold the thrust."""
    import casadi as ca

    frame = build_airframe(cfg)
    m = frame.mass if mass_kg is None else mass_kg
    weight = m * frame.gravity
    q = airframe_values(frame)
    w, u = hover_commands(q, [weight / 4] * 4)
    _, currents = motor_currents(ca.DM(w), ca.DM(u), cast("PropellerParams", q))
    motor = np.asarray(currents, float).ravel()
    thrust = 4 * full_static_thrust(cfg.propulsion, frame.air_density)
    ok = all(0.0 <= x <= 1.0 for x in u)
    return Hover(float(u[0]) if ok else math.nan, float(np.dot(u, motor)) if ok else math.nan,
                 float(motor.max()) if ok else math.nan, thrust / weight)


def refusal(template: AirframeConfig, combo: Combination, settings: BuildSettings,
            keys: tuple[str, ...], lower: np.ndarray, upper: np.ndarray) -> str:
    """Why no frame of the box can fly ``combo`` ("" when one may), checked in this order and
    without a solve: the propeller overlaps its neighbours at every corner of the box; the
    propeller's tip passes ``max_tip_mach`` at the motor's no-load speed on the full pack; the
    full-command static thrust is below the weight at the box's least mass (thrust-to-weight
    < 1); hovering at the least mass draws more than the pack's C·capacity or the motor's
    largest current."""
    p, m, b = combo.propeller, combo.motor, combo.pack
    try:
        cfg = start_airframe(template, combo, settings, keys, lower, upper)
    except ConfigError as exc:
        if "overlap" not in exc.lines[0]:
            return f"the template cannot take these parts: {exc.lines[0]}"
        cfg = None
    frames = [] if cfg is None else valid_frames(cfg, keys, lower, upper)
    if not frames:
        return (f"propeller diameter {p.diameter_m * 1000:.0f} mm: no frame of the geometry box "
                "keeps the propellers apart")
    tip = m.kv_rpm_per_v * b.full_voltage_v * math.pi * p.diameter_m / 60 / SPEED_OF_SOUND_M_S
    if tip > settings.max_tip_mach:
        return (f"tip Mach {tip:.2f} at the motor's no-load speed ({m.kv_rpm_per_v:.0f} KV x "
                f"{b.full_voltage_v:.1f} V) is above max_tip_mach {settings.max_tip_mach:g}")
    hover = hover_of(frames[0], least_mass_kg(frames))
    if hover.thrust_to_weight < 1:
        return (f"thrust-to-weight {hover.thrust_to_weight:.2f} < 1 at the least mass of the "
                "box: it cannot hover")
    if not math.isfinite(hover.throttle):
        return "the motor cannot hold a hover at the least mass of the box"
    if hover.pack_current_a > b.max_current_a:
        return (f"hover draws {hover.pack_current_a:.1f} A from the pack, above its "
                f"C x capacity {b.max_current_a:.1f} A")
    if hover.motor_current_a > m.max_current_a:
        return (f"hover draws {hover.motor_current_a:.1f} A per motor, above its largest "
                f"{m.max_current_a:.1f} A")
    return ""


def start_airframe(template: AirframeConfig, combo: Combination, settings: BuildSettings,
                   keys: tuple[str, ...], lower: np.ndarray, upper: np.ndarray
                   ) -> AirframeConfig:
    """The combination's airframe at the template's geometry, or, where the propeller overlaps
    there, at the box's largest corner; ConfigError where neither is valid."""
    try:
        return combination_airframe(template, combo, settings.propeller_mass_kg)
    except ConfigError:
        big = dict(zip(keys, (float(x) for x in upper), strict=True))
        return combination_airframe(template.model_copy(update=big), combo,
                                    settings.propeller_mass_kg)
