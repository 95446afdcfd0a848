"""The co-design of a problem: the fastest frame from every start
(:mod:`casadrone.codesign.driver`), its certificate (:mod:`casadrone.codesign.certificate`) and,
when the problem names a front measure, the design front (:mod:`casadrone.codesign.front`) with a
certificate at every point (:mod:`casadrone.codesign.frontcert`).
Above the three, so that the front builds on the driver without an import circle.
"""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

from casadrone.codesign import events
from casadrone.codesign.certificate import LAP_RTOL
from casadrone.codesign.certificate import certify as make_certificate
from casadrone.codesign.checks import load_codesign_problem
from casadrone.codesign.driver import (
    CodesignResult,
    StartReport,
    distinct_optima,
    initial_vector,
    prepare,
    refined,
    resampled,
    solve_from,
    start_points,
    vector_of,
    warm_laps,
)
from casadrone.codesign.front import design_front, write_run
from casadrone.config.codesign import FRONT_MEASURES, CodesignProblemConfig
from casadrone.limit.lap import refined_intervals
from casadrone.limit.result import LapSeeds
from casadrone.progress import nested

#: Co-design restarts from the certificate's faster fixed-frame lap (at most this many): where
#: the limit lap's own cold starts find a faster lap of the returned frame than the co-design's
#: (measured: SY250-components-propeller on the paper track, 4.2916 against 4.3331 s), the
#: co-design NLP stopped in a slower local optimum of the trajectory, and started from that lap
#: it can improve the frame as well.
RESTARTS = 2
#: Co-design re-poses a point whose certificate fails on the re-simulation on the limit lap's
#: refined grid (casadrone.limit.lap.refined_intervals: REFINE_FACTOR times finer, up to
#: MAX_INTERVALS; at most REFINEMENTS times), from the point
#: resampled onto it. Why: the legs share one number of intervals, so a long leg gets long
#: steps, and a frame whose optimum switches rotors faster than RK4's steps follow the rotor
#: speed's ~20 ms time constant (``propeller``) drifts open loop. Measured
#: (benchmarks/RESULTS-codesign.md): SY250-components-propeller's paper-track optimum on 80
#: intervals per leg flies its 1.5 s straights on 19 ms intervals and misses CVODES by 0.17 m.
REFINEMENTS = 2


def _faster_fixed_lap(cert) -> bool:
    """Whether a failed certificate's cold fixed-frame lap beat the co-design lap by more than
    the certificate's tolerance on some track."""
    return not cert.passed and any(
        t.fixed_cold_lap_s < t.codesign_lap_s * (1 - LAP_RTOL) for t in cert.tracks)


def _missed(cert, max_miss_m: float) -> bool:
    """Whether a certificate failed on some track's re-simulation miss."""
    return cert is not None and not cert.passed and any(
        t.resimulation_miss_m > max_miss_m for t in cert.tracks)


def _restart(prep, best, cert, reports: list):
    """The co-design solved from the certificate's cold fixed-frame laps (reported as a start);
    the new point when it converged faster than ``best``, else None."""
    c0 = time.process_time()
    cold_ws = [t.cold_w for t in cert.tracks if t.cold_w is not None]
    if len(cold_ws) < len(cert.tracks):
        return None
    ok, status, pt = solve_from(prep, vector_of(prep, best.theta, cold_ws))
    reports.append(StartReport("restart-from-certificate", best.theta, status, ok,
                               pt.objective, pt.theta, pt.iterations, time.process_time() - c0))
    events.start_done(reports[-1])
    return pt if ok and pt.objective < best.objective else None


def _refine(prep, best, reports: list):
    """(the problem on the refined grid (refined_intervals), the co-design point solved there from
    ``best``'s frame and laps) (reported as a start); None when the grid cannot be refined or
    the solve fails."""
    finer = refined_intervals(prep.options.intervals or 0)
    if finer <= (prep.options.intervals or 0):
        return None
    c0 = time.process_time()
    fine = refined(prep, finer)
    with nested():
        z0 = resampled(prep, best, fine)
    if z0 is None:
        reports.append(StartReport(f"refined-{finer}", best.theta, "the frame's limit lap on "
                                   "the finer grid failed", False, math.nan, best.theta, 0,
                                   time.process_time() - c0))
        events.start_done(reports[-1])
        return None
    ok, status, pt = solve_from(fine, z0)
    reports.append(StartReport(f"refined-{finer}", best.theta, status, ok, pt.objective,
                               pt.theta, pt.iterations, time.process_time() - c0))
    events.start_done(reports[-1])
    return (fine, pt) if ok else None


