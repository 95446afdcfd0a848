"""Co-design in one NLP: prepare the tracks, start from several frames, solve, certify.

``codesign(problem) -> CodesignResult``. Steps (each a function below):

1. :func:`prepare`: the template airframe, the decision variables and their box, each track's
   limit-lap NLP, bounds, start state and targets, and the co-design NLP around them (built once
   per process and problem shape);
2. :func:`start_points`: the template's geometry and ``codesign.starts`` random feasible frames
   in the box; each is given its own limit lap on every track (primal-dual warm-started from the
   template's), which with its θ is a consistent start of the co-design NLP;
3. :func:`solve_from`: IPOPT on the co-design NLP from one start (or a neighbour's primal-dual
   point: continuation); every start is reported, the best converged one is the result, and
   optima that differ by more than :data:`AGREE_REL` are reported as distinct local optima;
4. :func:`certify` (:mod:`casadrone.codesign.certificate`): the limit lap of the frame re-solved
   with θ fixed, the reduced gradient in θ with its multipliers, the CVODES re-simulation.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from casadrone.airframe import build_airframe, random_thetas, with_theta
from casadrone.codesign import events
from casadrone.codesign.budget import STOPPED
from casadrone.codesign.checks import codesign_lap_options, gate_clearance, template_of
from casadrone.codesign.frame import CODESIGN_KEYS, SymbolicFrame
from casadrone.codesign.nlp import CodesignNlp, TrackPart, build_codesign_nlp
from casadrone.config.airframe import AirframeConfig
from casadrone.config.codesign import DEFAULT_LAP_STARTS, FRONT_MEASURES, CodesignProblemConfig
from casadrone.config.io import ConfigError, load
from casadrone.config.track import TrackConfig
from casadrone.limit.lap import (
    LimitLap,
    LimitLapOptions,
    design_limit_lap,
)
from casadrone.limit.nlp import NlpPoint
from casadrone.limit.result import LapSeeds, Start, node_times, seeds_alone
from casadrone.limit.starts import prepare as prepare_lap
from casadrone.limit.starts import trajectory
from casadrone.progress import nested
from casadrone.propulsion import rotor_state_bounds
from casadrone.results import Status

#: Two optima agree when their objectives differ by at most this fraction (acceptance: 0.1 %).
AGREE_REL = 1e-3


@dataclass(frozen=True)
class Prepared:
    """Everything a co-design solve needs, built once per problem."""

    problem: CodesignProblemConfig
    template: AirframeConfig
    keys: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    labels: tuple[str, ...]
    tracks: tuple[TrackConfig, ...]
    weights: tuple[float, ...]
    options: LimitLapOptions
    nlp: CodesignNlp
    template_laps: tuple[LimitLap, ...]

    def config(self, theta: dict[str, float], name: str | None = None) -> AirframeConfig:
        return with_theta(self.template, theta, name=name)


@dataclass(frozen=True)
class StartReport:
    """One start of the co-design NLP: where from, what it reached."""

    label: str
    theta_start: dict[str, float]
    status: str
    success: bool
    objective: float
    theta: dict[str, float]
    iterations: int
    cpu_s: float


@dataclass(frozen=True)
class CodesignPoint:
    """A converged co-design point: θ, the lap on each track, the measures, the raw solution."""

    theta: dict[str, float]
    objective: float
    laps_s: dict[str, float]
    mass_kg: float
    span_m: float
    iterations: int
    cpu_s: float
    epsilon: dict[str, float] = field(default_factory=dict)
    z: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    lam_x: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)
    lam_g: np.ndarray = field(default_factory=lambda: np.zeros(0), repr=False)


@dataclass(frozen=True)
class CodesignResult:
    """The co-design of a problem: the best frame, every start, the distinct optima, and the
    certificate of the returned point."""

    status: Status  # casadrone.results' one word for success: completed
    reason: str
    problem: str
    keys: tuple[str, ...]
    tracks: tuple[str, ...]
    combine: str
    best: CodesignPoint | None
    starts: tuple[StartReport, ...]
    distinct: tuple[CodesignPoint, ...]
    certificate: Any = None  # casadrone.codesign.certificate.Certificate
    front: Any = None  # casadrone.codesign.front.Front, when the problem names a measure
    #: intervals per leg of the returned point (finer than the problem's after a refinement,
    #: casadrone.limit.lap.refined_intervals; 0 when no point was returned)
    intervals: int = 0
    cpu_s: float = math.nan
    wall_time_s: float = math.nan
    build_cpu_s: float = math.nan
    #: the returned point's lap on each track as a warm start of that track's limit lap with
    #: the point's θ fixed (:func:`warm_laps`; left out of :meth:`as_dict`); () without a point
    laps: tuple[LimitLap, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """Plain data for ``--json`` (arrays of the raw solution left out)."""
        def point(p: CodesignPoint | None):
            if p is None:
                return None
            d = asdict(p)
            for k in ("z", "lam_x", "lam_g"):
                d.pop(k)
            return d

        return {"status": self.status, "reason": self.reason, "problem": self.problem,
                "keys": list(self.keys), "tracks": list(self.tracks), "combine": self.combine,
                "best": point(self.best), "starts": [asdict(s) for s in self.starts],
                "distinct_optima": [point(p) for p in self.distinct],
                "certificate": None if self.certificate is None else self.certificate.as_dict(),
                "front": None if self.front is None else {
                    "measure": self.front.measure, "cpu_s": self.front.cpu_s,
                    "stopped": self.front.stopped,
                    "points": [{"lap_s": p.point.objective, "measure": p.measure,
                                "epsilon": p.epsilon, "theta": p.point.theta,
                                "iterations": p.point.iterations, "cpu_s": p.point.cpu_s,
                                "certificate": None if p.certificate is None
                                else p.certificate.as_dict()}
                               for p in self.front.points]},
                "intervals": self.intervals, "cpu_s": self.cpu_s,
                "wall_time_s": self.wall_time_s, "build_cpu_s": self.build_cpu_s}


def warm_laps(prep: Prepared, point: CodesignPoint) -> tuple[LimitLap, ...]:
    """Each track's lap of a co-design ``point`` as a warm start of the limit lap of the frame
    at its θ: the same NLP with θ fixed, so its primal-dual point (the slices of the point's own,
    as the certificate's fixed-frame check takes them) is that lap's optimum; its nodes serve a
    lap on another grid. Not verified: the lap that starts from it re-simulates its own."""
    cd = prep.nlp
    out = []
    for k, part in enumerate(cd.parts):
        nlp = part.nlp
        w = point.z[cd.offsets[k]:cd.offsets[k + 1]]
        T, X, U = nlp.unpack(w)
        solution = NlpPoint(w, point.lam_x[cd.offsets[k]:cd.offsets[k + 1]],
                            point.lam_g[cd.row_offsets[k]:cd.row_offsets[k + 1]],
                            np.zeros(nlp.problem["p"].numel()))
        out.append(LimitLap(status="completed", reason="", lap_time_s=float(np.sum(T)),
                            leg_times_s=T, t=node_times(T, nlp.layout.intervals), x=X, u=U,
                            attitude=nlp.model.attitude, layout=nlp.layout,
                            solution=solution))
    return tuple(out)


# --------------------------------------------------------------------------------------------
# 1. Prepare
# --------------------------------------------------------------------------------------------


def _tracks(problem: CodesignProblemConfig) -> tuple[tuple[str, ...], tuple[TrackConfig, ...],
                                                      tuple[float, ...]]:
    if problem.codesign.tracks:
        items = problem.codesign.tracks.items()
        return (tuple(k for k, _ in items), tuple(load(TrackConfig, t.track) for _, t in items),
                tuple(t.weight for _, t in items))
    assert problem.track is not None  # the schema requires a track or tracks
    track = load(TrackConfig, problem.track)
    return (track.name,), (track,), (1.0,)


def _part(template: AirframeConfig, track: TrackConfig, options: LimitLapOptions,
          weight: float) -> TrackPart:
    """One track's limit-lap problem as the limit lap poses it for the template
    (:func:`casadrone.limit.starts.prepare`): its NLP, box, row bounds, start and targets."""
    frame = build_airframe(template)
    pb = prepare_lap(frame, track, options, options.gate_clearance_m or 0.0)
    return TrackPart(pb.full, *pb.box, *pb.rows, pb.x0, pb.targets.vector, weight,
                     hover_start=options.start_state is None,
                     thrust_max=rotor_state_bounds(frame)[1],
                     first_timed=pb.targets.first_timed, propulsion=frame.propulsion)


def template_lap(template: AirframeConfig, track: TrackConfig,
                 options: LimitLapOptions, seeds: LapSeeds = LapSeeds()) -> LimitLap:
    """The template's limit lap, the co-design's first start and every other frame's warm
    start: from ``seeds`` alone where given (a neighbouring lap: a build's combination starts
    from the lap of one raced before it), else or where those give no verified lap from
    ``options.starts`` (``limit_lap.starts``), and where those give none from the schema's
    default starts (:data:`DEFAULT_LAP_STARTS`) not tried yet (each start is its own solve, so
    the ones tried would fail again). No point-mass reference unless a start needs it:
    co-design does not report it, and it is three point-mass solves (13 s of the paper track's
    38)."""
    if seeds.warm_starts:
        lap = design_limit_lap(template, track, seeds_alone(options), seeds)
        if lap.completed:
            return lap
    lap = design_limit_lap(template, track, options)
    rest: tuple[Start, ...] = tuple(s for s in DEFAULT_LAP_STARTS if s not in options.starts)
    if lap.completed or not rest:
        return lap
    return design_limit_lap(template, track, replace(options, starts=rest))


_BUILT: dict[tuple, CodesignNlp] = {}


def prepare(problem: CodesignProblemConfig, epsilon: tuple[str, ...] = (),
            seeds: LapSeeds = LapSeeds(), start: dict[str, float] | None = None) -> Prepared:
    """The template, the variables, the tracks and the co-design NLP (cached per shape); the
    template's laps started from ``seeds`` where given (:func:`template_lap`). ``start``: the
    template's geometry moved to these values of the variables (a neighbour's optimum, where
    they make a valid frame), so that co-design starts there."""
    template = at_start(template_of(problem), start)
    keys = tuple(v.name for v in problem.variables)
    bad = [k for k in keys if k not in CODESIGN_KEYS]
    if bad:
        raise ConfigError([f"{problem.name}: variables: co-design varies the geometry and "
                           f"inertia keys ({', '.join(CODESIGN_KEYS)}); not {', '.join(bad)}"])
    lower = np.array([v.lower for v in problem.variables])
    upper = np.array([v.upper for v in problem.variables])
    labels, tracks, weights = _tracks(problem)
    options = codesign_lap_options(problem, template,
                                   gate_clearance(template, lower, upper, keys))
    # the problem is read and valid (a ConfigError is raised before any progress line)
    events.preparing(problem.name, len(tracks), len(keys))
    parts = tuple(_part(template, t, options, w) for t, w in zip(tracks, weights, strict=True))
    frame = SymbolicFrame(template, keys, lower, upper)
    nlp = _built(problem, template, keys, lower, upper, tracks, weights, parts, frame, epsilon)
    with nested():  # the template's limit laps, reported as one line each
        laps = tuple(template_lap(template, t, options, seeds) for t in tracks)
    events.template_laps(labels, laps)
    return Prepared(problem, template, keys, lower, upper, labels, tracks, weights, options,
                    nlp, laps)


def at_start(template: AirframeConfig, start: dict[str, float] | None) -> AirframeConfig:
    """``template`` with ``start``'s geometry where given and valid; else as it is."""
    if not start:
        return template
    try:
        moved = with_theta(template, start)
        build_airframe(moved)  # a frame whose propellers overlap is refused here
    except ConfigError:
        return template
    return moved


