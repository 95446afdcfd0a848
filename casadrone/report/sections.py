"""Report sections on the run as a whole: the problem, convergence, the Pareto front and set,
failures, and hover-trim statistics. The candidates' own sections are in
:mod:`casadrone.report.candidates`."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure

from casadrone import plots
from casadrone.airframe import build_airframe, with_theta
from casadrone.config.airframe import ROTOR_LABELS
from casadrone.indices import INDICES
from casadrone.optimise.problem import study_setup

if TYPE_CHECKING:
    from casadrone.evaluate import EvaluationSetup
from casadrone.outfile import shown_path
from casadrone.propulsion import hover_rotors, propulsion_model
from casadrone.report.analysis import (
    STAGES,
    Candidate,
    Run,
    convergence_history,
    failure_groups,
    feasible_front,
)
from casadrone.report.markup import (
    SYMBOL,
    Figures,
    cell,
    empty_front,
    esc,
    kv_table,
    note,
    num,
    objective_label,
    table,
    unit_of,
    variable_label,
)
from casadrone.report.trimstudy import trim_study_part
from casadrone.report.verdict import Baseline
from casadrone.trim import TrimOptions, trim


def section_problem(run: Run) -> str:
    p, s, m = run.study.problem, run.study, run.manifest
    lo, hi = s.bounds
    variables = table(["variable", "symbol", "unit", "lower", "upper"],
                      [[n, SYMBOL.get(n, n), unit_of(n), a, b]
                       for n, a, b in zip(s.variable_names, lo, hi, strict=True)])
    objectives = table(["index", "sense", "unit", "meaning"],
                       [[n, sense, run.unit(n), INDICES[n].description if n in INDICES else ""]
                        for n, sense in zip(s.objective_names, s.senses, strict=True)])
    cons = [["lap completed (every stage of the chain succeeds)", "—", "—", "—"]]
    cons += [[c.index, num(c.min), num(c.max), run.unit(c.index)] for c in p.constraints]
    a = p.algorithm
    settings = [("problem", p.name), ("description", p.description),
                ("algorithm", a.name), ("population", a.population),
                ("generations (after the initial population)", a.generations),
                *[(f"setting {k}", v) for k, v in a.settings.items()],
                ("seed", p.seed), ("backend", f"{p.backend.name} (workers {p.backend.workers})"),
                ("integrator", p.integrator),  # files by relative path (no machine paths)
                *[(label, shown_path(f) if f else f) for label, f in (
                    ("airframe template", p.airframe), ("track", p.track),
                    ("controller", p.controller))],
                ("fixed airframe keys", ", ".join(f"{k} = {v}" for k, v in p.fixed.items()) or
                 "none"), ("test problem", p.test_problem.name if p.test_problem else "none")]
    man = [(k, shown_path(v) if k == "python_executable" and v else v)  # no machine paths
           for k, v in m.items() if k not in ("versions", "variables", "indices")]
    man += [(f"version {k}", v) for k, v in (m.get("versions") or {}).items()]
    text = (run.store.path / "config.yaml").read_text()
    return (f"<h3>Decision variables</h3>{variables}<h3>Objectives</h3>{objectives}"
            f"<h3>Constraints</h3>{table(['index', 'min', 'max', 'unit'], cons)}"
            f"<h3>Algorithm and evaluation</h3>{kv_table(settings)}"
            f"<h3>Manifest</h3>{kv_table(man)}"
            f"<details><summary>config.yaml (fully resolved)</summary><pre>{esc(text)}</pre>"
            "</details>")


def section_convergence(run: Run, figs: Figures) -> str:
    if not run.generations:
        return note("No generation stored yet.", "warn")
    ch = convergence_history(run)
    hv = dict(zip(ch.generations.tolist(), ch.hypervolume, strict=True))
    nd = dict(zip(ch.generations.tolist(), ch.n_non_dominated.tolist(), strict=True))
    gens = [g["generation"] for g in run.generations]
    logged = [g["archive_size"] for g in run.generations]
    fig = plots.convergence(gens, [hv[g] for g in gens], logged,
                            title="Convergence (hypervolume in one fixed normalised space)")
    done = [g for g in gens if math.isfinite(hv[g])]
    fig.axes[0].lines[0].set_data(done, [hv[g] for g in done])  # NaN: generations not computed
    ax = fig.axes[1]
    ax.lines[0].set_label("archive of the algorithm (as logged)")
    ax.step(gens, [nd[g] for g in gens], where="post", color="tab:green", ls="--",
            label="non-dominated feasible set of all evaluations")
    ax.legend(fontsize=8, loc="lower right")
    box = ", ".join(f"{n}{' (negated)' if s == 'max' else ''} [{num(a)}, {num(b)}] {run.unit(n)}"
                    for n, s, a, b in zip(run.study.objective_names, run.study.senses, ch.ideal,
                                          ch.nadir, strict=True))
    if not ch.n_non_dominated.any():
        box = "none: no feasible evaluation, the hypervolume is 0 throughout"
    text = ("Hypervolume, recomputed from history.sqlite: at each generation the archive is the "
            "non-dominated set of every feasible evaluation up to and including that generation; "
            "objectives are minimised (maximised ones negated) and scaled to [0, 1] between the "
            "ideal and nadir points of that set at the first generation with a feasible "
            "evaluation, the same space for every generation, with reference point 1.1 per "
            "objective, so the curve never falls (later designs better than that first set lie "
            "below 0 and add volume)"
            + (f" (computed at {len(done)} of {len(gens)} generations, evenly spaced, to bound "
               "its cost)" if len(done) < len(gens) else "") + ". Ideal and nadir: "
            f"{box}. The hypervolume logged by the run and shown on its console (last column of "
            "the table) is the same quantity, computed as the run went. "
            "The logged archive is the algorithm's own"
            + (" (ev-MOGA keeps one design per ε-box)"
               if run.study.problem.algorithm.name.strip().lower() == "evmoga" else "")
            + ", a subset of the non-dominated set.")
    rows = [[g["generation"], g["n_evaluations"], g["archive_size"], nd[g["generation"]],
             cell(100 * g["feasible_fraction"], ".1f"), cell(hv[g["generation"]], ".5f"),
             cell(g["elapsed_s"], ".1f"), cell(g["hypervolume"], ".5f")]
            for g in run.generations]
    head = ["generation", "evaluations (cumulative)", "archive, logged", "non-dominated",
            "feasible in generation (%)", "hypervolume, fixed space (–)", "elapsed (s)",
            "hypervolume as logged (–)"]
    return (figs.embed(fig, "convergence", "Hypervolume (top) and archive size (bottom) per "
                       "generation.") + note(text) +
            f"<details><summary>Per-generation table ({len(rows)} generations)</summary>"
            f"{table(head, rows)}</details>")


def section_pareto(run: Run, cands: list[Candidate], figs: Figures,
                   baseline: Baseline | None = None) -> str:
    """The front (every pair of objectives) and the set, the candidates ringed and ``baseline``
    drawn on both figures, and the table of the front."""
    if len(run.F) == 0:
        return empty_front(run)
    s = run.study
    names = s.objective_names
    mark = {c.row: c.label for c in cands}
    parts: list[str] = []
    if len(names) >= 2:
        fig = plots.pareto_front(run.F, names, {c.label: c.row for c in cands},
                                 units=[run.unit(n) for n in names],
                                 colours={c.label: plots.candidate_colour(c.label) for c in cands},
                                 descriptions={c.label: c.title for c in cands},
                                 baseline=(baseline.name, baseline.objectives)
                                 if baseline else None)
        key = "; ".join(c.title for c in cands)
        parts.append(figs.embed(fig, "pareto-front", "Pareto front, every pair of objectives, "
                                f"in their own units and sense; the candidates are ringed ({key})"
                                + (f"; the baseline {baseline.name} is the black star."
                                   if baseline else ".")))
    parts.append(figs.embed(_pareto_set_figure(run, cands, baseline), "pareto-set",
                            "Pareto set: each design's variables scaled to their bounds (0 = "
                            "lower, 1 = upper); the candidates in colour"
                            + (f", the baseline {baseline.name} in black." if baseline else ".")))
    senses = ", ".join(f"{n} {sn}" for n, sn in zip(names, s.senses, strict=True))
    parts.append(note(f"{len(run.F)} designs, from {run.front_source}. Senses: {senses}. "
                      + " ".join(f"{c.title} (row {c.row}, distance {num(c.distance, '.4f')} "
                                 "in normalised objective space)." for c in cands)))
    head = (["row", "candidate"] + [variable_label(n) for n in s.variable_names]
            + [objective_label(run, n) for n in names])
    rows = [[i, mark.get(i, "")] + [cell(v) for v in x] + [cell(v) for v in f]
            for i, (x, f) in enumerate(zip(run.X, run.F, strict=True))]
    t = table(head, rows, "wide")
    parts.append(t if len(rows) <= 40 else
                 f"<details><summary>Pareto table ({len(rows)} designs)</summary>{t}</details>")
    return "".join(parts)


def _pareto_set_figure(run: Run, cands: list[Candidate],
                       baseline: Baseline | None = None) -> Figure:
    lo, hi = run.study.bounds
    span = np.where(hi > lo, hi - lo, 1.0)
    Z = (run.X - lo) / span
    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    k = np.arange(Z.shape[1])
    for z in Z:
        ax.plot(k, z, color="0.7", lw=0.7)
    for c in cands:
        ax.plot(k, Z[c.row], "o-", color=plots.candidate_colour(c.label), lw=2.0, label=c.title)
    zb = None
    if baseline is not None and baseline.theta is not None:
        zb = (np.asarray(baseline.theta) - lo) / span
        ax.plot(k, zb, "*--", color="k", ms=11, lw=1.2, gid="baseline",
                label=plots.baseline_label(baseline.name))
    ax.set_xticks(k, [variable_label(n) for n in run.study.variable_names], fontsize=9)
    ax.set_ylabel("position in bounds (–)")
    low = min(-0.05, float(np.min(zb)) - 0.05) if zb is not None else -0.05
    high = max(1.05, float(np.max(zb)) + 0.05) if zb is not None else 1.05
    ax.set_ylim(low, high)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.set_title(f"Pareto set ({len(Z)} designs)")
    return fig


def section_failures(run: Run, figs: Figures) -> str:
    h = run.history
    if not h:
        return note("No evaluation stored yet.", "warn")
    n = len(h)
    gen, _, ok = feasible_front(run.study, h)
    done = np.array([r["status"] == "completed" for r in h])
    stage = Counter(r["stage"] or "?" for r in h if r["status"] != "completed")
    rows = [["completed, feasible", int(ok.sum()), 100 * ok.sum() / n],
            ["completed, violates a constraint", int((done & ~ok).sum()),
             100 * (done & ~ok).sum() / n]]
    rows += [[f"failed at {s}", stage.get(s, 0), 100 * stage.get(s, 0) / n]
             for s in STAGES + tuple(sorted(set(stage) - set(STAGES)))]
    parts: list[str] = [table(["outcome", "evaluations", "share (%)"],
                              rows + [["total", n, 100.0]])]
    viol = _constraint_violations(run, done)
    if viol:
        parts.append(table(["constraint", "completed laps violating it"], viol))
    groups = failure_groups(h)
    if groups:
        parts.append(table(["stage", "reason (numbers as #, time dropped)", "count", "example"],
                           [list(g) for g in groups]))
    else:
        parts.append(note("No evaluation failed."))
    parts.append(figs.embed(_outcome_figure(gen, done, ok, h), "failures",
                            "Outcome of the evaluations of each generation."))
    return "".join(parts)


def _constraint_violations(run: Run, done: np.ndarray) -> list[list]:
    out = []
    for c in run.study.problem.constraints if not run.test_problem else []:
        vals = np.array([r[c.index] if r.get(c.index) is not None else np.nan
                         for r in run.history])[done]
        bad = ((vals > c.max) if c.max is not None else False) | (
            (vals < c.min) if c.min is not None else False)
        out.append([f"{c.index} in [{num(c.min)}, {num(c.max)}] {run.unit(c.index)}",
                    int(np.sum(bad))])
    return out


#: One colour per failure stage (geometry, trim, control, lap, limit lap, …), none of them the
#: feasible green or the constraint olive.
STAGE_COLOURS = ("tab:pink", "tab:purple", "tab:red", "tab:orange", "tab:brown", "tab:gray",
                 "tab:cyan", "tab:blue")


def _outcome_figure(gen: np.ndarray, done: np.ndarray, ok: np.ndarray, history: Any) -> Figure:
    gens = np.unique(gen)
    series = [("feasible", ok, "tab:green"), ("violates a constraint", done & ~ok, "tab:olive")]
    series += [(f"failed: {s}", np.array([r["status"] != "completed" and r["stage"] == s
                                          for r in history]), c)
               for s, c in zip(STAGES, STAGE_COLOURS, strict=False)]
    fig = Figure(figsize=(9.0, 3.4), layout="constrained")
    ax = fig.add_subplot()
    bottom = np.zeros(len(gens))
    for label, mask, colour in series:
        counts = np.array([np.sum(mask & (gen == g)) for g in gens])
        if counts.any():
            ax.bar(gens, counts, bottom=bottom, color=colour, label=label, width=0.8)
            bottom += counts
    ax.set_xlabel("generation (–)")
    ax.set_ylabel("evaluations (–)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.set_title("Evaluations per generation by outcome")
    return fig


def _trims(setup: EvaluationSetup, theta: dict[str, float]) -> dict:
    """Hover trims of one design: as the chain does it (analytic start) and from a cold start
    (equal thrusts, level), each compared with the allocation solution."""
    af = build_airframe(with_theta(setup.template, theta))
    Ta = af.hover_thrusts()
    d = af.mass * af.gravity / (4 * af.thrust_gain)
    if not propulsion_model(af.propulsion).command_linear:  # a quarter of the weight per rotor
        d = float(np.mean(hover_rotors(af, np.full(4, af.mass * af.gravity / 4))[1]))
    out = {"share_a": (Ta[0] + Ta[1]) / Ta.sum()}
    for key, opts in (("chain", None), ("cold", TrimOptions(initial_guess=(0, 0, d, d, d, d)))):
        tp = trim(af, "hover", 0.0, solver=setup.trim_solver, options=opts)
        T = tp.thrusts
        out[key] = dict(ok=tp.success, res=tp.residual_norm, it=tp.iterations,
                        ms=1e3 * tp.wall_time_s, T=T, share=(T[0] + T[1]) / T.sum(),
                        agree=float(np.max(np.abs(T - Ta))), u0=tp.u0, spread=float(np.ptp(T)),
                        weight=abs(T.sum() - af.mass * af.gravity))
    return out


def section_trim(run: Run, cands: list[Candidate], figs: Figures, sample: int,
                 study_starts: int = 4) -> str:
    if run.test_problem:
        return note("A pymoo test problem has no trim.")

    return _hover_trims(run, cands, figs, sample) + trim_study_part(run, cands, figs,
                                                                    study_starts)


def _hover_trims(run: Run, cands: list[Candidate], figs: Figures, sample: int) -> str:
    setup = study_setup(run.study)
    names = run.study.variable_names
    valid = [r for r in run.history if r["status"] == "completed" or r["stage"] != "geometry"]
    pick = np.unique(np.linspace(0, len(valid) - 1, min(sample, len(valid))).astype(int))
    sam = [_trims(setup, {n: valid[i][n] for n in names}) for i in pick]
    text = (f"The run does not store trims: {len(sam)} hover trims were recomputed now, with the "
            f"current code, by the '{setup.trim_solver}' solver the evaluation chain uses, on "
            f"evenly spaced evaluations of the history with a valid geometry ({len(valid)} of "
            f"{len(run.history)}), and on the candidates. Each design is trimmed twice: as the "
            "chain does it, from the analytic guess (the thrusts of the 4 × 4 allocation ΣT = m "
            "g, zero moments, which is already the exact hover trim, hence one iteration), and "
            "from a cold start (level, four equal thrusts m g / 4), where the solver has to find "
            "the front/rear split itself. The allocation thrusts are the oracle for both. "
            "Residual: 2-norm of the 13 non-position rows of f(x0, u0, p) (SI units of ẋ); "
            f"success needs it below {TrimOptions().tolerance:g}. Hover only: the lap flies far "
            "from hover, and no trim along the lap is measured here.")
    ok = [r for r in sam if r["chain"]["ok"]]
    if not ok:
        return note(text) + note("No trim succeeded on the sample.", "warn")

    def stat(label: str, get: Callable[[dict], float], fmt: str = ".4g") -> list:
        row = [label]
        for key in ("chain", "cold"):
            v = np.array([get(r[key]) for r in ok if r[key]["ok"]], float)
            row += [cell(f(v), fmt) if len(v) else "—" for f in (np.min, np.median, np.max)]
        return row

    count = [f"{sum(r[k]['ok'] for r in sam)} of {len(sam)}" for k in ("chain", "cold")]
    stats = [["trims succeeded", count[0], "", "", count[1], "", ""],
             stat("residual norm (SI)", lambda r: r["res"], ".2e"),
             stat("iterations", lambda r: r["it"], ".0f"),
             stat("wall time per trim (ms)", lambda r: r["ms"], ".3f"),
             stat("max |T − T_allocation| (N)", lambda r: r["agree"], ".2e"),
             stat("|ΣT − m g| (N)", lambda r: r["weight"], ".2e"),
             stat("hover thrust spread, max − min (N)", lambda r: r["spread"]),
             stat("front share (T_FR + T_FL)/ΣT (%)", lambda r: 100 * r["share"], ".2f"),
             stat("smallest command u0 (–)", lambda r: min(r["u0"])),
             stat("largest command u0 (–)", lambda r: max(r["u0"]))]
    head = ["over the sample", "chain: min", "median", "max", "cold start: min", "median", "max"]
    parts: list[str] = [note(text), table(head, stats)]
    crows = []
    for c in cands:
        r = _trims(setup, c.theta)
        t = r["chain"]
        crows.append([c.label] + [cell(x, ".4f") for x in t["T"]]
                     + [cell(100 * t["share"], ".2f"), cell(100 * r["share_a"], ".2f"),
                        cell(min(t["u0"]), ".4f"), cell(max(t["u0"]), ".4f"),
                        cell(t["res"], ".2e"), cell(r["cold"]["res"], ".2e"),
                        r["cold"]["it"], "yes" if t["ok"] and r["cold"]["ok"] else "no"])
    if crows:
        parts.append("<h4>Candidates</h4>" + table(
            ["candidate", *(f"T {r} (N)" for r in ROTOR_LABELS), "front share (%)",
             "front share, allocation (%)", "u0 min (–)", "u0 max (–)", "residual, chain (SI)",
             "residual, cold start (SI)", "iterations, cold start", "both succeeded"], crows))
    parts.append(figs.embed(_trim_figure(ok), "trim", "Hover trims of the sample: cold-start "
                            "front thrust share against the allocation oracle, and residual "
                            "norms of both trims."))
    return "".join(parts)


def _trim_figure(rows: list[dict]) -> Figure:
    fig = Figure(figsize=(10.0, 3.8), layout="constrained")
    a, b = fig.subplots(1, 2)
    cold = [r for r in rows if r["cold"]["ok"]]
    x = np.array([100 * r["share_a"] for r in cold])
    a.plot(x, [100 * r["cold"]["share"] for r in cold], ".", color=plots.NOMINAL,
           label="cold-start trim")
    if len(x):
        ends = [x.min() - 0.5, x.max() + 0.5]
        a.plot(ends, ends, "k-", lw=0.6, label="equal")
    a.set_xlabel("front thrust share, allocation (%)")
    a.set_ylabel("front thrust share, trim (%)")
    a.legend(fontsize=8)
    floor = 1e-18
    for key, colour, label in (("chain", plots.NOMINAL, "chain (analytic start)"),
                               ("cold", "tab:orange", "cold start")):
        res = np.log10(np.maximum([r[key]["res"] for r in rows], floor))
        b.hist(res, bins=np.arange(-18.5, -3.0, 0.5), color=colour, alpha=0.6, label=label)
    b.axvline(np.log10(TrimOptions().tolerance), color="k", ls="--", lw=0.8, label="tolerance")
    b.set_xlabel("log10 residual norm (SI; exactly 0 drawn at −18)")
    b.set_ylabel("trims (–)")
    b.legend(fontsize=8)
    for ax in (a, b):
        ax.grid(True, alpha=0.3)
    fig.suptitle("Hover trim")
    return fig
