"""The HTML run report (DESIGN.md §9–10): one self-contained file that opens in any browser.

:func:`write_report` reads a run directory (``config.yaml``, ``manifest.json``,
``history.sqlite``, ``pareto.csv``) and writes ``report.html`` with seven sections: the resolved
problem, convergence, the Pareto front, the A/B/C candidates (re-evaluated with their
trajectories), the candidates over the reference airframes, failures and hover-trim statistics.
Every figure is embedded as a base64 PNG and also saved, as PNG and SVG, under ``plots/`` next to
the report; the page has inline CSS only: no script, font, stylesheet or image is fetched.

Candidate labels follow the paper (Figs 13, 16, Table C1): **A** closest to the utopian point,
**B** compromise (closest to the front's mean point), **C** extreme on the first objective
(:mod:`casadrone.decide`).
"""

from __future__ import annotations

import base64
import datetime as _dt
import html
import math
import re
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from casadrone import plots
from casadrone.evaluate import Evaluation, evaluate, theta_of
from casadrone.indices import INDICES
from casadrone.optimise.problem import FAILURE_CV, Record, Study, objectives_and_constraints
from casadrone.optimise.store import PARETO, RunStore, git_revision

__all__ = ["Candidate", "choose_candidates", "convergence_history", "failure_groups",
           "write_report"]

REPORT, PLOTS = "report.html", "plots"
#: Decision methods in label order (paper: A utopian, B trade-off, C extreme).
LABELS = (("A", "utopian", "closest to the utopian point"),
          ("B", "compromise", "compromise: closest to the front's mean point"),
          ("C", "extreme", "extreme on the first objective"))
UNIT_SUFFIX = {"mm": "mm", "deg": "deg", "kgm2": "kg·m²", "kg": "kg", "m2": "m²", "m": "m",
               "s": "s", "v": "V", "n": "N", "kgm3": "kg/m³", "mps2": "m/s²"}
SYMBOL = {"lambda_a_mm": "λa", "lambda_b_mm": "λb", "alpha_deg": "α", "beta_deg": "β",
          "ixx_kgm2": "Ixx", "iyy_kgm2": "Iyy", "izz_kgm2": "Izz"}
STAGES = tuple(FAILURE_CV)  # geometry, trim, control, lap


# ---------------------------------------------------------------------------------------------
# Reading the run
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Run:
    """What the report reads from a run directory."""

    store: RunStore
    study: Study
    manifest: dict
    history: list[dict]
    generations: list[dict]
    X: np.ndarray  # Pareto set (n, variables)
    F: np.ndarray  # Pareto front (n, objectives), own units and sense
    front_source: str

    @property
    def test_problem(self) -> bool:
        return self.study.problem.test_problem is not None

    def unit(self, objective: str) -> str:
        return "–" if self.test_problem or objective not in INDICES else INDICES[objective].unit


def _records(study: Study, history: list[dict]) -> list[Record]:
    names = study.variable_names
    index_names = study.objective_names if study.problem.test_problem else list(INDICES)
    return [Record(theta={n: h[n] for n in names}, status=h["status"], stage=h["stage"] or "",
                   reason=h["reason"] or "",
                   indices={n: h[n] for n in index_names if h.get(n) is not None})
            for h in history]


