"""The run's hypervolume (console, history log, report): fixed space, never falls."""

from __future__ import annotations

import numpy as np
import pytest

from casadrone.optimise.hypervolume import HypervolumeSpace, advance, non_dominated


def own_bounds_hv(F: np.ndarray) -> float:
    """The old display: the front normalised on its own bounds (reference 1.1)."""
    front = non_dominated(F)
    return HypervolumeSpace(front.min(axis=0), front.max(axis=0)).hypervolume(front)


def test_two_objective_value_by_hand():
    # first generation fixes ideal (0, 0), nadir (2, 2); points (0, 2), (2, 0) → (0, 1), (1, 0)
    state, hv = advance(None, np.array([[0.0, 2.0], [2.0, 0.0]]))
    # by hand: union of [0,1.1]x[1,1.1] and [1,1.1]x[0,1.1] = 1.1*0.1 + 0.1*1.1 - 0.1*0.1 = 0.21
    assert hv == pytest.approx(0.21, abs=1e-12)
    # a better point (1, 1) → (0.5, 0.5) adds the square [0.5,1]x[0.5,1] = 0.25
    state, hv2 = advance(state, np.array([[1.0, 1.0]]))
    assert hv2 == pytest.approx(0.46, abs=1e-12)
    np.testing.assert_array_equal(state.space.ideal, [0.0, 0.0])  # the space did not move


def test_never_falls_where_the_per_generation_normalisation_did():
    # an elitist run whose new front extends the extremes: the front normalised on its own
    # bounds loses value, the fixed-space value of the growing set cannot
    gens = [np.array([[2.5, 3.1], [2.5, 3.7], [0.2, 2.1]]),  # front: one point, 1.21
            np.array([[1.8, 0.2]]),  # a second front point: 0.21 on the front's own bounds
            np.array([[1.0, 1.0]])]
    seen, state, shown, old = np.empty((0, 2)), None, [], []
    for F in gens:
        seen = np.vstack([seen, F])
        state, hv = advance(state, F)
        shown.append(hv)
        old.append(own_bounds_hv(seen))
    assert min(np.diff(old)) < 0  # the old display fell
    assert np.all(np.diff(shown) >= 0)
    assert shown[-1] > shown[0]


def test_generation_without_feasible_points_keeps_the_value():
    state, hv = advance(None, np.empty((0, 3)))
    assert hv == 0.0 and state.space is None
    state, hv = advance(state, np.array([[1.0, 2.0, 3.0], [3.0, 2.0, 1.0]]))
    state2, hv2 = advance(state, np.empty((0, 3)))
    assert hv2 == hv and state2 is state


def test_raw_space_for_test_problems():
    state, hv = advance(None, np.array([[0.0, 1.0], [1.0, 0.0]]), raw=True)
    np.testing.assert_array_equal(state.space.ideal, [0, 0])
    np.testing.assert_array_equal(state.space.nadir, [1, 1])
    assert hv == pytest.approx(0.21, abs=1e-12)