def _built(problem, template, keys, lower, upper, tracks, weights, parts, frame,
           epsilon) -> CodesignNlp:
    """The co-design NLP of this shape, built once per process."""
    key = (template.model_dump_json(), keys, tuple(lower), tuple(upper),
           tuple(t.model_dump_json() for t in tracks), weights, problem.codesign.combine,
           problem.limit_lap.intervals, epsilon, problem.codesign.expand)
    if key not in _BUILT:
        _BUILT[key] = build_codesign_nlp(parts, frame, problem.codesign.combine, epsilon,
                                         expand=problem.codesign.expand)
    return _BUILT[key]


def refined(prep: Prepared, intervals: int) -> Prepared:
    """``prep`` posed on ``intervals`` per leg: each track's limit-lap NLP on that grid and the
    co-design NLP around them (built once per process); the template's limit laps are kept
    (they warm-start a frame's limit lap on any grid of the same legs)."""
    options = replace(prep.options, intervals=intervals)
    settings = prep.problem.limit_lap.model_copy(update={"intervals": intervals})
    problem = prep.problem.model_copy(update={"limit_lap": settings})
    parts = tuple(_part(prep.template, t, options, w)
                  for t, w in zip(prep.tracks, prep.weights, strict=True))
    nlp = _built(problem, prep.template, prep.keys, prep.lower, prep.upper, prep.tracks,
                 prep.weights, parts, prep.nlp.frame, prep.nlp.epsilon)
    return replace(prep, problem=problem, options=options, nlp=nlp)


