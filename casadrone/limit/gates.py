"""Packing a track's targets into the limit-lap NLP's parameter P: the gate frames and the
``TARGET_SIZE`` numbers of each leg's target (the layout and what each kind of target means:
:mod:`casadrone.targets`, the registry of target kinds).

The gate frame is R(roll, pitch, yaw) of the track's ``rpy_deg`` (ZYX,
:func:`casadrone.model.rotation_matrix`): yaw alone is a vertical gate flown along that heading,
as ``heading_deg``.
"""

from __future__ import annotations

import numpy as np

from casadrone.targets import (  # noqa: F401 (re-exported: where they were read before)
    MAX_EDGES,
    TARGET_SIZE,
    polygon_edges,
    target_miss,
    target_rows,
)

#: A target kind's name: a key of :data:`casadrone.targets.TARGET_KINDS`.
TargetKind = str


def gate_frame(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Columns n (through), a (left), b (up) of the gate frame at ZYX angles (rad)."""
    from casadrone.limit.attitude import euler_rotation_np

    return euler_rotation_np(roll, pitch, yaw)


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
