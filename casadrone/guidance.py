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

from casadrone.config.track import TrackConfig


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
