"""Targets of the limit lap: waypoint balls and gates of any orientation and shape.

Every leg ends in a target, packed into ``TARGET_SIZE`` numbers of the NLP parameter P:

=========  ==================================================================================
0:3        centre c (world, m)
3:6        n, the gate's through direction (unit; the gate frame's x axis)
6:9        a, the opening's left axis (gate frame y)
9:12       b, the opening's up axis (gate frame z)
12, 13     half width, half height of a rectangle (m; a circle's radius in 12), already shrunk
           by the clearance
14         a ball's radius (m)
15:39      polygon edges: MAX_EDGES rows (e_a, e_b, offset): inside where
           e · (a·d, b·d) ≤ offset for every edge (unit e; unused rows 0, 0, 1)
=========  ==================================================================================

A gate is passed at the leg's end node: on its plane (n · d = 0, d = x − c), inside the shrunk
opening, crossing forwards (n · v ≥ 0). The gate frame is R(roll, pitch, yaw) of the track's
``rpy_deg`` (ZYX, :func:`casadrone.model.rotation_matrix`): yaw alone is a vertical gate
flown along that heading, as ``heading_deg``. The clearance is a sphere around the vehicle's
centre: the opening shrinks by it on every side.
"""

from __future__ import annotations

import math
from typing import Literal

import casadi as ca
import numpy as np

TargetKind = Literal["ball", "gate", "circle", "polygon"]
MAX_EDGES = 8
TARGET_SIZE = 15 + 3 * MAX_EDGES


def gate_frame(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Columns n (through), a (left), b (up) of the gate frame at ZYX angles (rad)."""
    from casadrone.limit.attitude import euler_rotation_np

    return euler_rotation_np(roll, pitch, yaw)


def polygon_edges(vertices: np.ndarray, clearance: float) -> np.ndarray:
    """(MAX_EDGES, 3) rows (e_a, e_b, offset) of a convex polygon given counter-clockwise in
    the gate plane (left, up; m), each edge moved inwards by ``clearance`` (m)."""
    v = np.asarray(vertices, float)
    out = np.tile([0.0, 0.0, 1.0], (MAX_EDGES, 1))
    for j in range(len(v)):
        p, q = v[j], v[(j + 1) % len(v)]
        t = (q - p) / np.linalg.norm(q - p)
        e = np.array([t[1], -t[0]])  # outward normal of a counter-clockwise edge
        out[j] = [e[0], e[1], float(e @ p) - clearance]
    return out


def target_vector(centres: np.ndarray, kinds: tuple[str, ...], headings: np.ndarray,
                  half_widths: np.ndarray, half_heights: np.ndarray,
                  radius: float | np.ndarray, frames: np.ndarray | None = None,
                  edges: np.ndarray | None = None) -> np.ndarray:
    """The ``targets`` part of P for legs ending at ``centres`` (L × 3, m): gate frames from
    ``frames`` (L × 3 × 3, columns n, a, b) or from ``headings`` (rad, vertical gates);
    ``radius``: the balls' radius (m), one for all or one per leg; ``edges``: the polygons'
    (L × MAX_EDGES × 3, :func:`polygon_edges`)."""
    L = len(kinds)
    out = np.zeros((L, TARGET_SIZE))
    radii = np.broadcast_to(np.asarray(radius, float), (L,))
    for k in range(L):
        F = frames[k] if frames is not None else gate_frame(0.0, 0.0, float(headings[k]))
        out[k, 0:3] = centres[k]
        out[k, 3:12] = np.asarray(F).T.ravel()  # n, a, b
        out[k, 12:14] = half_widths[k], half_heights[k]
        out[k, 14] = radii[k]
        out[k, 15:] = (edges[k] if edges is not None
                       else np.tile([0.0, 0.0, 1.0], (MAX_EDGES, 1))).ravel()
    return out.ravel()


def _split(tp):
    return tp[0:3], tp[3:6], tp[6:9], tp[9:12], tp[12], tp[13], tp[14], tp[15:]


def target_rows(x, vw, tp, kind: str) -> list:
    """Constraint rows (expression, lower, upper) of passing target ``tp`` at node state x with
    world velocity vw (symbolic)."""
    c, n, a, b, hw, hh, r, e = _split(tp)
    d = x[0:3] - c
    if kind == "ball":
        return [(ca.sumsqr(d) - r**2, -np.inf, 0.0)]
    lat, up = ca.dot(a, d), ca.dot(b, d)
    rows = [(ca.dot(n, d), 0.0, 0.0)]
    if kind == "gate":
        rows += [(lat - hw, -np.inf, 0.0), (-lat - hw, -np.inf, 0.0),
                 (up - hh, -np.inf, 0.0), (-up - hh, -np.inf, 0.0)]
    elif kind == "circle":
        rows.append((lat**2 + up**2 - hw**2, -np.inf, 0.0))
    elif kind == "polygon":
        rows += [(e[3 * j] * lat + e[3 * j + 1] * up - e[3 * j + 2], -np.inf, 0.0)
                 for j in range(MAX_EDGES)]
    else:
        raise ValueError(f"unknown target kind {kind!r}")
    rows.append((ca.dot(n, vw), 0.0, np.inf))  # crossing forwards
    return rows


def target_miss(pos: np.ndarray, tp: np.ndarray, kind: str) -> float:
    """Distance (m) from ``pos`` to a target: outside the ball, or off the gate's opening (off
    its plane, and beyond the shrunk opening; for a polygon the largest edge violation, which
    is the distance wherever one edge is violated)."""
    c, n, a, b, hw, hh, r, e = _split(np.asarray(tp, float))
    d = np.asarray(pos, float) - c
    if kind == "ball":
        return max(0.0, float(np.linalg.norm(d)) - r)
    along, lat, up = float(n @ d), float(a @ d), float(b @ d)
    if kind == "gate":
        off = [max(0.0, abs(lat) - hw), max(0.0, abs(up) - hh)]
    elif kind == "circle":
        off = [max(0.0, math.hypot(lat, up) - hw)]
    else:
        E = e.reshape(MAX_EDGES, 3)
        off = [max(0.0, float(np.max(E[:, 0] * lat + E[:, 1] * up - E[:, 2])))]
    return float(np.linalg.norm([along, *off]))
