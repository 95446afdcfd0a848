"""Target kinds of the limit lap: what it means for a leg to end at a waypoint's ball or through a
gate's opening (docs/architecture.md#new-target-kind).

One registry, :data:`TARGET_KINDS` (name → :class:`TargetKind`), holds everything a kind means,
and everything else reads it: the track schema's gate ``shape`` choices
(:class:`casadrone.config.track.GateConfig`), the packing of a track's gates into the NLP's
parameter (:func:`casadrone.limit.problem.track_targets`) and the refusal of a gate narrower
than the clearance (:func:`casadrone.limit.problem.check_inputs`), the NLP's constraint rows at a
leg's end node (:func:`target_rows`, :mod:`casadrone.limit.nlp`), the re-simulation check's miss
distance (:func:`target_miss`, :mod:`casadrone.limit.check`) and the outlines the figures draw
(:func:`target_outline`, :mod:`casadrone.plots`).

Every target is ``TARGET_SIZE`` numbers of the NLP parameter P (one layout for every kind, so
the kinds of a track's legs are the only thing the NLP's structure depends on):

=========  ==================================================================================
0:3        centre c (world, m)
3:6        n, the gate's through direction (unit; the gate frame's x axis)
6:9        a, the opening's left axis (gate frame y)
9:12       b, the opening's up axis (gate frame z)
12, 13     half width, half height of the opening (m; a circle's radius in 12), already shrunk
           by the clearance
14         a ball's radius (m)
15:39      polygon edges: MAX_EDGES rows (e_a, e_b, offset): inside where
           e · (a·d, b·d) ≤ offset for every edge (unit e; unused rows 0, 0, 1)
=========  ==================================================================================

A gate is passed at the leg's end node: on its plane (n · d = 0, d = x − c), inside the shrunk
opening, crossing forwards (n · v ≥ 0); the clearance is a sphere around the vehicle's centre,
so the opening shrinks by it on every side. A ball is passed within its radius.

This module imports no CasADi at load time (the track schema reads the registry, and the
configuration imports no solver): the symbolic rows import it when they are built.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

MAX_EDGES = 8
TARGET_SIZE = 15 + 3 * MAX_EDGES

#: A constraint row of the NLP: (expression, lower bound, upper bound).
Row = tuple[Any, float, float]


class Opening(Protocol):
    """What a kind reads of a track's gate (:class:`casadrone.config.track.GateConfig`)."""

    @property
    def width_m(self) -> float: ...
    @property
    def height_m(self) -> float: ...
    @property
    def vertices_m(self) -> Sequence[tuple[float, float]] | None: ...


@dataclass(frozen=True)
class Parts:
    """One packed target, split (numbers, or CasADi expressions inside the NLP)."""

    c: Any  # centre (3)
    n: Any  # through direction (3)
    a: Any  # left axis of the opening (3)
    b: Any  # up axis of the opening (3)
    hw: Any  # half width (m)
    hh: Any  # half height (m)
    r: Any  # ball radius (m)
    e: Any  # polygon edges (3 MAX_EDGES)


def split(tp) -> Parts:
    """The parts of one packed target ``tp`` (TARGET_SIZE numbers or expressions)."""
    return Parts(tp[0:3], tp[3:6], tp[6:9], tp[9:12], tp[12], tp[13], tp[14], tp[15:])


@dataclass(frozen=True)
class Packed:
    """A gate's opening as the kind packs it: half width, half height (m) and polygon edges
    (MAX_EDGES × 3), already shrunk by the clearance."""

    half_width_m: float
    half_height_m: float
    edges: np.ndarray | None = None  # None: unused rows


