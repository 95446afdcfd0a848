"""The hybrid's polish (``algorithm.settings.polish``): a front member improved by the co-design
NLP with its effort held as an ε-constraint.

Oracles: the member's own limit lap and effort from the limit lap's driver (the member as the
optimiser would evaluate it); the polished frame's limit lap re-solved by the limit lap's own
driver with θ fixed and cold starts only (a different NLP, started from nothing the polish
produced); Pareto dominance written out by hand; the CLI's exit code and message for a refused
problem.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from casadrone.airframe import with_theta
from casadrone.config.codesign import CodesignProblemConfig
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.indices import limit_lap_effort
from casadrone.limit.lap import LapSeeds, LimitLapOptions, design_limit_lap

ROOT = Path(__file__).resolve().parents[2]
SHORT = ROOT / "tests" / "data" / "codesign" / "short-track.yaml"
INTERVALS = 8
#: A member away from the short track's fastest frame (the template is SY250: λa = λb = 125 mm).
MEMBER = {"lambda_a_mm": 140.0, "lambda_b_mm": 110.0, "alpha_deg": 70.0, "beta_deg": 85.0}


def _problem() -> CodesignProblemConfig:
    return CodesignProblemConfig.model_validate({
        "name": "short-polish",
        "airframe": str(ROOT / "configs/airframes/SY250-components.yaml"),
        "track": str(SHORT),
        "objectives": [{"index": "J3_limit"}, {"index": "effort"}],
        "variables": [{"name": k, "lower": lo, "upper": hi} for k, lo, hi in
                      [("lambda_a_mm", 100.0, 150.0), ("lambda_b_mm", 100.0, 150.0),
                       ("alpha_deg", 65.0, 90.0), ("beta_deg", 65.0, 90.0)]],
        "limit_lap": {"intervals": INTERVALS}, "codesign": {"starts": 0}})


def _own_lap(prep, theta):
    """A frame's limit lap and effort as the optimiser's evaluation chain defines them: its
    minimum-time lap primal-dual warm-started from the template's limit lap (the per-study
    reference, :func:`casadrone.evaluate.evaluate_limit`; nothing from the polish)."""
    template = prep.template_laps[0]
    lap = design_limit_lap(with_theta(prep.template, theta), load(TrackConfig, SHORT),
                           LimitLapOptions(intervals=INTERVALS, sensitivities=False, starts=(),
                                           gate_clearance_m=prep.options.gate_clearance_m),
                           LapSeeds(warm_starts=(template,)))
    assert lap.completed, lap.reason
    return {"J3_limit": lap.lap_time_s, "effort": limit_lap_effort(lap)}


@pytest.fixture(scope="module")
def polished():
    from casadrone.codesign.polish import polish_member, prepared

    prep = prepared(_problem())
    member = _own_lap(prep, MEMBER)
    return prep, member, polish_member(prep, MEMBER, member, check=True)


def test_polished_frame_is_not_dominated_by_its_member(polished):
    """The polished frame, evaluated as the optimiser evaluates any frame, is not dominated by
    the member (observed: lap 0.8090 -> 0.7918 s, effort 51.90 -> 54.31 N^1.5 s: faster for
    more effort, a trade-off), and the co-design point meets the member's effort (its ε row,
    IPOPT's tolerance 1e-6)."""
    from casadrone.codesign.polish import improves

    prep, member, p = polished
    assert p.accepted, p.reason
    assert p.values["effort"] <= member["effort"] * (1 + 1e-6)
    own = _own_lap(prep, p.theta)
    dominated = (member["J3_limit"] <= own["J3_limit"] and member["effort"] <= own["effort"]
                 and (member["J3_limit"] < own["J3_limit"] or member["effort"] < own["effort"]))
    assert not dominated
    assert improves(member, own)
    assert not improves(member, {"J3_limit": member["J3_limit"] + 1e-3,
                                 "effort": member["effort"]})


