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
    ``forward``)."""
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
    return np.array([float(speed_mps), math.radians(climb_angle_deg), math.radians(turn_rate_dps)])