@dataclass(frozen=True)
class TargetKind:
    """Everything one kind of target means.

    - ``rows(t, d, vw)``: the NLP's constraint rows (symbolic) at a leg's end node, ``t`` the
      target's :class:`Parts`, ``d = x − c`` the position from its centre, ``vw`` the world
      velocity;
    - ``miss(t, d)``: the distance (m) from ``d`` to the target (0 inside): the re-simulation
      check's measure, and zero exactly where ``rows`` accept a position;
    - ``outline(t)``: world points (k × 3, m) of its boundary, for the figures;
    - ``shape``: the track's gate ``shape`` that selects this kind (None: not a gate; the ball is
      every waypoint without one);
    - ``pack(gate, clearance_m)``: the gate's opening shrunk by the clearance (:class:`Packed`);
    - ``inner_m(gate)``: the opening's largest inscribed radius (m): a gate with
      ``inner_m ≤ clearance`` cannot be passed;
    - ``check(gate)``: why a gate of this shape is malformed (empty when it is not), checked
      when the track is read;
    - ``vertices``: whether the gate gives ``vertices_m``.
    """

    name: str
    description: str
    rows: Callable[[Parts, Any, Any], list[Row]]
    miss: Callable[[Parts, np.ndarray], float]
    outline: Callable[[Parts], np.ndarray]
    shape: str | None = None
    pack: Callable[[Opening, float], Packed] = lambda gate, clear: Packed(
        gate.width_m / 2 - clear, gate.height_m / 2 - clear)
    inner_m: Callable[[Opening], float] = lambda gate: min(gate.width_m, gate.height_m) / 2
    check: Callable[[Opening], str] = lambda gate: ""
    vertices: bool = False


#: Every target kind, by name (the NLP layout's name of it).
TARGET_KINDS: dict[str, TargetKind] = {}


def register_target_kind(kind: TargetKind) -> TargetKind:
    """Add ``kind`` to :data:`TARGET_KINDS`; a taken name or gate shape is refused."""
    if kind.name in TARGET_KINDS:
        raise ValueError(f"target kind {kind.name!r} is already registered")
    if kind.shape is not None and kind.shape in gate_shapes():
        raise ValueError(f"gate shape {kind.shape!r} already selects "
                         f"{kind_of_shape(kind.shape).name!r}")
    TARGET_KINDS[kind.name] = kind
    return kind


def target_kind(name: str) -> TargetKind:
    """The registered kind ``name`` (a ValueError naming the known ones otherwise)."""
    try:
        return TARGET_KINDS[name]
    except KeyError:
        raise ValueError(f"unknown target kind {name!r}; known: "
                         f"{', '.join(TARGET_KINDS)}") from None


def gate_shapes() -> tuple[str, ...]:
    """The track schema's gate ``shape`` choices, in registry order."""
    return tuple(k.shape for k in TARGET_KINDS.values() if k.shape is not None)


def kind_of_shape(shape: str) -> TargetKind:
    """The kind a gate ``shape`` selects."""
    for kind in TARGET_KINDS.values():
        if kind.shape == shape:
            return kind
    raise ValueError(f"unknown gate shape {shape!r}; known: {', '.join(gate_shapes())}")


# --------------------------------------------------------------------------------------------
# What every kind is read through
# --------------------------------------------------------------------------------------------


def target_rows(x, vw, tp, kind: str) -> list[Row]:
    """Constraint rows (expression, lower, upper) of passing target ``tp`` of ``kind`` at node
    state x with world velocity vw (symbolic)."""
    t = split(tp)
    return target_kind(kind).rows(t, x[0:3] - t.c, vw)


def target_miss(pos: np.ndarray, tp: np.ndarray, kind: str) -> float:
    """Distance (m) from ``pos`` to target ``tp`` of ``kind`` (0 when it is passed)."""
    t = split(np.asarray(tp, float))
    return target_kind(kind).miss(t, np.asarray(pos, float) - t.c)


def target_outline(tp: np.ndarray, kind: str) -> np.ndarray:
    """World points (k × 3, m) of the boundary of target ``tp`` of ``kind``, for figures."""
    return target_kind(kind).outline(split(np.asarray(tp, float)))


# --------------------------------------------------------------------------------------------
# Building blocks of gate kinds: an opening in the gate plane, crossed forwards
# --------------------------------------------------------------------------------------------


def through_opening(opening_rows: Callable[[Parts, Any, Any], list[Row]]
                    ) -> Callable[[Parts, Any, Any], list[Row]]:
    """The rows of a gate whose opening is ``opening_rows(t, lat, up)`` (lat, up: the position
    in the gate plane along a and b): on the plane, inside the opening, crossing forwards."""

    def rows(t: Parts, d, vw) -> list[Row]:
        import casadi as ca

        lat, up = ca.dot(t.a, d), ca.dot(t.b, d)
        return [(ca.dot(t.n, d), 0.0, 0.0), *opening_rows(t, lat, up),
                (ca.dot(t.n, vw), 0.0, np.inf)]

    return rows


