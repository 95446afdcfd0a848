"""Figures of a trim-solver study: success and iterations across the envelope, basins of
attraction, residual histories (:mod:`casadrone.trimstudy`). Built like :mod:`casadrone.plots`:
plain Figures, no pyplot state; angles in degrees, speeds in m/s, residuals in SI units of ẋ.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from matplotlib.colors import ListedColormap
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from casadrone.trimstudy import OUTCOMES, BasinSlice, ResidualHistory, TrimStudy

#: One colour per solver in every figure of a study.
SOLVER_COLOURS = {"ipopt": "C0", "nelder-mead": "C1", "newton": "C2"}
#: One colour per outcome: green at the reference, blue another trim, purple a root outside the
#: domain, orange no root, red ran away.
OUTCOME_COLOURS = {"converged": "#2ca02c", "other-trim": "#1f77b4", "out-of-domain": "#9467bd",
                   "failed": "#ff7f0e", "diverged": "#d62728"}
#: Marker of each kind of operating point (level flight, hover included, is a line).
_MARKERS = {"climb": "^", "descent": "v", "turn": "s"}


def _kind(point) -> str:
    if point.condition == "climb":
        return "climb" if point.climb_angle_deg >= 0 else "descent"
    return "level" if point.condition in ("hover", "forward") else point.condition


def envelope_figure(study: TrimStudy, title: str | None = None) -> Figure:
    """Success rate and iterations (median, quartiles as bars) against speed, per solver: level
    flight (hover at 0 m/s) as lines, climbs, descents and turns as markers at their speed."""
    fig = Figure(figsize=(7.5, 6.0), layout="constrained")
    ax_ok, ax_it = fig.subplots(2, 1, sharex=True)
    n = len(study.options.solvers)
    for i, solver in enumerate(study.options.solvers):
        colour = SOLVER_COLOURS.get(solver, f"C{i}")
        dx = (i - (n - 1) / 2) * 0.25  # side by side, so quartile bars do not hide each other
        for kind in ("level", *_MARKERS):
            pts = [p for p in study.points if _kind(p.point) == kind]
            if not pts:
                continue
            v = np.array([p.point.speed_mps for p in pts]) + dx
            s = [p.summary(solver) for p in pts]
            rate = [100 * x.success_rate for x in s]
            med = np.array([x.iterations_median for x in s])
            err = np.abs(np.array([[x.iterations_q25 for x in s], [x.iterations_q75 for x in s]])
                         - med)
            style = dict(color=colour, marker=_MARKERS.get(kind, "o"), ms=5,
                         ls="-" if kind == "level" else "none")
            ax_ok.plot(v, rate, gid=f"success-{solver}-{kind}", **style)
            ax_it.errorbar(v, med, yerr=err, capsize=2, gid=f"iterations-{solver}-{kind}",
                           **style)
    ax_ok.set_ylabel("success from the starts (%)")
    ax_ok.set_ylim(-3, 103)
    ax_it.set_yscale("log")
    ax_it.set_ylabel("iterations of a success (–)\nmedian, quartiles")
    ax_it.set_xlabel("speed along the path (m/s); hover at 0")
    for a in (ax_ok, ax_it):
        a.grid(True, alpha=0.3)
    handles = [Line2D([], [], color=SOLVER_COLOURS.get(s, f"C{i}"), label=s)
               for i, s in enumerate(study.options.solvers)]
    kinds = {_kind(p.point) for p in study.points}
    handles += [Line2D([], [], color="0.4", marker=_MARKERS.get(k, "o"), ls="none",
                       label={"level": "level flight"}.get(k, k))
                for k in ("level", *_MARKERS) if k in kinds]
    ax_ok.legend(handles=handles, fontsize=8, ncols=2, loc="lower left")
    o = study.options
    fig.suptitle(title or f"{study.airframe}: trim solvers from {o.starts + 1} starts per point "
                 f"(±{o.angle_spread_deg:g}° attitude, ±{100 * o.command_spread:g} % commands)")
    return fig


def basin_figure(basin: BasinSlice, title: str | None = None) -> Figure:
    """One panel per solver: the outcome from each start of the (φ0, θ0) slice, the analytic
    guess at the centre (white cross)."""
    solvers = list(basin.outcomes)
    fig = Figure(figsize=(3.4 * len(solvers) + 0.6, 3.8), layout="constrained")
    axes = np.atleast_1d(fig.subplots(1, len(solvers), sharey=True))
    cmap = ListedColormap([OUTCOME_COLOURS[o] for o in OUTCOMES])
    ph, th = basin.phi_offset_deg, basin.theta_offset_deg
    dph, dth = (ph[1] - ph[0]) / 2 if len(ph) > 1 else 1, (th[1] - th[0]) / 2 if len(th) > 1 else 1
    extent = (ph[0] - dph, ph[-1] + dph, th[0] - dth, th[-1] + dth)
    for ax, solver in zip(axes, solvers, strict=True):
        grid = basin.outcomes[solver]
        ax.imshow(grid, origin="lower", extent=extent, cmap=cmap, vmin=-0.5,
                  vmax=len(OUTCOMES) - 0.5, interpolation="nearest", aspect="auto", gid=solver)
        ax.plot(0, 0, "x", color="white", ms=8, mew=2)
        share = 100 * np.mean(grid == 0)
        ax.set_title(f"{solver}: {share:.0f} % to the reference", fontsize=9)
        ax.set_xlabel("φ0 − φ guess (deg)")
    axes[0].set_ylabel("θ0 − θ guess (deg)")
    present = sorted({int(v) for g in basin.outcomes.values() for v in np.unique(g)})
    fig.legend(handles=[Patch(color=OUTCOME_COLOURS[OUTCOMES[k]], label=OUTCOMES[k])
                        for k in present], loc="outside lower center", ncols=len(present),
               fontsize=8)
    fig.suptitle(title or f"Basins of attraction, {basin.point.label}: commands at the guess")
    return fig


def residual_figure(histories: Sequence[ResidualHistory], tolerances: dict[str, float],
                    title: str | None = None) -> Figure:
    """Residual norm against iterations, per solver (colour) and start (line style); each
    solver's acceptance tolerance dotted."""
    fig = Figure(figsize=(7.5, 4.0), layout="constrained")
    ax = fig.add_subplot()
    starts = list(dict.fromkeys(h.start for h in histories))
    styles = ["-", "--", ":", "-."]
    solvers = list(dict.fromkeys(h.solver for h in histories))
    for h in histories:
        colour = SOLVER_COLOURS.get(h.solver, "0.3")
        ls = styles[starts.index(h.start) % len(styles)]
        lw = 1.2 + 1.2 * (len(solvers) - 1 - solvers.index(h.solver))  # coinciding lines show
        ax.plot(h.iterations, np.maximum(h.residual_norm, 1e-17), color=colour, ls=ls, lw=lw,
                marker=".", ms=3, gid=f"{h.solver}-{h.start}")
    for solver, tol in tolerances.items():
        ax.axhline(tol, color=SOLVER_COLOURS.get(solver, "0.3"), ls=":", lw=0.8)
    ax.set_xscale("symlog", linthresh=10)
    ax.set_xlim(left=0)
    ax.set_yscale("log")
    ax.set_xlabel("iterations (–)")
    ax.set_ylabel("residual norm (SI units of ẋ)")
    ax.grid(True, alpha=0.3)
    handles = [Line2D([], [], color=SOLVER_COLOURS.get(s, "0.3"), label=s) for s in solvers]
    handles += [Line2D([], [], color="0.3", ls=styles[i % len(styles)], label=f"from {s}")
                for i, s in enumerate(starts)]
    ax.legend(handles=handles, fontsize=8)
    fig.suptitle(title or "Residual histories (dotted: acceptance tolerance)")
    return fig