def resampled(prep: Prepared, point: CodesignPoint, to: Prepared) -> np.ndarray | None:
    """A start of ``to`` (another grid of the same tracks) at ``point`` of ``prep``: the
    frame's limit lap on every track on the new grid, started from the point's own lap
    resampled onto it (the limit lap's ``resampled`` warm start: same leg durations, states
    interpolated, commands held) and verified as the limit lap verifies any lap; with its θ,
    a consistent start as :func:`initial_vector`'s. None when a lap fails."""
    cfg = to.config(point.theta)
    ws, _ = prep.nlp.split(point.z)
    out = []
    for part, track, w in zip(prep.nlp.parts, to.tracks, ws, strict=True):
        T, _, _ = part.nlp.unpack(w)
        own = replace(trajectory(part.nlp, w, part.nlp.layout), leg_times_s=T,
                      solution=NlpPoint(w, np.zeros(0), np.zeros(0), np.zeros(0)))
        lap = design_limit_lap(cfg, track, replace(to.options, starts=(),
                                                   point_mass_reference=False),
                               LapSeeds(warm_starts=(own,)))
        if not lap.completed or lap.solution is None:
            return None
        out.append(lap.solution.w)
    return vector_of(to, point.theta, out)


def constrained(prep: Prepared, epsilon: tuple[str, ...]) -> Prepared:
    """``prep`` with the measures ``epsilon`` bounded by ε rows: the same tracks, box and
    template laps, the NLP built once per process."""
    nlp = _built(prep.problem, prep.template, prep.keys, prep.lower, prep.upper, prep.tracks,
                 prep.weights, prep.nlp.parts, prep.nlp.frame, tuple(epsilon))
    return replace(prep, nlp=nlp)


