"""The limit-lap command's searches (casadrone.limit.search), how a solve ended
(casadrone.limit.result.ending) and the sensitivities' table (casadrone.limit.sensitivity):
pure functions, no solve."""

from __future__ import annotations

import math

import pytest

from casadrone.limit.result import LimitLap, LimitLapOptions, StartResult, ending
from casadrone.limit.search import SEARCHES, search_options
from casadrone.limit.sensitivity import key_sensitivity, percent_of_range, sensitivity_table


@pytest.mark.parametrize(("success", "status", "expected"), [
    (True, "Solve_Succeeded", "optimal"),
    (True, "Solved_To_Acceptable_Level", "acceptable"),
    (False, "Restoration_Failed", "failed"),
    (False, "Infeasible_Problem_Detected", "failed"),
    (False, "Maximum_Iterations_Exceeded", "failed"),
    (False, "not run: the fine grid's own lap failed", "not-run"),
])
def test_ending_names_ipopts_return_statuses(success, status, expected):
    assert ending(success, status) == expected


def test_lap_says_how_its_chosen_solve_ended():
    """HS210's winning solve had stopped at IPOPT's acceptable level while the lap said only
    "completed": the lap's ``ending`` is its chosen start's, in the result and its as_dict."""
    starts = (StartResult("closed-loop", True, "Solve_Succeeded", 3.91, 100, 1.0),
              StartResult("fine-grid", True, "Solved_To_Acceptable_Level", 3.83, 80, 1.0))
    lap = LimitLap(status="completed", reason="", start="fine-grid", starts=starts)
    assert lap.ending == "acceptable"
    assert lap.return_status == "Solved_To_Acceptable_Level"
    d = lap.as_dict()
    assert d["ending"] == "acceptable"
    assert [s["ending"] for s in d["starts"]] == ["optimal", "acceptable"]
    assert LimitLap(status="failed", reason="x").ending == "failed"


def test_percent_of_range_is_table1s():
    """1 % of paper Table 1's ranges, typed in: λ 100–150 mm, α 65–90°, Ixx 0.0014–0.0030."""
    assert percent_of_range("lambda_a_mm") == pytest.approx(0.5)
    assert percent_of_range("alpha_deg") == pytest.approx(0.25)
    assert percent_of_range("ixx_kgm2") == pytest.approx(1.6e-5)
    assert math.isnan(percent_of_range("mass_kg"))


def test_key_sensitivity_uncertainty_and_resolution():
    same_sign = key_sensitivity("lambda_a_mm", 2e-4, [1e-4, 5e-4])
    assert same_sign.resolved
    assert same_sign.uncertainty_s_per_unit == pytest.approx(3e-4)
    assert same_sign.s_per_percent == pytest.approx(1e-4)  # 2e-4 s/mm × 0.5 mm
    assert same_sign.uncertainty_s_per_percent == pytest.approx(1.5e-4)
    assert (same_sign.low_s_per_unit, same_sign.high_s_per_unit) == (1e-4, 5e-4)
    assert same_sign.optima == 3
    flipped = key_sensitivity("lambda_a_mm", 1.35e-4, [-0.74e-4])  # the two SY250 branches
    assert not flipped.resolved
    alone = key_sensitivity("alpha_deg", -1e-3, [])
    assert alone.resolved and alone.optima == 1 and math.isnan(alone.uncertainty_s_per_unit)


def test_uncertainty_covers_a_difference_that_mixes_optima_of_the_same_answer():
    """Two optima 1 ms apart on a 4 s lap (the same answer: within 0.1 %), slopes 1e-4 and
    2e-4 s/mm: a central difference over ±2 % of λa's range (h = 1 mm) whose ends come from one
    each shows (g_c + g_k)/2 ± δ/(2h) = 1.5e-4 ± 5e-4 s/mm, so the uncertainty is
    |g_k − g_c|/2 + δ/(2h) = 5.5e-4 (worked by hand); an optimum 10 ms (0.25 %) slower is
    another answer and adds only the slopes' distance."""
    same = 1e-3 * 4.0  # the search's 0.1 % of a 4 s lap
    near = key_sensitivity("lambda_a_mm", 1e-4, [2e-4], [1e-3], same)
    assert near.uncertainty_s_per_unit == pytest.approx(5.5e-4)
    assert near.uncertainty_s_per_percent == pytest.approx(2.75e-4)  # × 0.5 mm per %
    far = key_sensitivity("lambda_a_mm", 1e-4, [2e-4], [1e-2], same)
    assert far.uncertainty_s_per_unit == pytest.approx(1e-4)
    assert key_sensitivity("lambda_a_mm", 1e-4, [2e-4]).uncertainty_s_per_unit == \
        pytest.approx(1e-4)  # no laps given: the slopes' distance alone


