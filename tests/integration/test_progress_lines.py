"""Long commands say what they are doing (issue 44 item 2, issue 43 item 6): the limit lap emits
one event per start and per grid round with that solve's lap and iterations, co-design one per
start; on the command line they are lines on stderr, stdout stays the result (pure JSON with
``--json``) and ``-q`` silences them. Cheap set-ups: the short co-design test track, few
intervals; the per-start path is the one the shipped problems take."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from casadrone.progress import Event, listening

SHORT_TRACK = Path(__file__).resolve().parents[1] / "data" / "codesign" / "short-track.yaml"
SHORT_PROBLEM = SHORT_TRACK.parent / "short-problem.yaml"
LAP_ARGS = ["limit-lap", "SY250", "--track", str(SHORT_TRACK), "--intervals", "6",
            "--grid-rounds", "1"]


def test_each_start_and_round_of_a_limit_lap_is_an_event_with_its_lap_and_iterations():
    """The events of the outermost call name every start of the result, each with the lap and
    iterations the result itself reports for it (LimitLap.starts, an independent record), and
    one event per grid round; the grid-continuation starts' own laps on other grids are nested
    (depth ≥ 1), so a listener can tell them apart."""
    from casadrone.config.airframe import load_airframe
    from casadrone.config.io import load
    from casadrone.config.track import TrackConfig
    from casadrone.limit.lap import LimitLapOptions, design_limit_lap

    seen: list[Event] = []
    with listening(seen.append):
        lap = design_limit_lap(load_airframe("SY250"), load(TrackConfig, SHORT_TRACK),
                               LimitLapOptions(intervals=6, grid_rounds=1, sensitivities=False))
    assert lap.completed, lap.reason
    outer = {e.text.split(" ")[1]: e for e in seen if e.topic == "start" and e.depth == 0}
    assert set(outer) == {r.start for r in lap.starts}
    for r in lap.starts:
        e = outer[r.start]
        assert e.values["iterations"] == r.iterations, r.start
        if r.success:
            assert e.values["lap_s"] == pytest.approx(r.lap_time_s, rel=1e-12), r.start
            assert f"lap {r.lap_time_s:.4f} s" in e.text
        else:
            assert "no lap" in e.text
        assert e.values["cpu_s"] >= 0
    rounds = [e for e in seen if e.topic == "round"]
    assert [e.values["round"] for e in rounds] == [1]
    assert rounds[0].values["lap_s"] == pytest.approx(lap.lap_time_s, rel=1e-12)
    assert any(e.depth >= 1 for e in seen)  # the fine-grid start's lap on its own grid


def _lines(text: str, command: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith(f"{command}: ")]


def test_limit_lap_prints_a_line_per_start_on_stderr_json_on_stdout_and_nothing_with_q(
        cli_runner):
    from casadrone.cli import app

    r = cli_runner.invoke(app, [*LAP_ARGS, "--json"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)  # stdout is the JSON alone
    lines = _lines(r.stderr, "limit-lap")
    for s in data["starts"]:  # a line per start, with its lap as the JSON gives it
        mine = [line for line in lines if line.startswith(f"limit-lap: start {s['start']} ")]
        assert len(mine) == 1, (s["start"], lines)
        if s["success"]:
            assert f"lap {s['lap_time_s']:.4f} s, {s['iterations']} iterations" in mine[0]
        assert "CPU" in mine[0]
    assert any(line.startswith("limit-lap: grid round 1:") for line in lines)

    quiet = cli_runner.invoke(app, [*LAP_ARGS, "--json", "-q"])
    assert quiet.exit_code == 0, quiet.output
    assert quiet.stderr == ""
    assert json.loads(quiet.stdout)["lap_time_s"] == data["lap_time_s"]


def test_codesign_prints_each_start_and_its_certificate_and_nothing_with_quiet(cli_runner):
    """The short co-design problem with one random start: a line as each start begins and one
    as it ends (its objective as the JSON reports it), the certificate's stage and verdict."""
    from casadrone.cli import app

    args = ["codesign", str(SHORT_PROBLEM), "codesign.starts=1", "limit_lap.intervals=6",
            "--json"]
    r = cli_runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    lines = _lines(r.stderr, "codesign")
    starts = data["starts"]
    assert [s["label"] for s in starts][:2] == ["template", "random-1"]
    for k, s in enumerate(starts[:2], start=1):
        assert sum(line.startswith(f"codesign: start {k}/2 {s['label']}:")
                   for line in lines) == 1, lines
        done = [line for line in lines if line.startswith(f"codesign: start {s['label']}:")]
        assert len(done) == 1, lines
        if s["success"] and math.isfinite(s["objective"]):
            assert f"objective {s['objective']:.4f} s" in done[0]
    if data["certificate"] is not None:
        verdict = "PASSED" if data["certificate"]["passed"] else "FAILED"
        assert any(line.startswith(f"codesign: certificate: {verdict}") for line in lines)

    quiet = cli_runner.invoke(app, [*args, "--quiet"])
    assert quiet.exit_code == 0, quiet.output
    assert quiet.stderr == ""
    best = json.loads(quiet.stdout)["best"]
    assert (best["objective"], best["theta"]) == (data["best"]["objective"], data["best"]["theta"])