def off_opening(beyond: Callable[[Parts, float, float], list[float]]
                ) -> Callable[[Parts, np.ndarray], float]:
    """The miss of a gate whose distances beyond its opening, in its plane, are
    ``beyond(t, lat, up)`` (m, each 0 inside; one per direction they are measured in):
    combined with the distance off the plane as one Euclidean distance."""

    def miss(t: Parts, d: np.ndarray) -> float:
        along, lat, up = float(t.n @ d), float(t.a @ d), float(t.b @ d)
        return float(np.linalg.norm([along, *beyond(t, lat, up)]))

    return miss


def in_gate_plane(boundary: Callable[[Parts], np.ndarray]) -> Callable[[Parts], np.ndarray]:
    """The world outline of a gate whose boundary is ``boundary(t)`` (k × 2: lat, up; m)."""

    def outline(t: Parts) -> np.ndarray:
        la = boundary(t)
        return t.c + la[:, :1] * t.a + la[:, 1:2] * t.b

    return outline


def _circle(radius: float, n: int = 48) -> np.ndarray:
    s = np.linspace(0.0, 2 * math.pi, n + 1)
    return radius * np.column_stack([np.cos(s), np.sin(s)])


# --------------------------------------------------------------------------------------------
# The kinds
# --------------------------------------------------------------------------------------------


def _ball_rows(t: Parts, d, vw) -> list[Row]:
    import casadi as ca

    return [(ca.sumsqr(d) - t.r**2, -np.inf, 0.0)]


def _ball_outline(t: Parts) -> np.ndarray:
    """The ball's horizontal great circle (what a top view shows)."""
    ring = _circle(float(t.r))
    return t.c + np.column_stack([ring, np.zeros(len(ring))])


BALL = register_target_kind(TargetKind(
    "ball", "a waypoint's acceptance ball: within radius r of its centre",
    rows=_ball_rows, miss=lambda t, d: max(0.0, float(np.linalg.norm(d)) - float(t.r)),
    outline=_ball_outline))


def _rectangle_rows(t: Parts, lat, up) -> list[Row]:
    return [(lat - t.hw, -np.inf, 0.0), (-lat - t.hw, -np.inf, 0.0),
            (up - t.hh, -np.inf, 0.0), (-up - t.hh, -np.inf, 0.0)]


GATE = register_target_kind(TargetKind(
    "gate", "a rectangular opening, width_m × height_m",
    rows=through_opening(_rectangle_rows),
    miss=off_opening(lambda t, lat, up: [max(0.0, abs(lat) - t.hw), max(0.0, abs(up) - t.hh)]),
    outline=in_gate_plane(lambda t: np.array([[-t.hw, -t.hh], [t.hw, -t.hh], [t.hw, t.hh],
                                              [-t.hw, t.hh], [-t.hw, -t.hh]])),
    shape="rectangle"))


def _circle_check(gate: Opening) -> str:
    if gate.width_m != gate.height_m:
        return "shape: a circle's width_m and height_m are its diameter (equal)"
    return ""


CIRCLE = register_target_kind(TargetKind(
    "circle", "a circular opening of diameter width_m (= height_m)",
    rows=through_opening(lambda t, lat, up: [(lat**2 + up**2 - t.hw**2, -np.inf, 0.0)]),
    miss=off_opening(lambda t, lat, up: [max(0.0, math.hypot(lat, up) - t.hw)]),
    outline=in_gate_plane(lambda t: _circle(float(t.hw))), shape="circle",
    check=_circle_check))


def polygon_edges(vertices: np.ndarray, clearance: float) -> np.ndarray:
    """(MAX_EDGES, 3) rows (e_a, e_b, offset) of a convex polygon given counter-clockwise in
    the gate plane (left, up; m), each edge moved inwards by ``clearance`` (m)."""
    v = np.asarray(vertices, float)
    out = np.tile([0.0, 0.0, 1.0], (MAX_EDGES, 1))
    for j in range(len(v)):
        p, q = v[j], v[(j + 1) % len(v)]
        tangent = (q - p) / np.linalg.norm(q - p)
        e = np.array([tangent[1], -tangent[0]])  # outward normal of a counter-clockwise edge
        out[j] = [e[0], e[1], float(e @ p) - clearance]
    return out


