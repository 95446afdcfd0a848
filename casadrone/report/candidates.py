"""Report sections on the A/B/C candidates: each re-evaluated with its trajectory, and the
candidates over the reference airframes with their Eq. 21 gains (:mod:`casadrone.compare`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

from casadrone import plots
from casadrone.airframe import build_airframe, family, with_theta
from casadrone.compare import Candidate, compare_run, gain_pct
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.io import ConfigError
from casadrone.evaluate import Evaluation, evaluate, evaluate_limit, theta_of
from casadrone.export import FORMATS, export
from casadrone.export.source import candidate_source
from casadrone.indices import INDICES
from casadrone.massprops import mass_properties
from casadrone.optimise.problem import study_setup
from casadrone.outfile import shown_path
from casadrone.progress import emit, nested
from casadrone.report.analysis import Run
from casadrone.report.markup import (
    SYMBOL,
    Figures,
    Html,
    cell,
    empty_front,
    esc,
    kv_table,
    note,
    num,
    table,
    unit_of,
)
from casadrone.rundir.store import PARETO, atomic_write, git_revision


def evaluate_candidates(run: Run, cands: list[Candidate], limit: bool = True
                        ) -> list[Candidate]:
    """Fly each candidate again, keeping its trajectory (the chain is deterministic); without
    ``limit`` the closed-loop lap only (a co-design point's limit lap is stored with it)."""
    setup = study_setup(run.study)
    if not limit:
        setup = replace(setup, limit=None)
    out = []
    for k, c in enumerate(cands, start=1):  # progress: a limit lap takes seconds to minutes
        emit("stage", f"re-evaluating candidate {c.label} ({k}/{len(cands)}) with its "
             "trajectory" + (" and limit lap" if setup.limit is not None else ""))
        with nested():
            out.append(replace(c, evaluation=evaluate(c.theta, setup, keep_trajectory=True)))
    return out


def _reproduction(run: Run, cands: list[Candidate]) -> Html:
    failed = [c.label for c in cands if not c.flown.completed]
    diffs = [abs(c.flown.indices[n] - v) / max(abs(v), 1e-12) for c in cands
             if c.flown.completed for n, v in c.objectives.items()]
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


def _exports(run: Run, c: Candidate, folder: Path) -> str:
    """Write the candidate's exports under ``folder`` (beside report.html) and link them; the
    page stays self-contained, the files are optional extras."""
    template = study_setup(run.study).template
    tag = c.label.replace("=", "")  # "A=C" (one design, two decisions) → "AC"
    try:
        src = candidate_source(template, c.theta, f"{run.store.path.name}-{tag}",
                               f"run {shown_path(run.store.path)} (template {template.name})",
                               f"{c.label} ({', '.join(c.methods)}, {PARETO} row {c.row})")
        links = []
        folder.mkdir(parents=True, exist_ok=True)
        for fmt, spec in FORMATS.items():  # the report's own files: replaced on each report
            path = folder / f"candidate-{tag}-{fmt}{spec.suffix}"
            atomic_write(path, export(src, fmt))
            links.append(f'<a href="{folder.name}/{esc(path.name)}">{esc(fmt)}</a>')
    except (ConfigError, ValueError, RuntimeError) as exc:
        return note(f"No exports for candidate {c.label}: {exc}", "warn")
    return (f"<p>Exports (files beside the report, <code>casadrone export</code>): "
            f"{' · '.join(links)}: "
            f"{'; '.join(esc(spec.description) for spec in FORMATS.values())}.</p>")


def section_candidates(run: Run, cands: list[Candidate], figs: Figures,
                       exports: Path | None = None, limit: bool = True) -> str:
    """The candidates with their flights; with ``exports`` (a folder beside the report) also
    each candidate's exported files, linked; without ``limit`` (a co-design front) the stored
    limit-lap values are not re-solved here (the co-design section shows each point's lap)."""
    if not cands:
        return empty_front(run)
    parts: list[str] = [_reproduction(run, cands) if limit else note(
        "Closed-loop laps flown again now; the limit-lap objectives are the co-design points' "
        "own (frame and lap optimised together), shown in the co-design section.")]
    flown = {c.title: c.flown.trajectory for c in cands
             if c.flown.trajectory is not None}
    colours = {c.title: plots.candidate_colour(c.label) for c in cands}
    if len(flown) > 1:
        parts.append(figs.embed(plots.track_top_view(flown, title="Candidates, top view",
                                                     colours=colours),
                                "candidates-track", "Ground tracks of the candidates."))
        parts.append(figs.embed(plots.time_histories(flown, title="Candidates compared (paper "
                                                     "Figs 21, 22)", colours=colours),
                                "candidates-time-histories",
                                "Altitude, speed, roll effort and opposing-pair thrust of the "
                                "candidates; dashed lines: waypoint split times."))
    for c in cands:
        parts.append(f'<h3 id="candidate-{c.label}">Candidate {esc(c.title)}</h3>')
        parts.append(_candidate(run, c, figs))
        if limit:
            parts.append(_limit_lap(run, c, figs))
        if exports is not None:
            parts.append(_exports(run, c, exports))
    return "".join(parts)


def _limit_lap(run: Run, c: Candidate, figs: Figures) -> str:
    """The candidate's limit lap beside its closed-loop lap, when the problem uses a limit-lap
    index (J3_limit)."""
    setup = study_setup(run.study)
    if setup.limit is None or run.test_problem:
        return ""
    lap = evaluate_limit(with_theta(setup.template, c.theta), setup, c.flown.trajectory)
    if not lap.completed:
        return note(f"Limit lap of {c.title} failed: {lap.reason}", "warn")
    splits = ", ".join(f"{t:.3f}" for t in lap.split_times_s)
    out = [f"<h4>Limit lap of {esc(c.title)}</h4>",
           kv_table([("limit lap (s)", num(lap.lap_time_s)), ("split times (s)", splits),
                     ("bang-bang fraction", num(lap.bang_bang_fraction)),
                     ("winning start", lap.start), ("iterations", str(lap.iterations))])]
    figures = plots.limit_lap_figures(lap, c.flown.trajectory, setup.track.waypoints_m)
    for name in ("limit-top-view", "limit-time-histories"):
        out.append(figs.embed(figures[name], f"{name}-{c.label}",
                              f"Candidate {c.title}: limit lap beside its closed-loop lap."))
    return "".join(out)


def _candidate(run: Run, c: Candidate, figs: Figures) -> str:
    s, ev = run.study, c.flown
    lo, hi = s.bounds
    geo = [[SYMBOL.get(n, n), n, unit_of(n), cell(c.theta[n], exact=True), a, b]
           for n, a, b in zip(s.variable_names, lo, hi, strict=True)]
    out = [f"<p>Row {c.row} of the front. Status of the re-evaluation: "
           f"<b>{esc(ev.status)}</b>{esc(' — ' + ev.reason) if ev.reason else ''}.</p>",
           '<div class="row"><div>',
           table(["symbol", "variable", "unit", "value", "lower", "upper"], geo, "theta"),
           ]
    if not run.test_problem:
        cfg = with_theta(study_setup(s).template, c.theta)
        mp = mass_properties(cfg)
        source = "fixed" if mp.mass_model == "free" else "from the parts"
        out.append(kv_table([("family", family(cfg.alpha_deg, cfg.beta_deg)),
                             ("diagonal λa + λb (mm)", num(cfg.lambda_a_mm + cfg.lambda_b_mm)),
                             (f"mass (kg, {source})", num(mp.mass_kg))]))
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
        tr, colours = {c.title: ev.trajectory}, {c.title: plots.candidate_colour(c.label)}
        out.append(figs.embed(plots.track_top_view(tr, title=f"Candidate {c.label}, top view",
                                                   colours=colours),
                              f"candidate-{c.label}-track", f"Candidate {c.label}: ground track."))
        out.append(figs.embed(plots.time_histories(tr, title=f"Candidate {c.label}",
                                                   colours=colours),
                              f"candidate-{c.label}-time-histories",
                              f"Candidate {c.label}: altitude, speed, roll effort and "
                              "opposing-pair thrust."))
    return "".join(out)


def fly_references(run: Run, references: Any, limit: bool = True) -> list[tuple[Any, Evaluation]]:
    """(config, evaluation) of each reference airframe, flown with its own config on the run's
    track, controller and integrator (without ``limit``, no limit lap: a co-design front)."""
    setup = study_setup(run.study)
    if not limit:
        setup = replace(setup, limit=None)
    out = []
    for ref in references:
        cfg = load_airframe(ref)
        out.append((cfg, evaluate(theta_of(cfg), replace(setup, template=cfg))))
    return out


def section_airframes(run: Run, cands: list[Candidate], references: Any, figs: Figures,
                      flown: list[tuple[Any, Evaluation]]) -> str:
    """The candidates over the reference airframes (``flown``: :func:`fly_references`), with
    the Eq. 21 gains of the indices."""
    if run.test_problem:
        return note("A pymoo test problem has no airframe.")
    if not cands:
        return empty_front(run)

    setup = study_setup(run.study)
    frames = [build_airframe(with_theta(setup.template, c.theta, name=f"Candidate {c.label}"))
              for c in cands]
    colours = {f.name: plots.candidate_colour(c.label) for f, c in zip(frames, cands, strict=True)}
    parts: list[str] = []
    for cfg, ref_ev in flown:
        fig = plots.airframe_top_view(frames, build_airframe(cfg),
                                      setup.template.prop_diameter_mm / 1000.0,
                                      title=f"Candidates over {cfg.name} (grey, dashed)",
                                      colours=colours)
        parts.append(figs.embed(fig, f"airframes-{cfg.name}", f"Top view of each candidate "
                                f"(nose up, mm) over the reference {cfg.name} (paper Figs 15, "
                                "17, 19)."))
        parts.append(_index_gains(run, cands, cfg, ref_ev))
    if run.front_source != PARETO:
        return "".join(parts) + note("Per-interval gains need a finished run (pareto.csv).")
    return "".join(parts) + _interval_gains(run, tuple(references))


def _index_gains(run: Run, cands: list[Candidate], cfg: AirframeConfig, ref: Evaluation) -> str:
    if not ref.completed:
        return note(f"{cfg.name} does not complete the lap ({ref.reason}): no gains.", "warn")
    senses = dict(zip(run.study.objective_names, run.study.senses, strict=True))
    rows = []
    for n, index in INDICES.items():
        sense, rv = senses.get(n, index.sense), ref.indices.get(n)
        row = [f"{n} ({index.unit})", sense, cell(rv)]
        for c in cands:
            v = c.flown.indices.get(n)
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
    gains = compare_run(run.store.path, references)
    head = ["candidate", "reference", "to waypoint", "split time gain (%)", "roll effort gain (%)",
            "pair thrust max gain (%)", "pair thrust min gain (%)"]

    def rows(basis: str) -> list[list]:
        return [[g.candidate, g.reference, g.interval]
                + [cell(v, "+.1f") for v in (g.time_gain_pct, g.effort_gain_pct,
                                             g.thrust_max_gain_pct, g.thrust_min_gain_pct)]
                for g in gains if g.basis == basis]

    simulated = rows("simulated")
    t = table(head, simulated)
    out = ("<h4>Per-interval gains (paper Tables 9–11, <code>casadrone compare</code>)</h4>"
           + note("Positive is better: faster, less effort, smaller pair-thrust extremes (effort "
                  "and thrust compared by magnitude). The references are flown now on the run's "
                  "track, controller and integrator. — where a gain is undefined (a zero "
                  "reference).")
           + (t if len(simulated) <= 24 else
              f"<details><summary>{len(simulated)} rows</summary>{t}</details>"))
    if any(g.basis == "measured" for g in gains):
        # Not shown: the paper's laps take hundreds of seconds for the 105 m track, casadrone's
        # about fifteen, so a gain against them mixes two time bases (+93 % to -765 % on the
        # quick run): no reading of it is a result, not even folded away.
        out += note("Gains against the paper's measured Table 4 are left out: its laps are on "
                    "another time base (hundreds of seconds against about fifteen), so they are "
                    "not comparable; 'casadrone compare --measured' prints them.")
    return out