def test_report_says_each_section_as_it_builds_it_and_nothing_with_q(tmp_path, cli_runner):
    """A pymoo test-problem run (seconds): one ``section k/n: TITLE`` line per section of the
    page, in the page's order, then the path alone on stdout; ``-q``: stderr empty."""
    import re

    from casadrone.cli import app
    from casadrone.config.problem import BackendConfig
    from casadrone.optimise.checks import load_problem
    from casadrone.optimise.runner import run

    problem_file = tmp_path / "zdt.yaml"
    problem_file.write_text("name: zdt\ntest_problem: {name: zdt1, n_var: 4}\n"
                            "algorithm: {name: nsga2, population: 12, generations: 3}\n")
    run(load_problem(problem_file), tmp_path / "zdt", BackendConfig(name="serial"), quiet=True)
    r = cli_runner.invoke(app, ["report", str(tmp_path / "zdt")])
    assert r.exit_code == 0, r.output
    html = (tmp_path / "zdt" / "report.html").read_text()
    titles = re.findall(r'<section id="[a-z]+"><h2>\d+\. ([^<]+)</h2>', html)
    lines = _lines(r.stderr, "report")
    n = len(titles)
    assert [line.split(" [CPU")[0] for line in lines] == [
        f"report: section {k}/{n}: {t}" for k, t in enumerate(titles, start=1)]
    assert r.stdout.strip().endswith("report.html")

    quiet = cli_runner.invoke(app, ["report", str(tmp_path / "zdt"), "-q"])
    assert quiet.exit_code == 0, quiet.output
    assert quiet.stderr == ""


def test_trim_study_says_each_operating_point_and_nothing_with_q(cli_runner):
    """Two operating points, two starts each (the guess and one random), Newton alone: one
    ``point k/2`` line each, with the success rate the JSON reports for it."""
    from casadrone.cli import app

    args = ["trim-study", "SY250", "--conditions", "hover,forward:10", "--starts", "1",
            "--solvers", "newton", "--json"]
    r = cli_runner.invoke(app, args)
    assert r.exit_code == 0, r.output
    points = json.loads(r.stdout)["points"]
    lines = _lines(r.stderr, "trim-study")
    assert len(lines) == len(points) == 2
    for k, (line, p) in enumerate(zip(lines, points, strict=True), start=1):
        rate = p["summaries"][0]["success_rate"]
        assert line.startswith(f"trim-study: point {k}/2 {p['point']['label']}: trimmed from "
                               f"{len(p['starts'])} start(s): newton {rate:.0%};"), line
    quiet = cli_runner.invoke(app, [*args, "-q"])
    assert quiet.exit_code == 0 and quiet.stderr == "", quiet.output


def _console(console: list[str], *args: str) -> tuple[dict, list[str]]:
    """Run the console script; (its stdout as JSON, its stderr lines)."""
    import subprocess

    r = subprocess.run([*console, *args, "--json"], capture_output=True, text=True, check=False)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout), r.stderr.splitlines()


@pytest.mark.slow
def test_the_shipped_commands_say_each_start_on_stderr(console):
    """What the issue ran, at the defaults (seconds and about 75 s of CPU with the blocks
    compiled): ``limit-lap SY250`` a line per start of its result (the fast path: the shipped
    lap's; grid rounds print theirs in the test above); ``codesign codesign-paper`` a line as
    each of its starts begins and one as it ends."""
    lap, err = _console(console, "limit-lap", "SY250")
    assert lap["starts"]
    for s in lap["starts"]:
        assert sum(line.startswith(f"limit-lap: start {s['start']} ") for line in err) == 1, \
            (s["start"], err)

    design, err = _console(console, "codesign", "codesign-paper")
    labels = [s["label"] for s in design["starts"]]
    assert len(labels) >= 6  # the template and codesign.starts: 5 random frames
    for s in labels:
        assert sum(line.startswith(f"codesign: start {s}:") for line in err) == 1, (s, err)
    assert sum(line.startswith("codesign: start ") and "/" in line.split()[2]
               for line in err) == len([s for s in labels if s == "template"
                                        or s.startswith("random-")])
