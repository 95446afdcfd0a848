"""Trim-solver study: how often, how fast and to which point each solver converges from many
starts, at operating points across the flight envelope.

At each operating point every solver starts from the same N + 1 guesses: the analytic guess of
:func:`casadrone.trim.initial_guess` and N draws around it, uniform in a box of stated size:
φ0, θ0 = guess ± ``angle_spread_deg``; δ0_i = guess_i (1 ± ``command_spread``). These are the
unknowns every propulsion model shares and ``TrimOptions.initial_guess`` takes; the rotor states
a propulsion model adds to the unknowns (rotor speeds) start where the trim's own analytic
guess puts them. The draws come from
``numpy.random.default_rng([seed, crc32(point label)])`` (PCG64: the same numbers on any
machine), so a point's starts do not depend on which other points are studied.

Each solve is :func:`casadrone.trim.trim` itself, timed by it, and ends in one outcome:

* ``converged`` — a trim (residual within the solver's tolerance) at the reference solution;
* ``other-trim`` — a trim elsewhere (another root of the equations inside the model's domain);
* ``out-of-domain`` — a root of the equations outside the trim's domain, with a tilt beyond
  ``max_tilt_deg``: inverted on negative thrust (φ = π, commands < 0), or the same flight tail
  first (φ = π, θ − π: the attitude with the heading reversed, which ψ = 0 excludes);
* ``failed`` — no root: the iteration cap or a stall with a finite residual above tolerance;
* ``diverged`` — the iterate ran away: non-finite values.

A diverging start is an outcome, never an exception. The reference solution of a point is the
trim of ``reference_solver`` from the analytic guess (the other solvers if it fails); distances
are ∞-norms in Z = (φ, θ, δ…) with angles wrapped to (−π, π] (rad and command units, both of
order one). Converged points closer than ``distinct_tolerance`` are one solution.
"""

from __future__ import annotations

import math
import time
import zlib
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from casadrone.airframe import Airframe
from casadrone.conditions import OperatingPoint, envelope
from casadrone.progress import emit
from casadrone.results import AsDict
from casadrone.trim import (
    SOLVERS,
    UNKNOWN_NAMES,
    TrimOptions,
    TrimPoint,
    initial_guess,
    residual_norm,
    trim,
)

Outcome = Literal["converged", "other-trim", "out-of-domain", "failed", "diverged"]
OUTCOMES: tuple[str, ...] = ("converged", "other-trim", "out-of-domain", "failed", "diverged")


@dataclass(frozen=True)
class StudyOptions(AsDict):
    """Settings of a study; ValueError naming the field on a bad value.

    Attributes:
        starts: random starts per point and solver, besides the analytic guess (≥ 0).
        seed: seed of the start draws.
        angle_spread_deg: half-width of the box of φ0, θ0 around the guess (deg, 0–80).
        command_spread: half-width of the relative box of δ0 around the guess (0–1).
        solvers: the solvers compared, of :data:`casadrone.trim.SOLVERS`.
        reference_solver: whose trim from the analytic guess is the reference solution.
        distinct_tolerance: two trims closer than this (∞-norm in Z) are the same solution.
        trim: the solvers' own settings (tolerances, iteration caps); ``initial_guess`` unused.
    """

    starts: int = 20
    seed: int = 0
    angle_spread_deg: float = 60.0
    command_spread: float = 0.8
    solvers: tuple[str, ...] = SOLVERS
    reference_solver: str = "newton"
    distinct_tolerance: float = 1e-4
    trim: TrimOptions = field(default_factory=TrimOptions)

    def __post_init__(self) -> None:
        checks = {
            "starts": 0 <= self.starts <= 100_000,
            "angle_spread_deg": 0 <= self.angle_spread_deg <= 80,
            "command_spread": 0 <= self.command_spread < 1,
            "solvers": bool(self.solvers) and set(self.solvers) <= set(SOLVERS)
            and len(set(self.solvers)) == len(self.solvers),
            "reference_solver": self.reference_solver in SOLVERS,
            "distinct_tolerance": 0 < self.distinct_tolerance < 1,
            "seed": 0 <= self.seed < 2**63,
        }
        for name, ok in checks.items():
            if not ok:
                raise ValueError(f"{name}: {getattr(self, name)!r} is out of range "
                                 f"({_RANGES[name]})")


#: Most trim solves one study may ask for (points × (starts + 1) × solvers, and a --plot basin's
#: grid² × solvers): the default study is 819 solves and 16 s of CPU (SY250, ~20 ms a solve
#: over the three solvers' mix), so this is about 16 minutes; more is a typo (``--starts
#: 100000``), not a study.
MAX_SOLVES = 50_000


