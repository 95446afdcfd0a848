"""A generation's files written in the background (casadrone.rundir.writer) are the files the
coordinator wrote in turn before: same history, same checkpointed state, same front; the
checkpoint never gets ahead of the history; writes in flight finish before a stopped run lets go
of its lock; timings.csv of an older run gains the new column without losing rows."""

from __future__ import annotations

import csv
import sqlite3
import threading
import time

import numpy as np
import pytest

import casadrone.optimise.runner as runner_mod
from casadrone.config.problem import BackendConfig, ProblemConfig
from casadrone.optimise.runner import run
from casadrone.rundir.checkpoint import loads
from casadrone.rundir.store import RunStore
from casadrone.rundir.timings import FIELDS, append_timings, read_timings

SERIAL = BackendConfig(name="serial")


def dtlz2(generations: int = 6) -> ProblemConfig:
    """DTLZ2 in 4 objectives (evaluation nearly free; the sample hypervolume estimate)."""
    return ProblemConfig.model_validate({
        "name": "writer-dtlz2", "description": "DTLZ2, 5 variables, 4 objectives",
        "test_problem": {"name": "dtlz2", "n_var": 5, "n_obj": 4},
        "algorithm": {"name": "evmoga", "population": 60, "generations": generations,
                      "settings": {"n_ind_ga": 40, "n_div": 12}},
        "seed": 3,
    })


def table(path, sql: str) -> list[tuple]:
    with sqlite3.connect(path / "history.sqlite") as db:
        return db.execute(sql).fetchall()


def state_of(path) -> tuple:
    """What a checkpoint holds that a resume depends on (not the clock)."""
    state = loads((path / "checkpoint.pkl").read_bytes())
    alg = state["algorithm"]
    archive = alg.box_archive
    return (state["generation"], int(alg.n_gen), int(alg.evaluator.n_eval),
            {k: v.tobytes() for k, v in archive.rows.items()}, archive.box.tobytes(),
            archive.grid_min.tobytes(), archive.eps.tobytes(), alg.pop.get("X").tobytes(),
            alg.pop_F.tobytes(), alg.pop_cv.tobytes(), str(alg.random_state.bit_generator.state),
            state["hypervolume_state"].hit.tobytes())


def test_background_writes_equal_writes_in_turn(tmp_path, monkeypatch):
    dirs = {}
    for background in (False, True):
        monkeypatch.setattr(runner_mod, "BACKGROUND_WRITES", background)
        dirs[background] = tmp_path / f"background-{background}"
        run(dtlz2(), dirs[background], SERIAL, quiet=True)
    a, b = dirs[False], dirs[True]
    evals = "SELECT * FROM evaluations ORDER BY generation, idx"
    assert [r[:-1] for r in table(a, evals)] == [r[:-1] for r in table(b, evals)]  # not the time
    gens = "SELECT generation, n_evaluations, archive_size, feasible_fraction, hypervolume " \
           "FROM generations ORDER BY generation"
    assert table(a, gens) == table(b, gens) and len(table(a, gens)) == 7
    assert state_of(a) == state_of(b)
    assert (a / "pareto.csv").read_bytes() == (b / "pareto.csv").read_bytes()
    for path, background in ((a, False), (b, True)):
        rows = read_timings(path)
        assert [r["generation"] for r in rows] == list(range(7))
        for r in rows:
            assert r["write_s"] > 0.0
            steps = sum(r[k] for k in ("ask_s", "evaluate_s", "advance_s", "statistics_s",
                                       "history_s", "checkpoint_s"))
            assert steps == pytest.approx(r["wall_s"], abs=1e-9)
            if not background:  # the coordinator waited for its writes
                assert r["history_s"] >= r["write_s"]