def test_sensitivity_table_keeps_the_chosen_keys_in_order():
    table = sensitivity_table({"beta_deg": 1.0, "alpha_deg": -1.0},
                              [{"beta_deg": 2.0, "alpha_deg": 1.0}])
    assert [t.key for t in table] == ["beta_deg", "alpha_deg"]
    assert [t.resolved for t in table] == [True, False]


def test_searches_set_starts_solver_and_rounds():
    base = LimitLapOptions()
    fast = search_options("fast", base, periodic=False)
    assert (fast.starts, fast.solver, fast.grid_rounds) == (
        SEARCHES["fast"].starts, SEARCHES["fast"].solver, SEARCHES["fast"].grid_rounds)
    certify = search_options("certify", base, periodic=False)
    assert certify.starts == LimitLapOptions.starts and certify.grid_rounds >= 1
    assert "library" in certify.starts
    assert set(fast.starts) | set(fast.fallback_starts) <= set(certify.starts)  # never slower
    assert certify.solver == "ipopt"
    # the user's solver and rounds win; fatrop cannot solve a periodic lap
    assert search_options("fast", base, periodic=False, solver="ipopt").solver == "ipopt"
    assert search_options("certify", base, periodic=False, grid_rounds=0).grid_rounds == 0
    if SEARCHES["fast"].solver == "fatrop":
        assert search_options("fast", base, periodic=True).solver == "ipopt"


def _result(table, ending_="acceptable"):
    starts = [{"start": "fine-grid", "success": True, "ending": ending_, "lap_time_s": 3.8307,
               "return_status": "Solved_To_Acceptable_Level"},
              {"start": "closed-loop", "success": False, "ending": "failed",
               "lap_time_s": math.nan, "return_status": "Restoration_Failed"}]
    return {"start": "fine-grid", "lap_time_s": 3.8307, "ending": ending_,
            "return_status": starts[0]["return_status"], "starts": starts,
            "sensitivity_table": [t.as_dict() for t in table]}


def test_text_says_which_optimum_and_what_is_not_resolved():
    from casadrone.cli.limit import _sensitivity_text, _status_text

    table = sensitivity_table({"lambda_a_mm": 1.35e-4, "alpha_deg": -2e-3},
                              [{"lambda_a_mm": -0.74e-4, "alpha_deg": -1e-3}])
    text = "\n".join(_sensitivity_text(_result(table)))
    assert "fine-grid, 3.8307 s" in text and "2 verified optima" in text
    # λa: the two branches disagree in sign; α: −2e-3 s/deg × 0.25 deg = −0.5 ms per 1 %,
    # the other optimum −0.25 ms: ± 0.25 ms
    assert "lambda_a_mm" in text and "not resolved" in text.split("lambda_a_mm")[1]
    assert "-0.500 ± 0.250" in text
    status = "\n".join(_status_text(_result(table)))
    assert "chosen solve: acceptable (Solved_To_Acceptable_Level)" in status
    assert "closed-loop failed (Restoration_Failed)" in status


def test_text_of_one_optimum_points_to_certify():
    from casadrone.cli.limit import _sensitivity_text

    text = "\n".join(_sensitivity_text(_result(sensitivity_table({"beta_deg": 4e-3}, []))))
    assert "--certify" in text and "+1.000" in text and "±" not in text


def test_text_names_the_processes_whose_cpu_it_sums():
    from casadrone.cli.limit import _processes_cost

    one = _processes_cost({"cpu_time_s": 162.0, "wall_time_s": 300.0, "workers": 1})
    two = _processes_cost({"cpu_time_s": 138.2, "wall_time_s": 80.0, "workers": 2})
    assert one == "CPU 162.0 s, wall 300.0 s"
    assert two.startswith("CPU 138.2 s, wall 80.0 s on 2 processes")
