"""Performance indices J1…J5, Jp (paper Table 2) and the per-interval table (paper Table 4).

Which samples count
-------------------
A :class:`~casadrone.simulate.Trajectory` is sampled at the controller period Ts; row k holds the
state at t[k] and the ESC command held on [t[k], t[k+1]). ``Trajectory.waypoint_index[k]`` is the
(0-based) waypoint being flown to after the guidance switched at t[k]; it is W (the number of
timed waypoints) once the last one has been reached.

- **lap samples**: every k with ``waypoint_index[k] < W``, i.e. from t = 0 (on the ground) until
  the sample at which the last waypoint is reached, that sample excluded. The climb from the
  ground counts: it is part of the lap and of interval 1 (the paper times the lap from the start).
- **interval j** (j = 1…W): lap samples with ``waypoint_index == j − 1``, flying to waypoint j.
  Interval 1 includes the climb.
- **straight sector**: lap samples whose active waypoint's leg is straight
  (``Trajectory.straight``), *excluding the climb* (route segments before
  ``first_timed_segment``), so J1 measures the horizontal straights (the paper's 50 m
  legs), not the vertical take-off.
- **curved sector**: lap samples whose active waypoint's leg is not straight.

Means are plain sample means: the samples are equally spaced, so for the commands (held constant
over each sample) a sample mean is the exact time average, and for states it is the rectangle rule.

Failed laps
-----------
Indices are defined for completed laps only. :func:`compute_indices`, :func:`interval_table` and
every built-in index raise ``ValueError`` (naming the failure reason) for a failed trajectory: a
failed lap is an infeasible evaluation, to be recorded as such by the caller, never a set of NaNs
that could slip into a Pareto front. An index whose sector does not exist on the track (J2 on a
track without curves) is NaN.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Literal

import numpy as np

from casadrone.model import rotor_thrust_function
from casadrone.propulsion import DEFAULT_MODEL, propulsion_model
from casadrone.results import AsDict
from casadrone.simulate import Trajectory, row_norm

Sense = Literal["min", "max"]
IndexFunction = Callable[[Trajectory], float]
#: What an index is computed from: the closed-loop lap (a Trajectory) or the limit lap (a
#: :class:`~casadrone.limit.lap.LimitLap`, computed by the evaluation only when asked for).
Source = Literal["lap", "limit"]


@dataclass(frozen=True)
class Index:
    """A named scalar performance index of a closed-loop lap.

    Attributes:
        name: registry key (``"J1"``).
        unit: unit of the value (``"m/s"``).
        sense: default optimisation sense, ``"min"`` or ``"max"``.
        description: one line saying exactly what is measured.
        function: ``function(trajectory) -> float``, called on completed laps only (for a
            ``limit`` index: ``function(limit_lap) -> float``, on optimal limit laps only).
        source: ``"lap"`` (the closed-loop lap) or ``"limit"`` (the limit lap).
    """

    name: str
    unit: str
    sense: Sense
    description: str
    function: IndexFunction
    source: Source = "lap"

    def __call__(self, result) -> float:
        if self.source == "limit":
            if not result.completed:
                raise ValueError(f"{self.name} is not defined for a failed limit lap "
                                 f"({result.reason or 'failed'})")
        else:
            _require_completed(result)
        return float(self.function(result))


# --------------------------------------------------------------------------------------------
# Sample selections (public: user-defined indices use them too)
# --------------------------------------------------------------------------------------------


def _require_completed(traj: Trajectory) -> None:
    if not traj.completed:
        raise ValueError(f"indices are not defined for a failed lap ({traj.reason or 'failed'})")


def _shared(traj: Trajectory, key: str, make: Callable[[], np.ndarray]) -> np.ndarray:
    """A read-only array derived from ``traj``, computed once per trajectory and kept with it
    (as ``functools.cached_property`` does), so the indices of one lap share their masks."""
    slot = f"_indices_{key}"
    value = traj.__dict__.get(slot)
    if value is None:
        value = make()
        value.flags.writeable = False
        traj.__dict__[slot] = value
    return value


def lap_mask(traj: Trajectory) -> np.ndarray:
    """Samples of the lap: from t = 0 to the sample that reaches the last waypoint (excluded).
    Read-only (shared by every index of the lap)."""
    return _shared(traj, "lap", lambda: traj.waypoint_index < len(traj.waypoints))


def _rows(mask: np.ndarray) -> slice | np.ndarray:
    """``mask`` as a slice when its samples are one contiguous run (the lap and each interval
    are: the waypoint index never decreases), else the mask itself. Indexing with the slice
    selects the same samples in the same order, without a copy."""
    hits = np.flatnonzero(mask)
    if hits.size and hits[-1] - hits[0] + 1 == hits.size:
        return slice(int(hits[0]), int(hits[-1]) + 1)
    return mask


def _lap_rows(traj: Trajectory) -> slice | np.ndarray:
    """The lap samples as a slice (or mask), computed once per lap."""
    slot = "_indices_lap_rows"
    if slot not in traj.__dict__:
        traj.__dict__[slot] = _rows(lap_mask(traj))
    return traj.__dict__[slot]


def interval_mask(traj: Trajectory, waypoint: int) -> np.ndarray:
    """Samples of interval ``waypoint`` (1-based): flying to that waypoint (interval 1 includes
    the climb)."""
    if not 1 <= waypoint <= len(traj.waypoints):
        raise ValueError(f"waypoint must be 1…{len(traj.waypoints)}, got {waypoint}")
    return traj.waypoint_index == waypoint - 1


def sector_mask(traj: Trajectory, straight: bool) -> np.ndarray:
    """Lap samples on straight (``straight=True``) or curved legs; the climb is in neither.
    Read-only (shared by every index of the lap)."""
    def make() -> np.ndarray:
        wi = traj.waypoint_index
        legs = np.array(traj.straight, dtype=bool)
        on_leg = lap_mask(traj) & (traj.segment >= traj.first_timed_segment)
        return on_leg & (legs[np.minimum(wi, len(legs) - 1)] == straight)

    return _shared(traj, f"sector_{bool(straight)}", make)


def roll_effort_voltage(traj: Trajectory) -> np.ndarray:
    """Roll-effort voltage (N,), V: mean ESC voltage of the left rotors minus that of the right
    rotors, as a deviation from trim.

    With rotors FR, FL, RL, RR (1…4; FL and RL on the left, body y):
    ``((δ2 + δ3) − (δ1 + δ4)) / 2 · V_batt`` minus the same combination of the trim commands u0.
    It is the left-right voltage split an ESC log shows, twice the per-motor roll command δA of an
    X mixer (δ_i = δTh ± δA ± …). Positive: left rotors above right, a rolling moment about +x
    (right side down, φ growing). It is signed, so a mean over an interval can be negative, as in
    paper Table 4, and it is zero at trim for every casadrone frame (frames are mirror-symmetric
    about the body x axis, so trim thrusts are equal left and right).
    """
    u = traj.u - np.asarray(traj.u0)[None, :]
    return ((u[:, 1] + u[:, 2]) - (u[:, 0] + u[:, 3])) / 2 * traj.battery_voltage


def pair_thrust_difference(traj: Trajectory) -> np.ndarray:
    """Opposing-pair thrust difference (N,), N: left pair minus right pair, (T2 + T3) − (T1 + T4).

    The thrust couple behind the rolling moment (the paper's "opposing motor thrust"); zero at
    trim for every casadrone frame (see :func:`roll_effort_voltage`), so no trim is subtracted.
    In steady state T_i = K δ_i, so this equals (2 K / V_batt) × the roll-effort voltage.
    """
    T = traj.thrust
    return (T[:, 1] + T[:, 2]) - (T[:, 0] + T[:, 3])


# --------------------------------------------------------------------------------------------
# Built-in indices
# --------------------------------------------------------------------------------------------


def _mean_or_nan(values: np.ndarray) -> float:
    return float(np.mean(values)) if values.size else float("nan")


def mean_straight_speed(traj: Trajectory) -> float:
    """J1: mean speed |v| (m/s) over the straight-sector samples (climb excluded)."""
    return _mean_or_nan(traj.speed[sector_mask(traj, True)])


def mean_curve_speed(traj: Trajectory) -> float:
    """J2: mean speed |v| (m/s) over the curved-sector samples."""
    return _mean_or_nan(traj.speed[sector_mask(traj, False)])


def lap_time(traj: Trajectory) -> float:
    """J3: lap time (s), the interpolated time at which the last waypoint was reached."""
    return traj.lap_time


def max_acceleration(traj: Trajectory) -> float:
    """J4: maximum over the lap samples of |a| (m/s²), a the world kinematic acceleration
    (d/dt of the world velocity, gravity not included: zero in hover)."""
    return float(np.max(row_norm(traj.acceleration[_lap_rows(traj)])))


def effort_rms(traj: Trajectory) -> float:
    """J5: RMS (V) of the ESC voltage deviation from trim, (δ_i − u0_i) V_batt, over the lap
    samples and the four motors."""
    dv = (traj.u[_lap_rows(traj)] - np.asarray(traj.u0)[None, :]) * traj.battery_voltage
    return float(np.sqrt(np.mean(dv**2)))


def max_pitch(traj: Trajectory) -> float:
    """Jp: maximum |θ| (deg) over the lap samples, θ the ZYX Euler pitch angle."""
    return float(np.degrees(np.max(np.abs(traj.x[_lap_rows(traj), 10]))))


def limit_lap_time(lap) -> float:
    """J3_limit: the limit lap (s), the minimum time from the start to the last waypoint over
    every command history the airframe can fly (:func:`casadrone.limit.lap.limit_lap`)."""
    return lap.lap_time_s


#: Smoothing of T^{3/2} at zero thrust (N) in the limit lap's effort: (T² + δ²)^{3/4}, twice
#: differentiable, so the co-design NLP can hold the effort as a constraint
#: (:func:`casadrone.codesign.nlp.effort` uses the same δ; its effect at hover thrust is 1e-6).
EFFORT_SMOOTHING_N = 0.01


def limit_lap_thrusts(lap) -> np.ndarray:
    """Each rotor's thrust (N) at the limit lap's nodes, (M + 1, 4): the rotor states with the
    paper propulsion model; with ``propeller`` T = CT(J) ρ n² D⁴ of each rotor's speed and own
    axial inflow at the node, by the model's thrust (:func:`casadrone.model.rotor_thrusts`) on
    the airframe vector the lap was flown with (:attr:`LimitLap.params`)."""
    x = np.asarray(lap.x_euler, float)
    kind = getattr(lap, "propulsion", DEFAULT_MODEL)
    if propulsion_model(kind).thrust_is_state:
        return x[:, 12:16]
    p = np.asarray(getattr(lap, "params", np.zeros(0)), float)
    if p.size == 0:
        raise ValueError(f"the limit lap's thrusts need its airframe vector ({kind} propulsion)")

    f = rotor_thrust_function(kind)  # called with one column per node: CasADi maps it
    return np.asarray(f(x[:, 3:6].T, x[:, 6:9].T, x[:, 12:16].T, p), float).T


def limit_lap_effort(lap) -> float:
    """effort: the limit lap's ∫ Σ_i T_i^{3/2} dt (N^1.5·s), each interval's length times the
    rotor thrusts at its start node (the left rectangle rule the limit lap's commands are held
    on; the co-design NLP's :func:`casadrone.codesign.nlp.effort` is the same sum).

    Why: by momentum theory a rotor making thrust T in still air needs at least the ideal
    induced power T^{3/2} / sqrt(2 ρ A) (Leishman, Principles of Helicopter Aerodynamics, 2nd
    ed., eq. 2.17), so this is the rotors' ideal energy over the lap times sqrt(2 ρ A), a
    constant of the propellers. The thrusts are :func:`limit_lap_thrusts`: the rotor states
    under the paper's propulsion model, CT(J) ρ n² D⁴ of the rotor speeds under ``propeller``
    (the inflow changes the thrust a rotor speed gives; the measure of a thrust's cost stays
    the still-air ideal power, under both models)."""
    thrust = limit_lap_thrusts(lap)[:-1]
    h = np.diff(np.asarray(lap.t, float))
    return float(np.sum(h * np.sum((thrust**2 + EFFORT_SMOOTHING_N**2) ** 0.75, axis=1)))


_BUILTIN = (
    Index("J1", "m/s", "max", "mean speed on straight sectors (climb excluded)",
          mean_straight_speed),
    Index("J2", "m/s", "max", "mean speed on curved sectors", mean_curve_speed),
    Index("J3", "s", "min", "lap time: time at the last waypoint", lap_time),
    Index("J4", "m/s²", "max", "maximum world kinematic acceleration over the lap",
          max_acceleration),
    Index("J5", "V", "min", "RMS of ESC voltage deviation from trim over the lap and the four "
          "motors", effort_rms),
    Index("Jp", "deg", "min", "maximum pitch angle |θ| over the lap", max_pitch),
    Index("J3_limit", "s", "min", "limit lap: minimum-time lap of the airframe (optimal control, "
          "thrust and attitude limits)", limit_lap_time, source="limit"),
    Index("effort", "N^1.5 s", "min", "limit lap's effort: integral of the sum of T_i^1.5 over "
          "the lap, the rotors' ideal induced energy times sqrt(2 rho A)", limit_lap_effort,
          source="limit"),
)
#: Built-in closed-loop indices (J1…Jp) and built-in limit-lap indices (J3_limit, effort).
BUILTIN_NAMES: tuple[str, ...] = tuple(i.name for i in _BUILTIN if i.source == "lap")
BUILTIN_LIMIT_NAMES: tuple[str, ...] = tuple(i.name for i in _BUILTIN if i.source == "limit")

_REGISTRY: dict[str, Index] = {i.name: i for i in _BUILTIN}
#: Read-only view of the registry, in registration order (built-ins first).
INDICES = MappingProxyType(_REGISTRY)


def register_index(
    name: str, function: IndexFunction, *, unit: str, sense: Sense, description: str = ""
) -> Index:
    """Add a user index to the registry and return it.

    Args:
        name: registry key; must not be taken (``ValueError`` otherwise).
        function: ``function(trajectory) -> float``; it is only called on completed laps
            (:func:`lap_mask`, :func:`interval_mask`, :func:`sector_mask` select samples).
        unit: unit of the value. sense: ``"min"`` or ``"max"``. description: what it measures.
    """
    if not isinstance(name, str) or not name.strip():
        raise ValueError("index name must be a non-empty string")
    if name in _REGISTRY:
        raise ValueError(f"index {name!r} is already registered ({_REGISTRY[name].description}); "
                         "choose another name")
    if sense not in ("min", "max"):
        raise ValueError(f"index {name!r}: sense must be 'min' or 'max', got {sense!r}")
    if not callable(function):
        raise ValueError(f"index {name!r}: function must be callable")
    index = Index(name=name, unit=unit, sense=sense, description=description, function=function)
    _REGISTRY[name] = index
    return index


def unregister_index(name: str) -> None:
    """Remove a user index (built-in indices cannot be removed)."""
    if name in BUILTIN_NAMES + BUILTIN_LIMIT_NAMES:
        raise ValueError(f"index {name!r} is built in and cannot be removed")
    get_index(name)
    del _REGISTRY[name]


def get_index(name: str) -> Index:
    """The registered index called ``name`` (``ValueError`` listing the known names otherwise)."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown index {name!r}; known: {', '.join(_REGISTRY)}") from None


def compute_indices(traj: Trajectory, names: Sequence[str] | None = None
                    ) -> dict[str, float]:
    """Values of the named closed-loop indices (all registered ones by default) for a completed
    lap; limit-lap indices are skipped (see :func:`limit_indices`).

    Raises:
        ValueError: the lap failed, or a name is not registered.
    """
    selected = [get_index(n) for n in (INDICES if names is None else names)]
    _require_completed(traj)
    return {i.name: float(i.function(traj)) for i in selected if i.source == "lap"}


def limit_index_names(names) -> tuple[str, ...]:
    """The limit-lap indices among ``names`` (registered names only)."""
    return tuple(n for n in names if n in INDICES and INDICES[n].source == "limit")


def limit_indices(lap, names: Sequence[str] | None = None) -> dict[str, float]:
    """Values of the named limit-lap indices (all of them by default) of an optimal limit lap."""
    selected = [get_index(n) for n in (INDICES if names is None else names)]
    return {i.name: i(lap) for i in selected if i.source == "limit"}


# --------------------------------------------------------------------------------------------
# Per-interval table (paper Table 4)
# --------------------------------------------------------------------------------------------


#: What the interval columns of a printed table mean (``simulate``'s table, ``benchmark``'s):
#: printed under the table, so that "pair thrust max/min" is defined where it is read.
INTERVAL_LEGEND = (
    "effort = mean roll-effort voltage, left minus right ESCs, deviation from trim (V);",
    "pair thrust = max/min over the interval of (T_FL + T_RL) - (T_FR + T_RR), left rotors' "
    "thrust minus right rotors' (N)",
)


@dataclass(frozen=True)
class Interval(AsDict):
    """One row of the paper's Table 4 for a simulated lap.

    Attributes:
        waypoint: 1…W; the interval is the flight to this waypoint (1 includes the climb).
        split_time_s: time at which this waypoint was reached, cumulative from the start (s).
        effort_V: mean over the interval of :func:`roll_effort_voltage` (V, signed).
        pair_thrust_max_N, pair_thrust_min_N: max and min over the interval of
            :func:`pair_thrust_difference` (N).
        straight: the leg to this waypoint is a straight sector.
        n_samples: samples in the interval.
    """

    waypoint: int
    split_time_s: float
    effort_V: float
    pair_thrust_max_N: float
    pair_thrust_min_N: float
    straight: bool
    n_samples: int


def interval_table(traj: Trajectory) -> list[Interval]:
    """The per-interval split time, signed mean roll effort and opposing-pair thrust extremes."""
    _require_completed(traj)
    effort = roll_effort_voltage(traj)
    pair = pair_thrust_difference(traj)
    wi = traj.waypoint_index
    W = len(traj.waypoints)
    if np.all(wi[1:] >= wi[:-1]):  # as flown: each interval is one run of samples
        edges = np.searchsorted(wi, np.arange(W + 1), side="left")
        selections: list[slice | np.ndarray] = [slice(int(edges[j]), int(edges[j + 1]))
                                                for j in range(W)]
    else:
        selections = [interval_mask(traj, j) for j in range(1, W + 1)]
    rows = []
    for j, m in enumerate(selections, start=1):
        n = len(effort[m])
        rows.append(Interval(
            waypoint=j,
            split_time_s=float(traj.split_times[j - 1]),
            effort_V=float(effort[m].sum() / n) if n else float("nan"),  # np.mean's sum / n
            pair_thrust_max_N=float(pair[m].max()) if n else float("nan"),
            pair_thrust_min_N=float(pair[m].min()) if n else float("nan"),
            straight=bool(traj.straight[j - 1]),
            n_samples=n,
        ))
    return rows
