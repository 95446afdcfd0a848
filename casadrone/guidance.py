"""Race track and line-of-sight guidance, written symbolically so it compiles into the closed loop.

The route is the start point, an optional climb point, then the timed waypoints. Segment k runs
from route point k to k + 1. On the active segment (Breivik & Fossen style line of sight):

- along-track coordinate s and cross-track error e (the position error the LQR-I sees is the
  offset from the closest point of the segment, so only cross-track and height errors count);
- a look-ahead point Δ ahead of the projection (clamped at the segment end); the velocity
  reference points from the vehicle at it, with magnitude min(V, √(V_c² + 2 a_b d_end)) so the
  vehicle brakes to the corner speed V_c before each waypoint (the climb: capped at the climb
  speed, braking to rest at its top, so the race starts from a hover at altitude);
- the segment switches when the vehicle is inside the acceptance radius of the segment end or
  has passed it (s ≥ L);
- the nose points at the next waypoint: ψ_ref is the heading of the active segment (of the next
  horizontal one for a vertical climb).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np
from pydantic import Field, model_validator

from casadrone.configio import Schema

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


def segment_headings(route: np.ndarray, start_yaw: float) -> np.ndarray:
    """Heading (rad) of each segment; a vertical segment takes the next horizontal heading."""
    d = np.diff(route, axis=0)
    heads = np.arctan2(d[:, 1], d[:, 0])
    horizontal = np.hypot(d[:, 0], d[:, 1]) > 1e-6
    nxt = start_yaw
    for k in range(len(d) - 1, -1, -1):
        if horizontal[k]:
            nxt = heads[k]
        else:
            heads[k] = nxt
    # unwrap so consecutive headings differ by less than π (yaw error is wrapped anyway)
    return np.unwrap(heads)


@dataclass(frozen=True)
class GuidanceLayout:
    """Packing of the track into the guidance parameter vector."""

    n_route: int

    @property
    def n_seg(self) -> int:
        return self.n_route - 1

    @property
    def size(self) -> int:
        return 3 * self.n_route + 3 * self.n_seg + 6


_VECTORS: dict[int, tuple[TrackConfig, np.ndarray]] = {}


def track_vector(track: TrackConfig) -> np.ndarray:
    """Numeric guidance parameter vector of a track (layout :class:`GuidanceLayout`), read-only;
    computed once per track object (a study flies every candidate on the same one)."""
    hit = _VECTORS.get(id(track))
    if hit is not None and hit[0] is track:
        return hit[1]
    vector = _track_vector(track)
    vector.flags.writeable = False
    if len(_VECTORS) > 64:
        _VECTORS.clear()
    _VECTORS[id(track)] = (track, vector)  # holds the track: its id is not reused meanwhile
    return vector


def _track_vector(track: TrackConfig) -> np.ndarray:
    route = track.route
    heads = segment_headings(route, math.radians(track.start_yaw_deg))
    n_seg = len(route) - 1
    caps = np.full(n_seg, track.speed_mps)
    ends = np.full(n_seg, track.corner_speed_mps)
    if track.climb_to_m is not None:  # climb gently and stop at the top before racing
        caps[0], ends[0] = min(track.climb_speed_mps, track.speed_mps), 0.0
    return np.concatenate(
        [
            route.ravel(),
            heads,
            caps,
            ends,
            [
                track.acceptance_radius_m,
                track.look_ahead_m,
                track.brake_mps2,
                math.radians(track.max_yaw_error_deg),
                track.max_position_error_m,
                track.max_accel_mps2,
            ],
        ]
    )


def wrap(angle):
    """Wrap an angle to (−π, π] (symbolic)."""
    return ca.atan2(ca.sin(angle), ca.cos(angle))


def guidance(pos, seg, g, layout: GuidanceLayout):
    """Symbolic line-of-sight guidance.

    Args:
        pos: position (3, world, m). seg: active segment index (float, 0 … n_seg; n_seg = done).
        g: guidance parameter vector (``track_vector``). layout: its packing.

    Returns:
        (p_ref, v_ref, psi_ref, seg_next): closest point on the active segment (m), world
        velocity reference (m/s), yaw reference (rad), segment index after switching.
    """
    n, ns = layout.n_route, layout.n_seg
    route = ca.reshape(g[: 3 * n], 3, n)
    heads = g[3 * n : 3 * n + ns]
    caps = g[3 * n + ns : 3 * n + 2 * ns]
    ends = g[3 * n + 2 * ns : 3 * n + 3 * ns]
    r_acc, look, brake = (g[3 * n + 3 * ns + i] for i in range(3))

    def active(seg_index):
        """Start, end, heading, speed cap and end speed of segment ``seg_index`` (the last one
        once done)."""
        a, b, h = route[:, ns - 1], route[:, ns], heads[ns - 1]
        cap, end = caps[ns - 1], ends[ns - 1]
        for k in range(ns - 1, -1, -1):
            sel = seg_index <= k + 0.5
            a = ca.if_else(sel, route[:, k], a)
            b = ca.if_else(sel, route[:, k + 1], b)
            h = ca.if_else(sel, heads[k], h)
            cap = ca.if_else(sel, caps[k], cap)
            end = ca.if_else(sel, ends[k], end)
        return a, b, h, cap, end

    # switching on the segment that was active
    a, b, _, _, _ = active(seg)
    t_vec = b - a
    length = ca.norm_2(t_vec)
    s = ca.dot(pos - a, t_vec) / length
    switch = ca.logic_and(
        seg < ns - 0.5, ca.logic_or(ca.norm_2(pos - b) < r_acc, s >= length)
    )
    seg_next = seg + ca.if_else(switch, 1, 0)
    done = seg_next > ns - 0.5

    a, b, psi_ref, speed, v_corner = active(seg_next)
    t_vec = b - a
    length = ca.norm_2(t_vec)
    t_hat = t_vec / length
    s = ca.fmin(ca.fmax(ca.dot(pos - a, t_hat), 0), length)
    p_closest = a + s * t_hat
    p_look = a + ca.fmin(s + look, length) * t_hat
    los = p_look - pos
    d_end = length - s
    v_mag = ca.fmin(speed, ca.sqrt(v_corner**2 + 2 * brake * d_end))
    v_ref = v_mag * los / ca.fmax(ca.norm_2(los), 1e-6)
    p_ref = ca.if_else(done, b, p_closest)
    v_ref = ca.if_else(done, ca.DM.zeros(3), v_ref)
    return p_ref, v_ref, psi_ref, seg_next
