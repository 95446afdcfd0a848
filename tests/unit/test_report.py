"""The HTML run report: every section, embedded figures, no external reference, the candidates'
θ as stored, the figure files, and an empty front reported rather than crashing."""

from __future__ import annotations

import base64
import re
import struct
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest

from casadrone.compare import run_candidates
from casadrone.config.problem import BackendConfig
from casadrone.decide import decide
from casadrone.optimise.checks import load_problem
from casadrone.optimise.runner import run
from casadrone.report import write_report
from casadrone.report.analysis import (
    choose_candidates,
    convergence_history,
    failure_groups,
    feasible_front,
    read_run,
    reason_group,
)
from casadrone.report.markup import num
from casadrone.rundir.store import RunStore

ROOT = Path(__file__).resolve().parents[2]
SECTIONS = ("verdict", "problem", "convergence", "pareto", "candidates", "airframes", "failures",
            "trim")
TINY = ["algorithm.population=16", "algorithm.generations=2", "algorithm.settings.n_ind_ga=8"]
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
EXTERNAL = re.compile(r'src="http|href="http|url\(|<link|<script src', re.IGNORECASE)
IMG = re.compile(r'<img src="data:image/png;base64,([A-Za-z0-9+/=]+)"')


def make_run(path: Path, overrides: list[str]) -> Path:
    problem = load_problem(ROOT / "problems" / "quick.yaml", TINY + overrides)
    run(problem, path, BackendConfig(name="serial"), quiet=True)
    return path


#: (figure, paths) of every figure the report fixture saved
SAVED: list = []


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> tuple[Path, str]:
    """A tiny quick.yaml run and its report (every saved figure recorded in SAVED)."""
    from casadrone import plots

    run_dir = make_run(tmp_path_factory.mktemp("run") / "quick", [])
    save = plots.save_figure

    def recording(fig, *args, **kwargs):
        paths = save(fig, *args, **kwargs)
        SAVED.append((fig, paths))
        return paths

    from casadrone.progress import listening

    with pytest.MonkeyPatch.context() as mp, listening(EVENTS.append):
        mp.setattr(plots, "save_figure", recording)
        path = write_report(run_dir)
    return run_dir, path.read_text(encoding="utf-8")


#: the progress events of the report fixture's write_report (casadrone.progress)
EVENTS: list = []


def test_each_candidate_and_section_is_said_as_it_begins(report):
    """Progress of a report: one event per candidate re-evaluated (the decisions' labels, in
    order), then one per section of the page, in the page's order (its own headings)."""
    run_dir, html = report
    outer = [e.text for e in EVENTS if e.depth == 0]
    labels = [c.label for c in choose_candidates(read_run(run_dir))]
    n = len(labels)
    assert [t.split(" with ")[0] for t in outer[:n]] == [
        f"re-evaluating candidate {label} ({k}/{n})" for k, label in enumerate(labels, start=1)]
    titles = re.findall(r'<section id="[a-z]+"><h2>\d+\. ([^<]+)</h2>', html)
    assert outer[n:] == [f"section {k}/{len(titles)}: {t}"
                         for k, t in enumerate(titles, start=1)]


def require_front(run_dir: Path) -> None:
    """Fail with the reason when the tiny run found no feasible design (a broken chain)."""
    if not RunStore(run_dir).read_pareto()[1]:
        groups = failure_groups(RunStore(run_dir).history())
        pytest.fail("the tiny quick.yaml run has an empty front, the evaluation chain upstream of "
                    f"the report is broken; failures (stage, reason, count): "
                    f"{[g[:3] for g in groups]}")


def section(html: str, name: str) -> str:
    start = html.index(f'<section id="{name}">')
    return html[start:html.index("</section>", start)]


def test_report_is_written_in_the_run_directory(report):
    run_dir, _ = report
    assert (run_dir / "report.html").is_file()


def test_every_section_with_a_heading(report):
    _, html = report
    for name in SECTIONS:
        assert re.search(rf'<section id="{name}"><h2>', html), name
    assert html.count("<section ") == len(SECTIONS)


def test_figures_are_embedded_png(report):
    run_dir, html = report
    images = IMG.findall(html)
    assert len(images) >= 3  # convergence, failures, trim: even for an empty front
    png = base64.b64decode(images[0])
    assert png[:8] == PNG_MAGIC
    assert png[12:16] == b"IHDR"
    width, height = struct.unpack(">II", png[16:24])
    assert width >= 300 and height >= 200
    assert png == (run_dir / "plots" / "convergence.png").read_bytes()


