"""A run's A/B/C candidates against reference airframes: paper Eq. 21 gains (Tables 9-11).

:func:`run_candidates` picks the decisions A (utopian), B (compromise) and C (extreme) on a
finished run's front; :func:`compare_run` flies them and the reference airframes on the run's
platform and compares them interval by interval with :func:`gain_pct` (Eq. 21 as printed, for
times) and :func:`magnitude_gain_pct` (Eq. 21 on magnitudes, for signed efforts and thrusts), also
against the paper's measured Table 4 (:mod:`casadrone.benchmark`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np

from casadrone.benchmark import _f
from casadrone.config.airframe import load_airframe
from casadrone.config.reference import Table4Reference, load_reference
from casadrone.decide import METHODS, decide
from casadrone.evaluate import Evaluation, evaluate, theta_of
from casadrone.indices import Interval
from casadrone.results import AsDict
from casadrone.rundir.store import CONFIG, PARETO, RunStore

# --------------------------------------------------------------------------------------------
# Eq. 21
# --------------------------------------------------------------------------------------------


def gain_pct(candidate, reference, sense: str = "min"):
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
# A run's candidates against the reference airframes (paper Tables 9-11)
# --------------------------------------------------------------------------------------------

#: Labels of the decisions, as in the paper's Figs 13 and 14: A utopian, B compromise, C extreme.
CANDIDATE_LABELS: dict[str, str] = {"utopian": "A", "compromise": "B", "extreme": "C"}
#: A reference effort (V) or pair thrust (N) smaller than this is zero: the simulated interval 1
#: (climb and first straight) has no roll at all, and its values are round-off (~1e-14).
NUMERICAL_ZERO = 1e-6


#: What each decision picks, for titles (the report's candidate sections).
DECISION_TEXT: dict[str, str] = {
    "utopian": "closest to the utopian point",
    "compromise": "compromise: closest to the front's mean point",
    "extreme": "extreme on the first objective",
}


@dataclass(frozen=True)
class Candidate(AsDict):
    """A design chosen on a run's Pareto front (``casadrone decide``, ``compare``, the report).

    Attributes:
        label: ``"A"`` (utopian), ``"B"`` (compromise) or ``"C"`` (extreme); ``"A=C"`` when two
            decisions pick the same design (the report lists each design once).
        methods: the decision method(s) (:data:`casadrone.decide.METHODS`), in label order.
        row: row of the design in ``pareto.csv`` (0-based, header excluded).
        distance: the (first) decision's distance in normalised objective space (``decide``).
        theta: decision variables, name → value (the problem's variable names and units).
        objectives: objective name → value, in its own unit and sense, as in ``pareto.csv``.
        objective: the objective of an extreme decision, else None.
        evaluation: the design flown again, with its trajectory (the report), else None.
    """

    label: str
    methods: tuple[str, ...]
    row: int
    distance: float
    theta: dict[str, float]
    objectives: dict[str, float]
    objective: str | None = None
    evaluation: Evaluation | None = None

    _omit = ("evaluation",)

    @property
    def method(self) -> str:
        """The (first) decision method."""
        return self.methods[0]

    @property
    def flown(self) -> Evaluation:
        """The design's evaluation, once the report has flown it again (an error before)."""
        if self.evaluation is None:
            raise ValueError(f"candidate {self.label} has not been flown again")
        return self.evaluation

    @property
    def title(self) -> str:
        return f"{self.label}: " + "; ".join(DECISION_TEXT[m] for m in self.methods)


def empty_front(run_dir: str | Path) -> str:
    """What to say about a run whose front holds no design."""
    return (f"{run_dir}: the Pareto front is empty (no evaluated candidate was feasible), so "
            "there is no design to choose or export; 'casadrone run -v' and history.sqlite "
            "show why the candidates failed")


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
    from casadrone.optimise.problem import Study

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
    if not rows:
        raise ValueError(empty_front(run_dir))
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
            label=CANDIDATE_LABELS[method], methods=(method,), row=d.index, distance=d.distance,
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
class GainRow(AsDict):
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

    from casadrone.optimise.problem import Study, study_setup

    candidates = run_candidates(run_dir, objective=objective)
    problem = RunStore(Path(run_dir)).problem()
    if problem.test_problem is not None:
        raise ValueError(f"{run_dir}: a run of the test problem {problem.test_problem.name!r} has "
                         "no airframes to compare")
    # the gains are the closed-loop laps' (intervals of the shared controller): no limit lap
    # is solved here, also for a run that optimised a limit-lap index (J3_limit, effort)
    setup = replace(study_setup(Study(problem)), limit=None)
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
            sim = [(i.split_time_s, i.effort_V, i.pair_thrust_max_N, i.pair_thrust_min_N)
                   for i in ref_ev.intervals]
            m = measured.airframes.get(cfg.name)
            meas = [] if m is None else list(zip(m.split_times_s, m.effort_v, m.pair_thrust_max_n,
                                                 m.pair_thrust_min_n, strict=True))
            bases: tuple[tuple[Literal["simulated", "measured"], list, int], ...] = (
                ("simulated", sim, n), ("measured", meas, len(meas)))
            for basis, values, count in bases:
                for j in range(count):
                    ok = j < len(mine) and j < len(values)
                    g = _gains(mine[j], *values[j]) if ok else _NAN_GAINS
                    rows.append(GainRow(candidate=cand.label, method=cand.method,
                                        reference=cfg.name, basis=basis, interval=j + 1, **g))
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
