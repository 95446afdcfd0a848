"""Figures: track, time histories, robustness (paper Figs B1, B2), airframes, Pareto front.

Every function returns a :class:`matplotlib.figure.Figure` built directly (no pyplot state, no
window, no GUI backend needed), so figures can be drawn in worker processes and on servers.
Functions that draw a single panel take an optional ``ax`` to draw into an existing figure.
Units: SI, except angles in degrees and airframe dimensions in millimetres; every axis says which.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle

from casadrone.airframe import Airframe
from casadrone.config.airframe import ROTOR_LABELS
from casadrone.control import Ensemble, LQRIDesign, disturbance_response
from casadrone.indices import pair_thrust_difference, roll_effort_voltage
from casadrone.model import IDX
from casadrone.simulate import Trajectory
from casadrone.targets import TARGET_SIZE, target_outline

NOMINAL = "tab:blue"
ENSEMBLE = "0.6"


def _figure_of(ax: Axes) -> Figure:
    """The figure an Axes is drawn on (every Axes has one)."""
    fig = ax.get_figure(root=True)
    assert isinstance(fig, Figure)
    return fig


def _figure_axes(ax: Axes | None, figsize: tuple[float, float], **kw) -> tuple[Figure, Axes]:
    if ax is not None:
        return _figure_of(ax), ax
    fig = Figure(figsize=figsize, layout="constrained")
    return fig, fig.add_subplot(**kw)


def _colours(n: int) -> list:
    return [f"C{i % 10}" for i in range(n)]


def _colours_of(names: Sequence[str], colours: Mapping[str, Any] | None, skip: int = 0) -> list:
    """A colour per name: from ``colours`` (name → colour), else the default cycle, whose first
    ``skip`` colours are left out."""
    default = _colours(len(names) + skip)[skip:]
    return [(colours or {}).get(n, d) for n, d in zip(names, default, strict=True)]


def candidate_colour(label: str) -> str:
    """The colour of a candidate in every figure: A (utopian) → C1, B (compromise) → C2,
    C (extreme) → C3, and so on to I → C9.

    C0, the blue of the front and of nominal designs (:data:`NOMINAL`), is never a candidate's.
    A design that two decisions picked ("A=C") takes the colour of its first label. Pass the
    colours to a figure as a ``colours`` mapping (name in the figure → colour).

    Raises:
        ValueError: the label is not one letter A…I (or several joined by "=").
    """
    letter = label.split("=")[0].strip()
    if len(letter) != 1 or not "A" <= letter <= "I":
        raise ValueError(f"candidate label {label!r}: expected a letter A…I, e.g. 'A' or 'A=C'")
    return f"C{ord(letter) - ord('A') + 1}"


def _label(name: str, traj: Trajectory) -> str:
    if traj.completed:
        return f"{name} (lap {traj.lap_time:.2f} s)"
    return f"{name} (failed)"


# --------------------------------------------------------------------------------------------
# Track
# --------------------------------------------------------------------------------------------


def _waypoints(trajectories: Mapping[str, Trajectory], waypoints) -> np.ndarray:
    if waypoints is None:
        waypoints = next(iter(trajectories.values())).waypoints
    return np.atleast_2d(np.asarray(waypoints, float))


def track_top_view(trajectories: Mapping[str, Trajectory], waypoints=None, *,
                   ax: Axes | None = None, title: str | None = None,
                   colours: Mapping[str, Any] | None = None,
                   outlines: Sequence[np.ndarray] = ()) -> Figure:
    """Ground track (x east, y north) of each flight, waypoints marked and numbered from 1.

    ``waypoints`` (W × 3, m) defaults to the first trajectory's. Equal aspect: the paper's track
    is 50 m × 2.5 m, so the figure is wide and the cross-track overshoot shows at true scale.
    ``colours`` maps a flight's name to its colour (e.g. :func:`candidate_colour`); flights not
    in it take the default colour cycle. ``outlines`` (each k × 3, m) are the targets'
    boundaries (:func:`target_outlines`), drawn thin.
    """
    wp = _waypoints(trajectories, waypoints)
    pts = np.vstack([wp[:, :2]] + [tr.x[:, :2] for tr in trajectories.values()])
    span = np.ptp(pts, axis=0) + 4.0
    fig, ax = _figure_axes(ax, (10.0, float(np.clip(10.0 * span[1] / span[0] + 1.2, 3.0, 8.0))))
    for (name, tr), c in zip(trajectories.items(), _colours_of(list(trajectories), colours),
                             strict=True):
        ax.plot(tr.x[:, 0], tr.x[:, 1], color=c, lw=1.4, label=_label(name, tr),
                gid=f"track:{name}")
        ax.plot(tr.x[0, 0], tr.x[0, 1], "o", color=c, mfc="white", ms=6)
    for i, line in enumerate(outlines):
        ax.plot(line[:, 0], line[:, 1], color="0.35", lw=0.9, gid=f"target:{i + 1}",
                label="targets" if i == 0 else None)
    ax.plot(wp[:, 0], wp[:, 1], "s", color="k", ms=7, mfc="gold", label="waypoints",
            gid="waypoints", zorder=5)
    for i, (x, y) in enumerate(wp[:, :2], start=1):
        ax.annotate(f"WP{i}", (x, y), xytext=(6, 6), textcoords="offset points", fontsize=9,
                    fontweight="bold")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x, east (m)")
    ax.set_ylabel("y, north (m)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(title or "Track, top view")
    return fig


def trajectory_3d(trajectories: Mapping[str, Trajectory], waypoints=None, *,
                  title: str | None = None, colours: Mapping[str, Any] | None = None,
                  outlines: Sequence[np.ndarray] = ()) -> Figure:
    """3-D flight paths (m) with numbered waypoints and their shadows on the ground.

    The axes are not to scale: each spans its data so the narrow paper track (50 m × 2.5 m at
    20 m) reads as a loop; use :func:`track_top_view` for true proportions. ``colours`` and
    ``outlines`` as in :func:`track_top_view`.
    """
    wp = _waypoints(trajectories, waypoints)
    fig = Figure(figsize=(10.0, 6.0), layout="constrained")
    ax = fig.add_subplot(projection="3d")
    for (name, tr), c in zip(trajectories.items(), _colours_of(list(trajectories), colours),
                             strict=True):
        ax.plot(tr.x[:, 0], tr.x[:, 1], tr.x[:, 2], color=c, lw=1.4, label=_label(name, tr),
                gid=f"track:{name}")
        ax.plot(tr.x[:, 0], tr.x[:, 1], np.zeros(len(tr.t)), color=c, lw=0.8, alpha=0.3)
    for i, line in enumerate(outlines):
        ax.plot(line[:, 0], line[:, 1], line[:, 2], color="0.35", lw=0.9,
                label="targets" if i == 0 else None)
    ax.scatter(wp[:, 0], wp[:, 1], wp[:, 2], marker="s", s=40, color="gold", edgecolor="k",
               label="waypoints", depthshade=False)
    for i, p in enumerate(wp, start=1):
        ax.text(p[0], p[1], p[2] + 1.5, f"WP{i}", fontsize=9, fontweight="bold")
    pts = np.vstack([wp] + [tr.x[:, :3] for tr in trajectories.values()])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * np.maximum(hi - lo, 1.0)
    ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
    ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
    ax.set_zlim(min(lo[2], 0.0), hi[2] + 2 * pad[2])
    ax.set_box_aspect((1.0, 0.45, 0.45))
    ax.view_init(elev=25, azim=-70)
    ax.set_xlabel("x, east (m)")
    ax.set_ylabel("y, north (m)")
    ax.set_zlabel("z, up (m)")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(title or "Track, 3-D (axes not to scale)")
    return fig


def time_histories(trajectories: Mapping[str, Trajectory], *, title: str | None = None,
                   colours: Mapping[str, Any] | None = None) -> Figure:
    """Stacked altitude, speed, roll effort and left-minus-right thrust against time.

    Waypoint split times are dashed vertical lines in each flight's colour (``colours`` as in
    :func:`track_top_view`). Roll effort and thrust difference are the signals of the
    per-interval table (paper Table 4): :func:`casadrone.indices.roll_effort_voltage`
    ((V_FL + V_RL − V_FR − V_RR)/2 minus trim) and :func:`casadrone.indices.pair_thrust_difference`
    ((T_FL + T_RL) − (T_FR + T_RR)).
    """
    fig = Figure(figsize=(10.0, 8.0), layout="constrained")
    axes = fig.subplots(4, 1, sharex=True)
    rows = [
        ("altitude z (m)", lambda tr: tr.x[:, IDX["z"]]),
        ("speed |v| (m/s)", lambda tr: tr.speed),
        ("roll effort (V)", roll_effort_voltage),
        ("thrust left − right (N)", pair_thrust_difference),
    ]
    for (name, tr), c in zip(trajectories.items(), _colours_of(list(trajectories), colours),
                             strict=True):
        for ax, (_, signal) in zip(axes, rows, strict=True):
            ax.plot(tr.t, signal(tr), color=c, lw=1.0, label=_label(name, tr), gid=f"signal:{name}")
            for ts in tr.split_times[np.isfinite(tr.split_times)]:
                ax.axvline(ts, color=c, ls="--", lw=0.8, alpha=0.7)
    first = next(iter(trajectories.values()))
    for i, ts in enumerate(first.split_times, start=1):  # waypoint names once, above the top axes
        if np.isfinite(ts):
            axes[0].annotate(f"WP{i}", (ts, 1.0), xycoords=("data", "axes fraction"),
                             xytext=(0, 2), textcoords="offset points", fontsize=8,
                             ha="center", va="bottom")
    for ax, (ylabel, _) in zip(axes, rows, strict=True):
        ax.set_ylabel(ylabel)
        ax.grid(True, alpha=0.3)
    for ax in axes[2:]:
        ax.axhline(0.0, color="k", lw=0.6)
    axes[-1].set_xlabel("time t (s)")
    axes[0].legend(loc="lower right", fontsize=8)
    fig.suptitle(title or "Time histories")
    return fig


# --------------------------------------------------------------------------------------------
# Limit lap
# --------------------------------------------------------------------------------------------


def limit_lap_trajectory(lap, waypoints) -> Trajectory:
    """A limit lap (:class:`casadrone.limit.lap.LimitLap`) as a Trajectory at its nodes, so the
    track figures draw it beside closed-loop laps (commands repeated at the last node)."""
    n = len(lap.t)
    wp = np.atleast_2d(np.asarray(waypoints, float))
    return Trajectory(
        status="completed", reason="", integrator="limit lap", t=lap.t, x=lap.x_euler,
        u=np.vstack([lap.u, lap.u[-1:]]), p_ref=np.zeros((n, 3)), v_ref=np.zeros((n, 3)),
        psi_ref=np.zeros(n), acceleration=np.zeros((n, 3)), segment=np.zeros(n, int),
        u0=np.zeros(4), battery_voltage=1.0, waypoints=wp, straight=(True,) * len(wp),
        split_times=np.asarray(lap.split_times_s, float),
    )


def target_outlines(targets) -> list[np.ndarray]:
    """The boundary (k × 3, m) of every target of a limit lap's track (a
    :class:`casadrone.limit.problem.Targets`), each drawn as its kind draws it
    (:func:`casadrone.targets.target_outline`)."""
    vec = np.asarray(targets.vector, float).reshape(len(targets.kinds), TARGET_SIZE)
    return [target_outline(tp, kind) for tp, kind in zip(vec, targets.kinds, strict=True)]


def limit_lap_figures(lap, closed_loop: Trajectory | None, waypoints,
                      targets=None) -> dict[str, Figure]:
    """Top view and 3-D path of the limit lap beside the closed-loop lap (with the outlines of
    ``targets``, the track's :class:`casadrone.limit.problem.Targets`, when given), and the limit
    lap's speed (with the closed loop's) and ESC commands over time."""
    flights = {"limit lap": limit_lap_trajectory(lap, waypoints)}
    if closed_loop is not None:
        flights["closed loop"] = closed_loop
    fig = Figure(figsize=(10.0, 6.0), layout="constrained")
    ax_v, ax_u = fig.subplots(2, 1, sharex=True)
    for (name, tr), c in zip(flights.items(), _colours(len(flights)), strict=True):
        ax_v.plot(tr.t, tr.speed, color=c, lw=1.2, label=_label(name, tr))
    for i in range(lap.u.shape[1]):
        ax_u.step(lap.t[:-1], lap.u[:, i], where="post", lw=1.0, label=f"δ {ROTOR_LABELS[i]}")
    for ts in lap.split_times_s:
        for ax in (ax_v, ax_u):
            ax.axvline(ts, color="k", ls="--", lw=0.6, alpha=0.5)
    ax_v.set_ylabel("speed |v| (m/s)")
    ax_u.set_ylabel("ESC command δ (–)")
    ax_u.set_xlabel("time t (s)")
    ax_u.set_ylim(-0.05, 1.05)
    for ax in (ax_v, ax_u):
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
    fig.suptitle(f"Limit lap {lap.lap_time_s:.3f} s: speed and commands "
                 f"(bang-bang fraction {lap.bang_bang_fraction:.2f})")
    wp = flights["limit lap"].waypoints
    outlines = target_outlines(targets) if targets is not None else []
    return {
        "limit-top-view": track_top_view(flights, wp, title="Limit lap and closed-loop lap, top "
                                         "view", outlines=outlines),
        "limit-3d": trajectory_3d(flights, wp, title="Limit lap and closed-loop lap, 3-D",
                                  outlines=outlines),
        "limit-time-histories": fig,
    }


def thrust_against_airspeed(prop: dict, u: np.ndarray, static_full_n: float,
                            propulsion: str) -> Figure:
    """Each rotor's thrust against airspeed over a lap (``prop`` from
    :func:`casadrone.propulsion.lap_propulsion`), full-command nodes marked, with the static
    full-command thrust for reference."""
    fig = Figure(figsize=(8.0, 5.0), layout="constrained")
    ax = fig.subplots()
    v, T = prop["speed_m_s"], prop["thrust_n"]
    full = np.asarray(u)[: len(v)] >= 0.99
    for i in range(T.shape[1]):
        ax.plot(v, T[:, i], ".", ms=3, alpha=0.5, label=f"rotor {ROTOR_LABELS[i]}")
    ax.plot(v[:, None].repeat(T.shape[1], 1)[full], T[full], "kx", ms=4,
            label="full command (δ ≥ 0.99)")
    ax.axhline(static_full_n, color="k", ls="--", lw=0.8, label="static thrust, full command")
    ax.set_xlabel("airspeed |v| (m/s)")
    ax.set_ylabel("rotor thrust T (N)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title(f"Limit lap: rotor thrust against airspeed ({propulsion} propulsion model)")
    return fig


# --------------------------------------------------------------------------------------------
# Robustness (paper Appendix B)
# --------------------------------------------------------------------------------------------


def _zoom_window(eig: np.ndarray) -> tuple[float, float, float, float]:
    """Re/Im limits around the slowest eigenvalues (those with |z| ≥ 0.9, or the top quarter)."""
    mag = np.abs(eig)
    slow = eig[mag >= min(0.9, np.quantile(mag, 0.75))]
    re_lo = float(slow.real.min())
    half = 0.55 * max(1.0 - re_lo, 2 * float(np.max(np.abs(slow.imag))), 2e-3)  # square window
    mid = (re_lo + 1.0) / 2
    return mid - half, mid + half, -half, half


def eigenvalue_cloud(design: LQRIDesign, ensemble: Ensemble | None = None, *,
                     zoom: bool | tuple[float, float, float, float] = True,
                     ax: Axes | None = None, title: str | None = None) -> Figure:
    """Discrete closed-loop eigenvalues of A − BK in the z-plane (paper Fig. B2, top).

    The nominal design (blue crosses) over the perturbed plants of ``ensemble`` (grey dots),
    with the unit circle: stable means inside it. ``zoom`` adds a second panel around z = 1, where
    the slow modes sit at Ts = 0.01 s (True: window chosen from the eigenvalues; a tuple:
    (re_min, re_max, im_min, im_max)). With ``ax`` a single panel is drawn: the zoom window if a
    tuple is given, the whole disc otherwise.
    """
    nominal = np.asarray(design.closed_loop_eigenvalues)
    cloud = np.asarray(ensemble.eigenvalues).ravel() if ensemble is not None else np.empty(0)
    every = np.concatenate([nominal, cloud])
    windows: list[tuple[float, ...] | None] = [None]
    if zoom is not False:
        windows.append(_zoom_window(every) if zoom is True else tuple(zoom))
    if ax is not None:
        windows = [windows[-1] if not isinstance(zoom, bool) else None]
        fig, axes = _figure_of(ax), [ax]
    else:
        fig = Figure(figsize=(5.0 * len(windows), 5.4), layout="constrained")
        axes = list(np.atleast_1d(fig.subplots(1, len(windows))))
    phi = np.linspace(0, 2 * np.pi, 400)
    rho = float(np.max(np.abs(nominal)))
    for a, win in zip(axes, windows, strict=True):
        a.plot(np.cos(phi), np.sin(phi), color="k", lw=0.8, gid="unit-circle")
        a.axhline(0.0, color="k", lw=0.4)
        a.axvline(0.0, color="k", lw=0.4)
        if ensemble is not None and cloud.size:
            worst = ensemble.max_spectral_radius
            a.plot(cloud.real, cloud.imag, ".", color=ENSEMBLE, ms=4, gid="ensemble",
                   label=f"{ensemble.n} perturbed plants (max |z| = {worst:.4f})")
        a.plot(nominal.real, nominal.imag, "x", color=NOMINAL, ms=7, mew=1.5, gid="nominal",
               label=f"nominal (max |z| = {rho:.4f})")
        a.set_aspect("equal", adjustable="box")
        zoomed = windows[-1]
        if win is None and zoomed is not None:  # outline the zoom window on the whole disc
            zx0, zx1, zy0, zy1 = zoomed
            a.plot([zx0, zx1, zx1, zx0, zx0], [zy0, zy0, zy1, zy1, zy0], color="k", ls=":",
                   lw=0.8, gid="zoom-window")
        if win is not None:
            a.set_xlim(win[0], win[1])
            a.set_ylim(win[2], win[3])
            a.set_title("zoom near z = 1", fontsize=10)
        else:
            a.set_xlim(-1.1, 1.1)
            a.set_ylim(-1.1, 1.1)
        a.set_xlabel("Re z (–)")
        a.set_ylabel("Im z (–)")
        a.grid(True, alpha=0.3)
    head = title or f"Closed-loop eigenvalues, Ts = {design.sample_time_s:g} s"
    if ax is None:
        fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncols=2,
                   fontsize=9)
        fig.suptitle(head)
    else:
        ax.legend(loc="lower left", fontsize=8)
        ax.set_title(head)
    return fig


#: Fig. B1 panels: (state, axis label, scale from SI to the plotted unit).
B1_PANELS = (
    ("u", "u (m/s)", 1.0), ("v", "v (m/s)", 1.0), ("w", "w (m/s)", 1.0),
    ("p", "p (deg/s)", np.degrees(1.0)), ("q", "q (deg/s)", np.degrees(1.0)),
    ("r", "r (deg/s)", np.degrees(1.0)),
    ("phi", "φ (deg)", np.degrees(1.0)), ("theta", "θ (deg)", np.degrees(1.0)),
    ("psi", "ψ (deg)", np.degrees(1.0)),
    ("x", "X (m)", 1.0), ("y", "Y (m)", 1.0), ("z", "Z (m)", 1.0),
)  # fmt: skip


#: Smallest half-span of a Fig. B1 panel, in its plotted unit (below it a trace is round-off).
MIN_SPAN = 1e-3


def default_bump(n: int = 20) -> np.ndarray:
    """Fig. B1 bump: u = w = 1 m/s, p = q = 1 rad/s, every other deviation zero."""
    dx0 = np.zeros(n)
    for name, value in (("u", 1.0), ("w", 1.0), ("p", 1.0), ("q", 1.0)):
        dx0[IDX[name]] = value
    return dx0


def disturbance_responses(design: LQRIDesign, ensemble: Ensemble | None = None,
                          dx0: np.ndarray | None = None, horizon_s: float = 10.0, *,
                          title: str | None = None) -> Figure:
    """Hover disturbance responses of the nominal and perturbed closed loops (paper Fig. B1).

    State deviations from trim after the initial deviation ``dx0`` (20, augmented state; default
    :func:`default_bump`), for the nominal plant (blue) and each plant of ``ensemble`` (grey),
    all under the same gain K. Rates and angles in degrees.
    """
    dx0 = default_bump(design.Ad.shape[0]) if dx0 is None else np.asarray(dx0, float)
    Ts = design.sample_time_s
    steps = int(round(horizon_s / Ts)) + 1
    t = np.arange(steps) * Ts
    nominal = disturbance_response(design.Ad, design.Bd, design.K, dx0, steps)
    perturbed = [disturbance_response(A, B, design.K, dx0, steps)
                 for A, B in (ensemble.plants if ensemble is not None else ())]
    fig = Figure(figsize=(11.0, 9.0), layout="constrained")
    axes = fig.subplots(4, 3, sharex=True)
    for a, (state, ylabel, scale) in zip(axes.ravel(), B1_PANELS, strict=True):
        i = IDX[state]
        for resp in perturbed:
            a.plot(t, scale * resp[:, i], color=ENSEMBLE, lw=0.6, gid="ensemble")
        a.plot(t, scale * nominal[:, i], color=NOMINAL, lw=1.4, gid="nominal")
        a.axhline(0.0, color="k", lw=0.5)
        lo, hi = a.get_ylim()
        if hi - lo < 2 * MIN_SPAN:  # a state the bump does not excite: show it flat, not its noise
            a.set_ylim(-MIN_SPAN, MIN_SPAN)
        a.set_ylabel(ylabel)
        a.grid(True, alpha=0.3)
    for a in axes[-1]:
        a.set_xlabel("time t (s)")
    handles = [Line2D([], [], color=NOMINAL, lw=1.4, label="nominal")]
    if perturbed:
        handles.append(Line2D([], [], color=ENSEMBLE, lw=0.8,
                              label=f"{len(perturbed)} perturbed plants"))
    fig.legend(handles=handles, loc="outside lower center", ncols=2, fontsize=9)
    bump = ", ".join(f"{n} = {dx0[IDX[n]]:g} {'m/s' if n in 'uvw' else 'rad/s'}"
                     for n in ("u", "v", "w", "p", "q", "r") if dx0[IDX[n]] != 0)
    fig.suptitle(title or f"Hover disturbance response, deviation from trim "
                          f"(bump at t = 0: {bump})")
    return fig


# --------------------------------------------------------------------------------------------
# Airframes (paper Figs 15, 17, 19)
# --------------------------------------------------------------------------------------------


def top_view_xy(rotor_positions: np.ndarray) -> np.ndarray:
    """Body-frame positions (m) → drawing coordinates (mm): right (−y_b) across, nose (x_b) up,
    the paper's view of the airframe."""
    r = np.asarray(rotor_positions, float)
    return 1000.0 * np.column_stack([-r[:, 1], r[:, 0]])


