"""Tests of casadrone.decide on hand-computed fronts."""

from __future__ import annotations

import numpy as np
import pytest

from casadrone.decide import Decision, decide, normalise

# already in [0, 1] on both objectives (both minimised), so normalisation is the identity.
# utopian distances: 1, 0.60828, 0.49244, 0.46098, 1            -> row 3
# mean point (0.32, 0.48); distances: 0.46648, 0.25060, 0.12369, 0.13153, 0.82365 -> row 2
FRONT = np.array([[0.0, 1.0], [0.1, 0.6], [0.2, 0.45], [0.3, 0.35], [1.0, 0.0]])


def test_utopian_and_compromise_by_hand():
    d = decide(FRONT, ["min", "min"], "utopian")
    assert d == Decision("utopian", 3, pytest.approx(np.sqrt(0.09 + 0.1225), abs=1e-12))
    d = decide(FRONT, ["min", "min"], "compromise")
    assert d.index == 2
    assert d.distance == pytest.approx(np.sqrt(0.12**2 + 0.03**2), abs=1e-12)


def test_max_sense_and_units_do_not_change_the_choice():
    # column 2 as a maximised quantity in other units: g = 10 - 10 f2 (m/s, say)
    F = np.column_stack([60.0 * FRONT[:, 0] + 30.0, 10.0 - 10.0 * FRONT[:, 1]])
    np.testing.assert_allclose(normalise(F, ["min", "max"]), FRONT, rtol=0, atol=1e-12)
    for method in ("utopian", "compromise"):
        a = decide(F, ["min", "max"], method)
        b = decide(FRONT, ["min", "min"], method)
        assert a.index == b.index
        assert a.distance == pytest.approx(b.distance, abs=1e-12)


def test_extreme_by_index_and_name():
    assert decide(FRONT, ["min", "min"], "extreme", 0) == Decision("extreme", 0, 1.0)
    assert decide(FRONT, ["min", "min"], "extreme", 1).index == 4
    senses = {"lap_time": "min", "speed": "max"}
    F = FRONT.copy()  # "speed" = f2 maximised: best is row 0 (f2 = 1), not row 4
    assert decide(F, senses, "extreme", "speed").index == 0
    assert decide(F, senses, "extreme", 1).index == 0
    assert decide(F, senses, "extreme", "lap_time").index == 0


def test_extreme_ties_broken_by_utopian_distance():
    # rows 0 and 1 tie on f1 = 0; row 1 is closer to the utopian point (0.8 < 1.0)
    F = np.array([[0.0, 1.0], [0.0, 0.8], [0.5, 0.3], [1.0, 0.0]])
    d = decide(F, ["min", "min"], "extreme", 0)
    assert d.index == 1 and d.distance == pytest.approx(0.8, abs=1e-12)


def test_degenerate_fronts():
    assert decide(np.array([[3.0, 4.0]]), ["min", "max"], "compromise") == Decision(
        "compromise", 0, 0.0
    )
    # f1 constant over the front maps to 0; the choice follows f2
    d = decide(np.array([[1.0, 5.0], [1.0, 3.0]]), ["min", "min"], "utopian")
    assert d == Decision("utopian", 1, 0.0)


@pytest.mark.parametrize(
    ("F", "senses", "method", "objective", "match"),
    [
        (np.empty((0, 2)), ["min", "min"], "utopian", None, "empty"),
        (FRONT, ["min", "min"], "nadir", None, "unknown decision method"),
        (FRONT, ["min"], "utopian", None, "senses"),
        (FRONT, ["min", "minimise"], "utopian", None, "'min' or 'max'"),
        (FRONT, ["min", "min"], "extreme", None, "needs an objective"),
        (FRONT, ["min", "min"], "extreme", 2, "out of range"),
        (FRONT, ["min", "min"], "extreme", "speed", "unknown objective"),
        (FRONT, {"a": "min", "b": "min"}, "extreme", "c", "named objectives: a, b"),
        (np.array([[0.0, np.nan]]), ["min", "min"], "utopian", None, "non-finite"),
    ],
)
def test_errors(F, senses, method, objective, match):
    with pytest.raises(ValueError, match=match):
        decide(F, senses, method, objective)
