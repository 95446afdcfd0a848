"""What geometry changes, and why: index spread and rank correlations over random feasible frames.

Three set-ups, each over N random frames drawn uniformly inside paper Table 1 (draws with
overlapping rotors or an impossible inertia tensor redrawn, so every frame is a possible body):

- ``free + frozen-command``: Ixx, Iyy, Izz free decision variables, the SY250 gain frozen in
  ESC-command space (every frame flown through SY250's mixer): casadrone before issue 8;
- ``free + frozen-wrench``: the same frames, the SY250 gain frozen in wrench space and mixed by
  each frame's own allocation inverse (the paper problems' controller now);
- ``components + frozen-wrench``: mass, centre of mass and inertia from the parts
  (SY250-components), the gain designed on SY250-components and mixed per frame.

For every index J1…J5, Jp: min, max and relative spread (max − min) / mean, and Spearman's rank
correlation with each decision variable and with derived physical quantities: roll, pitch and yaw
control effectiveness (mean |(J⁻¹ A_M)_ij| over the rotors, rad/s² per N of one rotor's thrust,
J the inertia tensor, A_M the moment rows of the allocation), the front/rear arm ratio λa/λb,
the hover thrust ratio rear/front (T3 + T4)/(T1 + T2), mass and the principal inertias.

Also: the feasible fraction of the Table 1 box (Monte Carlo), the Jp spread over 20 frames under
frozen-wrench (issue acceptance: below 1 %), and, with ``--runs BEFORE AFTER``, the A/B/C
candidates of two optimisation runs side by side.

Run: ``python benchmarks/geometry_effects.py`` (writes benchmarks/RESULTS-geometry.md).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))
from benchmarks.machine import markdown  # noqa: E402
from casadrone.airframe import (  # noqa: E402
    TABLE1_BOUNDS,
    build_airframe,
    decision_keys,
    random_thetas,
    with_theta,
)
from casadrone.config.airframe import min_rotor_gap_mm  # noqa: E402
from casadrone.evaluate import default_setup, evaluate  # noqa: E402
from casadrone.indices import BUILTIN_NAMES, INDICES  # noqa: E402

HERE = Path(__file__).resolve().parent
SETUPS = (
    ("free + frozen-command", "SY250", "frozen-sy250"),
    ("free + frozen-wrench", "SY250", "frozen-wrench-sy250"),
    ("components + frozen-wrench", "SY250-components", "frozen-wrench-sy250-components"),
)
SHORT = {"lambda_a_mm": "λa", "lambda_b_mm": "λb", "alpha_deg": "α", "beta_deg": "β",
         "ixx_kgm2": "Ixx", "iyy_kgm2": "Iyy", "izz_kgm2": "Izz"}
DERIVED = ("roll eff.", "pitch eff.", "yaw eff.", "λa/λb", "T rear/front", "mass", "I1", "I2",
           "I3")


def derived(frame) -> dict[str, float]:
    """Physical quantities of a built airframe (see the module docstring)."""
    G = np.linalg.solve(frame.inertia, frame.allocation_matrix[1:4])
    T = frame.hover_thrusts()
    principal = np.linalg.eigvalsh(frame.inertia)
    return {"roll eff.": float(np.mean(np.abs(G[0]))), "pitch eff.": float(np.mean(np.abs(G[1]))),
            "yaw eff.": float(np.mean(np.abs(G[2]))),
            "λa/λb": float(frame.theta[0] / frame.theta[1]),
            "T rear/front": float((T[2] + T[3]) / (T[0] + T[1])), "mass": float(frame.mass),
            "I1": float(principal[0]), "I2": float(principal[1]), "I3": float(principal[2])}


def study(template: str, controller: str, n: int, seed: int) -> dict:
    """Indices, decision variables and derived quantities of n random feasible frames."""
    setup = default_setup(template, controller)
    thetas, rejected = random_thetas(setup.template, n, seed)
    rows, failed = [], []
    start = time.process_time()
    for theta in thetas:
        ev = evaluate(theta, setup)
        if not ev.completed:
            failed.append(f"{ev.stage}: {ev.reason}")
            continue
        frame = build_airframe(with_theta(setup.template, theta))
        rows.append({**theta, **derived(frame), **ev.indices})
    return {"rows": rows, "failed": failed, "rejected": rejected,
            "variables": list(decision_keys(setup.template)),
            "cpu_s": time.process_time() - start}


#: The cause of J4's spread under frozen-wrench (free inertia): one frame with a narrow tail and a
#: large roll inertia, then each changed alone, then both (Izz 0.0030 so every variant is a body).
FLOOR_BASE = {"lambda_a_mm": 125.0, "lambda_b_mm": 125.0, "alpha_deg": 88.6, "beta_deg": 68.2,
              "ixx_kgm2": 0.00278, "iyy_kgm2": 0.0017, "izz_kgm2": 0.0030}
FLOOR_CHANGES = ({}, {"beta_deg": 90.0}, {"ixx_kgm2": 0.0016},
                 {"beta_deg": 90.0, "ixx_kgm2": 0.0016}, {"alpha_deg": 68.2, "beta_deg": 88.6})


def floor_experiment() -> list[str]:
    """Table rows: where J4 is set and how long a motor sits at the 0 command floor before it."""
    from casadrone.indices import lap_mask

    setup = default_setup("SY250", "frozen-wrench-sy250")
    out = []
    for change in FLOOR_CHANGES:
        ev = evaluate({**FLOOR_BASE, **change}, setup, keep_trajectory=True)
        tr = ev.trajectory
        acc = np.where(lap_mask(tr), np.linalg.norm(tr.acceleration, axis=1), -np.inf)
        k = int(np.argmax(acc))
        window = tr.u[max(k - 30, 0): k + 1]  # the 0.3 s before the peak
        floor = int(np.sum(window <= 1e-12))
        what = ", ".join(f"{SHORT.get(a, a)} = {v:g}" for a, v in change.items()) or "base"
        out.append(f"| {what} | {ev.indices['J4']:.3f} | {tr.t[k]:.2f} | "
                   f"{int(tr.waypoint_index[k]) + 1} | {floor} | {ev.indices['J5']:.4f} |")
    return out


def swap_experiment() -> list[str]:
    """components + frozen-wrench: J2 of α = 66° and 85° (λa = λb = 125 mm, β = 90°), and of each
    geometry flown with the other's inertia tensor (same mass: the arms have the same lengths)."""
    import dataclasses

    from casadrone.control import design_for
    from casadrone.indices import compute_indices
    from casadrone.simulate import simulate

    setup = default_setup("SY250-components", "frozen-wrench-sy250-components")
    frames = {a: build_airframe(with_theta(setup.template, {"alpha_deg": a})) for a in (66, 85)}

    def j2(frame) -> float:
        design = design_for(frame, setup.controller, setup.reference_airframe)
        return compute_indices(simulate(frame, design, setup.track, "rk4"), ["J2"])["J2"]

    rows = []
    for geometry, inertia in ((66, 66), (66, 85), (85, 66), (85, 85)):
        frame = dataclasses.replace(frames[geometry], inertia=frames[inertia].inertia)
        rows.append(f"| α = {geometry}° | α = {inertia}° | {j2(frame):.4f} |")
    return rows