def _draw_airframe(ax: Axes, af: Airframe, colour, prop_mm: float, reference: bool) -> None:
    xy = top_view_xy(af.rotor_positions)
    ls, lw, z = ("--", 1.2, 1) if reference else ("-", 2.5, 3)
    for p in xy:
        ax.plot([0.0, p[0]], [0.0, p[1]], color=colour, ls=ls, lw=lw, zorder=z)
        ax.add_patch(Circle(tuple(p), prop_mm / 2, fill=not reference, facecolor=colour,
                            edgecolor=colour, alpha=0.8 if reference else 0.15, ls=ls, lw=1.0,
                            zorder=z - 0.5))
    ax.plot(xy[:, 0], xy[:, 1], "o", color=colour, ms=5 if reference else 12, zorder=z + 1,
            gid=f"rotors:{af.name}", label=f"{af.name} ({af.family}, λ = {af.diagonal_mm:.0f} mm)"
            + (" — reference" if reference else ""))
    if not reference:
        for label, p in zip(ROTOR_LABELS, xy, strict=True):
            ax.annotate(label, tuple(p), ha="center", va="center", fontsize=6.5,
                        fontweight="bold", zorder=z + 2, color="white", gid=f"rotor:{label}")
        nose = 0.5 * float(np.min(xy[:2, 1]))
        ax.annotate("", xy=(0.0, nose), xytext=(0.0, 0.0), zorder=z + 2,
                    arrowprops=dict(arrowstyle="-|>", color="k", lw=1.5))
        ax.text(0.0, nose + 2.0, "nose", ha="center", va="bottom", fontsize=8, zorder=z + 2)
        ax.plot(0.0, 0.0, "+", color="k", ms=10, mew=1.5, zorder=z + 2)


