"""The runner's per-generation timings (timings.csv) and progress statistics."""

import numpy as np
import pytest
from pymoo.indicators.hv import HV

from casadrone.config.problem import BackendConfig
from casadrone.optimise.checks import load_problem
from casadrone.optimise.hypervolume import (
    HV_SAMPLES,
    REFERENCE,
    HypervolumeSpace,
    advance,
)
from casadrone.optimise.runner import resume, run
from casadrone.rundir.store import RunStore
from casadrone.rundir.timings import FIELDS, read_timings

TINY = ["algorithm.population=16", "algorithm.generations=3", "algorithm.settings.n_ind_ga=8"]
STEPS = ("ask_s", "evaluate_s", "advance_s", "statistics_s", "history_s", "checkpoint_s")


def test_timings_one_row_per_generation_across_a_resume(tmp_path):
    out = tmp_path / "run"
    run(load_problem("problems/quick.yaml", TINY), out, BackendConfig(name="serial"), quiet=True,
        stop_after=2)
    assert [r["generation"] for r in read_timings(out)] == [0, 1]
    result = resume(out, quiet=True)
    # the logged archive size (counted without building pymoo's population) is the front's
    assert RunStore(out).generations()[-1]["archive_size"] == len(result.X) > 0
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


def test_incremental_estimate_equals_the_estimate_of_all_points_and_never_falls():
    rng = np.random.default_rng(0)
    batches = [rng.random((40, 5)) + 0.2 * (5 - k) for k in range(6)]
    state, shown = None, []
    for F in batches:
        state, value = advance(state, F)
        shown.append(value)
    assert np.all(np.diff(shown) >= 0) and shown[-1] > shown[0]
    # the same fixed samples: incremental = from scratch over every point, to the bit
    assert shown[-1] == state.space.hypervolume(np.vstack(batches))


def test_hypervolume_estimate_agrees_with_the_exact_value():
    rng = np.random.default_rng(1)
    for m in (4, 5):
        d = np.abs(rng.normal(size=(60, m)))
        F = d / np.linalg.norm(d, axis=1, keepdims=True)  # inside the unit box: all counted
        space = HypervolumeSpace(np.zeros(m), np.ones(m))
        exact = HV(ref_point=np.full(m, REFERENCE))(F)
        box = REFERENCE ** m
        p = exact / box
        se = box * np.sqrt(p * (1 - p) / HV_SAMPLES)
        assert space.hypervolume(F) == pytest.approx(exact, abs=4 * se)