def test_the_checkpoint_never_gets_ahead_of_the_history(tmp_path, monkeypatch):
    """Slow history writes in the background: whenever a checkpoint is written, the history
    already holds its generation, and the coordinator never has two generations in flight."""
    seen, in_flight, lock = [], [], threading.Lock()
    write_generation, write_checkpoint = RunStore.write_generation, RunStore.write_checkpoint

    def slow_history(self, generation, records, stats):
        with lock:
            in_flight.append(generation)
            assert len(in_flight) == 1, in_flight
        time.sleep(0.05)
        write_generation(self, generation, records, stats)

    def checked_checkpoint(self, data):
        generation = loads(data)["generation"]
        stored = [g["generation"] for g in self.generations()]
        assert stored == list(range(generation + 1))
        seen.append(generation)
        write_checkpoint(self, data)
        with lock:
            in_flight.remove(generation)

    monkeypatch.setattr(RunStore, "write_generation", slow_history)
    monkeypatch.setattr(RunStore, "write_checkpoint", checked_checkpoint)
    run(dtlz2(4), tmp_path / "run", SERIAL, quiet=True)
    assert seen == list(range(5))


def test_writes_in_flight_finish_before_a_stopped_run_lets_go(tmp_path, monkeypatch):
    """The evaluation of generation 3 fails while generation 2's writes are still going: the
    error reaches the caller only after they are done (history and checkpoint at 2, the run
    stopped, its lock free)."""
    write_generation = RunStore.write_generation

    def slow_history(self, generation, records, stats):
        time.sleep(0.3 if generation == 2 else 0.0)
        write_generation(self, generation, records, stats)

    import casadrone.optimise.backends as backends_mod

    real = backends_mod.make_backend

    def failing_backend(*args, **kwargs):
        backend, calls = real(*args, **kwargs), []

        class Failing:
            name = "failing"

            def evaluate(self, study, X):
                calls.append(1)
                if len(calls) == 4:  # generation 3
                    raise RuntimeError("worker lost")
                return backend.evaluate(study, X)

            def close(self):
                backend.close()

        return Failing()

    monkeypatch.setattr(RunStore, "write_generation", slow_history)
    monkeypatch.setattr(runner_mod, "make_backend", failing_backend)
    out = tmp_path / "run"
    with pytest.raises(RuntimeError, match="worker lost"):
        run(dtlz2(), out, SERIAL, quiet=True)
    store = RunStore(out)
    assert [g["generation"] for g in store.generations()] == [0, 1, 2]
    assert store.load_checkpoint()["generation"] == 2
    assert store.manifest["status"] == "stopped"
    store.acquire()  # free
    store.release()
    assert [r["generation"] for r in read_timings(out)] == [0, 1, 2]


def test_timings_of_an_older_run_gain_the_new_column(tmp_path):
    old = [f for f in FIELDS if f != "write_s"]
    with open(tmp_path / "timings.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=old)
        w.writeheader()
        for g in range(3):
            w.writerow({k: (g if k == "generation" else 0.5) for k in old})
    append_timings(tmp_path, {k: (3 if k == "generation" else 0.25) for k in FIELDS})
    rows = read_timings(tmp_path)
    assert [r["generation"] for r in rows] == [0, 1, 2, 3]
    assert [r["write_s"] for r in rows] == [None, None, None, 0.25]
    assert all(r["wall_s"] == 0.5 for r in rows[:3]) and rows[3]["wall_s"] == 0.25
    with open(tmp_path / "timings.csv", newline="") as fh:
        assert next(csv.reader(fh)) == list(FIELDS)
    assert not list(tmp_path.glob(".*tmp"))


def test_a_failed_background_write_stops_the_run_at_the_next_generation(tmp_path, monkeypatch):
    """A checkpoint that cannot be written (disk full) stops the run with that error, and the
    generations after it are neither evaluated nor stored."""
    write_checkpoint = RunStore.write_checkpoint
    evaluated = []

    def full_disk(self, data):
        if loads(data)["generation"] == 1:
            raise OSError(28, "No space left on device")
        write_checkpoint(self, data)

    monkeypatch.setattr(RunStore, "write_checkpoint", full_disk)
    out = tmp_path / "run"
    with pytest.raises(OSError, match="No space left"):
        run(dtlz2(), out, SERIAL, quiet=True,
            progress=lambda gen, stats: evaluated.append(gen))
    assert max(evaluated) <= 2  # it surfaced at the next generation's hand-over
    store = RunStore(out)
    assert store.load_checkpoint()["generation"] == 0
    assert store.manifest["status"] == "stopped"
    assert np.max([g["generation"] for g in store.generations()]) <= 2
