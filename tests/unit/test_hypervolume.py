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


def test_dominated_by_equals_brute_force():
    """The bitset test equals the definition (some z <= s in every objective), with exact ties,
    samples equal to points, more than 64 points (several words) and no points or samples."""
    from casadrone.optimise.hypervolume import dominated_by

    rng = np.random.default_rng(0)
    sizes = [(0, 10), (10, 0), (1, 1), (64, 500), (65, 500), (300, 3000)]
    for t in range(120):
        m = int(rng.integers(1, 7))
        n, ns = sizes[t] if t < len(sizes) else (int(rng.integers(0, 300)),
                                                int(rng.integers(0, 2000)))
        Z = rng.random((n, m)) * 1.2 - 0.1
        S = rng.random((ns, m)) * 1.1
        if t % 2:  # coarse values: many exact ties between points and samples
            Z, S = np.round(Z, 1), np.round(S, 1)
        k = min(n, ns) // 3
        S[:k] = Z[:k]  # a point weakly dominates itself
        brute = (Z[None, :, :] <= S[:, None, :]).all(axis=2).any(axis=1) if n else \
            np.zeros(ns, dtype=bool)
        np.testing.assert_array_equal(dominated_by(Z, S), brute, err_msg=str((t, m, n, ns)))
        assert brute[:k].all()


def test_estimate_from_four_objectives_against_a_monte_carlo_oracle():
    """From four objectives the value is the fraction of the fixed samples some evaluation so
    far dominates, kept generation by generation: equal to that fraction computed at once."""
    from casadrone.optimise.hypervolume import HV_SAMPLES, REFERENCE, samples

    rng = np.random.default_rng(5)
    state, seen = None, []
    for _ in range(6):
        F = rng.random((200, 4))
        state, hv = advance(state, F)
        seen.append(F)
    Z = state.space.normalise(np.vstack(seen))
    S = samples(4)
    frac = (Z[None, :, :] <= S[:, None, :]).all(axis=2).any(axis=1).mean()
    assert hv == REFERENCE ** 4 * frac
    assert 0 < frac < 1 and HV_SAMPLES == len(S)


def test_front_union_equals_recomputing_the_front_bit_for_bit():
    """Kept generation by generation (2 and 3 objectives: ties, duplicates of old and new
    points, new points dominating old ones, none at all), the front equals the front of all
    points so far computed at once: same rows in the same order."""
    from casadrone.optimise.hypervolume import front_union

    rng = np.random.default_rng(3)
    changed = 0
    for t in range(60):
        m = int(rng.integers(2, 4))
        seen, front = np.empty((0, m)), np.empty((0, m))
        for g in range(int(rng.integers(1, 12))):
            F = rng.random((int(rng.integers(0, 150)), m)) * rng.uniform(0.7, 1.3)
            if t % 2:
                F = np.round(F, 1)  # exact ties
            if len(front) and len(F) and g % 3 == 0:  # old front points again
                k = min(len(front), len(F)) // 2
                F[:k] = front[rng.integers(len(front), size=k)]
            seen = np.vstack([seen, F])
            before = front
            front = front_union(front, F)
            expected = non_dominated(seen) if len(seen) else seen
            assert front.shape == expected.shape and front.tobytes() == expected.tobytes()
            changed += len(before) and not np.array_equal(before, front)
    assert changed > 50  # old fronts lost and gained members
