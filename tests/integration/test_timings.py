"""The runner's per-generation timings (timings.csv) and progress statistics."""

import numpy as np
import pytest
from pymoo.indicators.hv import HV

from casadrone.optimise.hypervolume import (
    HV_EVERY,
    HypervolumeSpace,
    advance,
    dominated_fraction,
    due,
)
from casadrone.optimise.runner import resume, run
from casadrone.optimise.store import RunStore
from casadrone.optimise.timings import FIELDS, read_timings
from casadrone.problemconfig import BackendConfig, load_problem

TINY = ["algorithm.population=16", "algorithm.generations=3", "algorithm.settings.n_ind_ga=8"]
STEPS = ("ask_s", "evaluate_s", "advance_s", "statistics_s", "history_s", "checkpoint_s")


def test_timings_one_row_per_generation_across_a_resume(tmp_path):
    out = tmp_path / "run"
    run(load_problem("problems/quick.yaml", TINY), out, BackendConfig(name="serial"), quiet=True,
        stop_after=2)
    assert [r["generation"] for r in read_timings(out)] == [0, 1]
    resume(out, quiet=True)
    rows = read_timings(out)
    generations = RunStore(out).generations()
    assert [r["generation"] for r in rows] == [g["generation"] for g in generations] == [0, 1, 2, 3]
    assert set(rows[0]) == set(FIELDS)
    for row, gen in zip(rows, generations, strict=True):
        assert row["n_evaluations"] == gen["n_evaluations"] == 16 + 8 * row["generation"]
        assert row["archive_size"] == gen["archive_size"]
        steps = [row[k] for k in STEPS]
        assert min(steps) >= 0.0
        assert sum(steps) <= row["wall_s"] + 1e-9
        assert row["coordinator_s"] == pytest.approx(row["wall_s"] - row["evaluate_s"], abs=1e-9)
        assert 0.0 <= row["coordinator_cpu_s"] <= row["cpu_s"] + 1e-9
        assert row["evaluate_s"] > 0.0  # the serial backend flies 16 or 8 laps


def test_progress_hypervolume_schedule():
    assert all(due(m, gen, last=False) for m in (2, 3) for gen in (1, 7, 13))
    assert not due(4, 3, last=False)
    assert due(4, HV_EVERY, last=False) and due(5, 3, last=True)


def test_buffered_generations_give_the_same_value_as_computing_every_one():
    rng = np.random.default_rng(0)
    batches = [rng.random((30, 4)) + 0.3 * (5 - k) for k in range(5)]
    every, buffered = None, None
    for k, F in enumerate(batches):
        every, v_every = advance(every, F)
        buffered, v_buffered = advance(buffered, F, compute=k == len(batches) - 1)
        assert (v_buffered is None) == (k < len(batches) - 1)
    assert v_buffered == v_every
    np.testing.assert_array_equal(buffered.archive, every.archive)


def test_hypervolume_estimate_agrees_with_the_exact_value_and_never_falls():
    rng = np.random.default_rng(1)
    for m in (3, 6):
        d = np.abs(rng.normal(size=(60, m)))
        F = d / np.linalg.norm(d, axis=1, keepdims=True)
        lo, ref = np.zeros(m), np.full(m, 1.1)
        exact = HV(ref_point=ref)(F)
        box = np.prod(ref - lo)
        p = exact / box
        se = box * np.sqrt(p * (1 - p) / 4096)
        estimate = box * dominated_fraction(F, lo, ref)
        assert estimate == pytest.approx(exact, abs=4 * se)
        # fixed samples: adding points never lowers the estimate
        assert box * dominated_fraction(np.vstack([F, 0.9 * F[:5]]), lo, ref) >= estimate
    space = HypervolumeSpace(np.zeros(6), np.ones(6))
    assert space.hypervolume(F) == pytest.approx(box * dominated_fraction(F, lo, ref))
