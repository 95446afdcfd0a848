"""The track YAML (``configs/tracks/``): the route, its gates and the guidance settings flown on it.

The schema lives here, away from the symbolic guidance (:mod:`casadrone.guidance`), so checking a
track imports no CasADi.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field, StrictBool, field_validator, model_validator

from casadrone.config.io import CONFIG_DIR, MAX_MAGNITUDE, Schema, load, resolve_config
from casadrone.propulsion.data import SPEED_OF_SOUND_M_S
from casadrone.targets import TARGET_KINDS, gate_shapes, kind_of_shape

#: The paper's rectangular track (Fig. 7), flown when no track is named.
DEFAULT_TRACK = CONFIG_DIR / "tracks" / "paper-rectangle.yaml"

Vec3 = tuple[float, float, float]
#: Shortest leg between consecutive route points (m): a waypoint on top of the previous one
#: gives a segment with no direction, which the guidance cannot fly.
MIN_LEG_M = 0.01
#: Fastest speed a track may ask for (m/s): Mach 0.3 (0.3 × the speed of sound of the propeller
#: model's bound, 343 m/s), the usual limit of incompressible aerodynamics, on which every drag
#: and propeller model here rests. Racing quadrotors fly below it (SY250's limit lap peaks at
#: 55.6 m/s).
MAX_SPEED_MPS = 0.3 * SPEED_OF_SOUND_M_S


def _speed_over(v: tuple[float, ...] | float) -> bool:
    return float(np.linalg.norm(np.atleast_1d(v))) > MAX_SPEED_MPS


def _centre_or_placeholder(centre: object) -> object:
    """A gate's ``centre_m`` as the waypoint derived from it, or the origin where it is not three
    finite numbers within MAX_MAGNITUDE: the gate's own ``gates.N.centre_m`` error names the
    problem, and a copy would report it a second time under ``waypoints_m``, a key the file
    does not have. The placeholder never survives: with a field error the cross-field checks
    do not run."""
    ok = (isinstance(centre, list | tuple) and len(centre) == 3
          and all(isinstance(c, int | float) and not isinstance(c, bool) and math.isfinite(c)
                  and abs(c) <= MAX_MAGNITUDE for c in centre))
    return centre if ok else [0.0, 0.0, 0.0]


class GateConfig(Schema):
    """A race gate: an opening flown through along its through direction (the gate frame's x
    axis): vertical along ``heading_deg``, or of any orientation by ``rpy_deg``."""

    centre_m: Vec3 = Field(description="centre of the opening (world, m)")
    heading_deg: float | None = Field(None, description="direction of travel through a "
                                      "vertical gate (0 = east, counter-clockwise)")
    rpy_deg: Vec3 | None = Field(None, description="roll, pitch, yaw (ZYX, deg) of the gate "
                                 "frame: x through the gate, y left, z up in the opening; "
                                 "instead of heading_deg ([0, 0, h] is heading h; pitch 90 is "
                                 "a horizontal gate flown downwards)")
    shape: str = Field("rectangle", description="the opening, a gate shape of the target-kind "
                       "registry (casadrone.targets): " + "; ".join(
                           f"{k.shape}: {k.description}" for k in TARGET_KINDS.values()
                           if k.shape is not None),
                       json_schema_extra={"enum": list(gate_shapes())})  # the shipped kinds
    width_m: float = Field(gt=0, description="inner width of the opening (m)")
    height_m: float = Field(gt=0, description="inner height of the opening (m)")
    vertices_m: list[tuple[float, float]] | None = Field(
        None, description="polygon: vertices (left, up; m from the centre, in the gate plane), "
        "counter-clockwise, convex, 3 to 8")

    @field_validator("shape")
    @classmethod
    def _a_registered_shape(cls, shape: str) -> str:
        if shape not in gate_shapes():
            raise ValueError(f"{shape!r} is not a gate shape; known: {', '.join(gate_shapes())}")
        return shape

    @model_validator(mode="after")
    def _one_orientation_and_a_shape(self) -> GateConfig:
        if (self.heading_deg is None) == (self.rpy_deg is None):
            raise ValueError("give heading_deg or rpy_deg (one of them)")
        kind = kind_of_shape(self.shape)  # what the shape asks of the gate: its target kind
        if kind.vertices != (self.vertices_m is not None):
            with_vertices = " or ".join(k.shape for k in TARGET_KINDS.values()
                                        if k.vertices and k.shape is not None)
            raise ValueError(f"vertices_m: give them with shape: {with_vertices} (only)")
        why = kind.check(self)
        if why:
            raise ValueError(why)
        return self

    @property
    def rpy_rad(self) -> tuple[float, float, float]:
        """Roll, pitch, yaw of the gate frame (rad)."""
        if self.rpy_deg is not None:
            r, p, y = self.rpy_deg
        else:  # the validator has made sure of one of the two
            assert self.heading_deg is not None
            r, p, y = 0.0, 0.0, self.heading_deg
        return math.radians(r), math.radians(p), math.radians(y)


class BodyRateLimit(Schema):
    """Largest body rates (rad/s) the limit lap may fly (a rate-mode flight controller's
    configured maximum)."""

    roll_pitch: float = Field(gt=0, description="largest |p| and |q| (rad/s)")
    yaw: float = Field(gt=0, description="largest |r| (rad/s)")


class StartConfig(Schema):
    """The limit lap's start state: at ``start_position_m``, level at ``start_yaw_deg``, rotors
    at hover thrust, moving at ``velocity_mps`` (a flying start; default at rest)."""

    velocity_mps: Vec3 = Field((0.0, 0.0, 0.0), description="world velocity at the start (m/s)")


class TrackConfig(Schema):
    """A race track and the guidance settings flown on it (identical for every airframe)."""

    name: str = Field(description="name of the track, shown in tables and figures")
    start_position_m: Vec3 = Field(
        (0.0, 0.0, 0.0),
        description="take-off position in the world frame, x east, y north, z up (m)",
    )
    start_yaw_deg: float = Field(
        0.0,
        description="heading at take-off (deg, from world x towards y)",
    )
    climb_to_m: Vec3 | None = Field(None, description="route point before the first waypoint")
    climb_speed_mps: float = Field(
        5.0, gt=0, description="speed cap on the climb; the climb brakes to rest at its top"
    )
    waypoints_m: list[Vec3] = Field(
        min_length=1, description="timed waypoints, in order (with gates: the gate centres)")
    gates: list[GateConfig] | None = Field(
        None, description="gates in order, instead of waypoints_m: closed-loop guidance flies "
        "through their centres, the limit lap through their openings")
    straight: list[StrictBool] = Field(
        description="leg ending at each waypoint is a straight sector (true or false)")
    acceptance_radius_m: float = Field(
        1.0, gt=0,
        description="switch to the next segment within this distance of its end (m)",
    )
    look_ahead_m: float = Field(
        3.0, gt=0,
        description="line-of-sight look-ahead distance Δ along the segment (m)",
    )
    speed_mps: float = Field(15.0, gt=0, description="reference speed V on the track")
    corner_speed_mps: float = Field(4.0, ge=0, description="speed V_c to brake to at waypoints")
    brake_mps2: float = Field(6.0, gt=0, description="braking deceleration a_b of the profile")
    max_yaw_error_deg: float = Field(
        45.0, gt=0, le=180,
        description="clamp of the yaw error fed to the LQR-I (deg)",
    )
    max_position_error_m: float = Field(5.0, gt=0, description="clamp of the error fed to LQR")
    max_accel_mps2: float = Field(
        10.0, gt=0, description="rate limit of the velocity reference (reference shaping)"
    )
    time_limit_s: float = Field(60.0, gt=0, le=3600, description="lap time limit (s); the "
                                "compiled lap allocates every controller step up to it")
    max_tilt_deg: float = Field(
        80.0, gt=0, lt=90, description="attitude limit: the closed loop fails a lap whose roll "
        "or pitch (each axis, ZYX Euler) exceeds it; the limit lap bounds each axis, the total "
        "tilt (a cone) or nothing (LimitLapOptions.tilt_limit)")
    # Constraints of the limit lap only (the closed loop flies one lap through the acceptance
    # radius); they state what the field's time-optimal planners state.
    tolerance_m: float | list[float] | None = Field(
        None, description="limit lap: radius (m) of each waypoint's ball, one for all or one "
        "per waypoint; None: acceptance_radius_m")
    max_body_rate_rad_s: BodyRateLimit | None = Field(
        None, description="limit lap: largest body rates (rad/s); None: unlimited")
    floor_m: float | None = Field(None, description="limit lap: lowest altitude (m); None: "
                                  "0.1 m below the start or the ground")
    ceiling_m: float | None = Field(None, description="limit lap: highest altitude (m)")
    laps: int = Field(1, ge=1, le=20, description="limit lap: laps through the waypoints, the "
                      "time of each reported")
    end: Literal["free", "rest", "velocity", "periodic"] = Field(
        "free", description="limit lap: state at the last waypoint (any speed, at rest, "
        "end_velocity_mps, or periodic: the end state equals the start state, which is then "
        "optimised; position too where the start is the last waypoint)")
    end_velocity_mps: Vec3 = Field((0.0, 0.0, 0.0), description="limit lap: world velocity "
                                   "(m/s) at the end with end: velocity")
    start: StartConfig = Field(default_factory=StartConfig, description="limit lap: start state")

    @model_validator(mode="before")
    @classmethod
    def _gate_centres(cls, data: Any) -> Any:
        """With ``gates:`` and no ``waypoints_m``, the waypoints are the gate centres; an empty
        ``gates:`` list is named as such (not as missing waypoints)."""
        if isinstance(data, dict) and data.get("gates") == [] and "waypoints_m" not in data:
            raise ValueError("gates: give at least one gate (or waypoints_m instead of gates)")
        if isinstance(data, dict) and data.get("gates") and "waypoints_m" not in data:
            gates = data["gates"]
            if isinstance(gates, list) and all(isinstance(g, dict) for g in gates):
                return {**data, "waypoints_m": [_centre_or_placeholder(g.get("centre_m"))
                                                for g in gates]}
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
        if isinstance(self.tolerance_m, list) and len(self.tolerance_m) != len(self.waypoints_m):
            raise ValueError(f"tolerance_m: needs one entry per waypoint ({len(self.waypoints_m)})"
                             f", got {len(self.tolerance_m)}")
        if self.tolerance_m is not None and min(np.atleast_1d(self.tolerance_m)) <= 0:
            raise ValueError("tolerance_m: a radius must be positive (as acceptance_radius_m)")
        if self.tolerance_m is not None and self.gates is not None:
            raise ValueError("tolerance_m: the limit lap flies through the gates' openings; "
                             "a waypoint radius has nothing to apply to on a gate track")
        if self.end != "velocity" and any(self.end_velocity_mps):
            raise ValueError(f"end_velocity_mps: applies with end: velocity only (end is "
                             f"{self.end!r})")
        for key, v in (("start.velocity_mps", self.start.velocity_mps),
                       ("end_velocity_mps", self.end_velocity_mps),
                       ("speed_mps", self.speed_mps), ("corner_speed_mps", self.corner_speed_mps),
                       ("climb_speed_mps", self.climb_speed_mps)):
            if _speed_over(v):
                raise ValueError(f"{key}: {float(np.linalg.norm(np.atleast_1d(v))):.4g} m/s is "
                                 f"beyond {MAX_SPEED_MPS:.4g} m/s (Mach 0.3: the models' "
                                 "incompressible aerodynamics)")
        if self.floor_m is not None and self.ceiling_m is not None \
                and self.ceiling_m <= self.floor_m:
            raise ValueError(f"ceiling_m: {self.ceiling_m:g} m is not above floor_m "
                             f"{self.floor_m:g} m")
        if self.floor_m is not None and self.start_position_m[2] < self.floor_m:
            raise ValueError(f"floor_m: the start ({self.start_position_m[2]:g} m) is below "
                             f"the floor ({self.floor_m:g} m)")
        if self.ceiling_m is not None and self.start_position_m[2] > self.ceiling_m:
            raise ValueError(f"ceiling_m: the start ({self.start_position_m[2]:g} m) is above "
                             f"the ceiling ({self.ceiling_m:g} m)")
        self._targets_between_floor_and_ceiling()
        if self.end == "periodic" and any(self.start.velocity_mps):
            raise ValueError("start: a periodic lap (end: periodic) optimises its start state; "
                             "give no start.velocity_mps")
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

    def _targets_between_floor_and_ceiling(self) -> None:
        """A target wholly above the ceiling or below the floor cannot be reached
        (:func:`unreachable_target`)."""
        why = unreachable_target(self, self.floor_m, self.ceiling_m)
        if why:
            raise ValueError(why)

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


def unreachable_target(track: TrackConfig, floor_m: float | None, ceiling_m: float | None,
                       floor_note: str = "") -> str:
    """Why a target of ``track`` cannot be reached between ``floor_m`` and ``ceiling_m`` (empty
    when every one can): a waypoint's ball (tolerance_m, or acceptance_radius_m), a gate's
    opening (any orientation: its half-diagonal about the centre), and the climb point, which
    the limit lap passes as a ball of acceptance_radius_m (casadrone.limit.problem.
    track_targets): above the ceiling it was not refused and the lap failed in IPOPT's
    restoration instead. The message names the key; ``floor_note`` says where a floor that the
    track does not give comes from."""
    if floor_m is None and ceiling_m is None:
        return ""
    if track.gates is not None:
        reach = [math.hypot(g.width_m, g.height_m) / 2 for g in track.gates]
        what = "gate"
    else:
        tol = track.acceptance_radius_m if track.tolerance_m is None else track.tolerance_m
        reach = list(np.broadcast_to(np.asarray(tol, float), (len(track.waypoints_m),)))
        what = "waypoint"
    targets = [(f"{what} {j + 1}", w, r)
               for j, (w, r) in enumerate(zip(track.waypoints_m, reach, strict=True))]
    if track.climb_to_m is not None:
        targets.insert(0, ("the climb point climb_to_m", track.climb_to_m,
                           track.acceptance_radius_m))
    for name, w, r in targets:
        if ceiling_m is not None and w[2] - r > ceiling_m:
            return (f"ceiling_m: {name} (z {w[2]:g} m, reach {r:g} m) lies wholly above the "
                    f"ceiling ({ceiling_m:g} m)")
        if floor_m is not None and w[2] + r < floor_m:
            return (f"floor_m: {name} (z {w[2]:g} m, reach {r:g} m) lies wholly below the "
                    f"floor ({floor_m:g} m{floor_note})")
    return ""


def load_track(path: str | Path | None = None, overrides: list[str] | None = None) -> TrackConfig:
    """Load a track YAML or a shipped track's name; ``None`` gives the paper's rectangle."""
    return load(TrackConfig, resolve_config(path, "tracks") if path else DEFAULT_TRACK, overrides)
