"""Certificates at every point of a design front (:mod:`casadrone.codesign.front`).

The fastest frame (the front's first point, posed without an ε row) has the certificate of
:func:`casadrone.codesign.certificate.certify`: its limit lap re-solved with θ fixed by the limit
lap's own NLP (θ a parameter there), warm from the point and from the limit lap's cold starts.
An ε-point (θ*, laps, ε) is certified here, with the same three parts:

1. **Lap**: the fixed-frame problem of an ε-point is the limit lap of the frame θ* *under the
   same ε row*. With ``effort`` the row bounds the lap itself (∫ Σ T^1.5 dt ≤ ε), so the
   fixed-frame optimum is the fastest lap within the bound, not the frame's minimum-time lap;
   with ``mass_kg`` or ``span_m`` the row is θ-only and, θ fixed, a constant: the fixed-frame
   problem is the plain limit lap. One posing covers all three: the co-design NLP itself with
   θ's bounds fixed at θ* (lbx = ubx) and the θ-only rows (feasibility, mass, span) freed, solved
   warm from the point's primal-dual values. The co-design optimum is an optimum of that
   problem, so the re-solve must return the co-design lap on every track within
   :data:`~casadrone.codesign.certificate.LAP_RTOL`; a point whose lap or θ was recorded wrong,
   or that stopped short of a trajectory optimum, re-solves to another lap.
2. **Reduced gradient** (the "why"): dT/dP of the fixed-frame optimum on each track, P = [p,
   x_start, targets] of the limit-lap NLP, by the envelope theorem from the re-solve's
   multipliers (∂(λ·g)/∂P of the limit lap's own symbolic rows, and of the lifted effort rows
   with ``propeller``, whose thrusts depend on p; the ε row's multiplier is part of λ), chained
   through the numeric airframe build (:func:`~casadrone.codesign.certificate.theta_gradient`),
   plus the feasibility and mass/span ε rows times the point's multipliers. Zero for a variable
   inside its box, the bound's sign at a bound; printed beside IPOPT's bound multiplier of the
   co-design solve (a second derivation of the same number) and the active rows, the ε row
   among them.
3. **Re-simulation**: each track's lap of the point flown open loop by CVODES passes every
   target within the limit lap's ``max_miss_m``.

What is not done at an ε-point: the cold multi-start re-solve (the fastest point's check that
no faster lap of the same frame exists from the limit lap's own cold starts). It costs a cold
limit lap per point (12–22 s of CPU on the paper track at 40 intervals, quiet or loaded) and,
for ``effort``, answers another question (the frame's minimum-time lap, not the fastest lap
within ε). On the paper front it would add 170–300 s to a front whose target is 180 s in all,
while the ε-points' certificates as done here cost about 1 s each (benchmarks/
RESULTS-codesign.md, "Certificates at every front point"). The warm re-solve checks local
optimality at the returned frame; the front itself is a path of local optima followed from the
certified fastest frame, and a point may be faster than that frame (a crossing to another
trajectory optimum: measured there), which no local certificate reports.
"""

from __future__ import annotations

import math
from dataclasses import replace

import casadi as ca
import numpy as np

from casadrone.airframe import build_airframe
from casadrone.codesign.certificate import (
    LAP_RTOL,
    Certificate,
    TrackCheck,
    appended_rows,
    certify,
    frame_terms,
    theta_gradient,
    verdict,
)
from casadrone.codesign.driver import CodesignPoint, Prepared, solve_from
from casadrone.codesign.nlp import effort_terms
from casadrone.config.io import ConfigError
from casadrone.limit.check import resimulation_miss
from casadrone.limit.starts import prepare, trajectory
from casadrone.model import n_params
from casadrone.propulsion import propulsion_model

#: Errors of a certificate's solves and re-simulation that fail the certificate (reported)
#: instead of the front.
FAILURES = (RuntimeError, ValueError, ArithmeticError, ConfigError)


def fixed_theta_bounds(prep: Prepared, point: CodesignPoint) -> tuple[np.ndarray, ...]:
    """(lbx, ubx, lbg, ubg) of the co-design NLP with θ fixed at the point's (lbx = ubx on s)
    and the θ-only rows freed: the feasibility rows and the mass and span ε rows are constants
    once θ is fixed (the frame's validity is checked by the airframe schema instead)."""
    cd = prep.nlp
    lbx, ubx = cd.bounds()
    lo, n = cd.offsets[-1], cd.n_theta
    lbx[lo:lo + n] = ubx[lo:lo + n] = np.clip(cd.split(point.z)[1], 0.0, 1.0)
    lbg, ubg = cd.lbg.copy(), cd.ubg.copy()
    feas, _, eps = appended_rows(cd)
    for rows in [feas, *(r for m, r in eps.items() if m != "effort")]:
        lbg[rows], ubg[rows] = -np.inf, np.inf
    return lbx, ubx, lbg, ubg


_FUNCTIONS: dict[tuple[int, str], tuple] = {}


def _lagrangian_p(part) -> ca.Function:
    """(w, P, λ) → ∂(f + λ·g)/∂P of one track's limit-lap NLP (CasADi's reverse mode on the
    limit lap's own symbolic rows), built once per NLP."""
    key = (id(part.nlp), "rows")
    if key not in _FUNCTIONS:
        sym = part.nlp.problem
        lam = ca.MX.sym("lam", sym["g"].numel())
        grad = ca.jtimes(sym["g"], sym["p"], lam, True) + ca.gradient(sym["f"], sym["p"])
        _FUNCTIONS[key] = (part.nlp, ca.Function("lagrangian_p", [sym["x"], sym["p"], lam],
                                                 [grad]))
    return _FUNCTIONS[key][1]


