"""Report sections for a co-design front's run directory (``casadrone codesign --out``).

A co-design point is a frame and its limit lap optimised together: at an ε-bounded point the lap
is the fastest lap whose effort (or mass, span) stays within ε, not the frame's minimum-time lap.
So the report shows each point's own limit lap as the co-design stored it
(:data:`casadrone.codesign.front.LAPS_FILE`) and what holds it there: the active constraints with
IPOPT's multipliers, and its certificate (:mod:`casadrone.codesign.frontcert`), both in
:data:`casadrone.codesign.front.POINTS_FILE`. The candidates' closed-loop
laps are flown again as for any run (the controller does not depend on the limit lap).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from casadrone import plots
from casadrone.codesign.certificate import summary_of
from casadrone.codesign.front import LAPS_FILE, POINTS_FILE
from casadrone.compare import Candidate
from casadrone.limit.check import bang_bang_fraction
from casadrone.limit.lap import BANG_BANG_TOL, LimitLap
from casadrone.optimise.problem import study_setup
from casadrone.report.analysis import Run
from casadrone.report.markup import Figures, cell, esc, kv_table, note, num, table

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from casadrone.limit.lap import LimitLap

#: The manifest's backend of a co-design front's run directory.
BACKEND = "codesign"


def is_codesign(run: Run) -> bool:
    """Whether ``run`` is a co-design front's run directory."""
    return run.manifest.get("backend") == BACKEND


def read_points(path: Path) -> tuple[dict | None, dict[str, np.ndarray]]:
    """The front's point records and limit-lap arrays (None, {} for a run written before they
    were stored)."""
    if not (path / POINTS_FILE).is_file():
        return None, {}
    data = json.loads((path / POINTS_FILE).read_text(encoding="utf-8"))
    arrays: dict[str, np.ndarray] = {}
    if (path / LAPS_FILE).is_file():
        with np.load(path / LAPS_FILE) as npz:
            arrays = {k: npz[k] for k in npz.files}
    return data, arrays


def stored_lap(arrays: dict[str, np.ndarray], row: int, track: str) -> LimitLap | None:
    """Point ``row``'s limit lap on ``track`` as a :class:`casadrone.limit.lap.LimitLap` (None
    when not stored)."""
    key = f"{row}/{track}/"
    if key + "t" not in arrays:
        return None
    t, x, u = (arrays[key + k] for k in ("t", "x", "u"))
    return LimitLap(status="completed", reason="", lap_time_s=float(t[-1] - t[0]),
                    split_times_s=arrays[key + "splits"], t=t, x=x, u=u,
                    bang_bang_fraction=bang_bang_fraction(u, BANG_BANG_TOL), attitude="euler")


def _active(point: dict) -> str:
    items = point.get("active_constraints", {})
    return "; ".join(f"{name} ({value:+.3g})" for name, value in items.items()) or "none"


def _certificate(point: dict) -> str:
    """A point's stored certificate in one cell (its one-line summary without the active rows,
    which have their own column)."""
    c = point.get("certificate")
    # the active rows have their own column
    return "not certified" if c is None else summary_of(c, active=False)