def test_polished_frames_limit_lap_is_reached_from_the_polish(polished):
    """θ_p's minimum-time lap re-solved with θ fixed from the polished point is flown by CVODES
    within the limit lap's miss and is no slower than the co-design point's lap, which also
    holds the effort (a more constrained problem). The optimiser's evaluation chain flies the
    same frame from the template's limit lap, another start: a local optimum of the same
    problem, within a few percent of it. Which one each start reaches follows the last bits of
    the derivative blocks: with whole-step blocks both gave 0.79179 and 0.79177 s; with the
    chained ones the polish 0.7918 s and the evaluation chain 0.7678 s (the template's cold
    lap now sits in a faster basin); the limit lap's cold starts alone landed at 0.8162 s."""
    prep, _, p = polished
    own = _own_lap(prep, p.theta)
    assert p.resimulation_miss_m <= prep.options.max_miss_m
    assert p.fixed_lap_s <= p.values["J3_limit"] * (1 + 1e-6)
    assert own["J3_limit"] == pytest.approx(p.fixed_lap_s, rel=0.05)


def test_polish_of_a_closed_loop_objective_is_refused(tmp_path):
    text = (ROOT / "problems" / "limit-effort.yaml").read_text()
    text = text.replace("settings: {n_ind_ga: 8, n_div: 20}",
                        "settings: {n_ind_ga: 8, n_div: 20, polish: {members: 3}}")
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("{index: effort, sense: min}", "{index: J5}"))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-m", "casadrone", "run", str(bad), "--out",
                          str(tmp_path / "run")], capture_output=True, text=True, env=env,
                         timeout=120)
    assert out.returncode == 2, out.stderr
    assert "bad.yaml" in out.stderr and "algorithm.settings.polish" in out.stderr
    assert "'J5'" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "run").exists()


def _hybrid_problem(tmp_path):
    """A tiny ev-MOGA run of lap against effort on the short track, two members polished."""
    from casadrone.optimise.checks import load_problem

    text = (ROOT / "problems" / "limit-effort.yaml").read_text()
    for old, new in [("configs/tracks/paper-rectangle.yaml", str(SHORT)),
                     ("configs/airframes/SY250-components.yaml",
                      str(ROOT / "configs/airframes/SY250-components.yaml")),
                     ("configs/controllers/frozen-wrench-sy250-components.yaml",
                      str(ROOT / "configs/controllers/frozen-wrench-sy250-components.yaml"))]:
        text = text.replace(old, new)
    path = tmp_path / "hybrid.yaml"
    path.write_text(text)
    return load_problem(path, ["algorithm.population=4", "algorithm.generations=1",
                               "algorithm.settings.n_ind_ga=2", "algorithm.settings.n_div=4",
                               "algorithm.settings.polish={members: 2}"])