def _effort_p(part) -> ca.Function:
    """(w, p, ν) → ∂(ν·q)/∂p of one track's effort terms q (one per interval), built once."""
    key = (id(part.nlp), f"effort-{part.propulsion}")
    if key not in _FUNCTIONS:
        w = ca.MX.sym("w", part.nlp.problem["x"].numel())
        p = ca.MX.sym("p", n_params(part.propulsion))
        q = effort_terms(part, w, p)
        nu = ca.MX.sym("nu", q.numel())
        _FUNCTIONS[key] = (part.nlp, ca.Function("effort_p", [w, p, nu],
                                                 [ca.jtimes(q, p, nu, True)]))
    return _FUNCTIONS[key][1]


def track_dT_dP(prep: Prepared, point: CodesignPoint, k: int, P: np.ndarray) -> np.ndarray:
    """dT/dP of track k at a (fixed-frame) solution: the objective's Lagrangian differentiated
    in the limit-lap NLP's parameter P = [p, x_start, targets], with the point's multipliers of
    the track's rows and, with an ε row on effort, of its lifted effort rows (the row
    E_j − E_{j−1} − q_j = 0 enters as −ν_j q_j)."""
    cd = prep.nlp
    part = cd.parts[k]
    w = point.z[cd.offsets[k]:cd.offsets[k + 1]]
    lam = point.lam_g[cd.row_offsets[k]:cd.row_offsets[k + 1]]
    grad = np.asarray(_lagrangian_p(part)(w, P, lam), float).ravel()
    if "effort" in cd.epsilon and not propulsion_model(part.propulsion).thrust_is_state:
        # rotor states that are thrusts (paper): q has no p
        first = sum(q.nlp.layout.n_intervals for q in cd.parts[:k])
        nu = point.lam_g[len(cd.lbg) - cd.n_lift:][first:first + part.nlp.layout.n_intervals]
        n_p = n_params(part.propulsion)
        grad[:n_p] -= np.asarray(_effort_p(part)(w, P[:n_p], nu), float).ravel()
    return grad


def certify_epsilon_point(prep: Prepared, point: CodesignPoint) -> Certificate:
    """The certificate of an ε-point of a front posed by ``prep`` (the ε-constrained NLP; see
    the module docstring); never raises for a failed check (the certificate says why)."""
    try:
        return _certify(prep, point)
    except FAILURES as exc:
        return Certificate((), (), {}, False, f"the certificate failed: {exc}")


def _certify(prep: Prepared, point: CodesignPoint) -> Certificate:
    cd = prep.nlp
    try:
        cfg = prep.config(point.theta, name=f"{prep.template.name}-codesign")
    except ConfigError as exc:
        return Certificate((), (), {}, False, f"the frame is not a valid airframe: {exc}")
    ok, status, fixed = solve_from(prep, point.z, point.epsilon, warm=point,
                                   bounds=fixed_theta_bounds(prep, point))
    frame = build_airframe(cfg)
    ws, _ = cd.split(point.z)
    checks, grads = [], []
    for k, label in enumerate(prep.labels):
        pb = prepare(frame, prep.tracks[k], prep.options, prep.options.gate_clearance_m or 0.0)
        lap = fixed.laps_s[label] if ok else math.inf
        ref = point.laps_s[label]
        gap = 100 * (lap - ref) / ref
        miss = resimulation_miss(frame, trajectory(pb.full, ws[k], pb.layout),
                                 pb.targets.vector, pb.targets.kinds,
                                 legs=prep.options.resimulation == "legs")
        passed = abs(gap) <= 100 * LAP_RTOL and miss <= prep.options.max_miss_m
        checks.append(TrackCheck(label, ref, lap, math.nan, lap, gap, miss, bool(passed)))
        grads.append(theta_gradient(prep, cfg, prep.tracks[k],
                                    track_dT_dP(prep, fixed, k, pb.P))
                     if ok else np.full(len(prep.keys), np.nan))
    g_theta = np.sum(grads, axis=0)  # the multipliers carry the tracks' weights
    reduced = g_theta * (prep.upper - prep.lower) + frame_terms(prep, point)
    cert = verdict(prep, point, tuple(checks), g_theta, reduced)
    if not ok:
        reason = f"the fixed-frame re-solve failed: {status}"
        return replace(cert, passed=False, reason="; ".join(r for r in (reason, cert.reason)
                                                              if r))
    return cert


def certified_point(prep: Prepared, fp, first: Certificate | None = None):
    """``fp`` (a :class:`casadrone.codesign.front.FrontPoint` of a front posed by ``prep``)
    with its certificate: ``first`` for the fastest frame where given
    (:func:`casadrone.codesign.design.certified`'s), else
    :func:`casadrone.codesign.certificate.certify`'s; an ε-point's from
    :func:`certify_epsilon_point`. A failed certificate is kept on its point; nothing raises."""
    if not math.isinf(fp.epsilon):
        return replace(fp, certificate=certify_epsilon_point(prep, fp.point))
    cert = first
    if cert is None:  # the fastest frame: no ε row posed
        try:
            cert = certify(prep, fp.point)
        except FAILURES as exc:
            cert = Certificate((), (), {}, False, f"the certificate failed: {exc}")
    return replace(fp, certificate=cert)


def certify_front(front, first: Certificate | None = None):
    """``front`` (a :class:`casadrone.codesign.front.Front`) with a certificate on every point
    (:func:`certified_point`), e.g. a front read back or edited."""
    points = tuple(certified_point(front.prepared, fp, first) for fp in front.points)
    return replace(front, points=points)
