"""A run's A/B/C candidates against reference airframes: paper Eq. 21 on hand-computed numbers.

The chain is replaced by a fake ``evaluate`` returning hand-made interval tables, so every gain
below is computed by hand from the printed formula; the real chain is exercised by
tests/integration/test_cli_optimise.py.
"""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest

from casadrone import benchmark
from casadrone.compare import (
    CANDIDATE_LABELS,
    NUMERICAL_ZERO,
    GainRow,
    compare_run,
    gain_pct,
    magnitude_gain_pct,
    run_candidates,
)
from casadrone.config.reference import load_reference
from casadrone.evaluate import Evaluation
from casadrone.indices import Interval
from casadrone.optimise.checks import load_problem
from casadrone.optimise.problem import Study
from casadrone.rundir.store import RunStore

#: the module (``casadrone.evaluate`` as an attribute of the package is the function)
#: The module whose name ``evaluate`` compare_run calls (replaced by the tests' stand-ins).
compare_mod = importlib.import_module("casadrone.compare")
QUICK = "problems/quick.yaml"
TWO_OBJECTIVES = "objectives=[{index: J3, sense: min}, {index: J5, sense: min}]"


def test_compare_names_live_only_in_compare():
    # version 0.x: no compatibility re-exports; benchmark.py sits below compare.py in the chain
    for name in ("gain_pct", "magnitude_gain_pct", "CANDIDATE_LABELS", "GainRow", "compare_run",
                 "run_candidates"):
        assert callable(globals()[name]) or globals()[name] is not None
        assert not hasattr(benchmark, name)


# --------------------------------------------------------------------------------------------
# Eq. 21 by hand
# --------------------------------------------------------------------------------------------


def test_eq21_exactly_positive_is_faster():
    # (t_benchmark − t_candidate) / t_benchmark × 100
    assert gain_pct(9.0, 10.0) == pytest.approx(10.0, abs=1e-12)  # faster → positive
    assert gain_pct(12.6, 12.0) == pytest.approx(-5.0, abs=1e-12)  # slower → negative
    assert gain_pct(18.0, 18.0) == 0.0
    # Table 9, SY_O1 250, interval 1: 51.80 % over the measured 154.66 s ↔ a 74.546 s candidate
    # (154.66 × 0.482)
    assert gain_pct(74.546, 154.66) == pytest.approx(100 * (154.66 - 74.546) / 154.66, rel=1e-12)
    assert gain_pct(74.546, 154.66) == pytest.approx(51.80, abs=5e-3)


def test_magnitude_gain_equals_eq21_when_signs_agree():
    # Table 10, SY_O1 250, interval 1: 25.34 % less effort than the measured −1.16 V
    assert magnitude_gain_pct(-0.866056, -1.16) == pytest.approx(25.34, abs=1e-4)
    assert magnitude_gain_pct(-0.866056, -1.16) == pytest.approx(gain_pct(-0.866056, -1.16))
    # thrust maxima (positive) and minima (negative): a larger extreme is a negative gain
    assert magnitude_gain_pct(5.57, 5.33) == pytest.approx(100 * (5.33 - 5.57) / 5.33, rel=1e-12)
    assert magnitude_gain_pct(-3.72, -3.96) == pytest.approx(100 * 0.24 / 3.96, rel=1e-12)
    assert magnitude_gain_pct(-3.72, -3.96) == pytest.approx(gain_pct(-3.72, -3.96), rel=1e-12)


def test_magnitude_gain_on_a_sign_flip_is_not_above_100():
    # Table 10, SY_O1 220, interval 4: the printed 103.03 % is the signed ratio 1 − cand/ref with a
    # candidate of the other sign; by magnitude the effort fell by 96.97 %
    cand, ref = -0.001, 0.033
    assert gain_pct(cand, ref) == pytest.approx(103.0303, abs=1e-4)
    assert magnitude_gain_pct(cand, ref) == pytest.approx(96.9697, abs=1e-4)
    # a flip to twice the size: signed Eq. 21 would say +300 %, the effort doubled: −100 %
    assert gain_pct(-2.0, 1.0) == pytest.approx(300.0)
    assert magnitude_gain_pct(-2.0, 1.0) == pytest.approx(-100.0)