# --------------------------------------------------------------------------------------------
# 2. Starts
# --------------------------------------------------------------------------------------------


def start_points(prep: Prepared) -> list[tuple[str, dict[str, float]]]:
    """The template's θ (clipped into the box) and ``codesign.starts`` random feasible θ."""
    own = {k: float(np.clip(getattr(prep.template, k), lo, hi))
           for k, lo, hi in zip(prep.keys, prep.lower, prep.upper, strict=True)}
    bounds = {k: (lo, hi) for k, lo, hi in zip(prep.keys, prep.lower, prep.upper, strict=True)}
    out = []
    try:
        prep.config(own)
        out.append(("template", own))
    except ConfigError:
        pass
    if prep.problem.codesign.starts:
        thetas, _ = random_thetas(prep.template, prep.problem.codesign.starts,
                                  prep.problem.seed, bounds)
        out += [(f"random-{i + 1}", t) for i, t in enumerate(thetas)]
    return out


def initial_vector(prep: Prepared, theta: dict[str, float]) -> np.ndarray | None:
    """The co-design decision vector of a frame: its own limit lap on every track (warm-started
    from the template's) and its θ; None when a lap fails."""
    cfg = prep.config(theta)
    ws, laps = [], []
    for track, ref in zip(prep.tracks, prep.template_laps, strict=True):
        warm = (ref,) if ref.solution is not None else ()
        opts = replace(prep.options, starts=() if warm else prep.options.starts,
                       point_mass_reference=False)
        lap = design_limit_lap(cfg, track, opts, LapSeeds(warm_starts=warm))
        if not lap.completed or lap.solution is None:
            return None
        ws.append(lap.solution.w)
        laps.append(lap.lap_time_s)
    return vector_of(prep, theta, ws)


def vector_of(prep: Prepared, theta: dict[str, float], ws: list[np.ndarray]) -> np.ndarray:
    """The co-design decision vector of frame ``theta`` flying the limit-lap solutions ``ws``
    (one per track)."""
    z: list[Any] = [*ws, prep.nlp.frame.normalise(theta)]
    if prep.nlp.combine == "worst":
        laps = [float(np.sum(part.nlp.unpack(w)[0])) for part, w in zip(prep.nlp.parts, ws,
                                                                         strict=True)]
        z.append([max(w * t for w, t in zip(prep.weights, laps, strict=True))])
    return np.concatenate(z)


# --------------------------------------------------------------------------------------------
# 3. Solve
# --------------------------------------------------------------------------------------------


