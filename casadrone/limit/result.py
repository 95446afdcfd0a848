"""The limit lap's options, seeds and result types (docs/concepts/limit-lap.md): what goes into
:func:`casadrone.limit.lap.limit_lap` (settings, :class:`LimitLapOptions`; data,
:class:`LapSeeds`) and what comes out, with the conversions between the
model's states and the 16 Euler-model states."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace
from typing import Literal, Protocol

import numpy as np

from casadrone.config.controller import ControllerConfig
from casadrone.config.limitlap import (
    Attitude,
    Resimulation,
    RotorStep,
    Solver,
    Start,
    TiltLimit,
)
from casadrone.limit.attitude import euler_states_to_quat, quat_states_to_euler
from casadrone.limit.nlp import Layout, NlpPoint
from casadrone.limit.sensitivity import KeySensitivity
from casadrone.model import NX
from casadrone.propulsion import PROPULSION_MODELS
from casadrone.results import AsDict, Status

#: How far the verified starts agree (:func:`casadrone.limit.choose.certainty`).
Certainty = Literal["agreed", "single", "spread"]
#: How one solve ended, whatever the solver (:func:`ending`): "optimal" (converged to the
#: solver's tolerance, ``tol``), "acceptable" (stopped at IPOPT's acceptable level,
#: ``acceptable_tol`` = 1000 tol, held for 15 iterations: a point the solver itself calls less
#: than optimal), "failed" (no point: infeasible, restoration failed, iteration limit, an
#: evaluation error) or "not-run" (the start had no guess).
Ending = Literal["optimal", "acceptable", "failed", "not-run"]
#: The solvers' return statuses that count as converged, and the ending each is.
CONVERGED_STATUSES: dict[str, Ending] = {"Solve_Succeeded": "optimal",
                                         "Solved_To_Acceptable_Level": "acceptable"}


def ending(success: bool, return_status: str) -> Ending:
    """The :data:`Ending` of a solve from its success flag and the solver's return status
    (IPOPT's, or fatrop's mapped onto IPOPT's words by casadrone.limit.stagewise)."""
    if return_status.startswith("not run"):
        return "not-run"
    if not success:
        return "failed"
    return CONVERGED_STATUSES.get(return_status, "optimal")


def euler_states(attitude: str, X: np.ndarray) -> np.ndarray:
    """Model states (rows) as 16 Euler-model states."""
    if attitude == "quaternion":
        return quat_states_to_euler(X)
    return np.asarray(X, float)


def model_states(attitude: str, X: np.ndarray) -> np.ndarray:
    """16 Euler-model states (rows) as the model's states."""
    if attitude == "quaternion":
        return euler_states_to_quat(X)
    return np.atleast_2d(np.asarray(X, float))


class _DefaultIntervals(Mapping[str, int]):
    """The registered propulsion models' ``default_intervals``, read when asked (a model
    registered later is in it)."""

    def __getitem__(self, kind: str) -> int:
        return PROPULSION_MODELS[kind].default_intervals

    def __iter__(self) -> Iterator[str]:
        return iter(PROPULSION_MODELS)

    def __len__(self) -> int:
        return len(PROPULSION_MODELS)


#: Intervals per leg by propulsion kind (LimitLapOptions.intervals None): each model's own
#: (:attr:`casadrone.propulsion.base.PropulsionModel.default_intervals`; paper 40, propeller 80).
DEFAULT_INTERVALS: Mapping[str, int] = _DefaultIntervals()
#: Most intervals over the whole course (legs × laps × intervals per leg), the grid rounds and
#: the refinement then solving up to 1.5× as many. The NLP's memory grows ~0.3 MB per interval
#: in a whole limit lap (20 000 reached 5.8 GB: casadrone.config.limitlap.MAX_INTERVALS;
#: building the NLP and three IPOPT iterations alone: 0.07-0.1 MB, 390 MB at 3 200), so 6 000
#: keep a limit lap within about 2-3 GB, and still take a 20-gate, three-lap race at the
#: propeller model's 80 per leg. A 5 000-waypoint, 20-lap track had run out of memory (5.4 GB
#: under a 6 GB limit) unrefused.
MAX_TOTAL_INTERVALS = 6000


@dataclass(frozen=True)
class LimitLapOptions:
    """Numerical and modelling settings of the limit lap (identical for every candidate)."""

    # Intervals per leg; None: DEFAULT_INTERVALS of the frame's propulsion kind. Grid refinement
    # on SY250, from the coarse optimum resampled: 30 -> 60 changed the lap by 0.13 %, 40 -> 80
    # by 0.02 % (the acceptance is < 0.1 %); 40 with 2 RK4 steps per interval instead of 3
    # changed by up to 0.16 %.
    intervals: int | None = None
    method: Literal["shooting", "collocation"] = "shooting"  # see casadrone.limit.nlp
    substeps: int = 3  # RK4 steps per interval (shooting)
    # Step of the rotor states (shooting): "rk4" (classical RK4, every state) or "exponential"
    # (ETDRK4: the rotors' linear decay integrated exactly, RK4 elsewhere;
    # casadrone.limit.nlp.etdrk4_step), which follows the propeller kind's ~20 ms rotor lag on
    # coarser grids: SY250-propeller's point-mass start on 40 intervals of 4 steps re-simulates
    # within 2.1 cm (RK4 on 40 x 3: 0.30 m) and its warm solves take 0.69x the CPU of 80 x 3
    # RK4's at the same iterations (measured side by side on a quiet machine). Opt-in: the lap
    # the command's default starts chose on that grid missed by 13.3 cm (the issue asks 5 cm),
    # and the default grid decides every propeller figure and the co-design blocks
    # (benchmarks/RESULTS-propulsion.md, "The exponential rotor step, side by side").
    rotor_step: RotorStep = "rk4"
    degree: int = 3  # Radau collocation points per interval (collocation)
    # "coarse-grid": grid continuation, the closed-loop start solved on COARSE_SHARE of the
    # intervals and its optimum resampled onto this grid (a coarse grid smooths the problem);
    # "relaxed-tolerance": tolerance homotopy from the point-mass start (balls of at least
    # RELAXED_RADIUS_M first, then the track's tolerances from that point).
    # "fine-grid": the point-mass start solved on FINE_SHARE of the intervals, resampled.
    # Measured (benchmarks/RESULTS-limitlap-issue19.md): on the gate track the coarse-grid start
    # is 0.34 % faster than the other two; on the paper track it adds nothing (+0.03 %). The
    # fine-grid start was the best start on the paper track for SY250 (3.8800 s against 3.9097 s
    # from the other starts) and HS210 (3.8405 s against 3.8954 s), for about 20-30 s of CPU;
    # the best laps known are 3.8795 s (SY250, from grid rounds) and 3.8307 s (HS210, its
    # fine-grid start on another VM). The relaxed-tolerance start lands where the point-mass
    # start does.
    # "library": the best lap shipped for the track (casadrone.limit.library), solved first; it
    # does nothing on a track with none. With the chained derivative blocks HS210's four cold
    # starts alone stop at 3.8833 s on the paper track, from the shipped lap 3.8312 s.
    starts: tuple[Start, ...] = ("closed-loop", "point-mass", "coarse-grid", "fine-grid",
                                 "library")
    # Cold starts solved only when none of ``starts`` gave a verified lap: the fast path's
    # ("library" first; the grid-continuation starts where no lap of the track is shipped or
    # the shipped one does not lead to a verified lap: casadrone.limit.search).
    fallback_starts: tuple[Start, ...] = ()
    ball_radius_m: float | None = None  # None: the track's acceptance radius
    # Kept from the gate's frame on each side (m); None: the frame's own size (the farthest
    # rotor plus a propeller radius, frame_clearance_m).
    gate_clearance_m: float | None = None
    max_tilt_deg: float | None = None  # None: the track's max_tilt_deg
    # Attitude of the full model: "euler" (ZYX angles, singular at 90 deg of pitch) or
    # "quaternion" (no singularity: split-S, loops, inverted flight; casadrone.limit.attitude).
    attitude: Attitude = "euler"
    # Tilt limit at max_tilt_deg: "axes" |phi|, |theta| each (the closed loop's failure test;
    # Euler only; together they allow up to 88 deg of total tilt at 80), "cone" on the total
    # tilt (angle between body z and world z, at every node), or "none".
    tilt_limit: TiltLimit = "axes"
    start_state: tuple[float, ...] | None = None  # 16 values; None: hover at the start
    # NLP solver of the full model: "ipopt" (the reference) or "fatrop" (the same NLP in stage
    # order, Riccati factorisation; IPOPT re-solves where it fails: casadrone.limit.stagewise).
    # The point-mass reference is always IPOPT's.
    solver: Solver = "ipopt"
    tol: float = 1e-6  # IPOPT: laps agree with tol 1e-8's to ~1e-6 s in 5-20 % fewer iterations
    max_iter: int = 1000
    # The point-mass reference (not a bound: the best of REFERENCE_SPEEDS_MPS local optima of
    # the point-mass relaxation), solved once per (mass, thrust, drag, track) and cached.
    point_mass_reference: bool = True
    resimulate: bool = True  # re-simulate every converged start; choose among those that pass
    # Largest re-simulation miss (m) of a chosen start. Honest optima miss by 0.003-0.09 m (the
    # open-loop drift of a 4 s lap at up to 55 m/s); optima that exploit the discretisation
    # (RK4 near the Euler-angle singularity at 80 deg tilt) missed by 0.2-60 m.
    max_miss_m: float = 0.15
    # What the re-simulation flies: "lap", the whole lap's commands open loop from the start
    # state (the default: the commands alone fly the lap); "legs", each leg's commands from the
    # NLP's own state at the leg's start node, so a lap that is accurate but drifts open loop
    # (an open-loop-unstable optimum: local defects as small as a verified lap's, every leg
    # within 1.7 cm from its own node, the whole lap 2-15 m off; SY250-propeller's random frames
    # 14, 21, 35) passes, while one that exploits the discretisation still fails within its leg
    # (casadrone.limit.check.resimulation_miss; benchmarks/RESULTS-propulsion.md, "Random
    # Table 1 frames under `propeller`, 50 frames").
    resimulation: Resimulation = "lap"
    sensitivities: bool = True
    # Shipped airframe whose limit lap (same track and options) starts a frame whose own starts
    # all fail (module docstring, "fallback"); None: no fallback.
    fallback_reference: str | None = "SY250"
    # Grid refinements when starts converge but none passes the re-simulation check (the grid
    # too coarse for the lap: casadrone.limit.lap.refined): the fastest converged lap resampled
    # onto REFINE_FACTOR times the intervals, at most this many times; 0: none.
    refinements: int = 2
    # Grid-continuation rounds (casadrone.limit.lap.grid_rounds): a verified lap resampled
    # onto the coarse- and fine-grid starts' grids and solved there, then each of those laps
    # resampled back and solved here (verified like any other start): round 1 from every
    # verified start ("grid-N-round-1-START"), later rounds from the best lap ("grid-N-round-r"),
    # until a round improves the lap by less than CERTAIN_REL; 0: none. 0 here, the
    # setting of the searches that fly a limit lap per frame (evaluation, co-design); the
    # command's default is COMMAND_GRID_ROUNDS (benchmarks/RESULTS-limitlap-issue19.md, "Grid
    # rounds as the command's default").
    grid_rounds: int = 0


class FlownLap(Protocol):
    """What the closed-loop start reads of a lap already flown (a
    :class:`casadrone.simulate.Trajectory`, whose module this one does not import): sample times
    (s), the 16 Euler-model states and the ESC commands at them, the route segment flown."""

    @property
    def t(self) -> np.ndarray: ...

    @property
    def x(self) -> np.ndarray: ...

    @property
    def u(self) -> np.ndarray: ...

    @property
    def segment(self) -> np.ndarray: ...


@dataclass(frozen=True)
class LapSeeds:
    """What a limit lap may start from beside its options' cold starts: data (earlier laps, a
    flown trajectory, the controller that flies the closed-loop start), never settings, so the
    options stay the same for every candidate of a study while the seeds differ."""

    warm_starts: tuple[LimitLap, ...] = ()  # neighbouring solutions (same legs; any grid)
    guess_trajectory: FlownLap | None = None  # the frame's closed-loop lap, if already flown
    controller: ControllerConfig | None = None  # closed-loop start; None: the default controller


@dataclass(frozen=True)
class StartResult(AsDict):
    """What one start of the solver gave."""

    start: str
    success: bool
    return_status: str
    lap_time_s: float
    iterations: int
    wall_time_s: float
    resimulation_miss_m: float = math.nan  # NaN: not converged or not re-simulated
    solver: str = "ipopt"  # whose point it is ("ipopt" also where fatrop failed first)
    #: fatrop's own status where it ran ("" where it did not): its failure, e.g. "fatrop
    #: stalled: …" (casadrone.limit.watchdog), is otherwise hidden behind IPOPT's fallback
    fatrop_status: str = ""

    _properties = ("ending",)

    @property
    def ending(self) -> Ending:
        """How this start's solve ended (:func:`ending`)."""
        return ending(self.success, self.return_status)


@dataclass(frozen=True)
class LimitLap(AsDict):
    """The limit lap of one airframe on one track.

    ``t`` holds the node times (M + 1), ``x`` the node states (M + 1, the model's states: 16 for
    the Euler model, 17 for the quaternion model; :attr:`x_euler` gives 16 with Euler angles),
    ``u`` the ESC commands held on each interval (M, 4). ``certainty`` says whether the verified
    starts agree: "agreed" (two or more, all within CERTAIN_REL of the best), "single" (one
    verified start), "spread" (farther apart: a better optimum may exist). Agreement is no
    proof: the best known SY250 optimum on the paper track (3.8795 s, from a grid round) is
    reached by none of the default starts alone (3.8800 s at best).
    ``sensitivities`` maps decision-variable keys to dT/dθ in
    seconds per unit of the key (only when the airframe config was given); ``param_sensitivity``
    is dT/dp over the model parameters (PARAM_NAMES order), s per SI unit.
    """

    status: Status  # completed: a verified optimum (casadrone.results' one word for success)
    reason: str
    lap_time_s: float = math.nan
    split_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # at each waypoint
    leg_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # every route leg
    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    x: np.ndarray = field(default_factory=lambda: np.zeros((0, NX)))
    u: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    iterations: int = 0  # of the chosen start's solve
    wall_time_s: float = 0.0  # of the whole limit lap: every start, check and grid round
    # CPU time over the same: this process's and, with a pool, its workers' (casadrone.pool)
    cpu_time_s: float = 0.0
    workers: int = 1  # processes that solved side by side (casadrone.limit.parallel)
    bang_bang_fraction: float = math.nan
    point_mass_reference_s: float = math.nan  # best local optimum found, not a bound
    lap_times_s: np.ndarray = field(default_factory=lambda: np.zeros(0))  # time of each lap
    # slowest minus fastest of the verified starts and the other grids' laps (NaN: only one)
    spread_s: float = math.nan
    certainty: Certainty = "single"
    # laps on other grids (intervals per leg -> s) solved by the grid-continuation starts; they
    # count in certainty and spread_s
    grid_laps_s: dict[int, float] = field(default_factory=dict)
    attitude: str = "euler"
    # the start state flown, 16 Euler-model states (the optimised one with end: periodic)
    start_state: np.ndarray = field(default_factory=lambda: np.zeros(0))
    resimulation_miss_m: float = math.nan
    param_sensitivity: np.ndarray = field(default_factory=lambda: np.zeros(0))
    sensitivities: dict[str, float] = field(default_factory=dict)
    # each key's dT/dθ per unit and per 1 % of its Table 1 range, with its uncertainty over the
    # verified optima of this call (casadrone.limit.sensitivity)
    sensitivity_table: tuple[KeySensitivity, ...] = ()
    start: str = ""
    starts: tuple[StartResult, ...] = ()
    layout: Layout | None = None
    solution: NlpPoint | None = None  # primal-dual point, for warm starts
    #: the airframe's propulsion kind and vector p the lap was flown with (what turns rotor
    #: states into thrusts: casadrone.model.rotor_thrusts); empty p: not recorded
    propulsion: str = "paper"
    params: np.ndarray = field(default_factory=lambda: np.zeros(0))

    # the trajectory, the solver's internals and the airframe's numbers
    _omit = ("t", "x", "u", "layout", "solution", "propulsion", "params")
    _properties = ("return_status", "ending")

    @property
    def chosen(self) -> StartResult | None:
        """The chosen start's record among :attr:`starts` (None for a failed lap)."""
        return next((s for s in self.starts if s.start == self.start), None) \
            if self.start else None

    @property
    def return_status(self) -> str:
        """The solver's own return status of the chosen solve ("" for a failed lap)."""
        return self.chosen.return_status if self.chosen is not None else ""

    @property
    def ending(self) -> Ending:
        """How the chosen solve ended: "optimal" or "acceptable" for a completed lap (``status``
        says only that it is a verified optimum), "failed" otherwise."""
        return self.chosen.ending if self.chosen is not None else "failed"

    @property
    def completed(self) -> bool:
        return self.status == "completed"

    @property
    def optimal(self) -> bool:
        """The same as :attr:`completed` (the limit lap's earlier word for it)."""
        return self.completed

    @property
    def x_euler(self) -> np.ndarray:
        """Node states with ZYX Euler angles (16 columns), whatever the model's attitude."""
        return euler_states(self.attitude, self.x)

    @property
    def speed(self) -> np.ndarray:
        """Speed at the nodes (m/s)."""
        return np.linalg.norm(self.x[:, 3:6], axis=1)

    @property
    def waypoint_index(self) -> np.ndarray:
        """Route leg (0-based) each interval belongs to."""
        n = self.layout.intervals if self.layout else 1
        return np.arange(len(self.u)) // n



def node_times(T: np.ndarray, intervals: int) -> np.ndarray:
    """Node times (s) of leg durations ``T`` with ``intervals`` uniform intervals per leg."""
    ends = np.cumsum(T)
    return np.concatenate([[0.0]] + [e - d + np.linspace(0, d, intervals + 1)[1:]
                                     for e, d in zip(ends, T, strict=True)])



def seeds_alone(options: LimitLapOptions) -> LimitLapOptions:
    """``options`` for a lap solved from its seeds' warm starts alone: no cold start, no
    fallback start or reference (a caller that gets no verified lap solves again with
    ``options``, rather than paying the fallbacks twice)."""
    return replace(options, starts=(), fallback_starts=(), fallback_reference=None)