def solve_count(points: int, options: StudyOptions, basin_grid: int = 0) -> int:
    """The trim solves a study of ``points`` operating points asks for (the analytic guess and
    ``options.starts`` random starts per point and solver), a basin slice of ``basin_grid``²
    starts per solver added."""
    return (points * (options.starts + 1) + basin_grid ** 2) * len(options.solvers)


_RANGES = {
    "starts": "0 to 100000", "angle_spread_deg": "0 to 80 deg", "command_spread": "0 to < 1",
    "solvers": f"distinct names of {', '.join(SOLVERS)}", "reference_solver": ", ".join(SOLVERS),
    "distinct_tolerance": "> 0 and < 1", "seed": "0 to 2**63 - 1",
}


@dataclass(frozen=True)
class StartResult(AsDict):
    """One solver from one start: its outcome, cost and where it ended.

    Attributes:
        start: index of the start (0 is the analytic guess); solver: the solver.
        outcome: one of :data:`OUTCOMES`; success: the trim's own verdict.
        iterations, wall_time_s, residual_norm: as the TrimPoint reports them.
        distance: ∞-norm to the reference solution in Z (nan without a trim or a reference).
        solution: index into the point's ``solutions`` (−1 without a trim).
        z: where it ended, (φ, θ, δ1…δ4) (angles wrapped; the rotor states of another
            propulsion model follow from the commands at rest); message: the trim's message.
    """

    start: int
    solver: str
    outcome: str
    success: bool
    iterations: int
    wall_time_s: float
    residual_norm: float
    distance: float
    solution: int
    z: np.ndarray
    message: str


@dataclass(frozen=True)
class SolverSummary(AsDict):
    """One solver at one point over all its starts. Spreads are the quartiles (25 %, 75 %).

    Attributes:
        success_rate: trims (converged or other trim) per start.
        outcomes: count of each of :data:`OUTCOMES`.
        iterations_median, iterations_q25, iterations_q75, iterations_max: over the trims.
        wall_time_median_s, wall_time_q25_s, wall_time_q75_s: over every start (a failure
            costs time too).
        residual_median, residual_max: over the trims; distance_max: largest distance of a
            trim from the reference; solutions: distinct roots this solver found (trims and
            out-of-domain roots).
        from_guess: outcome from the analytic guess.
    """

    solver: str
    starts: int
    success_rate: float
    outcomes: dict[str, int]
    iterations_median: float
    iterations_q25: float
    iterations_q75: float
    iterations_max: float
    wall_time_median_s: float
    wall_time_q25_s: float
    wall_time_q75_s: float
    residual_median: float
    residual_max: float
    distance_max: float
    solutions: int
    from_guess: str


@dataclass(frozen=True)
class Solution(AsDict):
    """A distinct root of the trim equations found at a point: its Z, distance from the
    reference, which solvers found it how often, whether it lies in the model's domain (tilt
    within ``max_tilt_deg``: a trim) and whether its commands lie in [0, 1] (a flyable one)."""

    z: np.ndarray
    distance: float
    found_by: dict[str, int]
    in_domain: bool
    commands_in_range: bool


@dataclass(frozen=True)
class PointStudy:
    """Every solver from every start at one operating point."""

    point: OperatingPoint
    guess: np.ndarray
    reference: np.ndarray | None
    reference_solver: str
    starts: np.ndarray  # (N + 1, nz): row 0 the analytic guess
    results: tuple[StartResult, ...]
    summaries: tuple[SolverSummary, ...]
    solutions: tuple[Solution, ...]

    def summary(self, solver: str) -> SolverSummary:
        return next(s for s in self.summaries if s.solver == solver)

    def as_dict(self, starts: bool = True) -> dict[str, Any]:
        out = {
            "point": self.point.as_dict(), "guess": self.guess, "reference": self.reference,
            "reference_solver": self.reference_solver,
            "summaries": [s.as_dict() for s in self.summaries],
            "solutions": [s.as_dict() for s in self.solutions],
        }
        if starts:
            out |= {"starts": self.starts, "results": [r.as_dict() for r in self.results]}
        return out


@dataclass(frozen=True)
class TrimStudy:
    """A trim-solver study of one airframe over operating points. ``unknown_names`` name the
    columns of each point's ``starts`` and of every ``z``: (φ, θ, δ1…δ4)."""

    airframe: str
    options: StudyOptions
    points: tuple[PointStudy, ...]
    unknown_names: tuple[str, ...]
    wall_time_s: float

    def as_dict(self, starts: bool = True) -> dict[str, Any]:
        """Plain data (arrays stay arrays; :func:`casadrone.cli.common.jsonable` makes JSON)."""
        return {"airframe": self.airframe, "options": self.options.as_dict(),
                "unknown_names": list(self.unknown_names), "wall_time_s": self.wall_time_s,
                "points": [p.as_dict(starts) for p in self.points]}


