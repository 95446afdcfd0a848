"""Reference airframes flown on the paper track: a Table-4-style table beside the measured one.

:func:`run_benchmark` flies each reference airframe (paper Table 4: SY250, SY220, HS200, HS210,
NSY200) with the shared controller and track, and puts its per-interval split times, roll effort
and opposing-pair thrust (:func:`casadrone.indices.interval_table`) beside the values the paper
*measured* in flight (``configs/references/paper-table4.yaml``). The measured laps are on a
different time base (hundreds of seconds for the 105 m lap, against ~15 s simulated), so the two
are shown side by side, labelled, never subtracted. The Eq. 21 gains of a run's candidates over
these airframes are in :mod:`casadrone.compare`.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from casadrone.airframe import build_airframe
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.controller import ControllerConfig, load_controller
from casadrone.config.io import load, resolve_config
from casadrone.config.reference import MeasuredAirframe, Table4Reference, load_reference
from casadrone.config.track import DEFAULT_TRACK, TrackConfig
from casadrone.control import design_for
from casadrone.indices import (
    INDICES,
    INTERVAL_LEGEND,
    Interval,
    compute_indices,
    interval_table,
)
from casadrone.numtext import fixed
from casadrone.results import AsDict, Status
from casadrone.simulate import Integrator, simulate

#: The paper's reference airframes (Table 4), as names of configs/airframes/ files.
REFERENCE_NAMES: tuple[str, ...] = ("SY250", "SY220", "HS200", "HS210", "NSY200")
MEASURED_LABEL = "measured (paper Table 4, different time base)"
SIMULATED_LABEL = "simulated (casadrone)"


# --------------------------------------------------------------------------------------------
# Benchmark
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class BenchmarkRow(AsDict):
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
    status: Status
    reason: str
    intervals: tuple[Interval, ...]
    indices: dict[str, float]
    measured: MeasuredAirframe | None
    wall_time_s: float

    _keys = {"intervals": "simulated"}
    _properties = ("lap_time_s",)

    @property
    def lap_time_s(self) -> float:
        """Simulated lap time (s), NaN for a failed lap."""
        return self.intervals[-1].split_time_s if self.intervals else float("nan")


@dataclass(frozen=True)
class BenchmarkTable(AsDict):
    """Table-4-style comparison of the reference airframes (simulated beside measured)."""

    rows: tuple[BenchmarkRow, ...]
    integrator: str
    controller: str
    track: str
    reference: str
    measured_label: str = MEASURED_LABEL
    simulated_label: str = SIMULATED_LABEL
    extras: dict = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        """Plain data (``benchmark --json``), with every registered index's unit; NaN → None."""
        return _clean(super().as_dict() | {
            "index_units": {name: INDICES[name].unit for name in INDICES}})

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
    if ctrl.frozen_gain and ctrl.reference_airframe is not None:
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


def _f(value: float | None, digits: int) -> str:
    return "—" if value is None or not math.isfinite(value) else fixed(value, f".{digits}f")


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
        *(f"  {line}" for line in INTERVAL_LEGEND),
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
    """Plain-data form of the table (what :func:`to_json` writes; BenchmarkTable.as_dict)."""
    return table.as_dict()


def to_json(table: BenchmarkTable, indent: int | None = 2) -> str:
    """The table as JSON (NaN written as null)."""
    return json.dumps(as_dict(table), indent=indent, ensure_ascii=False)
