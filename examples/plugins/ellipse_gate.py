"""A new target kind for the limit lap, registered when this module is imported: an elliptic gate
opening (docs/architecture.md#new-target-kind).

A track then says ``shape: ellipse`` for a gate whose opening is an ellipse of axes ``width_m``
(left-right) by ``height_m`` (up-down); the limit lap flies through it, the re-simulation check
measures its miss and the figures draw it. Import this module before the track is read.
"""

import math

import numpy as np

from casadrone.targets import (
    TARGET_KINDS,
    Packed,
    TargetKind,
    in_gate_plane,
    off_opening,
    register_target_kind,
    through_opening,
)


def inside_ellipse(t, lat, up):
    """NLP row (symbolic): inside the ellipse of semi-axes hw (left) and hh (up)."""
    return [((lat / t.hw) ** 2 + (up / t.hh) ** 2 - 1.0, -np.inf, 0.0)]


def beyond_ellipse(t, lat, up):
    """Distance (m) beyond the opening in the gate plane, measured along the ray from the centre:
    0 inside, and never less than the true distance outside (the ray meets the ellipse at a point
    of the boundary), so the re-simulation check is never lenient."""
    rho = math.hypot(lat / t.hw, up / t.hh)  # 1 on the boundary
    return [math.hypot(lat, up) * (1.0 - 1.0 / rho) if rho > 1.0 else 0.0]


def shrunk(gate, clearance_m):
    """The opening shrunk for a vehicle of radius ``clearance_m``: both semi-axes scaled by
    1 − c / (the smaller one). The ellipse E contains a disc of radius min(a, b), so the scaled
    ellipse plus a ball of radius c stays inside E (exact for a circle, conservative otherwise;
    subtracting c from each semi-axis would not be safe)."""
    a, b = gate.width_m / 2, gate.height_m / 2
    scale = 1.0 - clearance_m / min(a, b)
    return Packed(scale * a, scale * b)


def boundary(t):
    """The ellipse (left, up; m), for the figures."""
    s = np.linspace(0.0, 2 * math.pi, 49)
    return np.column_stack([t.hw * np.cos(s), t.hh * np.sin(s)])


ELLIPSE = TargetKind(
    "ellipse", "an elliptic opening, axes width_m (left-right) by height_m (up-down)",
    rows=through_opening(inside_ellipse), miss=off_opening(beyond_ellipse),
    outline=in_gate_plane(boundary), shape="ellipse", pack=shrunk)

if ELLIPSE.name not in TARGET_KINDS:
    register_target_kind(ELLIPSE)