# ---------------------------------------------------------------------------------------------
# Starts, outcomes, solutions
# ---------------------------------------------------------------------------------------------


def draw_starts(guess: np.ndarray, point: OperatingPoint, options: StudyOptions) -> np.ndarray:
    """(N + 1, nz) starts: the guess, then N uniform draws in the box around it."""
    rng = np.random.default_rng([options.seed, zlib.crc32(point.label.encode())])
    n, nz = options.starts, len(guess)
    u = rng.uniform(-1.0, 1.0, size=(n, nz))
    draws = np.empty((n, nz))
    draws[:, :2] = guess[:2] + math.radians(options.angle_spread_deg) * u[:, :2]
    draws[:, 2:] = guess[2:] * (1.0 + options.command_spread * u[:, 2:])
    return np.vstack([guess, draws])


def _z_of(tp: TrimPoint) -> np.ndarray:
    """Z of a trim, angles wrapped to (−π, π]."""
    angles = np.angle(np.exp(1j * tp.x0[9:11]))
    return np.concatenate([angles, tp.u0])


def _distance(a: np.ndarray, b: np.ndarray | None) -> float:
    if b is None:
        return math.nan
    d = np.abs(a - b)
    d[:2] = np.minimum(d[:2], 2 * math.pi - d[:2])
    return float(np.max(d))


def outcome_of(tp: TrimPoint, distance: float, options: StudyOptions) -> str:
    """The :data:`OUTCOMES` entry of one solve."""
    if not (np.all(np.isfinite(tp.x0)) and math.isfinite(tp.residual_norm)):
        return "diverged"
    o = options.trim
    tol = o.nelder_mead_tolerance if tp.solver == "nelder-mead" else o.tolerance
    if tp.residual_norm > tol:
        return "failed"
    if math.degrees(float(np.max(np.abs(tp.x0[9:11])))) > o.max_tilt_deg:
        return "out-of-domain"
    if math.isnan(distance) or distance <= options.distinct_tolerance:
        return "converged"
    return "other-trim"


def _reference(frame: Airframe, point: OperatingPoint, options: StudyOptions):
    """(Z, solver) of the reference trim: ``reference_solver`` from the analytic guess, else
    the first other solver that succeeds there; (None, "") if none does."""
    order = [options.reference_solver, *(s for s in SOLVERS if s != options.reference_solver)]
    analytic = replace(options.trim, initial_guess=None)
    for solver in order:
        tp = trim(frame, point.condition, solver=solver, options=analytic, **point.kwargs)
        if tp.success:
            return _z_of(tp), solver
    return None, ""


def _cluster(zs: list[np.ndarray], tol: float) -> tuple[list[int], list[np.ndarray]]:
    """Greedy clustering of trims: each Z's cluster index and the cluster representatives."""
    reps: list[np.ndarray] = []
    labels = []
    for z in zs:
        k = next((i for i, r in enumerate(reps) if _distance(z, r) <= tol), None)
        if k is None:
            reps.append(z)
            k = len(reps) - 1
        labels.append(k)
    return labels, reps


# ---------------------------------------------------------------------------------------------
# The study
# ---------------------------------------------------------------------------------------------


def analytic_guess(frame: Airframe, point: OperatingPoint) -> np.ndarray:
    """The trim's analytic guess of (φ, θ, δ1…δ4) at ``point`` (the unknowns the study varies)."""
    full = initial_guess(frame, point.speed_mps, climb_angle_deg=point.climb_angle_deg,
                         turn_rate_dps=point.turn_rate_dps)
    return full[:len(UNKNOWN_NAMES)]


def study_point(frame: Airframe, point: OperatingPoint, options: StudyOptions) -> PointStudy:
    """Every solver of ``options`` from every start at one operating point."""
    guess = analytic_guess(frame, point)
    starts = draw_starts(guess, point, options)
    reference, ref_solver = _reference(frame, point, options)
    runs = []
    for solver in options.solvers:
        for k, z0 in enumerate(starts):
            opts = _with_guess(options.trim, z0)
            runs.append((k, solver, trim(frame, point.condition, solver=solver, options=opts,
                                         **point.kwargs)))
    zs = [_z_of(tp) for _, _, tp in runs]
    roots = [i for i, (_, _, tp) in enumerate(runs) if _is_root(tp, options)]
    labels, reps = _cluster([zs[i] for i in roots], options.distinct_tolerance)
    solution_of = dict(zip(roots, labels, strict=True))
    results = tuple(_start_result(k, solver, tp, zs[i], reference, solution_of.get(i, -1),
                                  options) for i, (k, solver, tp) in enumerate(runs))
    solutions = tuple(_solution(j, rep, results, reference, options)
                      for j, rep in enumerate(reps))
    summaries = tuple(summarise(solver, [r for r in results if r.solver == solver])
                      for solver in options.solvers)
    return PointStudy(point, guess, reference, ref_solver, starts, results, summaries, solutions)


