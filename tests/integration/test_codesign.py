"""Co-design end to end: on a short track (fast, default suite) and the paper track (slow).

Oracles: the limit lap of the returned frame solved by the limit lap's own driver with θ fixed
(a different NLP: θ is a parameter there); the envelope-theorem gradient chained through the
numeric mass model (casadrone.limit.check.theta_sensitivities) against IPOPT's bound
multipliers of the co-design NLP; the airframe schema for feasibility; the limit laps of the
template and of random frames for "at least as fast".
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from casadrone.airframe import build_airframe, with_theta
from casadrone.codesign.design import codesign
from casadrone.config.codesign import CodesignProblemConfig
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.limit.lap import LapSeeds, LimitLapOptions, design_limit_lap

ROOT = Path(__file__).resolve().parents[2]
SHORT = ROOT / "tests" / "data" / "codesign" / "short-track.yaml"
BOX = [("lambda_a_mm", 100.0, 150.0), ("lambda_b_mm", 100.0, 150.0), ("alpha_deg", 65.0, 90.0),
       ("beta_deg", 65.0, 90.0)]


def _problem(track: Path, starts: int, intervals: int) -> CodesignProblemConfig:
    return CodesignProblemConfig.model_validate({
        "name": "short", "airframe": str(ROOT / "configs/airframes/SY250-components.yaml"),
        "track": str(track), "objectives": [{"index": "J3_limit"}],
        "variables": [{"name": k, "lower": lo, "upper": hi} for k, lo, hi in BOX],
        "limit_lap": {"intervals": intervals}, "codesign": {"starts": starts}})


@pytest.fixture(scope="module")
def short_result():
    return codesign(_problem(SHORT, starts=0, intervals=8))


def test_codesign_frame_is_valid_and_no_slower_than_the_template(short_result):
    r = short_result
    assert r.status == "completed", r.reason
    cfg = with_theta(r_template(), r.best.theta)  # raises if the frame is no valid airframe
    for key, lo, hi in BOX:
        assert lo - 1e-6 <= r.best.theta[key] <= hi + 1e-6
    # oracle: the limit lap of the template frame (the co-design started from its geometry)
    track = load(TrackConfig, SHORT)
    template = design_limit_lap(r_template(), track,
                                       LimitLapOptions(intervals=8, sensitivities=False))
    assert r.best.laps_s["short"] <= template.lap_time_s * (1 + 1e-6)
    assert build_airframe(cfg).mass == pytest.approx(r.best.mass_kg, rel=1e-12)


def test_the_returned_laps_warm_start_the_fixed_frame_lap_at_its_optimum(short_result):
    """CodesignResult.laps (driver.warm_laps: the point's lap as a fixed-frame warm start,
    what a build's race starts from) against the limit lap of the co-designed frame solved from
    it alone: the same lap within the solver's tolerance, in a handful of iterations where the
    default starts take tens to hundreds (the same NLP with θ fixed, started at its optimum)."""
    from casadrone.limit.result import seeds_alone

    r = short_result
    (warm,) = r.laps
    assert warm.lap_time_s == pytest.approx(r.best.laps_s["short"], rel=1e-9)
    opts = LimitLapOptions(intervals=8, sensitivities=False, point_mass_reference=False)
    fixed = design_limit_lap(with_theta(r_template(), r.best.theta), load(TrackConfig, SHORT),
                             seeds_alone(opts), LapSeeds(warm_starts=r.laps))
    assert fixed.completed, fixed.reason
    assert fixed.start == "warm-1"
    assert fixed.lap_time_s == pytest.approx(r.best.laps_s["short"], rel=1e-5)
    assert fixed.iterations <= 15


def test_certificate_lap_gradient_and_resimulation(short_result):
    c = short_result.certificate
    assert c.passed, c.text()
    (track,) = c.tracks
    assert abs(track.gap_pct) <= 0.05
    assert track.resimulation_miss_m <= 0.15
    # two derivations of the same reduced gradient: envelope theorem through the numeric mass
    # model, and IPOPT's bound multiplier (its negative). Observed agreement 2-4 % at tol 1e-6.
    for v in c.variables:
        if v.state != "interior":
            assert v.reduced_gradient == pytest.approx(-v.bound_multiplier, rel=0.2, abs=2e-4)


def test_printed_result_reads(short_result):
    # one track: its lap is the headline; no negative zero (a gap of -1e-7 % printed "-0.0000");
    # the why is the sentence of the certificate's active set: both arm lengths at their lower
    # bound (positive multipliers: shorter would be faster)
    from casadrone.cli.codesign import text
    from casadrone.codesign.certificate import why_sentence
    from tests.unit.test_printed_labels import NEGATIVE_ZERO

    r = short_result
    out = text(r)
    lap = r.best.laps_s["short"]
    assert out.splitlines()[0] == f"short: co-design COMPLETED: lap {lap:.4f} s on short"
    assert not NEGATIVE_ZERO.search(out), out
    states = {v.key: v.state for v in r.certificate.variables}
    # shorter arms are faster on this short track, whichever local optimum the angles end in
    # (α interior with whole-step derivative blocks, at its upper bound with the chained ones:
    # the same derivatives to rounding, another path from the cold start)
    assert states["lambda_a_mm"] == states["lambda_b_mm"] == "lower"
    assert "both arms want to be shorter than the 100 mm bound" in out
    why = why_sentence(r.certificate.variables, r.certificate.active)  # its own unit tests
    assert f"  why: {why}" in out.splitlines()


def test_result_as_dict_is_json(short_result):
    data = json.loads(json.dumps(short_result.as_dict(), default=float))
    assert data["status"] == "completed"
    assert set(data["best"]["theta"]) == {k for k, _, _ in BOX}
    assert data["starts"][0]["label"] == "template"


def r_template():
    from casadrone.config import load_airframe

    return load_airframe(ROOT / "configs/airframes/SY250-components.yaml")


@pytest.mark.slow
def test_paper_track_codesign_beats_random_frames():
    """Five random starts plus the template on the paper track (40 intervals): the co-design
    lap is no slower than the limit laps of 8 random feasible frames (the 200-frame comparison
    is benchmarks/bench_codesign_random.py), and the certificate passes."""
    from casadrone.airframe import random_thetas

    r = codesign(ROOT / "problems" / "codesign-paper.yaml")
    assert r.status == "completed" and r.certificate.passed, r.certificate.text()
    track = load(TrackConfig, ROOT / "configs/tracks/paper-rectangle.yaml")
    thetas, _ = random_thetas(r_template(), 8, seed=11)
    laps = [design_limit_lap(with_theta(r_template(), t), track,
                             LimitLapOptions(sensitivities=False)).lap_time_s for t in thetas]
    assert r.best.objective <= np.nanmin(laps) * (1 + 1e-4)


@pytest.fixture(scope="module")
def short_front(tmp_path_factory):
    data = _problem(SHORT, starts=0, intervals=8).model_dump()
    data["objectives"] = [{"index": "J3_limit"}, {"index": "effort"}]
    data["codesign"] = {"starts": 0, "front": {"points": 3, "lowest": 0.7}}
    problem = CodesignProblemConfig.model_validate(data)
    out = tmp_path_factory.mktemp("front") / "run"
    return codesign(problem, certify=True, run_dir=out), out


def test_front_follows_the_effort_bound(short_front):
    """Each point meets its bound; a tighter bound never gives a faster lap (observed: 0.792,
    0.794, 0.804, ... s on this track); the effort recomputed from the unpacked nodes with numpy
    (an oracle for the symbolic index bookkeeping of casadrone.codesign.nlp.effort)."""
    from casadrone.codesign.driver import prepare
    from casadrone.codesign.nlp import EFFORT_SMOOTHING_N

    result, _ = short_front
    front = result.front
    assert len(front.points) == 3, front.stopped
    laps = [p.point.objective for p in front.points]
    assert all(b >= a - 1e-6 for a, b in zip(laps, laps[1:], strict=False))
    prep = prepare(_problem(SHORT, starts=0, intervals=8))
    for p in front.points[1:]:
        assert p.measure <= p.epsilon * (1 + 1e-6)
        part = prep.nlp.parts[0]
        T, X, _ = part.nlp.unpack(p.point.z[:prep.nlp.offsets[1]])
        h = np.repeat(T, part.nlp.layout.intervals) / part.nlp.layout.intervals
        thrust = X[:-1, part.nlp.model.rotor]
        numpy_effort = float(h @ np.sum((thrust ** 2 + EFFORT_SMOOTHING_N ** 2) ** 0.75, 1))
        assert numpy_effort == pytest.approx(p.measure, rel=1e-9)


def test_front_steps_after_the_first_run_on_a_budget(short_front):
    """The sweep's steps are solved within a CPU budget from the solves before them (a second or
    so each here, so the floor): the budget reached the step solver's callback. Unset (a wiring
    lost between the front, continued and solve_from) it stays unlimited."""
    from casadrone.codesign.nlp import STEP_MIN_CPU_S

    result, _ = short_front
    assert len(result.front.points) == 3
    assert max(p.point.cpu_s for p in result.front.points[1:]) < STEP_MIN_CPU_S / 3
    assert result.front.prepared.nlp.budget.limit_s == STEP_MIN_CPU_S


def test_front_run_directory_is_read_by_decide(short_front, cli_runner):
    from casadrone.cli import app
    from casadrone.rundir.store import RunStore

    result, out = short_front
    header, rows = RunStore(out).read_pareto()
    assert header[-2:] == ["J3_limit", "effort"] and len(rows) == len(result.front.points)
    decided = cli_runner.invoke(app, ["decide", str(out), "--json"])
    assert decided.exit_code == 0, decided.output
    assert json.loads(decided.stdout)


def test_front_run_directory_is_read_like_a_run(short_front, cli_runner, tmp_path):
    """report, compare and export open a co-design front's run directory like an optimiser's.

    Oracles, each reading the files with a consumer of its own: ``pareto.csv`` with the csv
    module; the stored limit laps with numpy (lap time = last node time, effort recomputed from
    the nodes: both must equal pareto.csv's columns); ``codesign.json`` with json (every ε-bounded
    point's lap is slower than the previous one, so its ε row must hold it: a multiplier listed
    as active); the report with html.parser (a row per front point in the co-design section)."""
    import csv
    from html.parser import HTMLParser

    from casadrone.cli import app
    from casadrone.indices import EFFORT_SMOOTHING_N
    from casadrone.report import write_report

    _, out = short_front
    with open(out / "pareto.csv", newline="") as fh:
        header, *rows = list(csv.reader(fh))
    F = np.array([[float(r[header.index("J3_limit")]), float(r[header.index("effort")])]
                  for r in rows])
    laps = np.load(out / "codesign-laps.npz")
    for i, (lap, eff) in enumerate(F):
        t, x = laps[f"{i}/short/t"], laps[f"{i}/short/x"]
        thrust = x[:-1, 12:16]
        assert t[-1] - t[0] == pytest.approx(lap, rel=1e-9)
        assert float(np.diff(t) @ np.sum((thrust ** 2 + EFFORT_SMOOTHING_N ** 2) ** 0.75, 1)) \
            == pytest.approx(eff, rel=1e-9)
    points = json.loads((out / "codesign.json").read_text())["points"]
    assert np.all(np.diff(F[:, 0]) > 0)  # tighter ε, slower lap (observed +0.3 %, +1.3 %)
    for p in points[1:]:
        assert any(k.startswith("ε effort") for k in p["active_constraints"]), p

    html = write_report(out, out=tmp_path / "report.html", trim_sample=4,
                        trim_study_starts=-1).read_text()

    class Sections(HTMLParser):
        def __init__(self):
            super().__init__()
            self.section, self.rows = "", {}

        def handle_starttag(self, tag, attrs):
            if tag == "section":
                self.section = dict(attrs)["id"]
            elif tag == "tr":
                self.rows[self.section] = self.rows.get(self.section, 0) + 1

    parsed = Sections()
    parsed.feed(html)
    assert parsed.rows["codesign"] >= len(rows) + 1  # the points' table (with its header row)
    assert "candidates" in parsed.rows and "ε effort" in html
    # each point's stored certificate is shown with its verdict and lap gap
    assert html.count("PASSED: lap gap") >= len(rows)

    compared = cli_runner.invoke(app, ["compare", str(out), "--json"])
    assert compared.exit_code == 0, compared.output
    gains = json.loads(compared.stdout)
    assert {g["candidate"] for g in gains} >= {"A"} and all(
        g["reference"] == "SY250" for g in gains)
    exported = cli_runner.invoke(app, ["export", str(out), "--candidate", "A", "--format",
                                       "urdf", "--out", str(tmp_path / "a.urdf")])
    assert exported.exit_code == 0, exported.output
    import xml.etree.ElementTree as ET

    assert ET.parse(tmp_path / "a.urdf").getroot().tag == "robot"


@pytest.mark.slow
def test_propeller_codesign_lap_equals_its_fixed_frame_limit_lap():
    """Co-design with the propeller propulsion model (short track, 16 intervals: at 8 the
    propeller lap misses the re-simulation by 2.3 m): the frame is valid, and the limit lap
    re-solved with θ fixed (the limit lap's own NLP, θ a parameter) equals the co-design lap
    (≤ 0.05 %; observed 0.0000 %, warm and cold 0.7459 s); a bound's reduced gradient equals
    IPOPT's multiplier (a second derivation); the CVODES re-simulation passes (6.8 mm)."""
    data = _problem(SHORT, starts=0, intervals=16).model_dump()
    data["airframe"] = str(ROOT / "configs/airframes/SY250-components-propeller.yaml")
    r = codesign(CodesignProblemConfig.model_validate(data))
    assert r.status == "completed", r.reason
    from casadrone.config import load_airframe

    cfg = load_airframe(ROOT / "configs/airframes/SY250-components-propeller.yaml")
    assert build_airframe(with_theta(cfg, r.best.theta)).propulsion == "propeller"
    assert r.certificate.passed, r.certificate.text()
    (track,) = r.certificate.tracks
    assert abs(track.gap_pct) <= 0.05
    for v in r.certificate.variables:
        if v.state != "interior":
            assert v.reduced_gradient == pytest.approx(-v.bound_multiplier, rel=0.2, abs=2e-4)


@pytest.mark.slow
def test_propeller_effort_front_meets_its_bounds(tmp_path):
    """A propeller effort front (short track, 16 intervals, 3 points, ~1 min): each point
    meets its bound, a tighter bound never gives a faster lap, and the measure equals the effort
    recomputed with numpy from the point's nodes (thrusts CT(J) ρ n² D⁴ of the rotor speeds and
    inflows, tests/unit/test_effort_propeller.py's oracle) and the effort index of the same lap."""
    from dataclasses import replace

    from casadrone.indices import EFFORT_SMOOTHING_N, INDICES
    from casadrone.limit.starts import trajectory
    from tests.unit.test_effort_propeller import numpy_thrusts

    data = _problem(SHORT, starts=0, intervals=16).model_dump()
    data["airframe"] = str(ROOT / "configs/airframes/SY250-components-propeller.yaml")
    data["objectives"] = [{"index": "J3_limit"}, {"index": "effort"}]
    data["codesign"] = {"starts": 0, "front": {"points": 3, "lowest": 0.8}}
    result = codesign(CodesignProblemConfig.model_validate(data), certify=True,
                      run_dir=tmp_path / "run")
    front = result.front
    assert len(front.points) == 3, front.stopped
    # every point certified; the last ε-point's dT/dθ, whose effort row reaches θ through p
    # (the rotor positions in the inflow), against its fixed-frame problem posed apart (CasADi's
    # parameter multipliers of the limit lap's NLP with one dense effort row)
    assert all(p.certificate.passed for p in front.points), \
        [p.certificate.text() for p in front.points]
    from casadrone.codesign.certificate import theta_gradient

    last = front.points[-1]
    lap, dT_dP = _effort_limited_lap(front.prepared, last.point, last.point.theta, last.epsilon)
    assert lap == pytest.approx(last.point.objective, rel=5e-4)
    grad = theta_gradient(front.prepared, front.prepared.config(last.point.theta),
                          front.prepared.tracks[0], dT_dP)
    dT = np.array([v.dT_dtheta for v in last.certificate.variables])
    # observed: 4e-5 apart; without the effort row's p-term the certificate's λa entry is 0.9 %
    # off and β's 9e-7 against 4e-9 (both caught here)
    assert np.allclose(grad, dT, rtol=2e-3, atol=1e-4 * np.max(np.abs(dT))), (grad, dT)
    laps = [p.point.objective for p in front.points]
    assert all(b >= a - 1e-6 for a, b in zip(laps, laps[1:], strict=False))
    assert front.points[-1].measure < 0.85 * front.points[0].measure
    prep = front.prepared
    part = prep.nlp.parts[0]
    for p in front.points[1:]:
        assert p.measure <= p.epsilon * (1 + 1e-6)
        frame = build_airframe(prep.config(p.point.theta))
        w = p.point.z[:prep.nlp.offsets[1]]
        T, X, _ = part.nlp.unpack(w)
        h = np.repeat(T, part.nlp.layout.intervals) / part.nlp.layout.intervals
        thrust = np.array([numpy_thrusts(frame, x[3:6], x[6:9], x[12:16]) for x in X[:-1]])
        numpy_effort = float(h @ np.sum((thrust ** 2 + EFFORT_SMOOTHING_N ** 2) ** 0.75, 1))
        assert numpy_effort == pytest.approx(p.measure, rel=1e-6)  # p(θ) against the build
        lap = replace(trajectory(part.nlp, w, part.nlp.layout), propulsion="propeller",
                      params=np.asarray(frame.p, float))
        assert INDICES["effort"](lap) == pytest.approx(p.measure, rel=1e-6)


@pytest.mark.slow
def test_grid_refined_when_the_resimulation_misses():
    """Propeller co-design on the short track at 8 intervals per leg (~3 min): that point misses
    the CVODES re-simulation by metres (2.3 m measured), so co-design re-poses it on 12
    intervals (``refined-12``) and certifies the point there; the certificate's re-simulation
    (CVODES, a second integrator) and its fixed-frame limit lap are the oracles."""
    from casadrone.codesign.checks import load_codesign_problem

    r = codesign(load_codesign_problem(str(ROOT / "tests/data/codesign/short-propeller.yaml"),
                                       ["limit_lap.intervals=8"]))
    assert r.status == "completed", r.reason
    assert r.intervals == 12 and "refined-12" in [s.label for s in r.starts]
    assert r.certificate.passed, r.certificate.text()
    (track,) = r.certificate.tracks
    assert track.resimulation_miss_m <= 0.15 and abs(track.gap_pct) <= 0.05


def test_template_lap_falls_back_to_the_default_starts(monkeypatch):
    """A template lap that the problem's own starts cannot fly is solved again from the default
    starts not tried yet (the limit lap's own call is replaced by one that fails for any other
    start set)."""
    from dataclasses import replace

    from casadrone.codesign import driver
    from casadrone.limit.lap import LimitLap

    calls = []

    def fake(cfg, track, options):
        calls.append(options.starts)
        ok = options.starts == ("closed-loop", "point-mass")
        return LimitLap(status="completed" if ok else "failed", reason="")

    monkeypatch.setattr(driver, "design_limit_lap", fake)
    opts = LimitLapOptions(intervals=8, starts=("coarse-grid",))
    track = load(TrackConfig, SHORT)
    assert driver.template_lap(r_template(), track, opts).completed
    # the failed coarse-grid start is not flown again
    assert calls == [("coarse-grid",), ("closed-loop", "point-mass")]
    calls.clear()  # the default starts themselves are not tried twice
    assert not driver.template_lap(r_template(), track, replace(
        opts, starts=("point-mass", "closed-loop", "coarse-grid"))).completed
    assert calls == [("point-mass", "closed-loop", "coarse-grid")]


@pytest.mark.slow
def test_paper_problem_lap_start_reaches_the_default_starts_optimum():
    """codesign-paper's template lap from the closed-loop start alone (its limit_lap.starts)
    leads the template start to the same frame and lap as the default three starts (measured:
    the same lap to 1e-16, benchmarks/RESULTS-codesign.md), and the certificate still passes."""
    from casadrone.codesign.checks import load_codesign_problem

    one = codesign(load_codesign_problem("codesign-paper", ["codesign.starts=0"]))
    three = codesign(load_codesign_problem("codesign-paper", [
        "codesign.starts=0", "limit_lap.starts=[closed-loop,point-mass,coarse-grid]"]),
        certify=False)
    assert one.certificate.passed, one.certificate.text()
    assert one.best.objective == pytest.approx(three.best.objective, rel=1e-9)
    for k, v in three.best.theta.items():
        assert one.best.theta[k] == pytest.approx(v, abs=1e-6)


# --------------------------------------------------------------------------------------------
# Certificates at every front point (casadrone.codesign.frontcert)
# --------------------------------------------------------------------------------------------


def test_every_front_point_carries_a_passing_certificate(short_front):
    """Each point's certificate passed, in the result's JSON and in the run directory's
    codesign.json; an ε-point's names the ε row among its active rows and runs no cold
    re-solve (only the fastest frame's does)."""
    from casadrone.cli.codesign import text

    result, out = short_front
    points = result.front.points
    assert all(p.certificate is not None and p.certificate.passed for p in points), \
        [p.certificate.text() for p in points]
    assert not np.isnan(points[0].certificate.tracks[0].fixed_cold_lap_s)
    for p in points[1:]:
        (track,) = p.certificate.tracks
        assert np.isnan(track.fixed_cold_lap_s)
        assert abs(track.gap_pct) <= 0.05 and track.resimulation_miss_m <= 0.15
        assert any(k.startswith("ε effort") for k in p.certificate.active)
    data = json.loads(json.dumps(result.as_dict(), default=float))
    assert [p["certificate"]["passed"] for p in data["front"]["points"]] == [True] * len(points)
    stored = json.loads((out / "codesign.json").read_text())["points"]
    assert [p["certificate"]["passed"] for p in stored] == [True] * len(points)
    assert f"front certificates: {len(points)} of {len(points)} points passed" in text(result)


def _effort_limited_lap(prep, point, theta, eps):
    """An oracle of an ε-point's fixed-frame problem posed apart from the co-design NLP: the
    limit lap's own NLP (the frame a parameter P built by the numeric airframe model) with the
    effort as one dense row ≤ ε (co-design lifts it into a running sum), CasADi's AD for its
    derivatives, solved warm from the point. Returns (lap s, dT/dP = −CasADi's lam_p)."""
    import casadi as ca

    from casadrone.codesign.nlp import effort
    from casadrone.limit.nlp import ipopt_options
    from casadrone.limit.starts import prepare as prepare_lap
    from casadrone.model import n_params

    part, cd = prep.nlp.parts[0], prep.nlp
    sym = part.nlp.problem
    p = sym["p"][:n_params(part.propulsion)]  # propeller: the thrusts depend on the frame
    solver = ca.nlpsol("effort_oracle", "ipopt",
                       {"x": sym["x"], "p": sym["p"], "f": sym["f"],
                        "g": ca.vertcat(sym["g"], effort(part, sym["x"], p))},
                       ipopt_options(1e-10, 500, True))
    pb = prepare_lap(build_airframe(prep.config(theta)), prep.tracks[0], prep.options,
                     prep.options.gate_clearance_m)
    n_rows = cd.row_offsets[1]
    eps_row = cd.row_offsets[-1] + cd.n_feas  # the ε row follows the frame's rows
    out = solver(x0=point.z[:cd.offsets[1]], p=pb.P, lbx=pb.box[0], ubx=pb.box[1],
                 lbg=np.append(pb.rows[0], -np.inf), ubg=np.append(pb.rows[1], eps),
                 lam_x0=point.lam_x[:cd.offsets[1]],
                 lam_g0=np.append(point.lam_g[:n_rows], point.lam_g[eps_row]))
    assert solver.stats()["success"], solver.stats()["return_status"]
    return float(out["f"]), -np.array(out["lam_p"]).ravel()


def test_epsilon_certificate_against_an_independent_fixed_frame_problem(short_front):
    """The last ε-point's certificate against its fixed-frame problem posed apart (the limit
    lap's own NLP with θ a parameter and one dense effort row, CasADi's AD): the same lap
    (≤ 0.05 %), and dT/dθ, from the certificate (the limit lap's rows differentiated with the
    co-design re-solve's multipliers) and from that problem's own parameter multipliers, against
    its lap re-solved at θ moved a little either way in each key.

    The oracle is the pair of one-sided difference quotients: dT/dθ must lie between them. Where
    the lap is smooth in θ both close in on the derivative (apart by the second-order term, T''h),
    so this is the derivative test. A co-design optimum can also sit where a constraint of the
    fixed-frame problem only just becomes active, and there the lap has a kink in θ: one-sided
    slopes that differ in every key (seen on one machine: 1.47e-4 and 1.64e-4 s/mm in λa,
    −6.2e-6 and +9.3e-6 s/deg in an α 0.05° inside its bound), multipliers that are not unique
    (the two derivations then differ by up to 1.2 %), and a multiplier derivative that is one of
    the slopes between the two sides (a subgradient). A wrong derivative (a sign, a missing term,
    another point's multipliers) falls outside the bracket either way."""
    from casadrone.codesign.certificate import theta_gradient
    from casadrone.config.io import ConfigError

    result, _ = short_front
    prep, fp = result.front.prepared, result.front.points[-1]
    cert, eps = fp.certificate, fp.epsilon
    lap, dT_dP = _effort_limited_lap(prep, fp.point, fp.point.theta, eps)
    assert lap == pytest.approx(fp.point.objective, rel=5e-4)
    cfg = prep.config(fp.point.theta)
    grad = theta_gradient(prep, cfg, prep.tracks[0], dT_dP)
    dT = np.array([v.dT_dtheta for v in cert.variables])
    scale = np.max(np.abs(dT))
    tol = 1e-3 * scale  # the re-solves' own accuracy (tol 1e-10) over h, with room
    steps = {"lambda_a_mm": 0.05, "lambda_b_mm": 0.05, "alpha_deg": 0.025, "beta_deg": 0.025}
    for i, (v, key) in enumerate(zip(cert.variables, prep.keys, strict=True)):
        slopes = []
        for h in (steps[key], -steps[key]):
            theta = {**fp.point.theta, key: fp.point.theta[key] + h}
            try:
                prep.config(theta)
            except ConfigError:
                continue  # no valid frame on that side (a feasibility row holds the frame)
            moved, _ = _effort_limited_lap(prep, fp.point, theta, eps)
            slopes.append((moved - lap) / h)
        assert slopes, key
        lo, hi = min(slopes), max(slopes)
        if len(slopes) == 1:  # one side only: the derivative test alone
            lo, hi = lo - 0.02 * abs(lo), hi + 0.02 * abs(hi)
        for derivation, value in (("certificate", v.dT_dtheta), ("multipliers", grad[i])):
            assert lo - tol <= value <= hi + tol, (key, derivation, value, slopes)


def test_planted_wrong_points_fail_their_certificates(short_front, tmp_path):
    """A point recorded with a lap 1 % faster than its own, or with its frame moved (λa from
    its lower bound 100 mm to 120 mm, the lap kept), fails its certificate: the fixed-frame
    re-solve returns another lap. The front keeps the failed point and is still written."""
    from dataclasses import replace

    from casadrone.codesign.front import write_run
    from casadrone.codesign.frontcert import certify_epsilon_point, certify_front

    result, _ = short_front
    front = result.front
    prep, fp = front.prepared, front.points[-1]
    p = fp.point
    fast = replace(p, objective=0.99 * p.objective,
                   laps_s={k: 0.99 * v for k, v in p.laps_s.items()})
    cert = certify_epsilon_point(prep, fast)
    assert not cert.passed and "lap gap" in cert.reason
    assert cert.tracks[0].gap_pct == pytest.approx(100 / 0.99 - 100, rel=1e-2)

    assert p.theta["lambda_a_mm"] == pytest.approx(100.0, abs=1e-3)  # at its lower bound
    z = p.z.copy()
    z[prep.nlp.offsets[-1] + prep.keys.index("lambda_a_mm")] = 0.4  # 100 + 0.4 × 50 mm
    moved = replace(p, z=z, theta={**p.theta, "lambda_a_mm": 120.0})
    cert = certify_epsilon_point(prep, moved)
    assert not cert.passed and "lap gap" in cert.reason, cert.text()
    assert cert.tracks[0].fixed_lap_s > p.objective  # longer arms: a slower lap

    planted = replace(front, points=(*front.points[:-1], replace(fp, point=fast)))
    certified = certify_front(planted, front.points[0].certificate)
    assert [q.certificate.passed for q in certified.points] == \
        [True] * (len(front.points) - 1) + [False]
    write_run(tmp_path / "run", prep, certified, len(certified.points))
    stored = json.loads((tmp_path / "run" / "codesign.json").read_text())["points"]
    assert stored[-1]["certificate"]["passed"] is False


def test_appended_rows_are_where_the_nlp_puts_them():
    """The layout the certificates read (casadrone.codesign.certificate.appended_rows: the
    multipliers, and the rows a fixed-frame re-solve frees) against the NLP's own row values at
    a start: each ε row equals its measure minus ε, the measure recomputed apart (the mass by
    the numeric airframe build, both tip-to-tip diagonals from its rotor positions),
    and each epigraph row of ``combine: worst`` equals its track's weighted lap minus t."""
    import casadi as ca

    from casadrone.codesign.certificate import appended_rows
    from casadrone.codesign.driver import constrained, initial_vector, prepare

    data = _problem(SHORT, starts=0, intervals=8).model_dump()
    del data["track"]
    data["codesign"]["tracks"] = {"a": {"track": str(SHORT), "weight": 1.0},
                                  "b": {"track": str(SHORT), "weight": 2.0}}
    data["codesign"]["combine"] = "worst"
    prep = constrained(prepare(CodesignProblemConfig.model_validate(data)),
                       ("span_m", "mass_kg"))
    cd = prep.nlp
    theta = {"lambda_a_mm": 120.0, "lambda_b_mm": 110.0, "alpha_deg": 85.0, "beta_deg": 80.0}
    z = initial_vector(prep, theta)
    assert z is not None
    z = cd.full(z)
    t = 1.7  # the epigraph variable, after θ
    z[cd.offsets[-1] + cd.n_theta] = t
    eps = np.array([0.3, 0.4])  # span_m, mass_kg: the NLP's ε order
    g = np.asarray(ca.Function("g", [cd.problem["x"], cd.problem["p"]],
                               [cd.problem["g"]])(z, eps), float).ravel()
    feas, epigraph, rows = appended_rows(cd)
    assert rows["span_m"].stop - rows["span_m"].start == 2
    assert feas.stop - feas.start == cd.n_feas and rows["mass_kg"].start == rows["span_m"].stop
    cfg = with_theta(r_template(), theta)
    frame = build_airframe(cfg)
    assert g[rows["mass_kg"]] == pytest.approx([frame.mass - 0.4], rel=1e-9)
    assert g[rows["span_m"]] + 0.3 == pytest.approx(_diagonals(frame, cfg), rel=1e-9)
    ws, _ = cd.split(z)
    laps = [float(np.sum(part.nlp.unpack(w)[0])) for part, w in zip(cd.parts, ws, strict=True)]
    assert g[epigraph] == pytest.approx([1.0 * laps[0] - t, 2.0 * laps[1] - t], rel=1e-12)


def _diagonals(frame, cfg) -> list[float]:
    """The two tip-to-tip diagonals (m), FR–RL and FL–RR: the distance between opposite rotor
    hubs (the numeric airframe's positions) plus one propeller diameter."""
    r = np.asarray(frame.rotor_positions, float)
    d = cfg.prop_diameter_mm / 1000
    return [float(np.linalg.norm(r[0] - r[2])) + d, float(np.linalg.norm(r[1] - r[3])) + d]
