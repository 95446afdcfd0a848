"""Reference airframes flown on the paper track: a Table-4-style table and paper Eq. 21 gains.

:func:`run_benchmark` flies each reference airframe (paper Table 4: SY250, SY220, HS200, HS210,
NSY200) with the shared controller and track, and puts its per-interval split times, roll effort
and opposing-pair thrust (:func:`casadrone.indices.interval_table`) beside the values the paper
*measured* in flight (``configs/references/paper-table4.yaml``). The measured laps are on a
different time base (hundreds of seconds for the 105 m lap, against ~15 s simulated), so the two
are shown side by side, labelled, never subtracted.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import Field

from casadrone.airframe import build_airframe
from casadrone.config import (
    CONFIG_DIR,
    AirframeConfig,
    ControllerConfig,
    Schema,
    load,
    load_airframe,
    load_controller,
    resolve_config,
)
from casadrone.control import design_for
from casadrone.guidance import TrackConfig
from casadrone.indices import INDICES, Interval, compute_indices, interval_table
from casadrone.simulate import Integrator, simulate

#: The paper's reference airframes (Table 4), as names of configs/airframes/ files.
REFERENCE_NAMES: tuple[str, ...] = ("SY250", "SY220", "HS200", "HS210", "NSY200")
DEFAULT_REFERENCE = CONFIG_DIR / "references" / "paper-table4.yaml"
DEFAULT_TRACK = CONFIG_DIR / "tracks" / "paper-rectangle.yaml"
MEASURED_LABEL = "measured (paper Table 4, different time base)"
SIMULATED_LABEL = "simulated (casadrone)"


# --------------------------------------------------------------------------------------------
# Reference file schema (configs/references/)
# --------------------------------------------------------------------------------------------


class MeasuredAirframe(Schema):
    """One airframe's measured per-interval values (interval j = the flight to waypoint j)."""

    airframe: str = Field(description="the casadrone airframe config the row refers to")
    split_times_s: list[float] = Field(min_length=1, description="time at each waypoint (s)")
    effort_v: list[float] = Field(min_length=1, description="signed controller effort (V)")
    pair_thrust_max_n: list[float] = Field(min_length=1, description="opposing-pair max (N)")
    pair_thrust_min_n: list[float] = Field(min_length=1, description="opposing-pair min (N)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found: list[tuple[str, str]] = []
        keys = ("split_times_s", "effort_v", "pair_thrust_max_n", "pair_thrust_min_n")
        lengths = {k: len(v[k]) for k in keys if k in v}
        n = lengths.get("split_times_s")
        for k, m in lengths.items():
            if n is not None and m != n:
                found.append((k, f"expected {n} values (one per waypoint, like split_times_s), "
                              f"got {m}"))
        s = v.get("split_times_s")
        if s is not None and any(b < a for a, b in zip(s, s[1:], strict=False)):
            found.append(("split_times_s", "split times must not decrease (they are cumulative)"))
        hi, lo = v.get("pair_thrust_max_n"), v.get("pair_thrust_min_n")
        if hi is not None and lo is not None and len(hi) == len(lo):
            bad = [j + 1 for j, (a, b) in enumerate(zip(hi, lo, strict=True)) if b > a]
            if bad:
                found.append(("pair_thrust_min_n", f"above pair_thrust_max_n at interval(s) {bad}"))
        return found


class Table4Reference(Schema):
    """Measured per-interval benchmark values (paper Table 4), keyed by airframe name."""

    name: str
    source: str = ""
    airframes: dict[str, MeasuredAirframe] = Field(min_length=1)

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        rows = v.get("airframes") or {}
        counts = {len(r.split_times_s) for r in rows.values() if isinstance(r, MeasuredAirframe)}
        if len(counts) > 1:
            return [("airframes", f"every airframe needs the same number of intervals, got "
                     f"{sorted(counts)}")]
        return []


def load_reference(path: str | Path | None = None) -> Table4Reference:
    """Load a measured reference table (default: ``configs/references/paper-table4.yaml``)."""
    return load(Table4Reference, resolve_config(path, "references") if path else DEFAULT_REFERENCE)


# --------------------------------------------------------------------------------------------
# Eq. 21
# --------------------------------------------------------------------------------------------


def gain_pct(candidate, reference, sense: Literal["min", "max"] = "min"):
    """Percentage gain of a candidate over a reference, positive meaning better (paper Eq. 21).

    Paper Eq. 21, for lap times::

        %Gain = (t_benchmark − t_candidate) / t_benchmark × 100

    ``sense="min"`` (times, effort: smaller is better) is Eq. 21 exactly,
    ``(reference − candidate) / reference × 100``. ``sense="max"`` (speeds, acceleration) flips the
    sign, ``(candidate − reference) / reference × 100``, so that positive still means better; that
    extension is casadrone's. The reference is the denominator as printed: for a signed quantity
    (roll effort) with a negative reference the sign of the result no longer reads "better", so
    compare magnitudes there. Works elementwise on arrays.

    Raises:
        ValueError: a reference value is zero, or ``sense`` is neither "min" nor "max".
    """
    if sense not in ("min", "max"):
        raise ValueError(f"sense must be 'min' or 'max', got {sense!r}")
    cand = np.asarray(candidate, dtype=float)
    ref = np.asarray(reference, dtype=float)
    if np.any(ref == 0):
        raise ValueError("gain_pct: the reference is zero, a percentage gain is undefined")
    gain = (ref - cand) / ref * 100.0
    gain = gain if sense == "min" else -gain
    return float(gain) if gain.ndim == 0 else gain


# --------------------------------------------------------------------------------------------
# Benchmark
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BenchmarkRow:
    """One reference airframe: its simulated lap beside the measured values (if any).

    Attributes:
        airframe: airframe name. config: path of its config file ("" if given as an object).
        status, reason: the simulated lap's outcome (``"completed"`` or ``"failed"``).
        intervals: simulated per-interval values (empty for a failed lap).
        indices: every registered index of the simulated lap (empty for a failed lap).
        measured: the paper's measured row for this airframe, or None.
        wall_time_s: time to design the controller and fly the lap (s).
    """

    airframe: str
    config: str
    status: str
    reason: str
    intervals: tuple[Interval, ...]
    indices: dict[str, float]
    measured: MeasuredAirframe | None
    wall_time_s: float

    @property
    def lap_time_s(self) -> float:
        """Simulated lap time (s), NaN for a failed lap."""
        return self.intervals[-1].split_time_s if self.intervals else float("nan")


@dataclass(frozen=True)
class BenchmarkTable:
    """Table-4-style comparison of the reference airframes (simulated beside measured)."""

    rows: tuple[BenchmarkRow, ...]
    integrator: str
    controller: str
    track: str
    reference: str
    measured_label: str = MEASURED_LABEL
    simulated_label: str = SIMULATED_LABEL
    extras: dict = field(default_factory=dict)

    def row(self, airframe: str) -> BenchmarkRow:
        """The row of the named airframe."""
        for r in self.rows:
            if r.airframe == airframe:
                return r
        raise KeyError(f"no row for {airframe!r}; rows: {', '.join(r.airframe for r in self.rows)}")


def _as_airframe(item: str | Path | AirframeConfig) -> tuple[AirframeConfig, str]:
    if isinstance(item, AirframeConfig):
        return item, ""
    return load_airframe(item), str(resolve_config(item, "airframes"))


def run_benchmark(
    integrator: Integrator = "rk4",
    airframes: tuple[str | Path | AirframeConfig, ...] = REFERENCE_NAMES,
    controller: str | Path | ControllerConfig | None = None,
    track: str | Path | TrackConfig | None = None,
    reference: str | Path | Table4Reference | None = None,
) -> BenchmarkTable:
    """Fly each airframe one lap and build the Table-4-style comparison.

    Args:
        integrator: ``rk4`` (default, fast) or ``cvodes``/``idas`` (reference).
        airframes: names (``SY250``), paths or configs; default the five paper references.
        controller: name, path or config; default ``configs/controllers/default.yaml``.
        track: name, path or config; default ``configs/tracks/paper-rectangle.yaml``.
        reference: measured table (name, path or object); default paper Table 4.

    A failed lap is a row with its reason, not an exception.
    """
    ctrl = controller if isinstance(controller, ControllerConfig) else load_controller(controller)
    if isinstance(track, TrackConfig):
        trk = track
    else:
        trk = load(TrackConfig, resolve_config(track, "tracks") if track else DEFAULT_TRACK)
    ref = reference if isinstance(reference, Table4Reference) else load_reference(reference)
    frozen_from = None
    if ctrl.gain_policy == "frozen":
        frozen_from = build_airframe(load_airframe(ctrl.reference_airframe))
    rows = []
    for item in airframes:
        cfg, path = _as_airframe(item)
        start = time.perf_counter()
        airframe = build_airframe(cfg)
        traj = simulate(airframe, design_for(airframe, ctrl, frozen_from), trk, integrator)
        done = traj.completed
        rows.append(BenchmarkRow(
            airframe=cfg.name, config=path, status=traj.status, reason=traj.reason,
            intervals=tuple(interval_table(traj)) if done else (),
            indices=compute_indices(traj) if done else {},
            measured=ref.airframes.get(cfg.name),
            wall_time_s=time.perf_counter() - start,
        ))
    return BenchmarkTable(rows=tuple(rows), integrator=integrator, controller=ctrl.name,
                          track=trk.name, reference=ref.name)


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------


def _f(value: float, digits: int) -> str:
    return "—" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def _pair(hi: float, lo: float) -> str:
    return f"{_f(hi, 2)}/{_f(lo, 2)}"


def format_table(table: BenchmarkTable) -> str:
    """The table for a terminal: per airframe, simulated rows above the measured ones."""
    n = max((max(len(r.intervals), len(r.measured.split_times_s) if r.measured else 0)
             for r in table.rows), default=0)
    head = f"  {'interval':28}" + "".join(f"{j:>14}" for j in range(1, n + 1))
    out = [
        f"Table-4-style benchmark: track {table.track}, controller {table.controller}, "
        f"integrator {table.integrator}",
        f"  sim  = {table.simulated_label}",
        f"  meas = {table.measured_label} [{table.reference}];",
        "         measured laps take hundreds of seconds for the 105 m lap: compare trends, "
        "not absolute times",
        "  effort = mean roll-effort voltage, left minus right ESCs, deviation from trim (V);",
        "  pair thrust = max/min of (T_FL + T_RL) - (T_FR + T_RR) over the interval (N)",
        "",
    ]
    for r in table.rows:
        if r.status == "completed":
            J = r.indices
            summary = (f"lap {_f(r.lap_time_s, 2)} s, J1 {_f(J.get('J1'), 2)} m/s, "
                       f"J2 {_f(J.get('J2'), 2)} m/s, J4 {_f(J.get('J4'), 1)} m/s², "
                       f"J5 {_f(J.get('J5'), 3)} V, Jp {_f(J.get('Jp'), 1)} deg")
        else:
            summary = f"FAILED: {r.reason}"
        out += [f"{r.airframe}: {summary}", head]
        sim, meas = r.intervals, r.measured

        rows = []
        if sim:
            rows += [("split time (s)", "sim", [_f(i.split_time_s, 2) for i in sim])]
        if meas:
            rows += [("", "meas", [_f(v, 2) for v in meas.split_times_s])]
        if sim:
            rows += [("effort (V)", "sim", [_f(i.effort_V, 3) for i in sim])]
        if meas:
            rows += [("", "meas", [_f(v, 3) for v in meas.effort_v])]
        if sim:
            rows += [("pair thrust max/min (N)", "sim",
                      [_pair(i.pair_thrust_max_N, i.pair_thrust_min_N) for i in sim])]
        if meas:
            pairs = zip(meas.pair_thrust_max_n, meas.pair_thrust_min_n, strict=True)
            rows += [("", "meas", [_pair(a, b) for a, b in pairs])]
        out += [f"  {q:24}{k:4}" + "".join(f"{c:>14}" for c in cells) for q, k, cells in rows]
        out.append("")
    return "\n".join(out).rstrip() + "\n"


def _clean(value: Any) -> Any:
    """JSON-safe copy: NaN/inf → None, numpy scalars → Python numbers."""
    if isinstance(value, dict):
        return {k: _clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_clean(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def as_dict(table: BenchmarkTable) -> dict[str, Any]:
    """Plain-data form of the table (what :func:`to_json` writes)."""
    units = {name: INDICES[name].unit for name in INDICES}
    return _clean({
        "integrator": table.integrator,
        "controller": table.controller,
        "track": table.track,
        "reference": table.reference,
        "simulated_label": table.simulated_label,
        "measured_label": table.measured_label,
        "index_units": units,
        "rows": [
            {
                "airframe": r.airframe,
                "config": r.config,
                "status": r.status,
                "reason": r.reason,
                "lap_time_s": r.lap_time_s,
                "wall_time_s": r.wall_time_s,
                "indices": r.indices,
                "simulated": [
                    {k: getattr(i, k) for k in ("waypoint", "split_time_s", "effort_V",
                                                "pair_thrust_max_N", "pair_thrust_min_N",
                                                "straight", "n_samples")}
                    for i in r.intervals
                ],
                "measured": r.measured.model_dump() if r.measured else None,
            }
            for r in table.rows
        ],
    })


def to_json(table: BenchmarkTable, indent: int | None = 2) -> str:
    """The table as JSON (NaN written as null)."""
    return json.dumps(as_dict(table), indent=indent, ensure_ascii=False)


# --------------------------------------------------------------------------------------------
# A run's candidates against the reference airframes (paper Tables 9-11)
# --------------------------------------------------------------------------------------------

#: Labels of the decisions, as in the paper's Figs 13 and 14: A utopian, B compromise, C extreme.
CANDIDATE_LABELS: dict[str, str] = {"utopian": "A", "compromise": "B", "extreme": "C"}
#: A reference effort (V) or pair thrust (N) smaller than this is zero: the simulated interval 1
#: (climb and first straight) has no roll at all, and its values are round-off (~1e-14).
NUMERICAL_ZERO = 1e-6


@dataclass(frozen=True)
class Candidate:
    """One decision on a run's Pareto front.

    Attributes:
        label: ``"A"`` (utopian), ``"B"`` (compromise) or ``"C"`` (extreme).
        method: the decision method (:data:`casadrone.decide.METHODS`).
        row: row of the design in ``pareto.csv`` (0-based, header excluded).
        distance: the decision's distance in normalised objective space (see ``decide``).
        theta: decision variables, name → value (the problem's variable names and units).
        objectives: objective name → value, in its own unit and sense, as in ``pareto.csv``.
        objective: the objective of an extreme decision, else None.
    """

    label: str
    method: str
    row: int
    distance: float
    theta: dict[str, float]
    objectives: dict[str, float]
    objective: str | None = None


def run_candidates(
    run_dir: str | Path,
    methods: tuple[str, ...] | None = None,
    objective: str | None = None,
) -> list[Candidate]:
    """The A/B/C decisions on a finished run's front (``pareto.csv`` and the problem's senses).

    Args:
        run_dir: a run directory (``casadrone run --out``).
        methods: decision methods, default all three (utopian, compromise, extreme).
        objective: objective of the extreme decision, default the problem's first.

    Raises:
        FileNotFoundError: not a run directory, or the run has no ``pareto.csv`` (not finished).
        ValueError: an empty front, or an unknown objective.
    """
    from casadrone.decide import METHODS, decide
    from casadrone.optimise.problem import Study
    from casadrone.optimise.store import CONFIG, PARETO, RunStore

    store = RunStore(Path(run_dir))
    if not (store.path / CONFIG).is_file():
        raise FileNotFoundError(f"{run_dir}: not a run directory (no {CONFIG})")
    if not (store.path / PARETO).is_file():
        raise FileNotFoundError(f"{run_dir}: no {PARETO}: the run has not finished (resume it "
                                f"with 'casadrone resume {run_dir}')")
    study = Study(store.problem())
    names, senses = study.objective_names, study.senses
    header, rows = store.read_pareto()
    n_var = len(header) - len(names)
    if header[n_var:] != names:
        raise ValueError(f"{run_dir}: {PARETO} columns {header} do not end with the problem's "
                         f"objectives {names}")
    if objective is not None and objective not in names:
        raise ValueError(f"unknown objective {objective!r}; objectives of this run: "
                         f"{', '.join(names)}")
    F = np.array(rows, dtype=float).reshape(len(rows), len(header))[:, n_var:]
    extreme_on = objective or names[0]
    out = []
    for method in methods or METHODS:
        d = decide(F, dict(zip(names, senses, strict=True)), method, extreme_on)
        row = rows[d.index]
        out.append(Candidate(
            label=CANDIDATE_LABELS[method], method=method, row=d.index, distance=d.distance,
            theta=dict(zip(header[:n_var], row[:n_var], strict=True)),
            objectives=dict(zip(names, row[n_var:], strict=True)),
            objective=extreme_on if method == "extreme" else None,
        ))
    return out


def magnitude_gain_pct(candidate: float, reference: float) -> float:
    """Paper Eq. 21 on magnitudes: ``(|ref| − |cand|) / |ref| × 100``, positive = smaller.

    For a signed quantity whose size is the cost and whose sign is only a direction: the
    roll-effort voltage (left minus right ESCs) and the opposing-pair thrust extremes.
    Where both values are numerically zero (below :data:`NUMERICAL_ZERO`) the gain is 0; where
    only the reference is, the gain is undefined (NaN).

    Why magnitudes. Eq. 21 is written for lap times, where smaller is better. The paper applies
    it to effort and thrust too (Tables 10, 11) and reads the results as *reductions* ("reduces
    stress on the voltage regulators", "average reduction of 78.02 %"), so smaller is better there
    as well; but its efforts and thrust minima are signed (Table 4: SY250 effort −1.16 V, thrust
    minimum −3.72 N), and a reduction of an effort is a smaller magnitude. Read as printed on the
    signed values, ``(ref − cand)/ref = 1 − cand/ref``, Eq. 21 equals the magnitude gain whenever
    candidate and reference have the same sign; every Table 10/11 entry below 100 % is consistent
    with both readings. The entries above 100 % (Table 10 interval 4: 103.03, 104.69, 167.46 %;
    Table 11 SY_O1 250 minimum 4: 541.67 %) can only come from the signed ratio with a candidate
    of the opposite sign: a magnitude cannot fall by more than 100 %, and a sign flip with
    a larger magnitude would count as a gain above 200 % although the effort grew. casadrone
    therefore applies Eq. 21 to magnitudes, which keeps "positive = better" true and agrees with
    the paper wherever the signs agree.
    """
    c, r = abs(float(candidate)), abs(float(reference))
    if not (math.isfinite(c) and math.isfinite(r)):
        return float("nan")
    if r < NUMERICAL_ZERO:
        return 0.0 if c < NUMERICAL_ZERO else float("nan")
    return gain_pct(c, r, "min")


@dataclass(frozen=True)
class GainRow:
    """Percentage gains (paper Eq. 21, positive = better) of one candidate over one reference
    airframe in one interval.

    Attributes:
        candidate: ``"A"``, ``"B"`` or ``"C"``; method: its decision method.
        reference: the reference airframe's name.
        basis: ``"simulated"`` (the reference flown on the run's platform) or ``"measured"``
            (the paper's Table 4; a different time base, orientation only).
        interval: 1…W, the flight to that waypoint.
        time_gain_pct: Eq. 21 on the split time at the waypoint (cumulative, as Table 4/9).
        effort_gain_pct: Eq. 21 on the magnitude of the mean roll effort (Table 10).
        thrust_max_gain_pct, thrust_min_gain_pct: Eq. 21 on the magnitudes of the opposing-pair
            thrust maximum and minimum (Table 11).

    A gain is NaN where it is undefined: a failed lap, or a reference of zero (see
    :func:`magnitude_gain_pct`).
    """

    candidate: str
    method: str
    reference: str
    basis: Literal["simulated", "measured"]
    interval: int
    time_gain_pct: float
    effort_gain_pct: float
    thrust_max_gain_pct: float
    thrust_min_gain_pct: float


def _time_gain_pct(candidate: float, reference: float) -> float:
    """Eq. 21 exactly on a time; NaN where undefined (a failed lap, a zero reference)."""
    if not (math.isfinite(candidate) and math.isfinite(reference)) or reference == 0:
        return float("nan")
    return gain_pct(candidate, reference, "min")


def _gains(cand: Interval, time_s: float, effort: float, hi: float, lo: float) -> dict:
    return {
        "time_gain_pct": _time_gain_pct(cand.split_time_s, time_s),
        "effort_gain_pct": magnitude_gain_pct(cand.effort_V, effort),
        "thrust_max_gain_pct": magnitude_gain_pct(cand.pair_thrust_max_N, hi),
        "thrust_min_gain_pct": magnitude_gain_pct(cand.pair_thrust_min_N, lo),
    }


_NAN_GAINS = dict.fromkeys(("time_gain_pct", "effort_gain_pct", "thrust_max_gain_pct",
                            "thrust_min_gain_pct"), math.nan)


def compare_run(
    run_dir: str | Path,
    references: tuple[str | Path, ...] = ("SY250",),
    objective: str | None = None,
    reference_table: str | Path | Table4Reference | None = None,
) -> list[GainRow]:
    """Benchmark-relative gains of a run's A/B/C candidates (paper Eq. 21, Tables 9-11).

    Each candidate airframe is the run's template (with the problem's ``fixed`` keys) carrying
    the candidate's θ; each reference is its own airframe config (name or path). Both are flown
    on the run's platform — its track, controller and integrator, through the same
    :func:`casadrone.evaluate.evaluate` chain as the optimisation — and compared interval by
    interval (``basis="simulated"``). A reference with a row in the measured table (default paper
    Table 4) is also compared against those measured values (``basis="measured"``): the paper's
    laps are on a different time base (hundreds of seconds), so read those rows as orientation.

    Rows: per candidate (A, B, C), per reference, simulated rows first then measured, per
    interval. Split times use Eq. 21 as printed (:func:`gain_pct`), efforts and pair thrusts use
    it on magnitudes (:func:`magnitude_gain_pct`, where the choice is argued).

    Raises:
        FileNotFoundError, ValueError: as :func:`run_candidates`; ValueError for a run of a
        pymoo test problem (no airframe). ConfigError: a reference that is not a valid airframe.
    """
    from dataclasses import replace

    from casadrone.evaluate import evaluate, theta_of
    from casadrone.optimise.problem import Study, study_setup
    from casadrone.optimise.store import RunStore

    candidates = run_candidates(run_dir, objective=objective)
    problem = RunStore(Path(run_dir)).problem()
    if problem.test_problem is not None:
        raise ValueError(f"{run_dir}: a run of the test problem {problem.test_problem.name!r} has "
                         "no airframes to compare")
    setup = study_setup(Study(problem))
    measured = (reference_table if isinstance(reference_table, Table4Reference)
                else load_reference(reference_table))
    refs = []
    for item in references:
        cfg = load_airframe(item)
        refs.append((cfg, evaluate(theta_of(cfg), replace(setup, template=cfg))))
    n = len(setup.track.waypoints_m)
    flown: dict[int, tuple[Interval, ...]] = {}  # pareto row -> intervals (A, B, C may coincide)
    rows: list[GainRow] = []
    for cand in candidates:
        if cand.row not in flown:
            ev = evaluate(cand.theta, setup)
            flown[cand.row] = ev.intervals if ev.completed else ()
        mine = flown[cand.row]
        for cfg, ref_ev in refs:
            head = {"candidate": cand.label, "method": cand.method, "reference": cfg.name}
            sim = [(i.split_time_s, i.effort_V, i.pair_thrust_max_N, i.pair_thrust_min_N)
                   for i in ref_ev.intervals]
            m = measured.airframes.get(cfg.name)
            meas = [] if m is None else list(zip(m.split_times_s, m.effort_v, m.pair_thrust_max_n,
                                                 m.pair_thrust_min_n, strict=True))
            for basis, values, count in (("simulated", sim, n), ("measured", meas, len(meas))):
                for j in range(count):
                    ok = j < len(mine) and j < len(values)
                    g = _gains(mine[j], *values[j]) if ok else _NAN_GAINS
                    rows.append(GainRow(**head, basis=basis, interval=j + 1, **g))
    return rows


def format_gains(rows: list[GainRow]) -> str:
    """The gains for a terminal: one line per candidate, reference, basis and interval."""
    head = (f"{'cand':<5}{'method':<11}{'reference':<11}{'basis':<10}{'int':>4}"
            f"{'time %':>10}{'effort %':>10}{'T max %':>10}{'T min %':>10}")
    out = ["Gains over the reference airframes, paper Eq. 21: positive = better (faster, less "
           "effort, smaller pair-thrust extremes);",
           "effort and pair thrust compared by magnitude; 'measured' = paper Table 4 (different "
           "time base: orientation only)", "", head]
    for r in rows:
        out.append(f"{r.candidate:<5}{r.method:<11}{r.reference:<11}{r.basis:<10}{r.interval:>4}"
                   + "".join(f"{_f(v, 2):>10}" for v in (r.time_gain_pct, r.effort_gain_pct,
                                                         r.thrust_max_gain_pct,
                                                         r.thrust_min_gain_pct)))
    return "\n".join(out) + "\n"