def _is_root(tp: TrimPoint, options: StudyOptions) -> bool:
    """Whether a solve ended on a root of the trim equations (in the domain or not)."""
    o = options.trim
    tol = o.nelder_mead_tolerance if tp.solver == "nelder-mead" else o.tolerance
    return bool(np.all(np.isfinite(tp.x0))) and tp.residual_norm <= tol


def _with_guess(o: TrimOptions, z0: np.ndarray) -> TrimOptions:
    return replace(o, initial_guess=tuple(float(v) for v in z0))


def _start_result(k: int, solver: str, tp: TrimPoint, z: np.ndarray, reference, solution: int,
                  options: StudyOptions) -> StartResult:
    distance = _distance(z, reference) if solution >= 0 else math.nan
    return StartResult(
        start=k, solver=solver, outcome=outcome_of(tp, distance, options), success=tp.success,
        iterations=tp.iterations, wall_time_s=tp.wall_time_s, residual_norm=tp.residual_norm,
        distance=distance, solution=solution, z=z, message=tp.message,
    )


def _solution(j: int, rep: np.ndarray, results, reference, options: StudyOptions) -> Solution:
    found: dict[str, int] = {}
    for r in results:
        if r.solution == j:
            found[r.solver] = found.get(r.solver, 0) + 1
    tilt = math.degrees(float(np.max(np.abs(rep[:2]))))
    return Solution(z=rep, distance=_distance(rep, reference), found_by=found,
                    in_domain=tilt <= options.trim.max_tilt_deg,
                    commands_in_range=bool(np.all((rep[2:] >= 0) & (rep[2:] <= 1))))


def summarise(solver: str, results: list[StartResult]) -> SolverSummary:
    """Statistics of one solver's starts at one point."""
    ok = [r for r in results if r.success]
    its = np.array([r.iterations for r in ok], float)
    wall = np.array([r.wall_time_s for r in results], float)
    res = np.array([r.residual_norm for r in ok], float)
    dist = np.array([r.distance for r in ok], float)  # nan without a reference

    def q(a: np.ndarray, p: float) -> float:
        return float(np.percentile(a, p)) if len(a) else math.nan

    guess = [r.outcome for r in results if r.start == 0]
    return SolverSummary(
        solver=solver, starts=len(results), success_rate=len(ok) / max(len(results), 1),
        outcomes={o: sum(r.outcome == o for r in results) for o in OUTCOMES},
        iterations_median=q(its, 50), iterations_q25=q(its, 25), iterations_q75=q(its, 75),
        iterations_max=float(its.max()) if len(its) else math.nan,
        wall_time_median_s=q(wall, 50), wall_time_q25_s=q(wall, 25), wall_time_q75_s=q(wall, 75),
        residual_median=q(res, 50), residual_max=float(res.max()) if len(res) else math.nan,
        distance_max=float(np.nanmax(dist)) if len(dist) and not np.all(np.isnan(dist))
        else math.nan,
        solutions=len({r.solution for r in results if r.solution >= 0}),
        from_guess=guess[0] if guess else "",
    )


def trim_study(
    frame: Airframe,
    points: tuple[OperatingPoint, ...] | str = "hover,forward,climb,turn",
    options: StudyOptions | None = None,
) -> TrimStudy:
    """Study the trim solvers of ``options`` on ``frame`` at ``points`` (operating points, or an
    envelope spec of :func:`casadrone.conditions.envelope`)."""
    o = options or StudyOptions()
    pts = envelope(points) if isinstance(points, str) else tuple(points)
    start = time.perf_counter()
    studies: list[PointStudy] = []
    for k, p in enumerate(pts, start=1):
        c0 = time.process_time()
        studies.append(study_point(frame, p, o))
        _point_done(k, len(pts), studies[-1], time.process_time() - c0)
    return TrimStudy(frame.name, o, tuple(studies), UNKNOWN_NAMES, time.perf_counter() - start)