def airframe_top_view(airframes: Sequence[Airframe], reference: Airframe | None = None,
                      prop_diameter_m: float = 0.127, *, overlay: bool = False,
                      ax: Axes | None = None, title: str | None = None,
                      colours: Mapping[str, Any] | None = None) -> Figure:
    """Top view of candidate airframes, each over the reference in grey dashed (mm, nose up).

    Arms from the centre of mass (+) to the rotors (labelled by position, FR, FL, RL, RR:
    :data:`casadrone.config.airframe.ROTOR_LABELS`), prop discs of
    ``prop_diameter_m``, an arrow to the nose. One panel per airframe, or all in one
    (``overlay=True``, or whenever ``ax`` is given). ``colours`` maps an airframe's name to its
    colour; airframes not in it take the default colour cycle.
    """
    airframes = list(airframes)
    prop_mm = 1000.0 * prop_diameter_m
    if ax is not None or overlay or len(airframes) <= 1:
        fig, a = _figure_axes(ax, (6.0, 6.0))
        panels = [(a, list(enumerate(airframes)))]
    else:
        fig = Figure(figsize=(5.0 * len(airframes), 5.4), layout="constrained")
        axs = fig.subplots(1, len(airframes), sharex=True, sharey=True)
        panels = [(a, [(i, af)]) for i, (a, af) in enumerate(zip(np.atleast_1d(axs), airframes,
                                                                  strict=True))]
    everything = airframes + ([reference] if reference is not None else [])
    reach = max(float(np.max(np.abs(top_view_xy(af.rotor_positions)))) for af in everything)
    lim = reach + prop_mm / 2 + 10.0
    drawn_in = _colours_of([af.name for af in airframes], colours)
    for a, group in panels:
        if reference is not None:
            _draw_airframe(a, reference, ENSEMBLE, prop_mm, reference=True)
        for i, af in group:
            _draw_airframe(a, af, drawn_in[i], prop_mm, reference=False)
        a.set_xlim(-lim, lim)
        a.set_ylim(-lim, lim)
        a.set_aspect("equal")
        a.set_xlabel("right, −y_b (mm)")
        a.set_ylabel("forward, x_b (mm)")
        a.grid(True, alpha=0.3)
        a.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), fontsize=8)
    head = title or "Airframes, top view (nose up)"
    if len(panels) > 1:
        fig.suptitle(head)
    else:
        panels[0][0].set_title(head)
    return fig