def test_magnitude_gain_of_numerical_zeros():
    tiny = NUMERICAL_ZERO / 10
    assert magnitude_gain_pct(3e-14, -5e-17) == 0.0  # both round-off: no change
    assert magnitude_gain_pct(0.0, 0.0) == 0.0
    assert math.isnan(magnitude_gain_pct(0.1, tiny))  # nothing to take a percentage of
    assert magnitude_gain_pct(tiny, 0.2) == pytest.approx(100.0, abs=1e-3)
    assert math.isnan(magnitude_gain_pct(math.nan, 1.0))


# --------------------------------------------------------------------------------------------
# A fake run directory and a fake chain
# --------------------------------------------------------------------------------------------

#: Pareto set (θ: λa, λb, α, β, Ixx, Iyy, Izz) and front (J3 s, J5 V), both objectives minimised.
SET = [
    [110.0, 130.0, 80.0, 85.0, 0.0020, 0.0016, 0.0035],
    [120.0, 125.0, 85.0, 80.0, 0.0021, 0.0017, 0.0036],
    [125.0, 125.0, 90.0, 90.0, 0.0022, 0.0017, 0.0036],
]
FRONT = [[16.0, 0.70], [16.5, 0.60], [17.0, 0.50]]
# normalised: J3 → 0, 0.5, 1 and J5 → 1, 0.5, 0. Utopian distances 1, 0.707, 1 → row 1 (A).
# Mean point (0.5, 0.5) → row 1 (B). Extreme on J3 (the first objective) → row 0 (C).


def make_run(path, problem, X=SET, F=FRONT):
    study = Study(problem)
    store = RunStore.create(path, problem, study.variable_names, study.objective_names, "serial")
    store.write_pareto(study.variable_names, study.objective_names, np.array(X), np.array(F))
    store.update_manifest(status="completed", n_evaluations=len(X))
    return path


@pytest.fixture
def problem():
    return load_problem(QUICK, [TWO_OBJECTIVES, "integrator=cvodes"])


@pytest.fixture
def run_dir(tmp_path, problem):
    return make_run(tmp_path / "run", problem)


def test_run_candidates_by_hand(run_dir):
    a, b, c = run_candidates(run_dir)
    assert [x.label for x in (a, b, c)] == ["A", "B", "C"]
    assert [x.method for x in (a, b, c)] == list(CANDIDATE_LABELS)
    assert (a.row, b.row, c.row) == (1, 1, 0)
    assert a.distance == pytest.approx(math.sqrt(0.5)) and b.distance == pytest.approx(0.0)
    assert c.objective == "J3" and a.objective is None
    assert list(a.theta) == ["lambda_a_mm", "lambda_b_mm", "alpha_deg", "beta_deg", "ixx_kgm2",
                             "iyy_kgm2", "izz_kgm2"]
    assert list(a.theta.values()) == SET[1] and a.objectives == {"J3": 16.5, "J5": 0.60}
    (c5,) = run_candidates(run_dir, ("extreme",), objective="J5")
    assert c5.row == 2 and c5.objectives == {"J3": 17.0, "J5": 0.50}


def test_run_candidates_errors(tmp_path, run_dir, problem):
    with pytest.raises(ValueError, match="unknown objective 'J9'"):
        run_candidates(run_dir, objective="J9")
    with pytest.raises(FileNotFoundError, match="not a run directory"):
        run_candidates(tmp_path / "nowhere")
    (run_dir / "pareto.csv").unlink()
    with pytest.raises(FileNotFoundError, match="has not finished"):
        run_candidates(run_dir)
    empty = make_run(tmp_path / "empty", problem, X=np.empty((0, 7)), F=np.empty((0, 2)))
    with pytest.raises(ValueError, match="empty"):
        run_candidates(empty)