def mapping_cost(n: int = 20000) -> float:
    """CPU time of one frozen_wrench_gain call (µs), the per-candidate cost of frozen-wrench."""
    from casadrone.control import frozen_wrench_gain

    ref = build_airframe(default_setup("SY250").template)
    frame = build_airframe(with_theta(default_setup("SY250").template, {"lambda_a_mm": 140.0}))
    K = np.random.default_rng(0).normal(size=(4, 20))
    start = time.process_time()
    for _ in range(n):
        frozen_wrench_gain(K, ref, frame)
    return 1e6 * (time.process_time() - start) / n


def spread(values: np.ndarray) -> tuple[float, float, float]:
    lo, hi = float(values.min()), float(values.max())
    return lo, hi, (hi - lo) / float(values.mean())


def table1_feasibility(n: int, seed: int, prop_mm: float = 127.0) -> dict[str, float]:
    """Fractions of the uniform Table 1 box that are possible bodies, without overlapping
    props, and both (vectorised; the schema is checked to agree on a subsample)."""
    rng = np.random.default_rng(seed)
    s = {k: rng.uniform(lo, hi, n) for k, (lo, hi) in TABLE1_BOUNDS.items()}
    ixx, iyy, izz = s["ixx_kgm2"], s["iyy_kgm2"], s["izz_kgm2"]
    body = (izz <= ixx + iyy) & (ixx <= iyy + izz) & (iyy <= ixx + izz)
    la, lb = s["lambda_a_mm"], s["lambda_b_mm"]
    ha, hb = np.radians(s["alpha_deg"]) / 2, np.radians(s["beta_deg"]) / 2
    front, rear = 2 * la * np.sin(ha), 2 * lb * np.sin(hb)
    side = np.hypot(la * np.cos(ha) + lb * np.cos(hb), la * np.sin(ha) - lb * np.sin(hb))
    diag = np.hypot(la * np.cos(ha) + lb * np.cos(hb), la * np.sin(ha) + lb * np.sin(hb))
    gap = np.minimum.reduce([front, rear, side, diag])
    props = gap >= prop_mm
    for i in range(200):  # cross-check against the config module
        assert (gap[i] >= prop_mm) == (min_rotor_gap_mm(la[i], lb[i], s["alpha_deg"][i],
                                                         s["beta_deg"][i]) >= prop_mm)
    return {"possible body": float(body.mean()), "props clear": float(props.mean()),
            "both": float((body & props).mean()),
            "Izz ≤ Ixx + Iyy": float((izz <= ixx + iyy).mean())}