# --------------------------------------------------------------------------------------------
# Optimisation
# --------------------------------------------------------------------------------------------


def _objective_label(name: str, unit: str | None) -> str:
    return f"{name} ({unit})" if unit else name


def pareto_front(F: np.ndarray, names: Sequence[str], highlight: Mapping[str, int] | None = None,
                 *, units: Sequence[str] | None = None, title: str | None = None,
                 colours: Mapping[str, Any] | None = None,
                 descriptions: Mapping[str, str] | None = None,
                 baseline: tuple[str, Sequence[float]] | None = None) -> Figure:
    """Objective values of a front: one scatter for 2 objectives, a lower-triangular scatter
    matrix (every pair once, m(m−1)/2 panels) for more.

    ``F`` (n × m) holds the objectives in their physical units and sense (not negated for
    maximisation); ``units`` labels each axis. ``highlight`` maps a short label (e.g. "A") to a
    row of ``F``: those points are ringed and annotated with the label. ``descriptions`` maps a
    label to its legend entry (default: the label itself, e.g. "A: closest to the utopian
    point"); ``colours`` maps a label to its ring colour (e.g. :func:`candidate_colour`), labels
    not in it taking the default cycle after the front's own C0. ``baseline`` (name, one value
    per objective) draws a reference design, e.g. the airframe the run started from, as a black
    star in every panel, labelled "<name> (baseline)".
    """
    F = np.atleast_2d(np.asarray(F, float))
    m = F.shape[1]
    if len(names) != m:
        raise ValueError(f"{len(names)} names for {m} objectives")
    if m < 2:
        raise ValueError("a Pareto front needs at least two objectives")
    unit_of: list[str | None] = list(units) if units else [None] * m
    labels = [_objective_label(n, u) for n, u in zip(names, unit_of, strict=True)]
    highlight = dict(highlight or {})
    if m == 2:
        fig = Figure(figsize=(6.5, 5.0), layout="constrained")
        pairs = [(fig.add_subplot(), 0, 1)]
    else:
        fig = Figure(figsize=(2.6 * (m - 1) + 1.0, 2.4 * (m - 1) + 0.8), layout="constrained")
        grid = fig.subplots(m - 1, m - 1, squeeze=False)
        pairs = []
        for r in range(m - 1):
            for c in range(m - 1):
                if c > r:
                    grid[r, c].remove()
                else:
                    pairs.append((grid[r, c], c, r + 1))
    ring = _colours_of(list(highlight), colours, skip=1)
    legend = dict(descriptions or {})
    for a, i, j in pairs:
        a.scatter(F[:, i], F[:, j], s=14, color=NOMINAL, alpha=0.7, gid="front",
                  label="Pareto front")
        for (name, k), c in zip(highlight.items(), ring, strict=True):
            a.scatter(F[k, i], F[k, j], s=90, facecolor="none", edgecolor=c, lw=2.0, zorder=3,
                      gid=f"highlight:{name}", label=legend.get(name, name))
            a.annotate(name, (F[k, i], F[k, j]), xytext=(5, 5), textcoords="offset points",
                       fontsize=8, color=c, fontweight="bold")
        if baseline is not None:
            b = baseline[1]
            a.scatter(b[i], b[j], s=150, marker="*", color="k", zorder=4, gid="baseline",
                      label=baseline_label(baseline[0]))
        a.grid(True, alpha=0.3)
        a.set_xlabel(labels[i], fontsize=9)
        a.set_ylabel(labels[j], fontsize=9)
    if m == 2:
        pairs[0][0].legend(fontsize=8)
    else:
        fig.legend(*pairs[0][0].get_legend_handles_labels(), loc="upper right", fontsize=9)
    fig.suptitle(title or f"Pareto front ({F.shape[0]} designs)")
    return fig


