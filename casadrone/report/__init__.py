"""The HTML run report (docs/architecture.md#runs): one self-contained file that opens in any
browser.

:func:`write_report` reads a run directory (``config.yaml``, ``manifest.json``,
``history.sqlite``, ``pareto.csv``) and writes ``report.html``. It opens with the verdict: each
candidate against the baseline (the first reference airframe), whether it dominates it, by how
much per index and whether each difference is within the evaluation's noise
(:mod:`casadrone.verdict`). Then the resolved problem, convergence, the Pareto front (with the
baseline drawn), the A/B/C candidates (re-evaluated with their trajectories), the candidates over
the reference airframes, failures and hover-trim statistics.
Every figure is embedded as a base64 PNG and also saved, as PNG and SVG, under ``plots/`` next to
the report; the page has inline CSS only: no script, font, stylesheet or image is fetched.

Candidate labels follow the paper (Figs 13, 16, Table C1): **A** closest to the utopian point,
**B** compromise (closest to the front's mean point), **C** extreme on the first objective
(:mod:`casadrone.decide`).

The package: :mod:`~casadrone.report.analysis` reads the run and computes what the report shows,
:mod:`~casadrone.report.markup` holds the HTML building blocks, :mod:`~casadrone.report.sections`
and :mod:`~casadrone.report.candidates` build the sections, and this module assembles the page.
"""

from __future__ import annotations

import datetime as _dt
from pathlib import Path

from casadrone.outfile import file_above, shown_path
from casadrone.progress import emit, nested
from casadrone.report.analysis import (
    choose_candidates,
    read_run,
)
from casadrone.report.candidates import (
    evaluate_candidates,
    fly_references,
    section_airframes,
    section_candidates,
)
from casadrone.report.codesign import is_codesign, section_codesign
from casadrone.report.markup import (
    PLOTS,
    Figures,
    esc,
    note,
)
from casadrone.report.sections import (
    section_convergence,
    section_failures,
    section_pareto,
    section_problem,
    section_trim,
)
from casadrone.report.verdict import baseline_of, baseline_verdict, section_verdict
from casadrone.rundir.store import atomic_write
from casadrone.verdict import default_baseline

__all__ = ["Candidate", "choose_candidates", "convergence_history", "failure_groups",
           "write_report"]

REPORT = "report.html"
EXPORTS = "exports"  # the candidates' exported files, beside the report


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

SECTIONS = (("verdict", "Verdict against the baseline"), ("problem", "Problem"),
            ("convergence", "Convergence"), ("pareto", "Pareto front"),
            ("codesign", "Co-design points"), ("candidates", "Candidates A, B, C"),
            ("airframes", "Airframes"), ("failures", "Failures"), ("trim", "Trim"))


def write_report(run_dir: str | Path, references: tuple[str, ...] | None = None,
                 out: str | Path | None = None, trim_sample: int = 200,
                 trim_study_starts: int = 4) -> Path:
    """Write the self-contained HTML report of a run and return its path.

    Args:
        run_dir: the run directory.
        references: reference airframes (names in ``configs/airframes/`` or paths) drawn under
            the candidates and used for the Eq. 21 gains; the first is the baseline of the
            verdict and of the front figures (default: the problem's airframe,
            :func:`casadrone.verdict.default_baseline`).
        out: the HTML file to write (default ``run_dir/report.html``); figures go to ``plots/``
            beside it, as PNG and SVG.
        trim_sample: at most this many evaluations are trimmed again for the trim section.
        trim_study_starts: random starts per operating point and solver of the trim section's
            solver study (besides the analytic guess); negative: no study.
    """
    path = Path(out) if out is not None else Path(run_dir) / REPORT
    if path.is_dir() or (path.exists() and not path.is_file()):
        raise ValueError(f"--out: {path}: is a directory; give the report's file name "
                         f"(e.g. {path / REPORT})")
    blocker = file_above(path)  # afile/sub/report.html: found before the run is read
    if blocker is not None:
        raise ValueError(f"--out: {path}: cannot be made: {blocker} is a file, not a folder")
    run = read_run(run_dir)
    if not references:
        references = (str(default_baseline(run.study.problem)),)
    figs = Figures(path.parent / PLOTS)
    cands = choose_candidates(run)
    codesign = is_codesign(run)
    flown: list = []
    rv = None
    if not run.test_problem and cands:
        cands = evaluate_candidates(run, cands, limit=not codesign)
        flown = fly_references(run, tuple(references), limit=not codesign)
        rv = baseline_verdict(run, cands, flown[0])
    builders = {
        "verdict": lambda: section_verdict(run, cands, rv),
        "problem": lambda: section_problem(run),
        "convergence": lambda: section_convergence(run, figs),
        "pareto": lambda: section_pareto(run, cands, figs, baseline_of(run, rv)),
        "codesign": lambda: section_codesign(run, cands, figs),
        "candidates": lambda: (section_candidates(run, cands, figs, path.parent / EXPORTS,
                                                  limit=not codesign)
                               if not run.test_problem
                               else note("A pymoo test problem has no trajectories.")),
        "airframes": lambda: section_airframes(run, cands, tuple(references), figs, flown),
        "failures": lambda: section_failures(run, figs),
        "trim": lambda: section_trim(run, cands, figs, trim_sample, trim_study_starts),
    }
    shown = [(k, t) for k, t in SECTIONS if k != "codesign" or codesign]
    body = {}
    for i, (k, t) in enumerate(shown, start=1):  # one progress line per section, as it begins
        emit("stage", f"section {i}/{len(shown)}: {t}")
        with nested():
            body[k] = builders[k]()
    m = run.manifest
    stamp = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
    nav = "".join(f'<a href="#{k}">{esc(t)}</a>' for k, t in shown)
    sections = "".join(f'<section id="{k}"><h2>{i}. {esc(t)}</h2>{body[k]}</section>'
                       for i, (k, t) in enumerate(shown, start=1))
    title = f"casadrone run report: {run.study.problem.name}"
    page = (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{esc(title)}</title><style>{CSS}</style></head><body><header>"
            f"<h1>{esc(title)}</h1><p>Run directory <code>{esc(shown_path(run.store.path))}</code>"
            f" · status {esc(m.get('status'))} · {len(run.history)} evaluations · "
            f"{len(run.F)} designs on the front · report written {esc(stamp)}</p>"
            f"<nav>{nav}</nav></header>{sections}</body></html>")

    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, page)
    return path