READING = [
    "## Reading: what each remaining spread is",
    "",
    "- **frozen-command (before issue 8) ranks mixers, not airframes.** Every frame is flown "
    "through SY250's motor mix, so on a frame with λa ≠ λb the collective correction also "
    "pitches it and the hover trim is met only by the integrators: J1 and Jp follow the "
    "front/rear arm ratio and the rear/front hover-thrust ratio almost perfectly (|ρ| 0.85–1.00) "
    "and Jp spreads by several per cent. That is a property of the set-up, not of the geometry.",
    "- **free + frozen-wrench.** With each frame's own allocation inverse as mixer, the "
    "commanded wrench reaches the rigid body exactly, and arm geometry can only act through "
    "the command limits (inertia and mass are free of it in this mode): two frames with other "
    "arms fly the same rigid-body trajectory to round-off until a motor command is first clipped "
    "(tests/integration/test_frozen_wrench.py). What is left: Jp follows Iyy (ρ = +1.00; the "
    "pitch-over after the climb is a pure pitch manoeuvre and the same pitch torque turns a "
    "larger Iyy more slowly) and spreads by only ~0.1 %. J5 (RMS ESC-voltage deviation) follows "
    "Izz and Ixx (the same frozen gain commands more torque for longer on a frame that turns "
    "slower, and the voltage is measured per motor, after the mixer, so short moment arms also "
    "need larger command differences). J2, J3 and J4 follow β, α and Ixx: the largest spread, "
    "J4's, is not set by the frame's acceleration capability at all (mass is fixed in this mode). "
    "Its cause is in the table above: in the final curve (interval 4) the rear motor on the "
    "inside of the turn sits at the 0 command floor for several samples; a narrow tail (small β: "
    "rear rotors close to the x axis) or a large Ixx needs more differential thrust for the "
    "same roll acceleration, so the commanded wrench is clipped for longer, the roll overshoots "
    "and the lateral acceleration peaks higher than the pitch-over that sets J4 on the other "
    "frames (t = 5.93 s, interval 1). Widening the tail or lowering Ixx alone shortens the "
    "clipping and brings J4 down to about the pitch-over value; both together, or the narrow "
    "pair moved to the nose (α small, β 90°), remove it and J4 is the pitch-over again. So "
    "J4, J2 and J3 measure control authority at the motor floor: physical (actuator limits "
    "and moment arms), but plain per-motor clipping exaggerates it; a flight controller's mixer "
    "desaturation (Betaflight airmode) would trade collective thrust for torque instead.",
    "- **components + frozen-wrench.** Longer arms now bring mass and inertia with them. Jp, J4 "
    "and J5 follow the mass (ρ +0.89 to +0.98) and the pitch and yaw inertias I2, I3 (ρ +0.82 "
    "to +1.00): a heavier frame needs more "
    "thrust (effort, J5) and the same pitch torque tilts a larger Iyy more slowly (Jp, J4). "
    "J2 and J3 follow α and β through the motor floor as above: swapping the inertia tensors "
    "of two frames moves J2 by a tenth of what swapping their rotor geometry does (table "
    "above). The parts give SY250 an Ixx below the Table 1 lower bound (0.0012 against "
    "0.0014–0.0030 kg·m²), and a small Ixx shortens the clipping (floor table): that fits J4 "
    "spreading by ~1 % here against ~16 % with free inertia.",
    "",
]