def intervals(split, effort, hi, lo):
    return tuple(Interval(waypoint=j + 1, split_time_s=s, effort_V=e, pair_thrust_max_N=a,
                          pair_thrust_min_N=b, straight=j % 2 == 0, n_samples=10)
                 for j, (s, e, a, b) in enumerate(zip(split, effort, hi, lo, strict=True)))


#: The reference airframe (SY250) as "simulated" by the fake chain.
REFERENCE = intervals([10.0, 12.0, 18.0, 20.0], [-1.0, 0.5, 2e-7, 0.0],
                      [1.0, 2.0, 1e-7, 0.5], [-1.0, -2.0, -1e-7, 0.0])
#: Candidates, by their λa (A and B are row 1, C is row 0).
CANDIDATES = {
    120.0: intervals([9.0, 12.6, 18.0, 21.0], [-0.75, -0.25, 1e-7, 0.1],
                     [1.5, 1.0, 5e-8, 0.5], [-0.5, -3.0, 0.3, 0.0]),
    110.0: intervals([8.0, 11.0, 17.0, 19.0], [-0.5, 0.5, 0.0, 0.0],
                     [1.0, 1.0, 0.0, 0.25], [-1.0, -1.0, 0.0, -0.25]),
}
# Row 1 over the simulated reference, by hand (interval 1…4):
#   time   (10−9)/10 = 10 %, (12−12.6)/12 = −5 %, 0 %, (20−21)/20 = −5 %
#   effort (1−0.75)/1 = 25 %, (0.5−0.25)/0.5 = 50 % (sign flip, by magnitude), 0 (both zero),
#          NaN (the reference is zero, the candidate is not)
#   T max  (1−1.5)/1 = −50 %, (2−1)/2 = 50 %, 0 (both zero), 0 %
#   T min  (1−0.5)/1 = 50 %, (2−3)/2 = −50 %, NaN (reference zero), 0 (both zero)
EXPECTED_ROW1 = [
    (10.0, 25.0, -50.0, 50.0),
    (-5.0, 50.0, 50.0, -50.0),
    (0.0, 0.0, 0.0, math.nan),
    (-5.0, math.nan, 0.0, 0.0),
]


@pytest.fixture
def fake_chain(monkeypatch):
    calls = []

    def fake_evaluate(theta, setup, index_names=None, keep_trajectory=False):
        calls.append((dict(theta), setup))
        if theta["lambda_a_mm"] == 125.0:  # a reference (no chosen candidate has λa = 125)
            table = REFERENCE
        else:
            table = CANDIDATES[theta["lambda_a_mm"]]
        return Evaluation(theta=dict(theta), status="completed", stage="", reason="",
                          indices={"J3": table[-1].split_time_s}, intervals=table)

    monkeypatch.setattr(compare_mod, "evaluate", fake_evaluate)
    return calls


def gains(row: GainRow) -> tuple[float, ...]:
    return (row.time_gain_pct, row.effort_gain_pct, row.thrust_max_gain_pct,
            row.thrust_min_gain_pct)


