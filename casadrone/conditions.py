"""The trim conditions: the kinds of steady flight casadrone trims, one registry (light: no
solver is imported, so the command line reads its choices from here).

Each condition is a value of the operating-point vector (V, γ, Ω): speed along the flight path
(m/s), climb angle of the path above the horizon (rad; negative: descent) and turn rate of the
heading about world z (rad/s; positive: left, counter-clockwise seen from above). Hover is
V = 0; :mod:`casadrone.trim` builds the state of a trim from it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from casadrone.config.track import MAX_SPEED_MPS  # the tracks' limit (Mach 0.3)

#: Fastest turn trimmed (deg/s): Betaflight's largest configurable rate (rate-mode "max rate",
#: about 2000 deg/s); a racing quadrotor's heading turns no faster.
MAX_TURN_RATE_DPS = 2000.0


@dataclass(frozen=True)
class TrimCondition:
    """A kind of steady flight: what it means and which operating-point parameters it takes
    (keyword names of :func:`trim`; the others must stay 0)."""

    name: str
    summary: str
    parameters: tuple[str, ...]


#: The trim conditions, by name: the one list every consumer (CLI, study, report) reads.
CONDITION_REGISTRY: dict[str, TrimCondition] = {c.name: c for c in (
    TrimCondition("hover", "at rest in still air", ()),
    TrimCondition("forward", "level flight along world +x at speed_mps", ("speed_mps",)),
    TrimCondition("climb", "straight flight at speed_mps along a path climb_angle_deg above "
                  "the horizon (negative: descent)", ("speed_mps", "climb_angle_deg")),
    TrimCondition("turn", "coordinated level turn at speed_mps, heading turning at "
                  "turn_rate_dps (positive: left), nose along the velocity",
                  ("speed_mps", "turn_rate_dps")),
)}
CONDITIONS: tuple[str, ...] = tuple(CONDITION_REGISTRY)
_OP_PARAMETERS = ("speed_mps", "climb_angle_deg", "turn_rate_dps")


def operating_vector(
    condition: str, speed_mps: float = 0.0, climb_angle_deg: float = 0.0,
    turn_rate_dps: float = 0.0,
) -> np.ndarray:
    """(V m/s, γ rad, Ω rad/s) of a condition; ValueError naming the parameter when a value is
    not finite, belongs to another condition, or is out of range (|γ| ≤ 90°, V ≥ 0 outside
    ``forward``, |V| within the tracks' Mach 0.3 (:data:`casadrone.config.track.MAX_SPEED_MPS`),
    |Ω| ≤ :data:`MAX_TURN_RATE_DPS`)."""
    if condition not in CONDITION_REGISTRY:
        raise ValueError(f"unknown condition '{condition}'; choose one of {', '.join(CONDITIONS)}")
    values = dict(zip(_OP_PARAMETERS, (speed_mps, climb_angle_deg, turn_rate_dps), strict=True))
    for key, value in values.items():
        if not math.isfinite(value):
            raise ValueError(f"{key} must be finite")
        if value != 0 and key not in CONDITION_REGISTRY[condition].parameters:
            hint = " (use condition='forward')" if condition == "hover" else ""
            raise ValueError(f"{condition}: {key} must be 0{hint}")
    if abs(climb_angle_deg) > 90:
        raise ValueError(f"climb_angle_deg must lie in [-90, 90] (got {climb_angle_deg:g})")
    if speed_mps < 0 and condition != "forward":
        raise ValueError(f"{condition}: speed_mps must be >= 0 (got {speed_mps:g})")
    if abs(speed_mps) > MAX_SPEED_MPS:
        raise ValueError(f"speed_mps: {speed_mps:g} m/s is beyond {MAX_SPEED_MPS:.4g} m/s (Mach "
                         "0.3, the tracks' limit: the models' incompressible aerodynamics)")
    if abs(turn_rate_dps) > MAX_TURN_RATE_DPS:
        raise ValueError(f"turn_rate_dps: {turn_rate_dps:g} deg/s is beyond "
                         f"{MAX_TURN_RATE_DPS:g} deg/s (the fastest rate a racing flight "
                         "controller is set to)")
    return np.array([float(speed_mps), math.radians(climb_angle_deg), math.radians(turn_rate_dps)])


@dataclass(frozen=True)
class OperatingPoint:
    """One operating point: a condition of :data:`CONDITION_REGISTRY` and its parameters (speed
    along the path in m/s, climb angle in deg, turn rate in deg/s; those the condition does not
    take stay 0). Validated when made: ValueError naming the parameter."""

    condition: str
    speed_mps: float = 0.0
    climb_angle_deg: float = 0.0
    turn_rate_dps: float = 0.0

    def __post_init__(self) -> None:
        operating_vector(self.condition, self.speed_mps, self.climb_angle_deg, self.turn_rate_dps)

    @property
    def kwargs(self) -> dict[str, float]:
        """The keyword arguments of :func:`casadrone.trim.trim` after the condition."""
        return {key: float(getattr(self, key)) for key in _OP_PARAMETERS}

    @property
    def label(self) -> str:
        """Short name: ``hover``, ``forward 10 m/s``, ``climb 10 m/s +30°``, ``turn 10 m/s 60°/s``
        (speed, climb angle, turn rate)."""
        text = self.condition
        if "speed_mps" in CONDITION_REGISTRY[self.condition].parameters:
            text += f" {self.speed_mps:g} m/s"
        if self.condition == "climb":
            text += f" {self.climb_angle_deg:+g}°"
        if self.condition == "turn":
            text += f" {self.turn_rate_dps:g}°/s"
        return text

    def as_dict(self) -> dict[str, float | str]:
        return {"condition": self.condition, "label": self.label, **self.kwargs}


#: The points each condition contributes to an envelope when named without values: level flight
#: every 5 m/s to 40 m/s (fast racing), a climb and a descent at 10 m/s and ±30°, and left turns
#: at 60°/s (10 m/s) and 30°/s (20 m/s), each a drag-free bank of 47° (tan φ = V Ω / g).
DEFAULT_POINTS: dict[str, tuple[OperatingPoint, ...]] = {
    "hover": (OperatingPoint("hover"),),
    "forward": tuple(OperatingPoint("forward", float(v)) for v in range(5, 45, 5)),
    "climb": (OperatingPoint("climb", 10.0, 30.0), OperatingPoint("climb", 10.0, -30.0)),
    "turn": (OperatingPoint("turn", 10.0, turn_rate_dps=60.0),
             OperatingPoint("turn", 20.0, turn_rate_dps=30.0)),
}


def envelope(spec: str = "hover,forward,climb,turn") -> tuple[OperatingPoint, ...]:
    """The operating points of a comma-separated ``spec``: a condition's name alone gives its
    :data:`DEFAULT_POINTS`; ``forward:20`` one speed; ``forward:0..40/5`` speeds from 0 to 40 m/s
    every 5; ``climb:10:-30`` a speed and climb angle; ``turn:10:60`` a speed and turn rate.
    ValueError with the offending item on anything else."""
    points: list[OperatingPoint] = []
    for item in (s.strip() for s in spec.split(",")):
        name, *values = item.split(":")
        if name not in CONDITION_REGISTRY:
            raise ValueError(f"'{item}': unknown condition '{name}'; choose one of "
                             f"{', '.join(CONDITIONS)}")
        if not values:
            points += DEFAULT_POINTS[name]
            continue
        wanted = CONDITION_REGISTRY[name].parameters
        if len(values) != len(wanted):
            raise ValueError(f"'{item}': {name} takes {len(wanted)} value(s) "
                             f"({', '.join(wanted) or 'none'})")
        try:
            speeds, rest = _speeds(values[0]), [float(v) for v in values[1:]]
            points += [OperatingPoint(name, **dict(zip(wanted, [v, *rest], strict=True)))
                       for v in speeds]
        except ValueError as exc:
            raise ValueError(f"'{item}': {exc}") from None
    return tuple(dict.fromkeys(points))  # in order, each point once


def _speeds(text: str) -> list[float]:
    """``20`` → [20]; ``0..40/5`` → [0, 5, …, 40] (m/s)."""
    if ".." not in text:
        return [float(text)]
    lo, _, rest = text.partition("..")
    hi, _, step = rest.partition("/")
    a, b, d = float(lo), float(hi), float(step or 5)
    if not (d > 0 and b >= a and (b - a) / d <= 1000):
        raise ValueError(f"speed range {text}: want LO..HI/STEP with HI >= LO, STEP > 0")
    return [a + k * d for k in range(int(math.floor((b - a) / d + 1e-9)) + 1)]