def baseline_label(name: str) -> str:
    """The legend entry of a baseline design drawn over a front or a set."""
    return f"{name} (baseline)"


def convergence(generations: Sequence[int], hypervolume: Sequence[float],
                archive_size: Sequence[int] | None = None, *, hypervolume_unit: str = "–",
                title: str | None = None) -> Figure:
    """Hypervolume (and, if given, the size of the Pareto archive) per generation."""
    rows = 1 if archive_size is None else 2
    fig = Figure(figsize=(7.0, 2.6 * rows + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, 1, sharex=True))
    axes[0].plot(generations, hypervolume, "o-", color=NOMINAL, ms=3, gid="hypervolume")
    axes[0].set_ylabel(f"hypervolume ({hypervolume_unit})")
    if archive_size is not None:
        axes[1].step(generations, archive_size, where="post", color="tab:orange", gid="archive")
        axes[1].set_ylabel("archive size (designs)")
    for a in axes:
        a.grid(True, alpha=0.3)
    axes[-1].set_xlabel("generation (–)")
    fig.suptitle(title or "Convergence")
    return fig


#: White margin (inches) around a figure saved with a tight bounding box.
PAD_INCHES = 0.05

#: The metadata entry, per format, that carries :func:`figure_mark` in every figure casadrone
#: writes: PNG's tEXt ``Software`` and SVG's creator (``<dc:creator><cc:Agent><dc:title>`` in the
#: RDF under ``<metadata>``), both as matplotlib writes them.
MARK_KEYS = {"png": "Software", "svg": "Creator"}