def test_no_external_reference(report):
    _, html = report
    assert EXTERNAL.search(html) is None
    assert "<script" not in html


def test_figure_files_exist_as_png_and_svg(report):
    run_dir, html = report
    names = re.findall(r"\(plots/([\w.-]+)\.png, \.svg\)", html)
    assert len(names) == len(IMG.findall(html))
    for name in names:
        png, svg = run_dir / "plots" / f"{name}.png", run_dir / "plots" / f"{name}.svg"
        assert png.read_bytes()[:8] == PNG_MAGIC
        assert svg.read_text(encoding="utf-8").lstrip().startswith("<?xml")
        assert "<svg" in svg.read_text(encoding="utf-8")


def test_candidate_theta_equals_pareto_rows(report):
    run_dir, html = report
    require_front(run_dir)
    header, rows = RunStore(run_dir).read_pareto()
    names = header[:7]
    cands = choose_candidates(read_run(run_dir))
    assert {m for c in cands for m in c.methods} == {"utopian", "compromise", "extreme"}
    part = section(html, "candidates")
    for c in cands:
        start = part.index(f'id="candidate-{c.label}"')
        theta = part[start:part.index("</table>", start)]
        values = [float(v) for v in re.findall(r'data-value="([^"]+)"', theta)]
        assert values == rows[c.row][:7]  # exact: repr round trip
        shown = re.findall(r'data-value="[^"]+">([^<]+)<', theta)
        np.testing.assert_allclose([float(v) for v in shown], rows[c.row][:7], rtol=1e-4)
        assert f"Row {c.row} of the front" in part[start:]
        for n in names:
            assert f"<td>{n}</td>" in theta
    # per candidate: top view and time histories; the airframes over SY250
    assert len(IMG.findall(part)) >= 2 * len(cands)
    assert len(IMG.findall(section(html, "airframes"))) == 1


def test_candidates_match_the_decisions(report):
    run_dir, _ = report
    require_front(run_dir)
    r = read_run(run_dir)
    cands = choose_candidates(r)
    by_method = {m: c.row for c in cands for m in c.methods}
    senses = r.study.senses
    assert by_method["utopian"] == decide(r.F, senses, "utopian").index
    assert by_method["compromise"] == decide(r.F, senses, "compromise").index
    assert by_method["extreme"] == decide(r.F, senses, "extreme", 0).index
    same = {(d.method, d.row) for d in run_candidates(run_dir)}  # `casadrone decide` agrees
    assert same == {(m, c.row) for c in cands for m in c.methods}
    labels = {m: c.label for c in cands for m in c.methods}
    assert labels["utopian"].startswith("A")  # paper: A utopian, B trade-off, C extreme
    assert "C" in labels["extreme"] and "B" in labels["compromise"]


def test_candidates_reproduce_the_stored_objectives(report):
    run_dir, html = report
    require_front(run_dir)
    part = section(html, "candidates")
    assert "every objective reproduces pareto.csv" in part


def test_convergence_is_monotone_and_ends_on_the_non_dominated_set(report):
    run_dir, _ = report
    require_front(run_dir)
    r = read_run(run_dir)
    ch = convergence_history(r)
    assert list(ch.generations) == [g["generation"] for g in r.generations]
    assert np.all(np.diff(ch.hypervolume) >= -1e-12)
    assert ch.hypervolume[-1] > 0
    _, F, ok = feasible_front(r.study, r.history)
    P = np.unique(F[ok], axis=0)  # brute-force oracle of the final non-dominated set
    dominated = [any(np.all(q <= p) and np.any(q < p) for q in P) for p in P]
    assert ch.n_non_dominated[-1] == len(P) - sum(dominated)
    # the space is fixed by the first generation with a feasible evaluation (its
    # non-dominated set's ideal and nadir) and stored in the manifest by the run
    gen, _, _ = feasible_front(r.study, r.history)
    first = P[:0]
    for g in sorted(set(gen.tolist())):
        if (ok & (gen == g)).any():
            first = F[ok & (gen == g)]
            break
    nd = [p for p in first if not any(np.all(q <= p) and np.any(q < p) for q in first)]
    np.testing.assert_allclose(ch.ideal, np.min(nd, axis=0), rtol=0, atol=0)
    np.testing.assert_allclose(ch.nadir, np.max(nd, axis=0), rtol=0, atol=0)
    assert r.manifest["hypervolume_space"] == {"ideal": list(ch.ideal), "nadir": list(ch.nadir)}
    # the console and the history log show the same values as the report's curve
    # (with four or more objectives it is logged only where computed: NULL in between)
    logged = [g["hypervolume"] for g in r.generations]
    computed = [k for k, v in enumerate(logged) if v is not None]
    assert computed[0] == 0 and computed[-1] == len(logged) - 1
    np.testing.assert_allclose([logged[k] for k in computed], ch.hypervolume[computed],
                               rtol=1e-12)
    sparse = convergence_history(r, max_points=1)  # 3 generations: first and last only
    assert np.isnan(sparse.hypervolume[1])
    np.testing.assert_allclose(sparse.hypervolume[[0, 2]], ch.hypervolume[[0, 2]], rtol=1e-12)
    np.testing.assert_array_equal(sparse.n_non_dominated, ch.n_non_dominated)


