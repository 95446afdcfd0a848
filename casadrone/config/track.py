"""The track YAML (``configs/tracks/``): the route, its gates and the guidance settings flown on it.

The schema lives here, away from the symbolic guidance (:mod:`casadrone.guidance`), so checking a
track imports no CasADi.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import Field, model_validator

from casadrone.config.io import CONFIG_DIR, Schema, load, resolve_config

#: The paper's rectangular track (Fig. 7), flown when no track is named.
DEFAULT_TRACK = CONFIG_DIR / "tracks" / "paper-rectangle.yaml"

Vec3 = tuple[float, float, float]
#: Shortest leg between consecutive route points (m): a waypoint on top of the previous one
#: gives a segment with no direction, which the guidance cannot fly.
MIN_LEG_M = 0.01


class GateConfig(Schema):
    """A race gate: a vertical rectangular opening, flown through along its heading."""

    centre_m: Vec3 = Field(description="centre of the opening (world, m)")
    heading_deg: float = Field(description="direction of travel through the gate (0 = east, "
                               "counter-clockwise)")
    width_m: float = Field(gt=0, description="inner width of the opening (m)")
    height_m: float = Field(gt=0, description="inner height of the opening (m)")


class TrackConfig(Schema):
    """A race track and the guidance settings flown on it (identical for every airframe)."""

    name: str
    start_position_m: Vec3 = (0.0, 0.0, 0.0)
    start_yaw_deg: float = 0.0
    climb_to_m: Vec3 | None = Field(None, description="route point before the first waypoint")
    climb_speed_mps: float = Field(
        5.0, gt=0, description="speed cap on the climb; the climb brakes to rest at its top"
    )
    waypoints_m: list[Vec3] = Field(
        min_length=1, description="timed waypoints, in order (with gates: the gate centres)")
    gates: list[GateConfig] | None = Field(
        None, description="gates in order, instead of waypoints_m: closed-loop guidance flies "
        "through their centres, the limit lap through their openings")
    straight: list[bool] = Field(description="leg ending at each waypoint is a straight sector")
    acceptance_radius_m: float = Field(1.0, gt=0)
    look_ahead_m: float = Field(3.0, gt=0)
    speed_mps: float = Field(15.0, gt=0, description="reference speed V on the track")
    corner_speed_mps: float = Field(4.0, ge=0, description="speed V_c to brake to at waypoints")
    brake_mps2: float = Field(6.0, gt=0, description="braking deceleration a_b of the profile")
    max_yaw_error_deg: float = Field(45.0, gt=0, le=180)
    max_position_error_m: float = Field(5.0, gt=0, description="clamp of the error fed to LQR")
    max_accel_mps2: float = Field(
        10.0, gt=0, description="rate limit of the velocity reference (reference shaping)"
    )
    time_limit_s: float = Field(60.0, gt=0, le=3600, description="lap time limit (s); the "
                                "compiled lap allocates every controller step up to it")
    max_tilt_deg: float = Field(80.0, gt=0, lt=90, description="attitude limit → failed lap")

    @model_validator(mode="before")
    @classmethod
    def _gate_centres(cls, data):
        """With ``gates:`` and no ``waypoints_m``, the waypoints are the gate centres."""
        if isinstance(data, dict) and data.get("gates") and "waypoints_m" not in data:
            gates = data["gates"]
            if isinstance(gates, list) and all(isinstance(g, dict) for g in gates):
                return {**data, "waypoints_m": [g.get("centre_m") for g in gates]}
        return data

    @model_validator(mode="after")
    def _consistent(self) -> TrackConfig:
        if self.gates is not None:
            if not self.gates:
                raise ValueError("gates: give at least one gate")
            if [tuple(g.centre_m) for g in self.gates] != [tuple(w) for w in self.waypoints_m]:
                raise ValueError("give gates or waypoints_m, not both")
        if len(self.straight) != len(self.waypoints_m):
            raise ValueError("straight: needs one entry per waypoint (or gate)")
        route = self.route
        legs = np.linalg.norm(np.diff(route, axis=0), axis=1)
        if np.any(legs < MIN_LEG_M):
            k = int(np.argmin(legs))
            name = "the climb point" if self.climb_to_m is not None and k == 0 else \
                f"waypoint {k - self.first_timed_segment + 1}"
            raise ValueError(f"waypoints_m: {name} is {legs[k]:.3g} m from the route point "
                             f"before it (a leg needs at least {MIN_LEG_M} m; a zero-length leg "
                             "has no direction to fly)")
        return self

    @property
    def route(self) -> np.ndarray:
        """Route points (n × 3, m): start, climb point (if any), waypoints."""
        pts = [self.start_position_m]
        if self.climb_to_m is not None:
            pts.append(self.climb_to_m)
        return np.array(pts + list(self.waypoints_m), dtype=float)

    @property
    def first_timed_segment(self) -> int:
        """Index of the segment that ends at the first waypoint."""
        return 0 if self.climb_to_m is None else 1


def load_track(path: str | Path | None = None, overrides: list[str] | None = None) -> TrackConfig:
    """Load a track YAML or a shipped track's name; ``None`` gives the paper's rectangle."""
    return load(TrackConfig, resolve_config(path, "tracks") if path else DEFAULT_TRACK, overrides)