#: How much of a file is read to find the mark (matplotlib puts it before any drawing).
_MARK_HEAD_BYTES = 64 * 1024


def figure_mark() -> str:
    """The mark of a figure casadrone wrote: ``casadrone <version>``."""
    from casadrone import __version__

    return f"casadrone {__version__}"


def _is_mark(text: str) -> bool:
    """Whether metadata text is casadrone's mark, of any version."""
    name, _, version = text.strip().partition(" ")
    return name == "casadrone" and bool(version) and " " not in version


def is_casadrone_figure(path: str | Path) -> bool:
    """Whether ``path`` is a figure casadrone wrote (:func:`save_figure`): a regular file, not a
    link, that is a PNG whose tEXt ``Software`` or an SVG whose creator is :func:`figure_mark`
    (any version). Reads at most a few tens of kilobytes; a file that cannot be read is not."""
    path = Path(path)
    if path.is_symlink() or not path.is_file():
        return False
    try:
        with path.open("rb") as fh:
            if path.suffix.lower() == ".png":
                return _png_marked(fh)
            if path.suffix.lower() == ".svg":
                return _svg_marked(fh.read(_MARK_HEAD_BYTES))
    except OSError:
        return False
    return False


def _png_marked(fh) -> bool:
    """The PNG's chunks up to its image data hold a tEXt ``Software`` that is the mark."""
    if fh.read(8) != b"\x89PNG\r\n\x1a\n":
        return False
    for _ in range(64):  # chunks before IDAT: matplotlib writes three
        head = fh.read(8)
        if len(head) < 8:
            return False
        size, kind = int.from_bytes(head[:4], "big"), head[4:]
        if kind in (b"IDAT", b"IEND"):
            return False
        if kind == b"tEXt" and size <= _MARK_HEAD_BYTES:
            key, _, text = fh.read(size).partition(b"\0")
            if key == MARK_KEYS["png"].encode("latin-1"):
                return _is_mark(text.decode("latin-1"))
            fh.seek(4, 1)  # CRC
        else:
            fh.seek(size + 4, 1)
    return False