def run_summary(run_dir: Path) -> tuple[list, str]:
    """A/B/C candidates of a run, and how many of its front and completed evaluations are
    impossible bodies (Izz > Ixx + Iyy or a sibling inequality)."""
    from casadrone.compare import run_candidates
    from casadrone.config.io import read_yaml
    from casadrone.rundir.store import RunStore

    def impossible(ixx, iyy, izz):
        return izz > ixx + iyy or ixx > iyy + izz or iyy > ixx + izz

    store = RunStore(run_dir)
    header, rows = store.read_pareto()
    k = [header.index(n) for n in ("ixx_kgm2", "iyy_kgm2", "izz_kgm2")]
    front = sum(impossible(*(r[i] for i in k)) for r in rows)
    done = [r for r in store.history() if r["status"] == "completed"]
    flown = sum(impossible(r["ixx_kgm2"], r["iyy_kgm2"], r["izz_kgm2"]) for r in done)
    controller = read_yaml(store.problem().controller).get("name")
    revision = (store.manifest.get("git_revision") or "unknown")[:7]
    note = (f"casadrone at {revision}, controller `{controller}`; impossible bodies: {front} of "
            f"{len(rows)} front designs, {flown} of {len(done)} completed evaluations")
    return run_candidates(run_dir), note


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-geometry.md")
    ap.add_argument("-n", type=int, default=120, help="random frames per set-up")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--runs", nargs=2, type=Path, metavar=("BEFORE", "AFTER"),
                    help="two quick.yaml run directories whose A/B/C candidates to compare")
    args = ap.parse_args(argv)
    start = time.perf_counter()
    names = list(BUILTIN_NAMES)
    results = {label: study(t, c, args.n, args.seed) for label, t, c in SETUPS}
    jp20 = {}
    for label, t, c in SETUPS[:2]:
        setup = default_setup(t, c)
        thetas, _ = random_thetas(setup.template, 20, args.seed + 1)
        jp = np.array([evaluate(th, setup, ["Jp"]).indices["Jp"] for th in thetas])
        jp20[label] = spread(jp)
    feas = table1_feasibility(1_000_000, args.seed)

    lines = [
        "# What geometry changes, and why",
        "",
        f"`python benchmarks/geometry_effects.py` — {__doc__.splitlines()[0].lower()}",
        "",
        markdown(),
        f"- {args.n} random feasible frames per set-up (seed {args.seed}), rk4, track "
        "paper-rectangle; wall time of the whole run "
        f"{time.perf_counter() - start:.0f} s",
        "",
        "Per-candidate cost of frozen-wrench: one `frozen_wrench_gain` call (two 4×4 solves "
        f"and a 4×20 product) takes {mapping_cost():.0f} µs of CPU; the whole evaluation CPU "
        "time per set-up is given with each table below.",
        "",
        "## How much of the paper's Table 1 box is a possible airframe",
        "",
        "Monte Carlo, 10⁶ uniform draws (vectorised; the rotor-gap test is cross-checked against "
        "`casadrone.config.min_rotor_gap_mm`):",
        "",
        "| condition | fraction of the box |",
        "|---|---:|",
        *[f"| {k} | {100 * v:.2f} % |" for k, v in feas.items()],
        "",
        "The paper problems keep the Table 1 bounds and refuse impossible bodies: a candidate "
        "outside the feasible part is a failed evaluation at stage `geometry` (infeasible, with "
        "its reason), exactly like overlapping props. The other two triangle inequalities "
        "never bind inside the box (Ixx ≤ 0.0030 < 0.0039 ≤ Iyy + Izz, Iyy ≤ 0.0021 < 0.0041 ≤ "
        "Ixx + Izz). A repaired parametrisation (e.g. Izz drawn as a fraction of Ixx + Iyy) "
        "was not chosen: it would change the paper's decision variables and their bounds.",
        "",
        "## Jp spread over 20 random frames (issue acceptance: < 1 % under frozen-wrench)",
        "",
        "| set-up | Jp min (deg) | Jp max (deg) | relative spread |",
        "|---|---:|---:|---:|",
        *[f"| {k} | {lo:.3f} | {hi:.3f} | {100 * r:.3f} % |" for k, (lo, hi, r) in jp20.items()],
        "",
    ]
    for label, _, controller in SETUPS:
        res = results[label]
        rows = res["rows"]
        variables = res["variables"]
        lines += [
            f"## {label} (controller `{controller}`)",
            "",
            f"{len(rows)} of {args.n} frames completed the lap; draws rejected before flying "
            f"(overlap or impossible inertia): {res['rejected']}; CPU time {res['cpu_s']:.1f} s."
            + (f" Failed: {'; '.join(res['failed'][:3])}" if res["failed"] else ""),
            "",
            "| index | unit | min | max | relative spread |",
            "|---|---|---:|---:|---:|",
        ]
        for n in names:
            lo, hi, rel = spread(np.array([r[n] for r in rows]))
            lines.append(f"| {n} | {INDICES[n].unit} | {lo:.4g} | {hi:.4g} | {100 * rel:.3f} % |")
        cols = variables + [d for d in DERIVED if not (d == "mass" and len(variables) == 7)]
        lines += [
            "",
            "Spearman rank correlation of each index with each decision variable and derived "
            "quantity (|ρ| ≥ 0.5 in bold):",
            "",
            "| index | " + " | ".join(SHORT.get(c, c) for c in cols) + " |",
            "|---|" + "---:|" * len(cols),
        ]
        for n in names:
            y = np.array([r[n] for r in rows])
            cells = []
            for c in cols:
                x = np.array([r[c] for r in rows])
                rho = spearmanr(x, y).statistic if np.ptp(x) > 0 else float("nan")
                cells.append(f"**{rho:+.2f}**" if abs(rho) >= 0.5 else f"{rho:+.2f}")
            lines.append(f"| {n} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += [
        "## The cause of the largest remaining spread (J4 under free + frozen-wrench)",
        "",
        "Base frame: " + ", ".join(f"{SHORT.get(k, k)} = {v:g}" for k, v in FLOOR_BASE.items())
        + "; controller frozen-wrench-sy250. 'floor samples': motor-samples with the ESC "
        "command clipped at 0 in the 0.3 s before J4's peak.",
        "",
        "| change | J4 (m/s²) | at t (s) | interval | floor samples | J5 (V) |",
        "|---|---:|---:|---:|---:|---:|",
        *floor_experiment(),
        "",
    ]
    lines += [
        "components + frozen-wrench, α moved alone (λa = λb = 125 mm, β = 90°): J2 with each "
        "geometry flown with either inertia tensor. The mass is the same (same arm lengths), so "
        "with the same tensor the two geometries differ only through the motor limits.",
        "",
        "| rotor geometry | inertia tensor of | J2 (m/s) |",
        "|---|---|---:|",
        *swap_experiment(),
        "",
    ]
    lines += READING
    if args.runs:
        lines += ["## Winners of a quick.yaml run before and after (casadrone decide)", "",
                  "Each run: `casadrone run problems/quick.yaml --out DIR` (full budget, seed 1, "
                  "`-j 2`) with casadrone at the revision named (before: the last revision "
                  "without issue 8's changes), then `python benchmarks/geometry_effects.py "
                  "--runs BEFORE AFTER`.", ""]
        for tag, run_dir in zip(("before", "after"), args.runs, strict=True):
            winners, note = run_summary(run_dir)
            lines += [f"{tag}: `{run_dir}`, {note}", "", "| candidate | θ | objectives |",
                      "|---|---|---|"]
            for c in winners:
                th = ", ".join(f"{SHORT.get(k, k)} {v:.4g}" for k, v in c.theta.items())
                ob = ", ".join(f"{k} {v:.4g}" for k, v in c.objectives.items())
                lines.append(f"| {c.label} ({c.method}) | {th} | {ob} |")
            lines.append("")
    args.out.write_text("\n".join(lines) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