def solve_from(prep: Prepared, z0: np.ndarray, epsilon: dict[str, float] | None = None,
               warm: CodesignPoint | None = None,
               bounds: tuple[np.ndarray, ...] | None = None, step: bool = False,
               budget_s: float | None = None) -> tuple[bool, str, CodesignPoint]:
    """IPOPT on the co-design NLP from ``z0`` (or ``warm``'s primal-dual point); ``bounds``
    (lbx, ubx, lbg, ubg) replace the NLP's own (a certificate fixes θ with them); ``step``: a
    warm start's solve with the continuation step's iteration cap (:attr:`CodesignNlp.step`,
    where the NLP has one), stopped past ``budget_s`` CPU seconds if given."""
    cd = prep.nlp
    lbx, ubx, lbg, ubg = bounds if bounds is not None else (*cd.bounds(), cd.lbg, cd.ubg)
    eps = np.array([(epsilon or {})[m] for m in cd.epsilon], float)
    args = dict(x0=np.clip(cd.full(z0), lbx, ubx), lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg,
                p=eps)
    solver = cd.cold
    if warm is not None:  # a point of the NLP without some rows or variables: zeros for them
        solver = cd.step if step and cd.step is not None else cd.warm
        args.update(x0=np.clip(cd.full(warm.z), lbx, ubx),
                    lam_x0=_padded(warm.lam_x, len(lbx)), lam_g0=_padded(warm.lam_g, len(cd.lbg)))
    if solver is cd.step and cd.budget is not None:
        cd.budget.start(budget_s)
    c0 = time.process_time()
    try:
        out = solver(**args)
        stats = solver.stats()
        status = str(stats.get("return_status", "unknown"))
        if status == STOPPED and cd.budget is not None and solver is cd.step:
            status = f"stopped at the step's CPU budget ({cd.budget.limit_s:.3g} s)"
        ok = bool(stats.get("success", False)) and np.isfinite(float(out["f"]))
        z, lam_x, lam_g = (np.array(out[k], float).ravel() for k in ("x", "lam_x", "lam_g"))
        iters = int(stats.get("iter_count", 0))
    except RuntimeError as exc:
        status, ok, iters = f"error: {str(exc).splitlines()[-1][:100]}", False, 0
        z, lam_x, lam_g = np.asarray(z0, float), np.zeros(len(lbx)), np.zeros(len(cd.lbg))
    cpu = time.process_time() - c0
    return ok, status, point_of(prep, z, lam_x, lam_g, iters, cpu, epsilon or {})


def _padded(v: np.ndarray, n: int) -> np.ndarray:
    """``v`` with zeros appended up to length ``n`` (multipliers of rows or variables that a
    warm start's NLP did not have)."""
    v = np.asarray(v, float).ravel()
    return np.concatenate([v, np.zeros(n - len(v))]) if len(v) < n else v


def point_of(prep: Prepared, z, lam_x, lam_g, iterations: int, cpu_s: float,
             epsilon: dict[str, float]) -> CodesignPoint:
    """A decision vector read as a :class:`CodesignPoint`."""
    cd = prep.nlp
    ws, s = cd.split(z)
    theta = {k: float(v) for k, v in cd.frame.theta(np.clip(s, 0.0, 1.0)).items()}
    laps = {lab: float(np.sum(part.nlp.unpack(w)[0]))
            for lab, part, w in zip(prep.labels, cd.parts, ws, strict=True)}
    _, _, _, mass, diagonals = cd.frame.function(np.clip(s, 0.0, 1.0))
    objective = (sum(w * t for w, t in zip(prep.weights, laps.values(), strict=True))
                 if cd.combine == "sum" else
                 max(w * t for w, t in zip(prep.weights, laps.values(), strict=True)))
    return CodesignPoint(theta, float(objective), laps, float(mass),
                         float(np.max(np.asarray(diagonals))), iterations, cpu_s,
                         dict(epsilon), z, lam_x, lam_g)


def distinct_optima(points: list[CodesignPoint]) -> list[CodesignPoint]:
    """Converged points whose objectives differ by more than AGREE_REL, best first."""
    out: list[CodesignPoint] = []
    for p in sorted(points, key=lambda p: p.objective):
        if all(abs(p.objective - q.objective) > AGREE_REL * q.objective for q in out):
            out.append(p)
    return out


__all__ = ["FRONT_MEASURES", "CodesignPoint", "CodesignResult", "StartReport", "prepare",
           "solve_from"]