_SVG_CREATOR = re.compile(r"<dc:creator>\s*<cc:Agent>\s*<dc:title>([^<]*)</dc:title>")


def _svg_marked(head: bytes) -> bool:
    """The SVG's ``<metadata>`` (within its first bytes) names the mark as its creator."""
    text = head.decode("utf-8", errors="replace")
    start = text.find("<metadata>")
    end = text.find("</metadata>", start)
    if start < 0 or end < 0 or "<svg" not in text[:start]:
        return False
    found = _SVG_CREATOR.search(text, start, end)
    return found is not None and _is_mark(found.group(1))


def save_figure(fig: Figure, path_without_suffix: str | Path,
                formats: Sequence[str] = ("png", "svg"), dpi: int = 150) -> list[Path]:
    """Write ``fig`` once per format (parent folders created); returns the paths written.

    The saved extent is the figure's tight bounding box plus :data:`PAD_INCHES`, so no label,
    title or legend is clipped off the edge whatever the figure size or dpi. PNG and SVG files
    carry casadrone's mark (:data:`MARK_KEYS`, :func:`is_casadrone_figure`). No check here: the
    caller decides whether an existing file may be replaced
    (:func:`casadrone.cli.common.save_figures`)."""
    base = Path(path_without_suffix)
    base.parent.mkdir(parents=True, exist_ok=True)
    paths = []
    for fmt in (f.lstrip(".") for f in formats):
        path = base.with_name(f"{base.name}.{fmt}")
        key = MARK_KEYS.get(fmt.lower())
        fig.savefig(path, format=fmt, dpi=dpi, bbox_inches="tight", pad_inches=PAD_INCHES,
                    metadata={key: figure_mark()} if key else None)
        paths.append(path)
    return paths


def _part_label(fit, part: str, text: str) -> str:
    """The legend of a fitted law: ``text``, marked when its part is refused or not fitted."""
    status = fit.status(part)
    return {"fitted": text, "refused": f"{text} (refused)"}.get(status, f"{part} not fitted")


