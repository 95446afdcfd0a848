"""The dominant frame of a combination's geometry box: a frame of the box at least as good as
every other in each way the geometry enters the model, so that its race is the co-design's
answer without the co-design.

The geometry (arm lengths, arm angles) enters the model through the frame's mass, its inertia
and its rotor positions about the centre of mass (:func:`casadrone.airframe.build_airframe`):
the torque arms, and the rotors' inflow v + Ω × r_i; the propellers' and motors' data, the body
drag, the gate clearance (one for the whole box: :func:`casadrone.codesign.checks.
gate_clearance`) and the pack do not move with it. A frame D of the box
*dominates* it where, against every frame F of the box,

1. **mass**: m_D ≤ m_F: the same thrusts give D every translational acceleration they give F
   (the argument of :mod:`casadrone.build.bound`, item 2);
2. **inertia**: each principal moment I_D,kk ≤ I_F,kk, and D has no products of inertia;
3. **angular authority**: about x and about y, the rotors' arms about that axis (from the
   centre of mass) summed over its moment of inertia, Σ|r_⊥| / I_kk, is at least F's: the
   angular acceleration a thrust moved across the axis makes. Yaw follows from 2: its arm is
   the propeller's κ, the same for every frame of the box.

Then any manoeuvre of F is within D's reach, and D's limit lap is the smallest of the box: the
co-design's optimum is D itself. For the components mass model with the arm lengths as the
box (build-small), every part on an arm moves out with it: mass and inertia grow, and the
inertia (∝ λ²) faster than the arm (∝ λ), so the short-arm corner dominates by these
criteria. Measured there (benchmarks/RESULTS-build.md), it is nearly but not quite the
co-design's optimum: the criterion sums the two senses of pitch, and a longer front arm
lengthens the front rotors' pitch arm about the centre of mass (which moves forward by less),
0.6 % more nose-up authority at λa = 112.5 mm; the races' gradient points into the box in
λa at the frames of 10 of build-small's 11 raced combinations (−0.03 to −0.58 ms per mm),
brute force's co-designs sit at λa 100.3–101.7 mm, and the corner's races are within −0.08 to
+0.22 % of theirs. With the arm
*angles* in the box, a frame gains roll authority only by losing pitch authority and no frame
dominates (:func:`dominant_theta` returns None and the combination is co-designed).

What the argument does not cover: the inflow Ω × r_i (a rolling frame's rotors see its rate
times their arm: a damping that grows with the arm, in favour of the short-arm corner); the
gyroscopic coupling ω × Iω of the rigid body (it moves
with the differences of the moments, not with their size); the products of inertia of the
dominated frames; the extremes of the rotors' thrust box. The strict form of 3 (every
combination of rotor thrusts in [0, T_max] of F, mapped to D's, needs no thrust outside
[0, T_max]) fails on build-small's box at the corners where three rotors are off: matching F's
yaw there with D's smaller I_zz needs a rotor at -2.6 % of its full thrust (at the long-arm
corner), a state no lap flies. And IPOPT returns local optima. That is why the build checks each
ranked dominant race a second way (:func:`stationary`: its own gradient dT/dθ meets the
co-design's first-order optimality over the box) and moves it by that gradient where that
fails (:mod:`casadrone.build.descent`, :func:`casadrone.build.search.confirmed`), and why the
benchmark compares every dominant race with the same combination co-designed alone
(benchmarks/bench_build.py).

The box is checked on a grid (:data:`GRID` points per key, its bounds among them): mass and
inertia are polynomials of the geometry, smooth over the box, and its extremes are at the
bounds for the arm lengths.
"""

from __future__ import annotations

import numpy as np

from casadrone.airframe import Airframe, build_airframe
from casadrone.build.combos import valid_frames
from casadrone.config.airframe import AirframeConfig

#: Points per key of the grid the box is checked on (its bounds included).
GRID = 5
#: Relative slack of every comparison (rounding of the mass model's sums).
TOL = 1e-9


def authority(frame: Airframe) -> np.ndarray:
    """The frame's angular authority about x and y: the rotors' arms about that axis (|y|
    for roll, |x| for pitch, from the centre of mass) summed, over its moment of inertia
    (1/(kg·m)): the angular acceleration per newton of thrust moved across the axis."""
    r, inertia = frame.rotor_positions, frame.inertia
    return np.array([np.abs(r[:, 1]).sum() / inertia[0, 0],
                     np.abs(r[:, 0]).sum() / inertia[1, 1]])


def dominates(d: Airframe, f: Airframe, tol: float = TOL) -> bool:
    """Whether ``d`` dominates ``f`` (module docstring: mass, inertia, angular authority)."""
    products = d.inertia[[0, 0, 1], [1, 2, 2]]
    return bool(d.mass <= f.mass * (1 + tol)
                and np.all(np.diag(d.inertia) <= np.diag(f.inertia) * (1 + tol))
                and np.all(np.abs(products) <= tol * np.trace(d.inertia))
                and np.all(authority(d) >= authority(f) * (1 - tol)))


def dominant_theta(cfg: AirframeConfig, keys: tuple[str, ...], lower: np.ndarray,
                   upper: np.ndarray, n: int = GRID) -> dict[str, float] | None:
    """The θ of the frame of ``cfg``'s box that dominates every valid frame of the box's grid
    (module docstring), the least massive first where several do; None where none does."""
    frames = [({k: float(getattr(f, k)) for k in keys}, build_airframe(f))
              for f in valid_frames(cfg, keys, lower, upper, n)]
    for theta, d in sorted(frames, key=lambda tf: tf[1].mass):
        if all(dominates(d, f) for _, f in frames):
            return theta
    return None


def stationary(theta: dict[str, float], gradient: dict[str, float], keys: tuple[str, ...],
               lower: np.ndarray, upper: np.ndarray) -> bool:
    """Whether a race's gradient dT/dθ (s per unit of each key) at ``theta`` meets the
    co-design's first-order optimality over the box: no key can move into the box and shorten
    the race (dT/dθ ≥ 0 at a lower bound, ≤ 0 at an upper one, zero inside), each slope taken
    over the box's width and counted as zero below the co-design certificate's tolerances
    (:data:`casadrone.codesign.certificate.GRAD_RTOL` of the largest, or ``GRAD_ATOL``). False
    where a key has no gradient."""
    from casadrone.codesign.certificate import AT_BOUND, GRAD_ATOL, GRAD_RTOL  # casadi: lazy

    if any(k not in gradient or not np.isfinite(gradient[k]) for k in keys):
        return False
    width = np.asarray(upper, float) - np.asarray(lower, float)
    g = np.array([gradient[k] for k in keys]) * width  # s per box width
    tol = max(GRAD_ATOL, GRAD_RTOL * float(np.max(np.abs(g))))
    x = (np.array([theta[k] for k in keys]) - lower) / width
    at_lower, at_upper = x <= AT_BOUND, x >= 1 - AT_BOUND
    return bool(np.all(np.where(at_lower, g >= -tol, np.where(at_upper, g <= tol,
                                                              np.abs(g) <= tol))))