def test_reason_groups_ignore_times_and_numbers():
    a = "attitude beyond 80 deg (roll 81.2 deg, pitch 3.0 deg) at t = 3.21 s"
    b = "attitude beyond 80 deg (roll 95.0 deg, pitch -1.5 deg) at t = 12.00 s"
    assert reason_group(a) == reason_group(b) == "attitude beyond # deg (roll # deg, pitch # deg)"
    assert reason_group("SY250: rotors overlap") == "SY250: rotors overlap"  # names keep digits
    history = [
        {"status": "failed", "stage": "lap", "reason": a},
        {"status": "failed", "stage": "lap", "reason": b},
        {"status": "failed", "stage": "geometry", "reason": "bad"},
        {"status": "completed", "stage": "", "reason": ""},
    ]
    groups = failure_groups(history)
    assert [(g[0], g[2]) for g in groups] == [("geometry", 1), ("lap", 2)]
    assert groups[1][3] == a  # first reason seen is the example


def test_number_cells():
    assert num(None) == "—" and num(float("nan")) == "—"
    assert num(-1e-17, ".3f") == "0.000"
    assert num(-0.04, "+.1f") == "+0.0"
    assert num(-0.06, "+.1f") == "-0.1"
    assert num(0.0017971107, ".5g") == "0.0017971"


def test_empty_front_is_reported_not_raised(tmp_path):
    # Jp below 1 deg: every completed lap violates the constraint, nothing is feasible
    run_dir = make_run(tmp_path / "empty", ["constraints.0.max=1.0", "algorithm.generations=1"])
    assert RunStore(run_dir).read_pareto()[1] == []
    html = write_report(run_dir, out=tmp_path / "elsewhere" / "r.html").read_text()
    for name in ("pareto", "candidates", "airframes"):
        assert "The Pareto front is empty" in section(html, name)
    assert "no feasible evaluation" in section(html, "convergence")
    assert (tmp_path / "elsewhere" / "plots" / "failures.svg").is_file()
    assert EXTERNAL.search(html) is None


def test_unfinished_run_reports_the_front_of_its_history(tmp_path):
    problem = load_problem(ROOT / "problems" / "quick.yaml", TINY)
    run(problem, tmp_path / "part", BackendConfig(name="serial"), quiet=True, stop_after=1)
    assert not (tmp_path / "part" / "pareto.csv").exists()
    html = write_report(tmp_path / "part").read_text()
    for name in SECTIONS:
        assert f'<section id="{name}">' in html
    assert "history.sqlite (no pareto.csv: the run has not finished)" in section(html, "pareto")


def test_report_of_a_test_problem_run(tmp_path):
    problem_file = tmp_path / "zdt.yaml"
    problem_file.write_text("name: zdt\ntest_problem: {name: zdt1, n_var: 4}\n"
                            "algorithm: {name: nsga2, population: 12, generations: 3}\n")
    run(load_problem(problem_file), tmp_path / "zdt", BackendConfig(name="serial"), quiet=True)
    html = write_report(tmp_path / "zdt").read_text()
    for name in SECTIONS:
        assert f'<section id="{name}">' in html
    assert "A pymoo test problem has no airframe" in section(html, "airframes")
    assert len(IMG.findall(section(html, "pareto"))) == 2


def test_candidate_exports_are_linked_and_written(report):
    run_dir, html = report
    require_front(run_dir)
    links = re.findall(r'<a href="exports/(candidate-([ABC]+)-([\w-]+)\.\w+)">', html)
    assert {fmt for _, _, fmt in links} == {"betaflight", "px4", "px4-shell", "urdf", "svg",
                                            "dxf", "bom", "bom-csv"}
    for name, label, _ in links:
        text = (run_dir / "exports" / name).read_text(encoding="utf-8")
        assert f"candidate: {'='.join(label)} (" in text and "casadrone" in text