def propulsion_fit_figures(fit, log) -> dict[str, Figure]:
    """``fit-propulsion``'s figures: the steady points against the fitted propeller, motor and
    battery laws (``steady``), and each fitted step response over the logged speed (``steps``).

    Args:
        fit: a :class:`casadrone.thruststand.PropulsionFit`. log: the
            :class:`~casadrone.thruststand.StandLog` it was fitted from.
    """
    p = fit.plateaus
    w = np.array([q.speed_rad_s for q in p])
    rho, D = fit.air_density_kg_m3, fit.diameter_m
    grid = np.linspace(0.0, 1.05 * float(w.max()), 100)
    ng = grid / (2 * np.pi)
    steady = Figure(figsize=(11, 3.4), layout="constrained")
    ax1, ax2, ax3 = steady.subplots(1, 3)
    rpm = 60 / (2 * np.pi)
    ax1.plot(w * rpm, [q.thrust_n for q in p], "o", label="steady points")
    ax1.plot(grid * rpm, fit.ct0 * rho * ng**2 * D**4, "-",
             label=_part_label(fit, "propeller", f"C_T0 = {fit.ct0:.4f}"))
    ax1.set(xlabel="rotor speed (rpm)", ylabel="thrust (N)", title="propeller thrust")
    ax2.plot(w * rpm, np.abs([q.torque_nm for q in p]), "o", label="steady points")
    ax2.plot(grid * rpm, fit.cp0 * rho * ng**2 * D**5 / (2 * np.pi), "-",
             label=_part_label(fit, "propeller", f"C_P0 = {fit.cp0:.4f}"))
    ax2.set(xlabel="rotor speed (rpm)", ylabel="shaft torque (N·m)", title="propeller torque")
    current = np.array([q.current_a for q in p])
    ax3.plot(current, [q.voltage_v for q in p], "o", label="steady points")
    ig = np.linspace(0.0, 1.05 * float(current.max()), 50)
    ax3.plot(ig, fit.open_circuit_voltage_v - fit.internal_resistance_ohm * ig, "-",
             label=_part_label(fit, "battery",
                               f"R_int = {1e3 * fit.internal_resistance_ohm:.1f} mΩ"))
    ax3.set(xlabel="bus current (A)", ylabel="bus voltage (V)", title="battery sag")
    for ax in (ax1, ax2, ax3):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    figures = {"propulsion-fit-steady": steady}
    if fit.steps:
        fig, ax = _figure_axes(None, (6, 3.6))
        for step, colour in zip(fit.steps, _colours(len(fit.steps)), strict=True):
            k = int(np.searchsorted(log.time_s, step.time_s))
            t = log.time_s[k - 1:k + int(8 * step.time_constant_s / np.median(np.diff(log.time_s)))]
            w_log = log.speed_rad_s[k - 1:k - 1 + len(t)]
            t0 = t[0]
            w0, winf = w_log[0], w_log[-1]
            ax.plot(1e3 * (t - t0), w_log * rpm, ".", ms=2, color=colour)
            ax.plot(1e3 * (t - t0), (winf + (w0 - winf) * np.exp(-(t - t0) / step.time_constant_s))
                    * rpm, "-", color=colour, lw=1)
        ax.set(xlabel="time after the step (ms)", ylabel="rotor speed (rpm)",
               title=f"step responses: τ = {1e3 * fit.time_constant_s:.1f} ms (median)")
        ax.grid(True, alpha=0.3)
        figures["propulsion-fit-steps"] = fig
    return figures


def propeller_part_figure(part, points) -> Figure:
    """A catalogue propeller's raw points and its fit: C_T(J) and C_P(J) side by side, each
    measured sweep in its own colour (the static points at J = 0), the fitted quadratic drawn
    to the end of the fitted sweep (``j_max_measured``), dashed beyond it to the last point.

    Args:
        part: a :class:`casadrone.parts.PropellerPart`. points: its raw (J, rpm, C_T, C_P)
            rows (:func:`casadrone.parts.propeller_points`).
    """
    a = np.asarray(points, dtype=float)
    fig = Figure(figsize=(9, 3.4), layout="constrained")
    axes = fig.subplots(1, 2)
    sweeps = sorted(set(a[a[:, 0] > 0, 1]))
    colours = dict(zip(sweeps, _colours(len(sweeps)), strict=True))
    J_end = float(a[:, 0].max())
    grid = np.linspace(0.0, part.j_max_measured, 100)
    beyond = np.linspace(part.j_max_measured, max(J_end, part.j_max_measured), 20)
    for ax, col, c, what in ((axes[0], 2, part.ct_coefficients, "C_T"),
                             (axes[1], 3, part.cp_coefficients, "C_P")):
        static = a[a[:, 0] == 0]
        ax.plot(static[:, 0], static[:, col], "k.", ms=4, label="static (J = 0, all rpm)")
        for rpm in sweeps:
            s = a[(a[:, 0] > 0) & (a[:, 1] == rpm)]
            ax.plot(s[:, 0], s[:, col], "o", ms=3, color=colours[rpm], label=f"{rpm:.0f} rpm")
        ax.plot(grid, np.polynomial.polynomial.polyval(grid, c), "k-", lw=1.5,
                label=f"fit {c[0]:.4f} {c[1]:+.4f} J {c[2]:+.4f} J²")
        ax.plot(beyond, np.polynomial.polynomial.polyval(beyond, c), "k--", lw=1)
        ax.axhline(0.0, color="0.7", lw=0.8)
        ax.set(xlabel="advance ratio J", ylabel=what)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=6, loc="lower left")
    fig.suptitle(f"{part.name}: {part.caveat}", fontsize=8)
    return fig


def propeller_overview_figure(parts, points_by_name: Mapping[str, Any]) -> Figure:
    """Every catalogue propeller's C_T points and fit in one grid of small panels (the fitted
    sweep's points dark, the other points grey), for the documentation."""
    n = len(parts)
    cols = 6
    rows = -(-n // cols)
    fig = Figure(figsize=(2.2 * cols, 1.9 * rows), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, sharex=True, sharey=True)).ravel()
    for ax, part in zip(axes, parts, strict=False):
        a = np.asarray(points_by_name[part.name], dtype=float)
        used = (a[:, 1] == part.sweep_rpm) & (a[:, 0] > 0)
        ax.plot(a[~used, 0], a[~used, 2], ".", color="0.7", ms=2)
        ax.plot(a[used, 0], a[used, 2], ".", color="C0", ms=3)
        J = np.linspace(0.0, part.j_max_measured, 50)
        ax.plot(J, np.polynomial.polynomial.polyval(J, part.ct_coefficients), "k-", lw=1)
        ax.axhline(0.0, color="0.8", lw=0.6)
        ax.set_title(part.name.removeprefix("uiuc-"), fontsize=7)
        ax.tick_params(labelsize=6)
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.supxlabel("advance ratio J", fontsize=8)
    fig.supylabel("C_T", fontsize=8)
    return fig
