"""The bound of a combination: a point-mass race no co-designed frame of it can beat.

The bound of a combination is the point-mass relaxation of the limit lap
(:func:`casadrone.limit.pointmass.point_mass_reference`) flown by the combination at the
*least mass* of the geometry box, on the race's track and grid. Why it is below the race time
of every frame of the box:

1. **Relaxation of the model.** The point mass keeps the full model's translational dynamics
   (mass, gravity, the same body drag) and replaces the attitude, body-rate and rotor dynamics
   by a thrust vector whose size is at most four times the propeller's largest steady
   full-command thrust over every airspeed (:func:`casadrone.propulsion.thrust_bound`, which
   argues why) and whose tilt is bounded per axis by the track's tilt limit, which contains the
   full model's cone; the current, advance-ratio and tilt-cone rows are dropped. Where the
   frame's currents are limited (the pack's C × capacity, the motor's ``max_current_a``) the
   thrust bound is the smaller :func:`current_thrust_cap`: the largest steady thrust of a rotor
   over every airspeed with its motor at most at its current and a quarter of the pack's power
   at its current limit (the four share it; a rotor's thrust grows slower than its power, so an
   equal share gives the most), which lifts the bounds of the current-limited combinations
   (the 650 mAh packs of build-small: from 0.73 to 0.85 of their race). Every flight of a frame
   of the combination is therefore a flight of its point mass.
2. **Least mass.** The geometry moves a frame's mass (the components mass model) and its
   inertia, not its thrust or drag. The point mass reads the inertia nowhere; a lighter point
   mass with the same thrust bound reaches every acceleration a heavier one does (the thrust it
   needs is the heavier one's scaled by m'/m < 1, plus a share of the drag), so the least mass
   of the box, found at its corners (:func:`casadrone.build.combos.least_mass_kg`), gives the
   smallest point-mass lap.
3. **The race is slower than its lap model.** The race flies at the open-circuit voltage of its
   end state of charge, the lowest of the flight (:mod:`casadrone.limit.race`): a lower voltage
   lowers the thrust bound no further than the full pack's, which the bound uses.

What is *not* certified by the argument: IPOPT returns local optima, of the point mass as of
the full model, and the two are on their own grids. The bound is the best of the point mass's
straight-line starts for the first combination and, for each next one in catalogue order, the
relaxation solved from the one before (:func:`point_mass_bound`'s ``near``), so a poor local
optimum of the point mass could lie above the full model's lap. That is why the inequality is
tested, combination by combination, against the co-designed race on the build's small
catalogue (tests/integration/test_build_search.py), against every combination co-designed alone
(benchmarks/bench_build.py, pruned ones included) and reported by every build
(``bound_ratio``: bound over race time, at most 1 where it holds).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from casadrone.airframe import Airframe, build_airframe
from casadrone.config.airframe import AirframeConfig
from casadrone.config.track import TrackConfig
from casadrone.limit.nlp import NlpSolution
from casadrone.limit.pointmass import point_mass_from, point_mass_reference
from casadrone.limit.result import LimitLapOptions
from casadrone.limit.starts import prepare as prepare_lap
from casadrone.propulsion.propeller import airframe_values, electric_thrust_bound, pack_power
from casadrone.results import AsDict


@dataclass(frozen=True)
class Bound(AsDict):
    """The point-mass race time (s) of a combination at its least mass (kg); NaN where no
    point-mass start converged (then the combination is never pruned)."""

    race_s: float
    mass_kg: float
    cpu_s: float


def point_mass_bound(frame_cfg: AirframeConfig, mass_kg: float, track: TrackConfig,
                     options: LimitLapOptions, near: NlpSolution | None = None
                     ) -> tuple[float, NlpSolution | None]:
    """The point-mass race (s) of ``frame_cfg`` with its mass set to ``mass_kg`` on ``track``
    (module docstring) and its solution; (NaN, None) where no start converged.

    ``near``: the relaxation's solution for a neighbouring combination (the same track and
    grid): the relaxation is solved from it alone, tens of iterations instead of the three
    straight-line starts' 430-600 each, and from those where it does not converge. Either is a
    local optimum; the bound's check against every raced combination (``bound_ratio``) covers
    both."""
    light = replace(build_airframe(frame_cfg), mass=mass_kg)  # p follows the mass
    pb = prepare_lap(light, track, options, options.gate_clearance_m or 0.0)
    cap = current_thrust_cap(light)
    if near is not None:
        sol = point_mass_from(pb.point_mass, near.point.w, pb.frame, track, options,
                              pb.targets, pb.x0_euler, cap)
        if sol is not None:
            return float(sol.objective), sol
    ref = point_mass_reference(pb.point_mass, pb.frame, track, options, pb.targets,
                               pb.x0_euler, cap)
    return (math.nan, None) if ref is None else (float(ref.objective), ref)


def current_thrust_cap(frame: Airframe) -> float | None:
    """A rotor's share (N) of the point mass's total thrust under the frame's current limits
    (:func:`casadrone.propulsion.propeller.electric_thrust_bound`: each motor at most its
    ``max_current_a``, the four at most the pack's power at C × capacity, a quarter each);
    None where the frame's propulsion has no currents or no limit is set."""
    if frame.propulsion != "propeller" or (frame.max_pack_current_a is None
                                           and frame.max_motor_current_a is None):
        return None
    q = airframe_values(frame)
    share = None if frame.max_pack_current_a is None else \
        pack_power(q, frame.max_pack_current_a) / 4
    return electric_thrust_bound(q, frame.max_motor_current_a, share)