def _polygon_check(gate: Opening) -> str:
    if gate.vertices_m is None:
        return "vertices_m: a polygon needs its vertices"
    v = np.asarray(gate.vertices_m, float)
    if not 3 <= len(v) <= MAX_EDGES:
        return f"vertices_m: 3 to {MAX_EDGES} vertices, got {len(v)}"
    e = np.roll(v, -1, axis=0) - v
    nxt = np.roll(e, -1, axis=0)
    cross = e[:, 0] * nxt[:, 1] - e[:, 1] * nxt[:, 0]
    if np.any(cross <= 0):
        return "vertices_m: not a convex polygon given counter-clockwise"
    # every turn to the left is not enough: a star (pentagram) turns left at each vertex too,
    # but winds twice; a simple convex polygon's exterior angles add up to one turn, 2π
    turning = float(np.sum(np.arctan2(cross, np.sum(e * nxt, axis=1))))
    if turning > 3 * math.pi:
        return (f"vertices_m: the edges cross (they wind {turning / (2 * math.pi):.0f} times "
                "around the centre): not a simple convex polygon")
    if _polygon_inner(gate) <= 0:
        return "vertices_m: the polygon does not hold the gate's centre (0, 0) inside it"
    # width_m and height_m of a polygon are the smallest rectangle about the centre that holds
    # it (what figures and the closed-loop guidance read); other values would be silently unused
    w, h = 2 * float(np.max(np.abs(v[:, 0]))), 2 * float(np.max(np.abs(v[:, 1])))
    if abs(gate.width_m - w) > 1e-3 or abs(gate.height_m - h) > 1e-3:
        return (f"width_m, height_m: a polygon's are those of the smallest rectangle about the "
                f"centre that holds it, {w:.4g} x {h:.4g} m (got {gate.width_m:g} x "
                f"{gate.height_m:g} m)")
    return ""


def _polygon_pack(gate: Opening, clear: float) -> Packed:
    assert gate.vertices_m is not None  # _polygon_check, when the track was read
    return Packed(gate.width_m / 2 - clear, gate.height_m / 2 - clear,
                  polygon_edges(np.asarray(gate.vertices_m), clear))


def _polygon_inner(gate: Opening) -> float:
    """The smallest distance from the centre to an edge: the largest circle about the centre
    inside the polygon."""
    assert gate.vertices_m is not None
    return float(np.min(polygon_edges(np.asarray(gate.vertices_m), 0.0)[
        :len(gate.vertices_m), 2]))


def _polygon_beyond(t: Parts, lat: float, up: float) -> list[float]:
    """The largest edge violation (the distance wherever one edge is violated)."""
    E = np.asarray(t.e).reshape(MAX_EDGES, 3)
    return [max(0.0, float(np.max(E[:, 0] * lat + E[:, 1] * up - E[:, 2])))]


def _polygon_outline(t: Parts) -> np.ndarray:
    """The vertices where consecutive used edges meet."""
    E = np.asarray(t.e, float).reshape(MAX_EDGES, 3)
    E = E[~np.all(E == [0.0, 0.0, 1.0], axis=1)]
    pts = [np.linalg.solve(np.array([E[j, :2], E[(j + 1) % len(E), :2]]),
                           [E[j, 2], E[(j + 1) % len(E), 2]]) for j in range(len(E))]
    return in_gate_plane(lambda _: np.array([*pts, pts[0]]))(t)


POLYGON = register_target_kind(TargetKind(
    "polygon", f"a convex polygonal opening, vertices_m (3 to {MAX_EDGES}, counter-clockwise)",
    rows=through_opening(lambda t, lat, up: [
        (t.e[3 * j] * lat + t.e[3 * j + 1] * up - t.e[3 * j + 2], -np.inf, 0.0)
        for j in range(MAX_EDGES)]),
    miss=off_opening(_polygon_beyond),
    outline=_polygon_outline, shape="polygon", pack=_polygon_pack, inner_m=_polygon_inner,
    check=_polygon_check, vertices=True))
