"""Sensitivity of every index to each decision variable, against the integrator tolerance.

Each of the seven decision variables (paper Table 1) is moved by ±5 % of its Table 1 range around
SY250, one at a time, and J1…J5, Jp are recomputed from an rk4 lap. α and β sit at their upper
bound (90°) on SY250, so they are moved downward only (−5 % and −10 % of the range); the moved
frame is then of family HS. The controller gain is redesigned for each frame (the default
``redesign`` policy), so an inertia change acts through the gain as well as the dynamics.

Integrator tolerance of index J: max over all frames flown here of |J_rk4 − J_cvodes|, CVODES at
rtol = atol = 1e-10 (its own convergence is checked against 1e-12 on SY250). A variable passes
when it moves at least one index by more than that index's tolerance.

Run: ``python benchmarks/sensitivity.py`` (writes benchmarks/RESULTS-sensitivity.md).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks.machine import markdown, summary_section  # noqa: E402
from casadrone.airframe import TABLE1_BOUNDS, THETA_KEYS, build_airframe, random_thetas, with_theta
from casadrone.benchmark import DEFAULT_TRACK
from casadrone.config.airframe import load_airframe
from casadrone.config.controller import load_controller
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.control import design_for
from casadrone.indices import BUILTIN_NAMES, INDICES, compute_indices, lap_mask
from casadrone.simulate import SimOptions, simulate

HERE = Path(__file__).resolve().parent
STEP = 0.05  # fraction of the Table 1 range
ANGLES = ("alpha_deg", "beta_deg")


def lap(cfg, ctrl, track, integrator: str, tol: float | None = None):
    """One lap (raises if it fails: a sensitivity run must not hide that)."""
    airframe = build_airframe(cfg)
    options = SimOptions() if tol is None else SimOptions(rtol=tol, atol=tol)
    traj = simulate(airframe, design_for(airframe, ctrl), track, integrator, options)
    if not traj.completed:
        raise RuntimeError(f"{cfg.name} ({integrator}): lap failed: {traj.reason}")
    return traj


def fly(cfg, ctrl, track, integrator: str, tol: float | None = None) -> dict[str, float]:
    """Indices of one lap."""
    return compute_indices(lap(cfg, ctrl, track, integrator, tol), BUILTIN_NAMES)


def where_max(traj) -> dict[str, tuple[float, int]]:
    """(time, waypoint interval) of the samples that set J4 and Jp."""
    m = lap_mask(traj)
    acc = np.where(m, np.linalg.norm(traj.acceleration, axis=1), -np.inf)
    pitch = np.where(m, np.abs(traj.x[:, 10]), -np.inf)
    out = {}
    for name, v in (("J4", acc), ("Jp", pitch)):
        k = int(np.argmax(v))
        out[name] = (float(traj.t[k]), int(traj.waypoint_index[k]) + 1, int(traj.segment[k]))
    return out


def perturbations(base) -> list[tuple[str, float, object]]:
    """(key, step in config units, config) for every perturbed frame."""
    out = []
    for key in THETA_KEYS:
        lo, hi = TABLE1_BOUNDS[key]
        h = STEP * (hi - lo)
        steps = (-h, -2 * h) if key in ANGLES else (+h, -h)
        for s in steps:
            value = getattr(base, key) + s
            out.append((key, s, with_theta(base, {key: value}, name=f"SY250 {key}{s:+g}")))
    return out


def spread(base, ctrl, track, n: int, seed: int) -> dict[str, dict[str, tuple[float, float]]]:
    """(min, max) of every index over n random Table 1 frames, per gain policy."""
    thetas, _ = random_thetas(base, n, seed)  # overlapping rotors are redrawn
    frames = [with_theta(base, th, name=f"random {i}") for i, th in enumerate(thetas)]
    frozen = ctrl.model_copy(update={"gain_policy": "frozen-command"})
    ref = build_airframe(base)
    out = {}
    for policy, c in (("redesign", ctrl), ("frozen (SY250 gain)", frozen)):
        vals = []
        for cfg in frames:
            airframe = build_airframe(cfg)
            traj = simulate(airframe, design_for(airframe, c, ref), track, "rk4")
            if traj.completed:
                vals.append([compute_indices(traj, BUILTIN_NAMES)[k] for k in BUILTIN_NAMES])
        v = np.array(vals)
        out[policy] = {k: (float(v[:, i].min()), float(v[:, i].max()))
                       for i, k in enumerate(BUILTIN_NAMES)}
        out[policy]["completed"] = (len(vals), n)
    return out


def fmt(v: float) -> str:
    return f"{v:+.2e}"


def summary_row(tol: dict[str, float], J0: dict[str, float]) -> tuple[str, str, str]:
    """The performance page's row: the largest rk4-against-CVODES difference over the indices
    and frames, absolute and relative to SY250's value."""
    worst = max(tol.values())
    relative = max(tol[n] / abs(J0[n]) for n in tol)
    return ("rk4 vs CVODES on every index, SY250 and the frames moved from it",
            f"≤ {worst:.1g} absolute (≤ {relative:.1g} relative)",
            "`python benchmarks/sensitivity.py`")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-sensitivity.md")
    ap.add_argument("--cvodes-tol", type=float, default=1e-10)
    ap.add_argument("--n-random", type=int, default=30, help="random frames for the spread")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    start = time.perf_counter()

    base = load_airframe("SY250")
    ctrl = load_controller()
    track = load(TrackConfig, DEFAULT_TRACK)
    names = BUILTIN_NAMES

    traj0 = lap(base, ctrl, track, "rk4")
    J0 = compute_indices(traj0, BUILTIN_NAMES)
    at = where_max(traj0)
    J0_cv = fly(base, ctrl, track, "cvodes", args.cvodes_tol)
    J0_cv_tight = fly(base, ctrl, track, "cvodes", args.cvodes_tol * 1e-2)
    cases = []
    for key, step, cfg in perturbations(base):
        J = fly(cfg, ctrl, track, "rk4")
        Jcv = fly(cfg, ctrl, track, "cvodes", args.cvodes_tol)
        cases.append((key, step, getattr(cfg, key), J, Jcv))
        print(f"{cfg.name}: " + ", ".join(f"Δ{n} {fmt(J[n] - J0[n])}" for n in names), flush=True)

    spans = spread(base, ctrl, track, args.n_random, args.seed)
    tol_base = {n: abs(J0[n] - J0_cv[n]) for n in names}
    tol = {n: max([tol_base[n]] + [abs(J[n] - Jcv[n]) for *_, J, Jcv in cases]) for n in names}
    cv_conv = {n: abs(J0_cv[n] - J0_cv_tight[n]) for n in names}

    lines = [
        "# Sensitivity of the indices to the decision variables (SY250, rk4)",
        "",
        f"`python benchmarks/sensitivity.py` — {__doc__.splitlines()[0].lower()}",
        "",
        markdown(),
        f"- track `{track.name}`, controller `{ctrl.name}` (gain policy {ctrl.gain_policy}), "
        f"rk4 with the default SimOptions (substeps {SimOptions().substeps}), CVODES "
        f"rtol = atol = {args.cvodes_tol:g}",
        f"- wall time of the whole run: {time.perf_counter() - start:.0f} s",
        "",
        "Each variable is moved by 5 % of its paper Table 1 range around SY250 (one at a time); "
        "α and β are at their upper bound (90°) on SY250, so they move downward only (−5 % and "
        "−10 % of the range; the moved frame is of family HS). The LQR-I gain is redesigned for "
        "every frame (default policy), so inertia acts through the gain as well as the dynamics.",
        "",
        "## Baseline SY250 and integrator tolerance",
        "",
        "| index | unit | rk4 | cvodes | \\|rk4 − cvodes\\| SY250 | tolerance (max over all "
        "frames) | cvodes vs 100× tighter |",
        "|---|---|---:|---:|---:|---:|---:|",
    ]
    for n in names:
        lines.append(f"| {n} | {INDICES[n].unit} | {J0[n]:.6f} | {J0_cv[n]:.6f} | "
                     f"{tol_base[n]:.1e} | {tol[n]:.1e} | {cv_conv[n]:.1e} |")
    lines += [
        "",
        "## Change of each index, J(perturbed) − J(SY250), rk4",
        "",
        "| variable | step | value | " + " | ".join(f"Δ{n} ({INDICES[n].unit})" for n in names)
        + " |",
        "|---|---:|---:|" + "---:|" * len(names),
    ]
    for key, step, value, J, _ in cases:
        lines.append(f"| {key} | {step:+.4g} | {value:.5g} | "
                     + " | ".join(fmt(J[n] - J0[n]) for n in names) + " |")
    lines += [
        "",
        "## Verdict per variable",
        "",
        "Ratio = |ΔJ| / tolerance of that index; a variable passes when some index has ratio > 1.",
        "",
        "| variable | largest ratio | on index | indices above tolerance | largest relative "
        "change | verdict |",
        "|---|---:|---|---|---|---|",
    ]
    failures = []
    for key in THETA_KEYS:
        ratios, rel = {}, {}
        for k, _, _, J, _ in cases:
            if k != key:
                continue
            for n in names:
                r = abs(J[n] - J0[n]) / max(tol[n], 1e-15)
                ratios[n] = max(ratios.get(n, 0.0), r)
                rel[n] = max(rel.get(n, 0.0), abs(J[n] - J0[n]) / abs(J0[n]) * 100)
        top = max(rel, key=rel.get)
        best = max(ratios, key=ratios.get)
        above = [n for n in names if ratios[n] > 1]
        ok = bool(above)
        failures += [] if ok else [key]
        lines.append(f"| {key} | {ratios[best]:.2g} | {best} | {', '.join(above) or 'none'} | "
                     f"{rel[top]:.3f} % ({top}) | "
                     f"{'moves the lap' if ok else '**NO EFFECT above tolerance**'} |")
    lines += [
        "",
        f"Variables with no effect above the integrator tolerance: "
        f"{', '.join(failures) if failures else 'none'}.",
        "",
        f"## Spread over the whole Table 1 space ({args.n_random} random frames, seed "
        f"{args.seed}, rk4)",
        "",
        "For scale: min … max of each index over uniformly drawn θ inside paper Table 1 "
        "(overlapping-rotor draws redrawn), relative span = (max − min) / mean of the two.",
        "",
        "| gain policy | completed | " + " | ".join(f"{n} ({INDICES[n].unit})" for n in names)
        + " |",
        "|---|---:|" + "---|" * len(names),
    ]
    for policy, sp in spans.items():
        done, total = sp["completed"]
        cells = []
        for n in names:
            lo, hi = sp[n]
            cells.append(f"{lo:.4g} … {hi:.4g} ({200 * (hi - lo) / abs(lo + hi):.2f} %)")
        lines.append(f"| {policy} | {done}/{total} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "## Reading",
        "",
        "- Every variable clears the integrator tolerance by orders of magnitude, but the effects "
        "are small in absolute terms: see the largest relative change per variable above. The "
        "lap is shaped by the guidance (reference speed, reference acceleration limit, braking "
        "profile), which is the same for every frame, rather than by what the frame can do: on "
        f"SY250 the largest ESC command is {traj0.u[lap_mask(traj0)].max():.2f} of full range "
        f"and the largest tilt {np.degrees(np.abs(traj0.x[lap_mask(traj0), 9:11]).max()):.0f}° "
        f"(limit {track.max_tilt_deg:g}°). The per-frame LQR-I redesign also compensates much "
        "of each geometry change.",
        f"- On SY250, J4 is set at t = {at['J4'][0]:.2f} s and Jp at t = {at['Jp'][0]:.2f} s, both "
        f"in interval {at['Jp'][1]} (route segment {at['Jp'][2]}, just after the climb point): "
        "the turn from the vertical climb into the first straight, a pure pitch manoeuvre. That "
        "is why Ixx and Izz (roll, yaw) leave J4 and Jp unchanged to round-off (~1e-13).",
        "",
        summary_section([summary_row(tol, J0)]),
    ]
    args.out.write_text("\n".join(lines))
    print(f"wrote {args.out}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
