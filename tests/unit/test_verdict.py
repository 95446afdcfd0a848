"""The verdict of a candidate against the baseline (casadrone.verdict): dominance, the change of
each index and the noise, against values computed by hand; the baseline on the front figure."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from casadrone import plots
from casadrone.evaluate import default_setup
from casadrone.report.verdict import impossible_bodies
from casadrone.simulate import SimOptions
from casadrone.verdict import (
    compare_to_baseline,
    format_verdicts,
    headline,
    jitter_moves,
    refined,
)

SENSES = {"J1": "max", "J3": "min", "J5": "min"}
UNITS = {"J1": "m/s", "J3": "s", "J5": "V"}
BASE = {"J1": 10.0, "J3": 16.5, "J5": 0.5}


def verdict(values, noise=None):
    return compare_to_baseline("A", "SY250", values, BASE, SENSES, ["J1", "J3"], UNITS, noise)


def test_a_candidate_better_on_every_objective_dominates():
    v = verdict({"J1": 10.5, "J3": 16.0, "J5": 0.6})
    j1, j3, j5 = v.indices
    # by hand: J1 +0.5 m/s = +5 % (max: better); J3 −0.5 s = −0.5/16.5 = −3.0303 % (min: better)
    assert (j1.index, j1.difference, j1.direction) == ("J1", pytest.approx(0.5), "better")
    assert j1.difference_pct == pytest.approx(5.0, rel=1e-12)
    assert j3.difference == pytest.approx(-0.5) and j3.direction == "better"
    assert j3.difference_pct == pytest.approx(-3.0303030303, rel=1e-9)
    # J5 is not an objective: worse (+20 %), but dominance is on the objectives only
    assert not j5.objective and j5.direction == "worse"
    assert j5.difference_pct == pytest.approx(20.0, rel=1e-12)
    assert v.dominates is True
    assert v.dominates_beyond_noise is None and j1.within_noise is None  # noise not measured


def test_one_worse_objective_breaks_dominance_unless_within_noise():
    values = {"J1": 10.5, "J3": 16.55, "J5": 0.5}  # J3 +0.05 s: worse
    v = verdict(values, {"J1": 0.1, "J3": 0.1, "J5": 0.1})
    assert v.dominates is False
    j3 = v.indices[1]
    assert j3.direction == "worse" and j3.within_noise is True  # |0.05| <= 0.1
    assert v.dominates_beyond_noise is True  # J3 a tie within the noise, J1 better beyond it
    assert v.indices[2].direction == "equal"
    # a noise larger than every difference: all ties, nothing better beyond noise
    tied = verdict(values, {"J1": 1.0, "J3": 1.0})
    assert tied.dominates_beyond_noise is False
    assert "dominates SY250: no (worse on J3)" in headline(v)
    assert "within noise as ties: yes (J3 within noise)" in headline(v).replace(
        "differences within the noise", "within noise")


def test_max_sense_lower_is_worse_and_equal_is_not_dominance():
    v = verdict({"J1": 9.9, "J3": 16.5, "J5": 0.5})
    assert v.indices[0].direction == "worse" and v.indices[0].difference_pct == pytest.approx(-1.0)
    assert v.dominates is False
    same = verdict(dict(BASE))
    assert same.dominates is False and {c.direction for c in same.indices} == {"equal"}


def test_a_zero_baseline_has_no_percentage_and_a_missing_objective_is_refused():
    v = compare_to_baseline("A", "B", {"J1": 1.0}, {"J1": 0.0}, {"J1": "max"}, ["J1"])
    assert math.isnan(v.indices[0].difference_pct) and v.dominates is True
    with pytest.raises(ValueError, match="no value of J3"):
        compare_to_baseline("A", "B", {"J1": 1.0}, {"J1": 0.0}, {"J1": "max"}, ["J1", "J3"])


def test_the_decide_block_states_each_objective():
    v = verdict({"J1": 10.5, "J3": 16.55, "J5": 0.5}, {"J1": 0.1, "J3": 0.1})
    text = format_verdicts([v], "how")
    assert text.splitlines() == [
        "Verdict against SY250:",
        "  A dominates SY250: no (worse on J3); counting differences within the noise as ties: "
        "yes (J3 within noise)",
        "    J1 +5.0 % better; J3 +0.3 % worse (within noise)",  # 0.05 / 16.5 = 0.303 %
        "  (how)"]


def test_jitter_moves_every_variable_by_the_step_and_stays_in_bounds():
    theta = {"a": 1.0, "b": 90.0, "c": 5.0}
    bounds = {"a": (0.0, 2.0), "b": (65.0, 90.0)}  # b at its upper bound; c not a variable
    moves = jitter_moves(theta, bounds, moves=8, step=1e-3, seed=3)
    assert len(moves) == 8
    for m in moves:
        assert abs(m["a"] - 1.0) == pytest.approx(2e-3, rel=1e-9)
        assert m["b"] == pytest.approx(90.0 - 0.025, rel=1e-12)  # reflected into the bounds
        assert m["c"] == 5.0
    assert {np.sign(m["a"] - 1.0) for m in moves} == {-1.0, 1.0}


def test_refined_halves_the_rk4_step_or_tightens_sundials():
    base = default_setup("SY250")
    rk4 = replace(base, sim_options=SimOptions(substeps=2))
    assert refined(rk4).sim_options.substeps == 4 and refined(rk4).limit is None
    cv = replace(base, integrator="cvodes", sim_options=SimOptions(rtol=1e-8, atol=1e-9))
    assert refined(cv).sim_options.rtol == pytest.approx(1e-10)
    assert refined(cv).sim_options.atol == pytest.approx(1e-11)


def test_impossible_bodies_are_counted_from_their_reasons():
    history = [
        {"status": "completed", "stage": "", "reason": ""},
        {"status": "failed", "stage": "geometry", "reason": "SY250: izz_kgm2: Ixx + Iyy ≥ Izz "
         "violated: ...; no rigid body has these moments (each principal moment ...)"},
        {"status": "failed", "stage": "geometry", "reason": "SY250: alpha_deg: rotors FR and FL "
         "overlap"},
        {"status": "failed", "stage": "geometry", "reason": "x: ixx_kgm2: inertia tensor is not "
         "positive definite"},
        {"status": "failed", "stage": "trim", "reason": "no rigid body has these moments"},
    ]
    assert impossible_bodies(history) == 2


@pytest.mark.parametrize("m", [2, 3])
def test_the_front_figure_draws_the_baseline_in_every_panel(m):
    F = np.array([[16.6, 14.0, 64.3], [16.7, 15.0, 64.2], [16.8, 16.0, 64.1]])[:, :m]
    names, base = ["J3", "J4", "Jp"][:m], [16.65, 13.6, 64.4][:m]
    fig = plots.pareto_front(F, names, {"A": 0}, baseline=("SY250", base))
    panels = [a for a in fig.axes if a.collections]
    assert len(panels) == m * (m - 1) // 2
    for a in panels:
        (star,) = [c for c in a.collections if c.get_label() == "SY250 (baseline)"]
        x_name, y_name = a.get_xlabel(), a.get_ylabel()
        want = [base[names.index(x_name)], base[names.index(y_name)]]
        np.testing.assert_allclose(star.get_offsets()[0], want, rtol=0, atol=1e-12)
    legend = fig.legends[0] if fig.legends else fig.axes[0].get_legend()
    assert "SY250 (baseline)" in [t.get_text() for t in legend.get_texts()]