def test_compare_run_by_hand(run_dir, problem, fake_chain):
    rows = compare_run(run_dir, ("SY250",))
    # 3 candidates × (4 simulated + 4 measured intervals)
    assert len(rows) == 24
    assert [(r.candidate, r.basis, r.interval) for r in rows[:8]] == (
        [("A", "simulated", j) for j in range(1, 5)] + [("A", "measured", j) for j in range(1, 5)])
    assert {r.reference for r in rows} == {"SY250"}
    sim_a = [r for r in rows if r.candidate == "A" and r.basis == "simulated"]
    for row, expected in zip(sim_a, EXPECTED_ROW1, strict=True):
        assert gains(row) == pytest.approx(expected, rel=1e-12, abs=1e-12, nan_ok=True)
    # B is the same design as A: same gains; C (row 0) is faster everywhere
    sim_b = [r for r in rows if r.candidate == "B" and r.basis == "simulated"]
    np.testing.assert_array_equal([gains(r) for r in sim_b], [gains(r) for r in sim_a])
    sim_c = [r for r in rows if r.candidate == "C" and r.basis == "simulated"]
    np.testing.assert_allclose([r.time_gain_pct for r in sim_c], [20.0, 100 / 12, 100 / 18, 5.0])
    # measured basis: the same formulas against paper Table 4's SY250 row
    t4 = load_reference().airframes["SY250"]
    meas_a = [r for r in rows if r.candidate == "A" and r.basis == "measured"]
    cand = CANDIDATES[120.0]
    for j, r in enumerate(meas_a):
        assert r.time_gain_pct == pytest.approx(
            100 * (t4.split_times_s[j] - cand[j].split_time_s) / t4.split_times_s[j], rel=1e-12)
        assert r.effort_gain_pct == pytest.approx(
            100 * (abs(t4.effort_v[j]) - abs(cand[j].effort_V)) / abs(t4.effort_v[j]), rel=1e-12)
        assert r.thrust_min_gain_pct == pytest.approx(
            100 * (abs(t4.pair_thrust_min_n[j]) - abs(cand[j].pair_thrust_min_N))
            / abs(t4.pair_thrust_min_n[j]), rel=1e-12)
    assert meas_a[0].time_gain_pct == pytest.approx(100 * (154.66 - 9.0) / 154.66)
    assert meas_a[0].effort_gain_pct == pytest.approx(100 * (1.16 - 0.75) / 1.16)


def test_compare_run_flies_on_the_runs_platform(run_dir, problem, fake_chain):
    compare_run(run_dir, ("SY250",))
    setups = [s for _, s in fake_chain]
    # one flight per distinct design (A and B coincide) plus the reference
    assert len(fake_chain) == 3
    assert {s.integrator for s in setups} == {"cvodes"}  # the run's integrator, not the default
    first = setups[0]
    for s in setups[1:]:
        assert (s.controller, s.track, s.trim_solver, s.sim_options) == (
            first.controller, first.track, first.trim_solver, first.sim_options)
    ref_theta, ref_setup = fake_chain[0]
    assert ref_setup.template.name == "SY250" and ref_theta["lambda_a_mm"] == 125.0
    cand_thetas = [t for t, s in fake_chain[1:]]
    assert [list(t.values()) for t in cand_thetas] == [SET[1], SET[0]]


def test_compare_run_reference_without_measured_row(tmp_path, run_dir, fake_chain):
    other = tmp_path / "mine.yaml"
    text = (load_problem(QUICK).airframe).read_text().replace("name: SY250", "name: mine")
    other.write_text(text)  # SY250's numbers under another name: no Table 4 row
    rows = compare_run(run_dir, (str(other),))
    assert {r.basis for r in rows} == {"simulated"} and {r.reference for r in rows} == {"mine"}
    assert len(rows) == 12


def test_compare_run_failed_candidate_gives_nan(run_dir, monkeypatch):
    def failing(theta, setup, index_names=None, keep_trajectory=False):
        if setup.template.name == "SY250" and theta["lambda_a_mm"] == 125.0:
            return Evaluation(theta=dict(theta), status="completed", stage="", reason="",
                              intervals=REFERENCE)
        return Evaluation(theta=dict(theta), status="failed", stage="lap", reason="time-out")

    monkeypatch.setattr(compare_mod, "evaluate", failing)
    rows = compare_run(run_dir, ("SY250",))
    assert len(rows) == 24
    assert all(math.isnan(g) for r in rows for g in gains(r))