def section_codesign(run: Run, cands: list[Candidate], figs: Figures) -> str:
    """Every point of the front: its limit lap on each track, its measure, θ and the active
    constraints, and the limit laps drawn together."""
    data, arrays = read_points(run.store.path)
    if data is None:
        return note("This co-design run directory predates the stored points: re-run "
                    "casadrone codesign to see each point's limit lap.", "warn")
    keys = run.study.variable_names
    tracks, measure = data["tracks"], data["measure"]
    head = (["row"] + [f"lap {t} (s)" for t in tracks] + [f"{measure}", "ε bound"]
            + keys + ["mass (kg)", "iterations", "active constraints (multiplier)",
                      "certificate (reduced gradient, s per box width)"])
    rows = []
    for i, p in enumerate(data["points"]):
        rows.append([i] + [cell(p["laps_s"][t], ".5f") for t in tracks]
                    + [cell(p["value"]), cell(p["epsilon"]) if p["epsilon"] is not None
                       else "– (fastest frame)"]
                    + [cell(p["theta"][k], ".4f") for k in keys]
                    + [cell(p["mass_kg"], ".4f"), p["iterations"], esc(_active(p)),
                       esc(_certificate(p))])
    out: list[str] = [note(
                f"A co-design front: the limit lap against {esc(measure)}, each point one NLP "
                "solve over the frame and its lap together, warm-started from the previous "
                f"point (ε-continuation; {data['intervals']} intervals per leg, gate clearance "
                f"{num(data['gate_clearance_m'])} m for every frame). At an ε-bounded point the "
                "lap is the fastest within the bound, so it may be slower than the frame's own "
                "minimum-time lap: the frame and the lap are the design. Active constraints: "
                "the rows and bounds IPOPT holds, with their multipliers (s of lap per unit of "
                "the row; per box width for a bound), the 'why' of each point. Certificate: "
                "the point's lap re-solved with the frame fixed (under its ε row) equals its "
                "lap within 0.05 %, the reduced gradient in θ is zero inside the box and of "
                "the bound's sign at a bound, and CVODES flies the lap through every target."),
           table(head, rows, "wide")]
    for track in tracks:
        laps = {f"row {i}": stored_lap(arrays, i, track) for i in range(len(data["points"]))}
        laps = {k: v for k, v in laps.items() if v is not None}
        if laps:
            out.append(figs.embed(_laps_figure(laps, track), f"codesign-laps-{track}",
                                  f"Track {track}: every front point's limit lap, top view and "
                                  "total rotor thrust over time (fastest frame darkest)."))

    waypoints = study_setup(run.study).track.waypoints_m
    for c in cands:
        for track in tracks:
            lap = stored_lap(arrays, c.row, track)
            if lap is None:
                continue
            p = data["points"][c.row]
            out.append(f"<h4>Candidate {esc(c.title)}: its limit lap on {esc(track)}</h4>")
            out.append(kv_table([("limit lap (s)", num(lap.lap_time_s)),
                                 ("split times (s)", ", ".join(f"{s:.3f}"
                                                               for s in lap.split_times_s)),
                                 (measure, num(p["value"])),
                                 ("bang-bang fraction", num(lap.bang_bang_fraction)),
                                 ("active constraints", _active(p)),
                                 ("certificate", _certificate(p))]))
            flown = c.evaluation.trajectory if c.evaluation is not None else None
            fig = plots.limit_lap_figures(lap, flown, waypoints)["limit-time-histories"]
            out.append(figs.embed(fig, f"codesign-candidate-{c.label}-{track}",
                                  f"Candidate {c.title}: its co-design limit lap on {track} "
                                  "(speed and ESC commands) beside its closed-loop lap."))
    return "".join(out)


def _laps_figure(laps: dict, track: str) -> Figure:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10.0, 4.5), layout="constrained")
    ax_xy, ax_t = fig.subplots(1, 2)
    n = len(laps)
    for i, (name, lap) in enumerate(laps.items()):
        shade = 0.15 + 0.7 * i / max(n - 1, 1)
        colour = (shade, shade, 0.85 if i == 0 else shade)
        label = f"{name}: {lap.lap_time_s:.3f} s" if i in (0, n - 1) else None
        ax_xy.plot(lap.x[:, 0], lap.x[:, 1], color=colour, lw=1.0, label=label)
        ax_t.plot(lap.t, np.sum(lap.x[:, 12:16], axis=1), color=colour, lw=1.0, label=label)
    ax_xy.set_aspect("equal", adjustable="datalim")
    ax_xy.set_xlabel("x (m)")
    ax_xy.set_ylabel("y (m)")
    ax_t.set_xlabel("time t (s)")
    ax_t.set_ylabel("total rotor thrust ΣT (N)")
    for ax in (ax_xy, ax_t):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.suptitle(f"Co-design front on {track}: {n} limit laps")
    return fig


def codesign_indices(run: Run, row: int) -> dict[str, float]:
    """Point ``row``'s stored objectives (the lap and the measure) for the candidate tables."""
    data, _ = read_points(run.store.path)
    if data is None:
        return {}
    p = data["points"][row]
    out = {"J3_limit": float(p["objective_s"])}
    value = p.get("value")
    if value is not None and not math.isnan(float(value)):
        out[data["measure"]] = float(value)
    return out