def _point_done(k: int, n: int, study: PointStudy, cpu_s: float) -> None:
    """Progress (:mod:`casadrone.progress`): operating point ``k`` of ``n`` studied."""
    rates = ", ".join(f"{s.solver} {s.success_rate:.0%}" for s in study.summaries)
    emit("stage", f"point {k}/{n} {study.point.label}: trimmed from {len(study.starts)} "
         f"start(s): {rates}; {cpu_s:.1f} s CPU", cpu_s=cpu_s)


# ---------------------------------------------------------------------------------------------
# Basins of attraction and residual histories (for the figures)
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BasinSlice:
    """Outcomes from a grid of starts in a 2-D slice through the analytic guess: φ0 and θ0 offset
    by up to ± ``angle_spread_deg``, the other unknowns at the guess.

    Attributes:
        point: the operating point; phi_offset_deg, theta_offset_deg: the grid axes (deg).
        outcomes: solver → (n_theta, n_phi) array of :data:`OUTCOMES` indices.
        iterations: solver → (n_theta, n_phi) iterations.
    """

    point: OperatingPoint
    phi_offset_deg: np.ndarray
    theta_offset_deg: np.ndarray
    outcomes: dict[str, np.ndarray]
    iterations: dict[str, np.ndarray]

    def as_dict(self) -> dict[str, Any]:
        return {"point": self.point.as_dict(), "phi_offset_deg": self.phi_offset_deg,
                "theta_offset_deg": self.theta_offset_deg, "outcome_names": list(OUTCOMES),
                "outcomes": self.outcomes, "iterations": self.iterations}


def basin_slice(frame: Airframe, point: OperatingPoint, options: StudyOptions | None = None,
                grid: int = 21) -> BasinSlice:
    """Every solver of ``options`` from a ``grid`` × ``grid`` lattice of (φ0, θ0) starts."""
    o = options or StudyOptions()
    guess = analytic_guess(frame, point)
    reference, _ = _reference(frame, point, o)
    offsets = np.linspace(-o.angle_spread_deg, o.angle_spread_deg, grid)
    outcomes, iterations = {}, {}
    for solver in o.solvers:
        out = np.zeros((grid, grid), int)
        its = np.zeros((grid, grid), int)
        for i, dth in enumerate(offsets):
            for j, dph in enumerate(offsets):
                z0 = guess + np.r_[math.radians(dph), math.radians(dth), np.zeros(len(guess) - 2)]
                tp = trim(frame, point.condition, solver=solver, options=_with_guess(o.trim, z0),
                          **point.kwargs)
                z = _z_of(tp)
                d = _distance(z, reference) if _is_root(tp, o) else math.nan
                out[i, j] = OUTCOMES.index(outcome_of(tp, d, o))
                its[i, j] = tp.iterations
        outcomes[solver], iterations[solver] = out, its
        emit("stage", f"basin slice of {point.label}: {solver} from {grid} x {grid} starts")
    return BasinSlice(point, offsets, offsets.copy(), outcomes, iterations)


@dataclass(frozen=True)
class ResidualHistory(AsDict):
    """Residual norm (SI) after k iterations of one solver from one start: the same solver run
    again with its iteration cap at k (each solver is deterministic, so this is its k-th
    iterate, restarts of Nelder–Mead included); k = 0 is the start."""

    solver: str
    start: str
    iterations: np.ndarray
    residual_norm: np.ndarray


def residual_history(frame: Airframe, point: OperatingPoint, solver: str, z0: np.ndarray,
                     options: TrimOptions | None = None, start: str = "",
                     samples: int = 25) -> ResidualHistory:
    """:class:`ResidualHistory` of ``solver`` from ``z0``: every iteration up to ``samples``,
    then ``samples`` geometrically spaced iteration counts up to where it stopped."""
    o = _with_guess(options or TrimOptions(), z0)
    full = trim(frame, point.condition, solver=solver, options=o, **point.kwargs)
    n = max(full.iterations, 1)
    ks = np.unique(np.r_[np.arange(1, min(n, samples) + 1),
                         np.geomspace(1, n, samples).round().astype(int)])
    everything = initial_guess(frame, point.speed_mps, climb_angle_deg=point.climb_angle_deg,
                               turn_rate_dps=point.turn_rate_dps)
    z_start = np.concatenate([z0, everything[len(z0):]])  # rotor states beyond z0, as trim does
    res = [residual_norm(frame, z_start, point.condition, **point.kwargs)]
    for k in ks:
        capped = replace(o, max_iterations=int(k), nelder_mead_max_iterations=int(k))
        res.append(trim(frame, point.condition, solver=solver, options=capped,
                        **point.kwargs).residual_norm)
    return ResidualHistory(solver, start, np.r_[0, ks], np.array(res))
