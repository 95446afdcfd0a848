"""The point-mass reference of the limit lap: the best of a few local optima of the point-mass
relaxation, solved once per (mass, thrust, drag, track) and cached, never per frame."""

from __future__ import annotations

import numpy as np

from casadrone.airframe import Airframe
from casadrone.config.track import TrackConfig
from casadrone.drag import DRAG_PARAM_NAMES
from casadrone.limit.guesses import straight_guess
from casadrone.limit.nlp import Nlp, NlpSolution, solve
from casadrone.limit.problem import Targets, bounds, row_bounds
from casadrone.limit.result import LimitLapOptions
from casadrone.model import param_names, rotation_matrix
from casadrone.propulsion import PROPELLER_PARAM_NAMES

#: Constant speeds (m/s) of the straight-line starts of the point-mass reference (best of them).
REFERENCE_SPEEDS_MPS = (5.0, 10.0, 20.0)
#: Entries of p the point-mass model reads (casadrone.limit.nlp.point_mass_ocp_model).
POINT_MASS_PARAMS = ("mass", "g", "rho", "CdA_x", "CdA_y", "CdA_z") + DRAG_PARAM_NAMES
_POINT_MASS: dict[bytes, NlpSolution | None] = {}


def point_mass_p(airframe: Airframe) -> np.ndarray:
    """p with every entry the point mass does not read set to zero, so the point-mass problem,
    and its cache key, depend on mass, gravity, drag and density only (thrust is its bound)."""
    names = np.array(param_names(airframe.propulsion))
    # the propeller's data set the point mass's thrust bound: they stay in the key
    keep = np.isin(names, POINT_MASS_PARAMS + PROPELLER_PARAM_NAMES)
    return np.where(keep, airframe.p, 0.0)


def point_mass_problem(pm: Nlp, airframe: Airframe, track: TrackConfig,
                       options: LimitLapOptions, targets: Targets, x0: np.ndarray,
                       thrust_cap: float | None = None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                  np.ndarray]:
    """The point-mass relaxation's P, box (lbx, ubx), row bounds (lbg, ubg) and start state
    (position, world velocity) for the full model's start state ``x0`` (16 Euler states).
    ``thrust_cap``: a rotor's thrust bound (N) below the propulsion's own where the currents
    are limited (:func:`casadrone.propulsion.propeller.electric_thrust_bound`): the total
    thrust at most four times it; None: the propulsion's (:func:`casadrone.propulsion.
    rotor_thrust_bound`)."""
    R = np.asarray(rotation_matrix(*x0[9:12])).reshape(3, 3)
    x0_pm = np.concatenate([x0[0:3], R @ x0[3:6]])
    P = np.concatenate([point_mass_p(airframe), x0_pm, targets.vector])
    lbx, ubx = bounds(pm, airframe, track, options, point_mass=True)
    if thrust_cap is not None:
        T, X, U = pm.unpack(ubx)
        U[:, 3] = np.minimum(U[:, 3], 4 * thrust_cap)
        ubx = pm.pack(T, X, U)
    lbg, ubg = row_bounds(pm, track, options)
    return P, lbx, ubx, lbg, ubg, x0_pm


def point_mass_reference(pm: Nlp, airframe: Airframe, track: TrackConfig,
                         options: LimitLapOptions, targets: Targets, x0: np.ndarray,
                         thrust_cap: float | None = None) -> NlpSolution | None:
    """The best converged point-mass solve over straight-line starts at REFERENCE_SPEEDS_MPS,
    cached per (mass, gravity, drag, thrust, track targets, start, bounds): never per frame.

    Not a lower bound: the point-mass problem is a relaxation of the limit lap (every flight of
    the full model is one of the point mass), so its *global* optimum bounds the lap from below,
    but IPOPT finds local optima, and the best of a few starts is only the best found.
    """
    P, lbx, ubx, lbg, ubg, x0_pm = point_mass_problem(pm, airframe, track, options, targets, x0,
                                                      thrust_cap)
    key = b"".join(np.ascontiguousarray(a, float).tobytes() for a in (P, lbx, ubx, lbg, ubg)) \
        + repr((pm.layout, options.tol, options.max_iter)).encode()
    if key not in _POINT_MASS:
        x0_guess = np.concatenate([x0_pm[0:3], np.zeros(3)])
        sols = [solve(pm, straight_guess(pm, targets.route, x0_guess, v,
                                     airframe.mass * airframe.gravity), P, lbx, ubx,
                      lbg=lbg, ubg=ubg) for v in REFERENCE_SPEEDS_MPS]
        good = [s for s in sols if s.success]
        _POINT_MASS[key] = min(good, key=lambda s: s.objective) if good else None
    return _POINT_MASS[key]


def point_mass_from(pm: Nlp, w_pm: np.ndarray, airframe: Airframe, track: TrackConfig,
                    options: LimitLapOptions, targets: Targets, x0: np.ndarray,
                    thrust_cap: float | None = None) -> NlpSolution | None:
    """The point-mass relaxation solved from ``w_pm`` (the projection of a full-model lap:
    :func:`casadrone.limit.guesses.point_mass_guess`), None when it does not converge. A
    feasible lap of the full model is a feasible point of the relaxation, so this local optimum
    lies at or below that lap: tens to a few hundred iterations where the straight-line starts
    take 430-600 (benchmarks/RESULTS-limitlap-fastpath.md). ``thrust_cap``: as in
    :func:`point_mass_problem`."""
    P, lbx, ubx, lbg, ubg, _ = point_mass_problem(pm, airframe, track, options, targets, x0,
                                                  thrust_cap)
    sol = solve(pm, np.clip(w_pm, lbx, ubx), P, lbx, ubx, lbg=lbg, ubg=ubg)
    return sol if sol.success else None