def feasible_front(study: Study, history: list[dict]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per evaluation: generation, minimised objectives F and feasibility (completed and within
    every constraint), with the run's own definition (:func:`objectives_and_constraints`)."""
    if not history:
        m = len(study.objective_names)
        return np.empty(0, int), np.empty((0, m)), np.empty(0, bool)
    F, G = objectives_and_constraints(study, _records(study, history))
    return np.array([h["generation"] for h in history]), F, np.all(G <= 0, axis=1)


def _non_dominated(F: np.ndarray) -> np.ndarray:
    from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting

    F = np.unique(F, axis=0)
    return F[NonDominatedSorting().do(F, only_non_dominated_front=True)] if len(F) > 1 else F


def read_run(run_dir: str | Path) -> Run:
    """Read a run directory; without ``pareto.csv`` (an unfinished run) the front is the
    non-dominated feasible set of every evaluation stored so far."""
    store = RunStore(Path(run_dir))
    study = Study(store.problem())
    history = store.history()
    nv = len(study.variable_names)
    if (store.path / PARETO).exists():
        _, rows = store.read_pareto()
        A = np.asarray(rows, float).reshape(len(rows), nv + len(study.objective_names))
        X, F, source = A[:, :nv], A[:, nv:], PARETO
    else:
        _, Fmin, ok = feasible_front(study, history)
        best = _non_dominated(Fmin[ok]) if ok.any() else Fmin[:0]
        keep = [i for i in np.flatnonzero(ok) if (best == Fmin[i]).all(axis=1).any()]
        keep = list({tuple(Fmin[i]): i for i in keep}.values())  # one design per point
        X = np.array([[history[i][n] for n in study.variable_names] for i in keep]).reshape(-1, nv)
        F = np.array([[history[i][n] for n in study.objective_names] for i in keep]).reshape(
            len(keep), -1)
        source = f"history.sqlite (no {PARETO}: the run has not finished)"
    return Run(store, study, store.manifest, history, store.generations(), X, F, source)


# ---------------------------------------------------------------------------------------------
# Analysis
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Candidate:
    """A design of the front shown in the report: its label(s) (``"A"``, or ``"A=C"`` when two
    decisions pick the same design), decision method(s), row of ``pareto.csv``, the first
    decision's distance (normalised objective space), θ and objectives as stored, and its
    re-evaluation with trajectory."""

    label: str
    methods: tuple[str, ...]
    row: int
    distance: float
    theta: dict[str, float]
    objectives: dict[str, float]
    evaluation: Evaluation | None = None

    @property
    def title(self) -> str:
        text = {m: t for _, m, t in LABELS}
        return f"{self.label}: " + "; ".join(text[m] for m in self.methods)


def choose_candidates(run: Run) -> list[Candidate]:
    """A (utopian), B (compromise) and C (extreme on the first objective) on the run's front, as
    :func:`casadrone.compare.run_candidates` chooses them (which needs ``pareto.csv``; this
    also works on the front of an unfinished run), one entry per distinct design. Empty for an
    empty front."""
    from casadrone.decide import decide

    if len(run.F) == 0:
        return []
    names = run.study.objective_names
    senses = dict(zip(names, run.study.senses, strict=True))
    rows: dict[int, list] = {}
    for label, method, _ in LABELS:
        d = decide(run.F, senses, method, names[0] if method == "extreme" else None)
        rows.setdefault(d.index, []).append((label, method, d.distance))
    return sorted((Candidate(
        label="=".join(x[0] for x in picks), methods=tuple(x[1] for x in picks), row=row,
        distance=picks[0][2],
        theta=dict(zip(run.study.variable_names, map(float, run.X[row]), strict=True)),
        objectives=dict(zip(names, map(float, run.F[row]), strict=True)))
        for row, picks in rows.items()), key=lambda c: c.label)


@dataclass(frozen=True)
class ConvergenceHistory:
    """Per generation: hypervolume of the non-dominated feasible set of all evaluations so far,
    in one normalised space fixed for the whole run (ideal and nadir of the final such set,
    objectives minimised, scaled to [0, 1], reference point 1.1 per objective)."""

    generations: np.ndarray
    hypervolume: np.ndarray
    n_non_dominated: np.ndarray
    ideal: np.ndarray
    nadir: np.ndarray


def convergence_history(run: Run, max_points: int = 60) -> ConvergenceHistory:
    """Recompute the hypervolume per generation from the history (see ConvergenceHistory).

    The archive is updated every generation; the hypervolume (whose cost grows fast with the
    archive in five objectives) is computed at no more than ``max_points`` evenly spaced
    generations, the last always included, and is NaN at the others.
    """
    from pymoo.indicators.hv import HV

    gen, F, ok = feasible_front(run.study, run.history)
    gens = np.array(sorted({g["generation"] for g in run.generations} | set(gen.tolist())), int)
    final = _non_dominated(F[ok]) if ok.any() else np.empty((0, F.shape[1]))
    m = F.shape[1]
    lo = final.min(axis=0) if len(final) else np.full(m, np.nan)
    hi = final.max(axis=0) if len(final) else np.full(m, np.nan)
    span = np.where(hi > lo, hi - lo, 1.0)
    indicator = HV(ref_point=np.full(m, 1.1))
    every = max(1, math.ceil(len(gens) / max_points))
    archive, hv, size = np.empty((0, m)), [], []
    for k, g in enumerate(gens):
        new = F[ok & (gen == g)]
        if len(new):
            archive = _non_dominated(np.vstack([archive, new]))
        due = k % every == 0 or k == len(gens) - 1
        hv.append(float(indicator((archive - lo) / span)) if due and len(archive) else
                  0.0 if due else math.nan)
        size.append(len(archive))
    return ConvergenceHistory(gens, np.array(hv), np.array(size, int), lo, hi)


_NUMBER = re.compile(r"(?<![A-Za-z_\d.])[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?")


def reason_group(reason: str) -> str:
    """A failure reason without its time (text before `` at t =``) and with numbers as ``#``,
    so that the same failure at different times or values is one group."""
    return _NUMBER.sub("#", reason.split(" at t =")[0]).strip()


def failure_groups(history: list[dict]) -> list[tuple[str, str, int, str]]:
    """(stage, reason group, count, first reason seen) of the failed evaluations, most frequent
    first within each stage (stages in chain order)."""
    counts: Counter = Counter()
    example: dict[tuple[str, str], str] = {}
    for h in history:
        if h["status"] != "completed":
            key = (h["stage"] or "?", reason_group(h["reason"] or ""))
            counts[key] += 1
            example.setdefault(key, h["reason"] or "")
    order = {s: i for i, s in enumerate(STAGES)}
    return [(s, r, n, example[(s, r)]) for (s, r), n in
            sorted(counts.items(), key=lambda kv: (order.get(kv[0][0], 99), -kv[1], kv[0][1]))]


# ---------------------------------------------------------------------------------------------
# HTML helpers
# ---------------------------------------------------------------------------------------------


class Html(str):
    """Text already in HTML (not escaped again)."""


def esc(value) -> str:
    return value if isinstance(value, Html) else html.escape(str(value))


def num(value, fmt: str = ".5g") -> str:
    """A number for a table cell: ``—`` for missing or non-finite."""
    if value is None or isinstance(value, str):
        return "—" if value is None else esc(value)
    v = float(value)
    if not math.isfinite(v):
        return "—"
    text = format(v, fmt)
    if text.startswith("-") and not any(ch in "123456789" for ch in text):  # no "-0.000"
        text = ("+" if fmt.startswith("+") else "") + text[1:]
    return text


def cell(value, fmt: str = ".5g", exact: bool = False) -> Html:
    """A numeric table cell; ``exact`` adds the full value (``repr``) as ``data-value``."""
    data = f' data-value="{float(value)!r}"' if exact and value is not None else ""
    return Html(f'<td class="num"{data}>{num(value, fmt)}</td>')


def table(head: list[str], rows: list[list], cls: str = "") -> Html:
    """A table; a cell that is an :class:`Html` ``<td>`` is inserted as is, anything else is
    escaped (numbers formatted with :func:`num`)."""
    def td(c):
        if isinstance(c, Html) and c.startswith("<td"):
            return c
        if isinstance(c, int | float | np.floating | np.integer) and not isinstance(c, bool):
            return cell(c)
        return f"<td>{esc(c)}</td>"

    h = "".join(f"<th>{esc(x)}</th>" for x in head)
    body = "".join("<tr>" + "".join(td(c) for c in r) + "</tr>" for r in rows)
    return Html(f'<table class="{cls}"><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>')


def kv_table(pairs: list[tuple[str, object]]) -> Html:
    return table(["item", "value"], [[k, "—" if v is None else str(v)] for k, v in pairs], "kv")


def note(text: str, kind: str = "note") -> Html:
    return Html(f'<p class="{kind}">{esc(text)}</p>')


class Figures:
    """Saves figures under ``plots/`` (PNG and SVG) and embeds the PNG bytes in the page."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.saved: list[Path] = []

    def embed(self, fig: Figure, name: str, caption: str) -> Html:
        paths = plots.save_figure(fig, self.folder / name)
        self.saved += paths
        data = base64.b64encode(paths[0].read_bytes()).decode("ascii")
        return Html(f'<figure><img src="data:image/png;base64,{data}" alt="{esc(caption)}">'
                    f"<figcaption>{esc(caption)} <span class=\"file\">({PLOTS}/{name}.png, "
                    f".svg)</span></figcaption></figure>")


def unit_of(variable: str) -> str:
    """Unit of an airframe config key from its suffix (``alpha_deg`` → deg)."""
    for suffix, unit in sorted(UNIT_SUFFIX.items(), key=lambda kv: -len(kv[0])):
        if variable.endswith("_" + suffix):
            return unit
    return "–"


def variable_label(name: str) -> str:
    return f"{SYMBOL.get(name, name)} ({unit_of(name)})"


def objective_label(run: Run, name: str) -> str:
    return f"{name} ({run.unit(name)})"


# ---------------------------------------------------------------------------------------------
# Sections
# ---------------------------------------------------------------------------------------------


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
                ("integrator", p.integrator), ("airframe template", p.airframe),
                ("track", p.track), ("controller", p.controller),
                ("fixed airframe keys", ", ".join(f"{k} = {v}" for k, v in p.fixed.items()) or
                 "none"), ("test problem", p.test_problem.name if p.test_problem else "none")]
    man = [(k, v) for k, v in m.items() if k not in ("versions", "variables", "indices")]
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
            "ideal and nadir points of the final such set, the same for every generation, with "
            "reference point 1.1 per objective, so the curve never falls"
            + (f" (computed at {len(done)} of {len(gens)} generations, evenly spaced, to bound "
               "its cost)" if len(done) < len(gens) else "") + ". Ideal and nadir: "
            f"{box}. The hypervolume logged by the run (last column of the table) normalises "
            "each generation over its own front, so it is not comparable across generations. "
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


def _empty_front(run: Run) -> Html:
    n = len(run.history)
    done = sum(h["status"] == "completed" for h in run.history)
    return note(f"The Pareto front is empty: no feasible design in {n} evaluations ({done} "
                f"completed the lap, {n - done} failed; completed laps that violate a "
                "constraint are infeasible). There are no candidates to show: see the failures "
                "section and relax the constraints or the bounds.", "warn")


def section_pareto(run: Run, cands: list[Candidate], figs: Figures) -> str:
    if len(run.F) == 0:
        return _empty_front(run)
    s = run.study
    names = s.objective_names
    mark = {c.row: c.label for c in cands}
    parts = []
    if len(names) >= 2:
        fig = plots.pareto_front(run.F, names, {c.label: c.row for c in cands},
                                 units=[run.unit(n) for n in names])
        key = "; ".join(c.title for c in cands)
        parts.append(figs.embed(fig, "pareto-front", "Pareto front, every pair of objectives, "
                                f"in their own units and sense; the candidates are ringed ({key})."
                                ))
    parts.append(figs.embed(_pareto_set_figure(run, cands), "pareto-set",
                            "Pareto set: each design's variables scaled to their bounds (0 = "
                            "lower, 1 = upper); the candidates in colour."))
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


def _pareto_set_figure(run: Run, cands: list[Candidate]) -> Figure:
    lo, hi = run.study.bounds
    Z = (run.X - lo) / np.where(hi > lo, hi - lo, 1.0)
    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    k = np.arange(Z.shape[1])
    for z in Z:
        ax.plot(k, z, color="0.7", lw=0.7)
    for c, col in zip(cands, plots._colours(len(cands) + 1)[1:], strict=True):
        ax.plot(k, Z[c.row], "o-", color=col, lw=2.0, label=c.title)
    ax.set_xticks(k, [variable_label(n) for n in run.study.variable_names], fontsize=9)
    ax.set_ylabel("position in bounds (–)")
    ax.set_ylim(-0.05, 1.05)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.set_title(f"Pareto set ({len(Z)} designs)")
    return fig


def evaluate_candidates(run: Run, cands: list[Candidate]) -> list[Candidate]:
    """Fly each candidate again, keeping its trajectory (the chain is deterministic)."""
    from casadrone.optimise.problem import study_setup

    setup = study_setup(run.study)
    return [replace(c, evaluation=evaluate(c.theta, setup, keep_trajectory=True)) for c in cands]


def _reproduction(run: Run, cands: list[Candidate]) -> Html:
    failed = [c.label for c in cands if not c.evaluation.completed]
    diffs = [abs(c.evaluation.indices[n] - v) / max(abs(v), 1e-12) for c in cands
             if c.evaluation.completed for n, v in c.objectives.items()]
    worst = max(diffs, default=0.0)
    if not failed and worst <= 1e-9:
        return note(f"Re-evaluated now: every objective reproduces {PARETO} (largest relative "
                    f"difference {worst:.1e}).")
    what = (f"candidate(s) {', '.join(failed)} now fail" if failed else "")
    what += ("; " if failed and diffs else "") + (
        f"the largest relative difference of an objective is {worst:.3g}" if diffs else "")
    return note(f"Re-evaluated now, the candidates do NOT reproduce {PARETO} ({what}): the code, "
                "or a config file the run refers to (track, controller, airframe: config.yaml "
                "stores their paths, not their contents), has changed since the run (run "
                f"revision {run.manifest.get('git_revision')}, current {git_revision()}). The "
                "figures and tables below show the re-evaluation; the stored values are beside "
                "them.", "warn")


def section_candidates(run: Run, cands: list[Candidate], figs: Figures) -> str:
    if not cands:
        return _empty_front(run)
    parts = [_reproduction(run, cands)]
    flown = {c.title: c.evaluation.trajectory for c in cands
             if c.evaluation.trajectory is not None}
    if len(flown) > 1:
        parts.append(figs.embed(plots.track_top_view(flown, title="Candidates, top view"),
                                "candidates-track", "Ground tracks of the candidates."))
        parts.append(figs.embed(plots.time_histories(flown, title="Candidates compared (paper "
                                                     "Figs 21, 22)"),
                                "candidates-time-histories",
                                "Altitude, speed, roll effort and opposing-pair thrust of the "
                                "candidates; dashed lines: waypoint split times."))
    for c in cands:
        parts.append(f'<h3 id="candidate-{c.label}">Candidate {esc(c.title)}</h3>')
        parts.append(_candidate(run, c, figs))
    return "".join(parts)


def _candidate(run: Run, c: Candidate, figs: Figures) -> str:
    from casadrone.airframe import family

    s, ev = run.study, c.evaluation
    lo, hi = s.bounds
    geo = [[SYMBOL.get(n, n), n, unit_of(n), cell(c.theta[n], exact=True), a, b]
           for n, a, b in zip(s.variable_names, lo, hi, strict=True)]
    out = [f"<p>Row {c.row} of the front. Status of the re-evaluation: "
           f"<b>{esc(ev.status)}</b>{esc(' — ' + ev.reason) if ev.reason else ''}.</p>",
           '<div class="row"><div>',
           table(["symbol", "variable", "unit", "value", "lower", "upper"], geo, "theta"),
           ]
    if not run.test_problem:
        from casadrone.airframe import with_theta
        from casadrone.optimise.problem import study_setup

        cfg = with_theta(study_setup(s).template, c.theta)
        out.append(kv_table([("family", family(cfg.alpha_deg, cfg.beta_deg)),
                             ("diagonal λa + λb (mm)", num(cfg.lambda_a_mm + cfg.lambda_b_mm)),
                             ("mass (kg, fixed)", num(cfg.mass_kg))]))
    idx = [[n, INDICES[n].unit if n in INDICES else "–",
            dict(zip(s.objective_names, s.senses, strict=True)).get(n, "(not an objective)"),
            cell(c.objectives.get(n)), cell(ev.indices.get(n))]
           for n in (list(INDICES) if not run.test_problem else s.objective_names)]
    out += ["</div><div>", table(["index", "unit", "objective sense",
                                  f"stored ({PARETO})", "re-evaluated"], idx), "</div></div>"]
    if ev.intervals:
        rows, prev = [], 0.0
        for i in ev.intervals:
            rows.append([i.waypoint, "straight" if i.straight else "curve", i.split_time_s,
                         i.split_time_s - prev, cell(i.effort_V, ".3f"),
                         cell(i.pair_thrust_max_N, ".3f"), cell(i.pair_thrust_min_N, ".3f"),
                         i.n_samples])
            prev = i.split_time_s
        out.append("<h4>Per interval (paper Table 4)</h4>" + table(
            ["to waypoint", "leg", "split time (s)", "interval time (s)", "mean roll effort (V)",
             "pair thrust max (N)", "pair thrust min (N)", "samples"], rows))
        out.append(note("Roll effort: left minus right ESC voltage, deviation from trim; pair "
                        "thrust: (T_FL + T_RL) − (T_FR + T_RR). Interval 1 includes the climb."))
    if ev.trajectory is not None:
        tr = {c.title: ev.trajectory}
        out.append(figs.embed(plots.track_top_view(tr, title=f"Candidate {c.label}, top view"),
                              f"candidate-{c.label}-track", f"Candidate {c.label}: ground track."))
        out.append(figs.embed(plots.time_histories(tr, title=f"Candidate {c.label}"),
                              f"candidate-{c.label}-time-histories",
                              f"Candidate {c.label}: altitude, speed, roll effort and "
                              "opposing-pair thrust."))
    return "".join(out)


def section_airframes(run: Run, cands: list[Candidate], references, figs: Figures) -> str:
    if run.test_problem:
        return note("A pymoo test problem has no airframe.")
    if not cands:
        return _empty_front(run)
    from casadrone.airframe import build_airframe, with_theta
    from casadrone.config import load_airframe
    from casadrone.optimise.problem import study_setup

    setup = study_setup(run.study)
    frames = [build_airframe(with_theta(setup.template, c.theta, name=f"Candidate {c.label}"))
              for c in cands]
    parts = []
    for ref in references:
        cfg = load_airframe(ref)
        fig = plots.airframe_top_view(frames, build_airframe(cfg),
                                      setup.template.prop_diameter_mm / 1000.0,
                                      title=f"Candidates over {cfg.name} (grey, dashed)")
        parts.append(figs.embed(fig, f"airframes-{cfg.name}", f"Top view of each candidate "
                                f"(nose up, mm) over the reference {cfg.name} (paper Figs 15, "
                                "17, 19)."))
        parts.append(_index_gains(run, cands, cfg, evaluate(theta_of(cfg),
                                                            replace(setup, template=cfg))))
    if run.front_source != PARETO:
        return "".join(parts) + note("Per-interval gains need a finished run (pareto.csv).")
    return "".join(parts) + _interval_gains(run, tuple(references))


def _index_gains(run: Run, cands: list[Candidate], cfg, ref: Evaluation) -> str:
    from casadrone.compare import gain_pct

    if not ref.completed:
        return note(f"{cfg.name} does not complete the lap ({ref.reason}): no gains.", "warn")
    senses = dict(zip(run.study.objective_names, run.study.senses, strict=True))
    rows = []
    for n, index in INDICES.items():
        sense, rv = senses.get(n, index.sense), ref.indices.get(n)
        row = [f"{n} ({index.unit})", sense, cell(rv)]
        for c in cands:
            v = c.evaluation.indices.get(n)
            row += [cell(v), cell(gain_pct(v, rv, sense) if v is not None and rv else None,
                                  "+.1f")]
        rows.append(row)
    head = ["index", "sense", cfg.name] + [h for c in cands
                                           for h in (c.label, f"{c.label} gain (%)")]
    return (f"<h4>Indices against {esc(cfg.name)} (paper Eq. 21)</h4>" + table(head, rows)
            + note(f"{cfg.name} flown now on the run's track, controller and integrator with its "
                   "own airframe config. Gain (compare.gain_pct): (reference − candidate) / "
                   "reference × 100 for minimised indices, the opposite sign for maximised ones; "
                   "positive is better."))


def _interval_gains(run: Run, references: tuple) -> str:
    from casadrone.compare import compare_run

    rows = [[g.candidate, g.reference, g.basis, g.interval]
            + [cell(v, "+.1f") for v in (g.time_gain_pct, g.effort_gain_pct,
                                         g.thrust_max_gain_pct, g.thrust_min_gain_pct)]
            for g in compare_run(run.store.path, references)]
    t = table(["candidate", "reference", "basis", "to waypoint", "split time gain (%)",
               "roll effort gain (%)", "pair thrust max gain (%)", "pair thrust min gain (%)"],
              rows)
    return ("<h4>Per-interval gains (paper Tables 9–11, <code>casadrone compare</code>)</h4>"
            + note("Positive is better: faster, less effort, smaller pair-thrust extremes (effort "
                   "and thrust compared by magnitude). Basis 'simulated': the reference flown on "
                   "the run's platform; 'measured': the paper's Table 4, a different time base, "
                   "for orientation only. — where a gain is undefined (a zero reference).")
            + (t if len(rows) <= 24 else
               f"<details><summary>{len(rows)} rows</summary>{t}</details>"))


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
    parts = [table(["outcome", "evaluations", "share (%)"], rows + [["total", n, 100.0]])]
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


def _outcome_figure(gen, done, ok, history) -> Figure:
    gens = np.unique(gen)
    series = [("feasible", ok, "tab:green"), ("violates a constraint", done & ~ok, "tab:olive")]
    series += [(f"failed: {s}", np.array([r["status"] != "completed" and r["stage"] == s
                                          for r in history]), c)
               for s, c in zip(STAGES, ("tab:purple", "tab:red", "tab:orange", "tab:brown"),
                               strict=True)]
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


def _trims(setup, theta: dict[str, float]) -> dict:
    """Hover trims of one design: as the chain does it (analytic start) and from a cold start
    (equal thrusts, level), each compared with the allocation solution."""
    from casadrone.airframe import build_airframe, with_theta
    from casadrone.trim import TrimOptions, trim

    af = build_airframe(with_theta(setup.template, theta))
    Ta = af.hover_thrusts()
    d = af.mass * af.gravity / (4 * af.thrust_gain)
    out = {"share_a": (Ta[0] + Ta[1]) / Ta.sum()}
    for key, opts in (("chain", None), ("cold", TrimOptions(initial_guess=(0, 0, d, d, d, d)))):
        tp = trim(af, "hover", 0.0, solver=setup.trim_solver, options=opts)
        T = tp.thrusts
        out[key] = dict(ok=tp.success, res=tp.residual_norm, it=tp.iterations,
                        ms=1e3 * tp.wall_time_s, T=T, share=(T[0] + T[1]) / T.sum(),
                        agree=float(np.max(np.abs(T - Ta))), u0=tp.u0, spread=float(np.ptp(T)),
                        weight=abs(T.sum() - af.mass * af.gravity))
    return out


def section_trim(run: Run, cands: list[Candidate], figs: Figures, sample: int) -> str:
    if run.test_problem:
        return note("A pymoo test problem has no trim.")
    from casadrone.optimise.problem import study_setup
    from casadrone.trim import TrimOptions

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

    def stat(label, get, fmt=".4g"):
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
             stat("front share (T1 + T2)/ΣT (%)", lambda r: 100 * r["share"], ".2f"),
             stat("smallest command u0 (–)", lambda r: min(r["u0"])),
             stat("largest command u0 (–)", lambda r: max(r["u0"]))]
    head = ["over the sample", "chain: min", "median", "max", "cold start: min", "median", "max"]
    parts = [note(text), table(head, stats)]
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
            ["candidate", "T1 FR (N)", "T2 FL (N)", "T3 RL (N)", "T4 RR (N)", "front share (%)",
             "front share, allocation (%)", "u0 min (–)", "u0 max (–)", "residual, chain (SI)",
             "residual, cold start (SI)", "iterations, cold start", "both succeeded"], crows))
    parts.append(figs.embed(_trim_figure(ok), "trim", "Hover trims of the sample: cold-start "
                            "front thrust share against the allocation oracle, and residual "
                            "norms of both trims."))
    return "".join(parts)


def _trim_figure(rows: list[dict]) -> Figure:
    from casadrone.trim import TrimOptions

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


# ---------------------------------------------------------------------------------------------
# The page
# ---------------------------------------------------------------------------------------------

CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", Helvetica, Arial, sans-serif;
       margin: 0 auto; max-width: 1200px; padding: 0 1.5em 3em; color: #1d1d1f; line-height: 1.4; }
header { border-bottom: 2px solid #2a6ebb; margin-bottom: 1em; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 1px solid #ccc; padding-top: 0.6em; }
nav a { margin-right: 1em; color: #2a6ebb; text-decoration: none; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.86em; }
th, td { border: 1px solid #d5d5d5; padding: 0.2em 0.55em; text-align: left; vertical-align: top; }
th { background: #eef2f7; }
tbody tr:nth-child(even) { background: #f8f8f8; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
table.wide { display: block; overflow-x: auto; max-width: 100%; }
table.kv td:first-child { color: #555; white-space: nowrap; }
figure { margin: 1em 0; } figure img { max-width: 100%; height: auto; border: 1px solid #eee; }
figcaption { font-size: 0.85em; color: #444; } .file { color: #888; }
p.note { color: #333; font-size: 0.9em; max-width: 70em; }
p.warn { background: #fff4e0; border-left: 4px solid #e69500; padding: 0.5em 0.8em; }
pre { background: #f6f6f6; padding: 0.8em; overflow-x: auto; font-size: 0.8em; }
.row { display: flex; flex-wrap: wrap; gap: 2em; align-items: flex-start; }
"""

SECTIONS = (("problem", "Problem"), ("convergence", "Convergence"), ("pareto", "Pareto front"),
            ("candidates", "Candidates A, B, C"), ("airframes", "Airframes"),
            ("failures", "Failures"), ("trim", "Trim"))


def write_report(run_dir: str | Path, references: tuple[str, ...] = ("SY250",),
                 out: str | Path | None = None, trim_sample: int = 200) -> Path:
    """Write the self-contained HTML report of a run and return its path.

    Args:
        run_dir: the run directory.
        references: reference airframes (names in ``configs/airframes/`` or paths) drawn under
            the candidates and used for the Eq. 21 gains.
        out: the HTML file to write (default ``run_dir/report.html``); figures go to ``plots/``
            beside it, as PNG and SVG.
        trim_sample: at most this many evaluations are trimmed again for the trim section.
    """
    run = read_run(run_dir)
    path = Path(out) if out is not None else run.store.path / REPORT
    figs = Figures(path.parent / PLOTS)
    cands = choose_candidates(run)
    if not run.test_problem:
        cands = evaluate_candidates(run, cands)
    body = {
        "problem": section_problem(run),
        "convergence": section_convergence(run, figs),
        "pareto": section_pareto(run, cands, figs),
        "candidates": (section_candidates(run, cands, figs) if not run.test_problem
                       else note("A pymoo test problem has no trajectories.")),
        "airframes": section_airframes(run, cands, tuple(references), figs),
        "failures": section_failures(run, figs),
        "trim": section_trim(run, cands, figs, trim_sample),
    }
    m = run.manifest
    stamp = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    nav = "".join(f'<a href="#{k}">{esc(t)}</a>' for k, t in SECTIONS)
    sections = "".join(f'<section id="{k}"><h2>{i}. {esc(t)}</h2>{body[k]}</section>'
                       for i, (k, t) in enumerate(SECTIONS, start=1))
    title = f"casadrone run report: {run.study.problem.name}"
    page = (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{esc(title)}</title><style>{CSS}</style></head><body><header>"
            f"<h1>{esc(title)}</h1><p>Run directory <code>{esc(run.store.path.resolve())}</code>"
            f" · status {esc(m.get('status'))} · {len(run.history)} evaluations · "
            f"{len(run.F)} designs on the front · report written {esc(stamp)}</p>"
            f"<nav>{nav}</nav></header>{sections}</body></html>")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(page, encoding="utf-8")
    return path