@pytest.mark.slow
def test_hybrid_run_polishes_and_resumes_as_uninterrupted(tmp_path, monkeypatch):
    """A run killed during its polish resumes and ends as the uninterrupted run (the same
    pareto.csv and history); every polish the run says improves on its member is not dominated
    by it (the member's and the evaluation's objectives, compared by hand); the front is the
    non-dominated set of the stored evaluations' ε-box archive, so no member of pareto.csv is
    dominated by a stored completed evaluation's objectives."""
    import json

    import casadrone.codesign.polish as polish
    import casadrone.optimise.hybrid as hybrid  # the polish's steps are called by these names
    from casadrone.config.problem import BackendConfig
    from casadrone.optimise.runner import resume, run
    from casadrone.rundir.store import RunStore

    problem = _hybrid_problem(tmp_path)
    full = tmp_path / "full"
    run(problem, full, BackendConfig(name="serial"), quiet=True)
    report = json.loads((full / "polish.json").read_text())
    assert len(report["members"]) == 2
    for m in report["members"]:
        if m["improves"]:
            a, b = m["member"], m["evaluation"]
            assert not (a["J3_limit"] <= b["J3_limit"] and a["effort"] <= b["effort"]
                        and (a["J3_limit"] < b["J3_limit"] or a["effort"] < b["effort"]))
    history = RunStore(full).history()
    assert max(r["generation"] for r in history) == report["generation"] == 2
    _, rows = RunStore(full).read_pareto()
    done = [(r["J3_limit"], r["effort"]) for r in history if r["status"] == "completed"]
    for *_, lap, effort in rows:
        assert not any(t <= lap and e <= effort and (t < lap or e < effort) for t, e in done)

    calls = []
    real = polish.polish_member

    def killed_on_second(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise RuntimeError("killed during the polish")
        return real(*args, **kwargs)

    monkeypatch.setattr(hybrid, "polish_member", killed_on_second)
    part = tmp_path / "part"
    with pytest.raises(RuntimeError, match="killed during the polish"):
        run(problem, part, BackendConfig(name="serial"), quiet=True)
    assert not (part / "pareto.csv").exists()
    monkeypatch.setattr(hybrid, "polish_member", real)
    resume(part, quiet=True)
    assert (part / "pareto.csv").read_bytes() == (full / "pareto.csv").read_bytes()
    strip = lambda h: [{k: v for k, v in r.items() if k != "wall_time_s"} for r in h]  # noqa: E731
    assert strip(RunStore(part).history()) == strip(history)


@pytest.mark.slow
def test_polish_stage_stores_evaluates_and_resumes(tmp_path, monkeypatch):
    """The runner's side of the polish with a stand-in for the co-design solve (it proposes the
    box's centre for every member; ~3 min instead of the real solve's ~30): the proposals are
    evaluated as one more generation, every evaluation in the history is the problem's own (the
    centre's indices equal a fresh evaluation of it), and a run killed during the polish resumes
    to the same pareto.csv and history."""
    import json

    import casadrone.codesign.polish as polish
    import casadrone.optimise.hybrid as hybrid  # the polish's steps are called by these names
    from casadrone.config.problem import BackendConfig
    from casadrone.optimise.problem import Study, evaluate_rows
    from casadrone.optimise.runner import resume, run
    from casadrone.rundir.store import RunStore

    problem = _hybrid_problem(tmp_path)
    centre = {v.name: (v.lower + v.upper) / 2 for v in problem.variables}
    calls = []

    def stand_in(prep, theta, member, check=False):
        calls.append(1)
        if calls == [1] * 4:  # the second member of the second run: killed
            raise RuntimeError("killed during the polish")
        return polish.Polished(theta, member, centre, {}, True, "stand-in", "", 0, 0.0)

    monkeypatch.setattr(hybrid, "polish_member", stand_in)
    monkeypatch.setattr(hybrid, "prepared", lambda problem: None)
    full = tmp_path / "full"
    run(problem, full, BackendConfig(name="serial"), quiet=True)
    report = json.loads((full / "polish.json").read_text())
    history = RunStore(full).history()
    last = [r for r in history if r["generation"] == report["generation"]]
    assert len(report["members"]) == len(last) == 2
    (fresh,) = evaluate_rows(Study(problem), np.array([[centre[k] for k in centre]]))
    for r in last:
        assert [r[k] for k in centre] == list(centre.values())
        assert r["J3_limit"] == pytest.approx(fresh.indices["J3_limit"], rel=1e-9)
    part = tmp_path / "part"
    with pytest.raises(RuntimeError, match="killed during the polish"):
        run(problem, part, BackendConfig(name="serial"), quiet=True)
    assert not (part / "pareto.csv").exists()
    resume(part, quiet=True)
    assert (part / "pareto.csv").read_bytes() == (full / "pareto.csv").read_bytes()
    strip = lambda h: [{k: v for k, v in r.items() if k != "wall_time_s"} for r in h]  # noqa: E731
    assert strip(RunStore(part).history()) == strip(history)


@pytest.mark.slow
def test_propeller_polish_holds_the_members_effort():
    """The polish with the propeller propulsion model (short track, 16 intervals, ~3 min): the
    member's effort is its own limit lap's (the index reads each rotor's thrust from its speed
    and inflow: casadrone.indices.limit_lap_thrusts), the co-design point meets it, and the
    polished frame evaluated as the optimiser evaluates any frame is not dominated by the
    member."""
    from casadrone.codesign.polish import improves, polish_member, prepared

    data = _problem().model_dump()
    data["airframe"] = str(ROOT / "configs/airframes/SY250-components-propeller.yaml")
    data["limit_lap"] = {"intervals": 16}
    data["codesign"] = {"starts": 0}
    prep = prepared(CodesignProblemConfig.model_validate(data))

    def own(theta):
        lap = design_limit_lap(with_theta(prep.template, theta), load(TrackConfig, SHORT),
                               LimitLapOptions(intervals=16, sensitivities=False, starts=(),
                                               gate_clearance_m=prep.options.gate_clearance_m),
                               LapSeeds(warm_starts=(prep.template_laps[0],)))
        assert lap.completed and lap.propulsion == "propeller", lap.reason
        return {"J3_limit": lap.lap_time_s, "effort": limit_lap_effort(lap)}

    member = own(MEMBER)
    p = polish_member(prep, MEMBER, member)
    assert p.accepted, p.reason
    assert p.values["effort"] <= member["effort"] * (1 + 1e-6)
    assert improves(member, own(p.theta))