def test_report_and_its_exports_name_no_machine_path(report):
    import sys

    import casadrone

    run_dir, html = report
    install = str(Path(casadrone.__file__).resolve().parent.parent)
    machine = (str(run_dir.resolve().parent), install, sys.executable)
    texts = [html] + [p.read_text(encoding="utf-8") for p in (run_dir / "exports").iterdir()]
    for text in texts:
        found = [(m, text[max(0, text.find(m) - 80):text.find(m) + 40]) for m in machine
                 if m in text]
        assert not found


def test_measured_table4_gains_are_left_out_saying_why(report):
    # gains against the paper's measured laps mix two time bases (hundreds of seconds against
    # about fifteen): not a result, so the report shows none of them, and says where they are
    run_dir, html = report
    require_front(run_dir)
    gains = section(html, "airframes").split("Per-interval gains")[1]
    assert "Against the paper's measured" not in html
    assert gains.count("<table") == 1  # the simulated gains only
    assert "another time base" in gains and "casadrone compare --measured" in html


def test_no_figure_is_clipped(report):
    # Every figure's PNG covers the extent of everything drawn on it (its tight bounding box,
    # labels and legends included) plus the pad: a bottom axis label can no longer fall off the
    # image. And the PNG keeps a white margin on all four sides: no ink touches its border.
    from matplotlib.image import imread

    from casadrone.plots import PAD_INCHES

    run_dir, _ = report
    pngs = [paths[0] for _, paths in SAVED]
    assert len(pngs) >= 3 and all(p.suffix == ".png" and p.parent == run_dir / "plots"
                                  for p in pngs)
    for fig, paths in SAVED:
        img = imread(paths[0])
        fig.set_dpi(150)  # text extents as rendered into the PNG
        tight = fig.get_tightbbox()  # inches
        content = np.array([tight.width, tight.height]) + 2 * PAD_INCHES
        image = np.array(img.shape[1::-1]) / 150
        assert np.all(image >= content - 0.1), (paths[0].name, image, content)
    for png in pngs:
        img = imread(png)[..., :3]
        border = np.concatenate([img[:2].reshape(-1, 3), img[-2:].reshape(-1, 3),
                                 img[:, :2].reshape(-1, 3), img[:, -2:].reshape(-1, 3)])
        assert np.all(border > 0.99), f"{png.name}: ink touches the image border (clipped)"


def test_trim_section_holds_the_solver_study(report):
    run_dir, html = report
    trim = section(html, "trim")
    assert "Trim solvers across the envelope" in trim
    # one row per operating point and solver, each with its outcomes summed to the starts
    from casadrone.conditions import envelope
    from casadrone.report.trimstudy import POINTS

    labels = [p.label for p in envelope(POINTS)]
    for label in labels:
        assert trim.count(f"<td>{label}</td>") == 3, label
    for name in ("trim-study-envelope", "trim-study-basins", "trim-study-residuals"):
        assert (run_dir / "plots" / f"{name}.png").is_file()


class Page(HTMLParser):
    """The page's sections in order (id, heading text) and every table as rows of cell texts,
    by Python's own HTML parser."""

    def __init__(self):
        super().__init__()
        self.sections: list[list[str]] = []
        self.tables: list[tuple[str, list[list[str]]]] = []  # (section id, rows)
        self._heading = self._cell = False
        self._text = ""

    def handle_starttag(self, tag, attrs):
        if tag == "section":
            self.sections.append([dict(attrs)["id"], ""])
        elif tag == "h2":
            self._heading = True
        elif tag == "table":
            self.tables.append((self.sections[-1][0] if self.sections else "", []))
        elif tag == "tr":
            self.tables[-1][1].append([])
        elif tag in ("td", "th"):
            self._cell, self._text = True, ""

    def handle_endtag(self, tag):
        if tag == "h2":
            self._heading = False
        elif tag in ("td", "th"):
            self.tables[-1][1][-1].append(self._text.strip())
            self._cell = False

    def handle_data(self, data):
        if self._heading:
            self.sections[-1][1] += data
        if self._cell:
            self._text += data


def parsed(html: str) -> Page:
    page = Page()
    page.feed(html)
    return page


def test_the_report_opens_with_the_verdict_against_the_baseline(report):
    run_dir, html = report
    require_front(run_dir)
    page = parsed(html)
    assert page.sections[0] == ["verdict", "1. Verdict against the baseline"]
    text = re.sub(r"<[^>]+>", "", section(html, "verdict"))
    for c in choose_candidates(read_run(run_dir)):
        assert re.search(rf"{re.escape(c.label)} dominates SY250: (yes|no)", text), c.label