def certified(prep, points: list, reports: list, certify: bool = True):
    """(the problem as finally posed, the best point, the distinct optima, its certificate or
    None) from the converged ``points``: the best is certified and, while its certificate fails,
    restarted from a faster fixed-frame lap (:data:`RESTARTS`) or re-posed on a finer grid when
    it misses the re-simulation (:data:`REFINEMENTS`); each such solve is appended to
    ``reports``. Optima of a coarser grid are kept among the distinct ones, after the best."""
    distinct = distinct_optima(points)
    best = distinct[0]
    cert = _certificate(prep, best) if certify else None
    others: list = []  # optima of a coarser grid, after a refinement
    restarts = refinements = 0
    while cert is not None and not cert.passed:
        if _faster_fixed_lap(cert) and restarts < RESTARTS:
            # the certificate's cold fixed-frame solve found a faster lap of the same frame:
            # the co-design stopped in a slower local optimum of the trajectory; start again
            # from it
            restarts += 1
            pt = _restart(prep, best, cert, reports)
            if pt is None:
                break
            points = [*points, pt]
        elif _missed(cert, prep.options.max_miss_m) and refinements < REFINEMENTS:
            # the point's trajectory is too coarse to be flown: the same frame and lap on a
            # finer grid, solved there and certified again
            refinements += 1
            fine = _refine(prep, best, reports)
            if fine is None:
                break
            prep, pt = fine
            others += [p for p in distinct if p is not best]
            points = [pt]
        else:
            break
        distinct = distinct_optima(points) + others
        best = distinct[0]
        cert = _certificate(prep, best)
    return prep, best, distinct, cert


def _certificate(prep, best):
    """The certificate of ``best`` (:func:`casadrone.codesign.certificate.certify`), its stage
    reported (the limit laps it solves run nested)."""
    events.certifying("the best point", best.objective)
    c0 = time.process_time()
    with nested():
        cert = make_certificate(prep, best)
    events.certified(cert, time.process_time() - c0)
    return cert


def codesign(problem: CodesignProblemConfig | str | Path, certify: bool = True,
             run_dir: Path | None = None, seeds: LapSeeds = LapSeeds(),
             start: dict[str, float] | None = None) -> CodesignResult:
    """The fastest frame of ``problem`` (see the module docstring) and, when the problem names
    a front measure beside J3_limit, the design front (written as a run directory to
    ``run_dir`` if given); the template's laps started from ``seeds`` and its geometry moved to
    ``start`` where given (:func:`casadrone.codesign.driver.prepare`); never raises for a start
    that fails (it is reported), raises ConfigError for a problem co-design cannot pose."""
    if not isinstance(problem, CodesignProblemConfig):
        problem = load_codesign_problem(problem)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    prep = prepare(problem, seeds=seeds, start=start)
    build_cpu = time.process_time() - cpu0
    reports, points = [], []
    starts = start_points(prep)
    for k, (label, theta) in enumerate(starts, start=1):
        events.start_begun(label, k, len(starts), theta)
        c0 = time.process_time()
        with nested():
            z0 = initial_vector(prep, theta)
        if z0 is None:
            reports.append(StartReport(label, theta, "start frame has no limit lap", False,
                                       math.nan, theta, 0, time.process_time() - c0))
            events.start_done(reports[-1])
            continue
        ok, status, pt = solve_from(prep, z0)
        reports.append(StartReport(label, theta, status, ok, pt.objective, pt.theta,
                                   pt.iterations, time.process_time() - c0))
        events.start_done(reports[-1])
        if ok:
            points.append(pt)
    names = tuple(prep.labels)
    common: dict[str, Any] = dict(problem=problem.name, keys=prep.keys, tracks=names,
                  combine=problem.codesign.combine, starts=tuple(reports), build_cpu_s=build_cpu)
    if not points:
        return CodesignResult("failed", "no start converged: " + "; ".join(
            f"{r.label}: {r.status}" for r in reports), best=None, distinct=(), **common,
            cpu_s=time.process_time() - cpu0, wall_time_s=time.perf_counter() - wall0)
    prep, best, distinct, cert = certified(prep, points, reports, certify)
    common["starts"] = tuple(reports)
    front = None
    measures = [o.index for o in problem.objectives if o.index in FRONT_MEASURES]
    if measures:
        # every point certified: the fastest frame by its certificate above, each ε-point by
        # its own (casadrone.codesign.frontcert)
        front = design_front(prep, best, measures[0], problem.codesign.front.points,
                             problem.codesign.front.lowest, certify=certify, first=cert)
        if run_dir is not None:
            write_run(run_dir, prep, front, len(front.points))
    return CodesignResult("completed", "", best=best, distinct=tuple(distinct), certificate=cert,
                          front=front, intervals=prep.options.intervals or 0,
                          laps=warm_laps(prep, best),
                          cpu_s=time.process_time() - cpu0,
                          wall_time_s=time.perf_counter() - wall0, **common)