def _verdict_tables(page: Page) -> dict[str, dict[str, list[str]]]:
    """candidate → index → row of its verdict table."""
    out = {}
    for sec, rows in page.tables:
        if sec == "verdict" and rows[0][:4] == ["index", "sense", "unit", "SY250"]:
            out[rows[0][4]] = {r[0].split()[0]: r for r in rows[1:]}
    return out


def test_the_verdict_agrees_with_the_eq21_gains_of_the_airframes_section(report):
    # Two code paths: the verdict (casadrone.verdict) and the Eq. 21 gains of the airframes
    # section (casadrone.compare.gain_pct, positive = better). Same values of both designs, the
    # same direction per index, and the verdict's "dominates" is what the gains say.
    run_dir, html = report
    require_front(run_dir)
    page = parsed(html)
    verdicts = _verdict_tables(page)
    (gains,) = [rows for sec, rows in page.tables if sec == "airframes"
                and rows[0][:3] == ["index", "sense", "SY250"]]
    head = gains[0]
    r = read_run(run_dir)
    cands = choose_candidates(r)
    assert sorted(verdicts) == sorted(c.label for c in cands)
    text = re.sub(r"<[^>]+>", "", section(html, "verdict"))
    for c in cands:
        rows = verdicts[c.label]
        col, gcol = head.index(c.label), head.index(f"{c.label} gain (%)")
        better = []
        for g in gains[1:]:
            name = g[0].split()[0]
            if name not in rows:  # an index the lap does not give (J3_limit: no limit lap)
                assert g[gcol] == "—"
                continue
            v = rows[name]
            assert v[3] == g[2] and v[4] == g[col]  # SY250's value and the candidate's
            gain = float(g[gcol])
            diff = float(v[4]) - float(v[3])
            np.testing.assert_allclose(float(v[5]), diff, rtol=1e-3, atol=2e-4 * abs(float(v[3])))
            if abs(gain) >= 0.05:  # the gains table shows one decimal
                assert v[7].startswith("better" if gain > 0 else "worse"), (c.label, name)
            if name in r.study.objective_names:
                better.append(gain)
        dominated = all(g >= 0 for g in better) and any(g > 0 for g in better)
        if all(abs(g) >= 0.05 for g in better):  # the decimal shown decides every sign
            assert f"{c.label} dominates SY250: {'yes' if dominated else 'no'}" in text


def test_every_front_figure_draws_the_baseline(report):
    run_dir, _ = report
    require_front(run_dir)
    fronts = [(fig, paths[0].stem) for fig, paths in SAVED if paths[0].stem.startswith("pareto")]
    assert {name for _, name in fronts} == {"pareto-front", "pareto-set"}
    for fig, name in fronts:
        drawn = [a for a in fig.axes if a.collections or a.lines]
        assert drawn, name
        for a in drawn:
            labels = [x.get_label() for x in (*a.collections, *a.lines)]
            assert "SY250 (baseline)" in labels, (name, labels)


def test_the_impossible_bodies_share_is_counted_from_the_history(report):
    # the oracle: the inertias of each evaluation checked by hand against the triangle
    # inequality (each principal moment at most the sum of the other two; diagonal tensors)
    run_dir, html = report
    h = RunStore(run_dir).history()
    bad = sum(max(J) > sum(J) - max(J) for J in
              ([r["ixx_kgm2"], r["iyy_kgm2"], r["izz_kgm2"]] for r in h))
    text = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", "", section(html, "verdict")))
    assert f"{bad} of {len(h)} evaluations ({100 * bad / len(h):.1f} %)" in text
    assert "keeps the mass fixed" in text and "problems/quick-parts.yaml" in text
    assert (ROOT / "problems" / "quick-parts.yaml").is_file()


def test_the_airframe_figure_labels_each_rotor_by_position(report):
    # the rotor labels of the report's own figure, at the position their drawing coordinates
    # say (x across = right of the drone, y up = nose); no rotor numbered 1…4
    from casadrone.config.airframe import ROTOR_LABELS, position_of

    run_dir, _ = report
    require_front(run_dir)
    (fig,) = [f for f, paths in SAVED if paths[0].stem == "airframes-SY250"]
    for a in fig.axes:
        texts = [t for t in a.texts if t.get_text() in ROTOR_LABELS]
        assert len(texts) % 4 == 0 and texts
        for t in texts:
            right, nose = t.xy
            assert position_of(nose, -right) == t.get_text()
        assert not [t for t in a.texts if t.get_text() in ("1", "2", "3", "4")]
