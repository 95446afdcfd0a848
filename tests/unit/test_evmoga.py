"""Tests of ev-MOGA (casadrone.optimise.evmoga) against docs/concepts/evmoga.md.

Oracles: hand-built archives for the insertion and extreme-value cases, the analytic ZDT1 front
(HV = 1.1 * 1.1 - integral_0^1 (1 - sqrt(f1)) df1 = 1.21 - 1/3 = 0.87667 for reference (1.1, 1.1)),
a constrained toy problem whose feasible front is known, and invariants asserted after every
generation through a pymoo callback.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from pymoo.core.callback import Callback
from pymoo.core.problem import Problem
from pymoo.indicators.hv import HV
from pymoo.indicators.igd import IGD
from pymoo.optimize import minimize
from pymoo.problems import get_problem

from casadrone.optimise.algorithms import ALGORITHM_NAMES, make_algorithm
from casadrone.optimise.boxarchive import BoxArchive, box_dominates, box_index, pareto_dominates
from casadrone.optimise.evmoga import EvMOGA, constrained_dominates, shrinking_schedule

ZDT1_HV = 1.21 - 1.0 / 3.0  # 0.876667, exact, reference point (1.1, 1.1)
REF = np.array([1.1, 1.1])


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------


def hv2d(F: np.ndarray, ref: np.ndarray) -> float:
    """Hand-written 2-D hypervolume (minimisation): sweep in f1, add the new horizontal slab."""
    F = np.asarray(F, dtype=float)
    F = F[(F[:, 0] < ref[0]) & (F[:, 1] < ref[1])]
    F = F[np.lexsort((F[:, 1], F[:, 0]))]
    volume, f2_best = 0.0, ref[1]
    for f1, f2 in F:
        if f2 < f2_best:
            volume += (ref[0] - f1) * (f2_best - f2)
            f2_best = f2
    return volume


def assert_archive_invariants(alg: EvMOGA | BoxArchive) -> None:
    """The archive invariants of docs/concepts/evmoga.md on the archive A of ``alg`` (any number of
    objectives)."""
    if isinstance(alg, EvMOGA):
        A = alg.archive_pop
        assert len(A) == len(alg.archive_F)
        if len(A):
            np.testing.assert_array_equal(np.asarray(A.get("F"), dtype=float), alg.archive_F)
            np.testing.assert_array_equal(np.asarray(A.get("X"), dtype=float), alg.archive_X)
        alg = alg.box_archive
    F, B = alg.F, alg.box
    assert len(alg) == len(F) == len(B) == len(alg.rows["X"])
    if len(F) == 0:
        return
    assert np.all(alg.rows["CV"] <= 0.0), "infeasible member in A"
    assert np.all(np.isfinite(F))
    # stored boxes are the boxes of the members on the stored grid, inside [0, n_div]: the box
    # ceil((f - min) / ε), rounded to 6 decimals first, 0 where ε = 0 (docs/concepts/evmoga.md),
    # computed here rather than by the package's box_index, which it checks
    width = np.where(alg.eps > 0.0, alg.eps, 1.0)
    boxes = np.where(alg.eps > 0.0, np.ceil(np.round((F - alg.grid_min) / width, 6)), 0.0)
    np.testing.assert_array_equal(B, boxes.astype(np.int64))
    assert np.all(B >= 0) and np.all(B <= alg.n_div)
    assert np.all(alg.eps >= 0.0)
    # one member per box
    assert len(np.unique(B, axis=0)) == len(B), "two members share a box"
    for i in range(len(B)):
        others = np.delete(np.arange(len(B)), i)
        assert not np.any(box_dominates(B[i], B[others])), "a member's box dominates another"
        assert not np.any(pareto_dominates(F[i], F[others])), "a member dominates another"
    if F.shape[1] == 2:
        assert len(F) <= alg.n_div[0] + 1


class InvariantCheck(Callback):
    """Assert the archive invariants after every pymoo generation (initialisation included)."""

    def __init__(self) -> None:
        super().__init__()
        self.n_calls = 0
        self.sizes: list[int] = []

    def notify(self, algorithm: EvMOGA) -> None:
        assert_archive_invariants(algorithm)
        if len(algorithm.archive_pop):
            np.testing.assert_array_equal(algorithm.opt.get("F"), algorithm.archive_F)
        self.n_calls += 1
        self.sizes.append(len(algorithm.archive_pop))


def run(problem, seed: int, callback=None, **settings) -> tuple:
    alg = EvMOGA(**settings)
    extra = {} if callback is None else {"callback": callback}
    res = minimize(problem, alg, seed=seed, copy_algorithm=False, **extra)
    return res, alg


def individual(f) -> dict[str, np.ndarray]:
    """An archive row: X = F = f, no constraints, feasible."""
    f = np.asarray(f, dtype=float)
    return {"X": f.copy(), "F": f, "G": np.empty(0), "H": np.empty(0), "CV": np.zeros(1)}


def bare_archive(n_div=10, f_min=(0.0, 0.0), f_max=(1.0, 1.0)) -> BoxArchive:
    """An empty archive on a fixed grid, to drive insert / offer by hand."""
    arc = BoxArchive(np.array([n_div, n_div]), {"X": 2, "F": 2, "G": 0, "H": 0, "CV": 1})
    arc.set_grid(np.array(f_min, float), np.array(f_max, float))
    return arc


class RecordingZDT1(Problem):
    """ZDT1 (vectorised) that records the size of every evaluation batch."""

    def __init__(self, n_var: int = 4) -> None:
        super().__init__(n_var=n_var, n_obj=2, xl=0.0, xu=1.0)
        self.batches: list[int] = []
        self._zdt1 = get_problem("zdt1", n_var=n_var)

    def _evaluate(self, x, out, *args, **kwargs):
        self.batches.append(len(x))
        out["F"] = self._zdt1.evaluate(x)


class CornerProblem(Problem):
    """min (x1, x2) on [0, 1]^2 s.t. x1 + x2 >= 1.5; feasible front f1 + f2 = 1.5, f1 in [0.5, 1].

    The objectives push towards the infeasible side; with a small P the start has few or no
    feasible points, so the run relies on feasibility-first dominance.
    """

    def __init__(self) -> None:
        super().__init__(n_var=2, n_obj=2, n_ieq_constr=1, xl=0.0, xu=1.0)

    def _evaluate(self, x, out, *args, **kwargs):
        out["F"] = x.copy()
        out["G"] = 1.5 - x[:, :1] - x[:, 1:2]


# ---------------------------------------------------------------------------------------------
# pure functions
# ---------------------------------------------------------------------------------------------


def test_box_index_rounds_noise_and_handles_zero_eps():
    f_min, eps = np.array([0.0, 1.0]), np.array([0.1, 0.0])
    F = np.array([[0.0, 1.0], [0.1, 1.0], [0.3 + 1e-12, 1.0], [0.1000001, 1.0]])
    np.testing.assert_array_equal(box_index(F, f_min, eps), [[0, 0], [1, 0], [3, 0], [2, 0]])


def test_dominance_rules():
    B = np.array([[1, 2], [2, 2], [1, 1], [0, 3]])
    np.testing.assert_array_equal(box_dominates(np.array([1, 2]), B), [False, True, False, False])
    F = np.array([[1.0, 2.0], [1.0, 1.0], [2.0, 3.0]])
    np.testing.assert_array_equal(pareto_dominates(np.array([1.0, 2.0]), F), [False, False, True])
    # feasible beats infeasible; among infeasible the smaller violation wins
    CV = np.array([0.0, 0.5, 2.0])
    np.testing.assert_array_equal(
        constrained_dominates(np.array([9.0, 9.0]), 0.0, F, CV), [False, True, True]
    )
    np.testing.assert_array_equal(
        constrained_dominates(np.array([0.0, 0.0]), 1.0, F, CV), [False, False, True]
    )


def test_shrinking_schedule_endpoints():
    assert shrinking_schedule(0.25, 0.1, 0, 50) == pytest.approx(0.25, rel=1e-12)
    assert shrinking_schedule(0.25, 0.1, 49, 50) == pytest.approx(0.1, rel=1e-12)
    assert shrinking_schedule(20.0, 0.1, 49, 50) == pytest.approx(0.1, rel=1e-12)
    assert shrinking_schedule(20.0, 0.1, 500, 50) == pytest.approx(0.1, rel=1e-12)  # clamped
    values = [shrinking_schedule(20.0, 0.1, t, 50) for t in range(50)]
    assert np.all(np.diff(values) < 0)


def test_hv2d_matches_hand_values_and_pymoo():
    assert hv2d(np.array([[0.5, 0.5]]), np.array([1.0, 1.0])) == pytest.approx(0.25, abs=1e-15)
    # union of [0,2]x[1,2] and [1,2]x[0,2]; the dominated (1.5, 1.5) and the point outside add 0
    F = np.array([[0.0, 1.0], [1.0, 0.0], [1.5, 1.5], [3.0, 0.0]])
    assert hv2d(F, np.array([2.0, 2.0])) == pytest.approx(3.0, abs=1e-15)
    rng = np.random.default_rng(0)
    for _ in range(20):
        F = rng.random((rng.integers(1, 40), 2)) * 1.3
        assert hv2d(F, REF) == pytest.approx(HV(ref_point=REF).do(F), abs=1e-12)
    # dense exact ZDT1 front: the sweep converges to 1.21 - 1/3 from below (error ~ 1/(2n))
    f1 = np.linspace(0.0, 1.0, 20001)
    front = np.column_stack([f1, 1.0 - np.sqrt(f1)])
    assert hv2d(front, REF) == pytest.approx(ZDT1_HV, abs=1e-4)
    assert HV(ref_point=REF).do(front) == pytest.approx(hv2d(front, REF), abs=1e-12)


# ---------------------------------------------------------------------------------------------
# archive: insertion cases and extreme-value cases, by hand (grid min (0,0), max (1,1), eps 0.1)
# ---------------------------------------------------------------------------------------------


def test_insertion_cases():
    alg = bare_archive()
    assert alg.insert(individual([0.25, 0.75]))  # case 4, box (3, 8)
    np.testing.assert_array_equal(alg.box, [[3, 8]])
    assert not alg.insert(individual([0.35, 0.85]))  # case 1, (4, 9)
    assert alg.insert(individual([0.45, 0.15]))  # case 4, (5, 2)
    assert alg.insert(individual([0.15, 0.55]))  # case 2: deletes (3, 8)
    np.testing.assert_array_equal(alg.box, [[5, 2], [2, 6]])
    # case 3, box (2, 6), centre (0.15, 0.55)
    member = alg.rows["X"][1].copy()
    assert not alg.insert(individual([0.12, 0.58]))  # farther: keep
    assert not alg.insert(individual([0.15, 0.55]))  # equal: keep
    np.testing.assert_array_equal(alg.rows["X"][1], member)
    assert alg.insert(individual([0.14, 0.54]))  # dominates: replace
    np.testing.assert_allclose(alg.F[1], [0.14, 0.54], rtol=0, atol=0)
    assert not alg.insert(individual([0.145, 0.545]))  # dominated
    # neither dominates: (0.11, 0.6) is 0.64 eps from the centre, (0.16, 0.52) 0.32 eps
    alg2 = bare_archive()
    alg2.insert(individual([0.11, 0.6]))
    assert alg2.insert(individual([0.16, 0.52]))
    np.testing.assert_allclose(alg2.F, [[0.16, 0.52]], rtol=0, atol=0)
    assert_archive_invariants(alg)
    assert_archive_invariants(alg2)


def two_point_archive() -> BoxArchive:
    alg = bare_archive()
    for f in ([0.0, 1.0], [1.0, 0.0]):
        alg.insert(individual(f))
    return alg


def test_extreme_value_cases():
    alg = two_point_archive()
    alg.offer(individual([1.2, 1.2]))  # a = m, b = 0: reject
    assert len(alg) == 2
    alg.offer(individual([0.0, 1.5]))  # mixed, dominated: reject
    assert len(alg) == 2
    np.testing.assert_allclose(alg.grid_max, [1.0, 1.0], rtol=0, atol=0)

    # mixed (a = 1, b = 1), non-dominated: grid grows to min (-0.5, 0), max (1, 2), all kept
    alg.offer(individual([-0.5, 2.0]))
    np.testing.assert_allclose(alg.grid_min, [-0.5, 0.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(alg.grid_max, [1.0, 2.0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(alg.eps, [0.15, 0.2], rtol=1e-12)
    assert len(alg) == 3
    assert_archive_invariants(alg)

    # mixed (a = 0, b = 1), dominates (1, 0): it is deleted and the grid shrinks to A + child
    alg = two_point_archive()
    alg.offer(individual([0.5, -0.2]))
    np.testing.assert_allclose(alg.F, [[0.0, 1.0], [0.5, -0.2]], rtol=0, atol=0)
    np.testing.assert_allclose(alg.grid_min, [0.0, -0.2], rtol=0, atol=0)
    np.testing.assert_allclose(alg.grid_max, [0.5, 1.0], rtol=0, atol=0)
    assert_archive_invariants(alg)

    # a = 0, b = m: the child dominates everything, A = {child}, min = max = f, eps kept
    alg = two_point_archive()
    alg.offer(individual([-0.1, -0.1]))
    np.testing.assert_allclose(alg.F, [[-0.1, -0.1]], rtol=0, atol=0)
    np.testing.assert_allclose(alg.grid_min, [-0.1, -0.1], rtol=0, atol=0)
    np.testing.assert_allclose(alg.grid_max, [-0.1, -0.1], rtol=0, atol=0)
    np.testing.assert_allclose(alg.eps, [0.1, 0.1], rtol=1e-12)
    assert_archive_invariants(alg)

    # interior child (a = b = 0) goes through the ordinary insertion
    alg = two_point_archive()
    alg.offer(individual([0.5, 0.5]))
    assert len(alg) == 3


# ---------------------------------------------------------------------------------------------
# whole runs
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("problem", "n_div", "generations"),
    [
        (get_problem("zdt1", n_var=4), 5, 300),  # coarse grid: many box collisions and rebuilds
        (get_problem("zdt2", n_var=3), [20, 40], 300),  # one n_div per objective
        (get_problem("dtlz2", n_var=5, n_obj=3), 8, 200),
    ],
)
def test_invariants_hold_after_every_generation(problem, n_div, generations):
    check = InvariantCheck()
    res, alg = run(problem, 1, check, n_ind_p=60, n_div=n_div, generations=generations)
    assert check.n_calls == generations + 1  # pymoo's generation 1 is the initialisation
    assert alg.evaluator.n_eval == 60 + 8 * generations
    assert check.sizes[-1] > 1
    np.testing.assert_array_equal(res.F, alg.archive_F)
    np.testing.assert_array_equal(res.X, alg.archive_pop.get("X"))


def test_one_batch_per_generation_and_children_in_bounds():
    problem = RecordingZDT1()
    run(problem, 0, n_ind_p=30, n_ind_ga=6, generations=40)
    assert problem.batches == [30] + [6] * 40


def test_crossover_children_lie_on_the_parent_line():
    """With p_m = 0, each pair is beta*p1 + (1-beta)*p2 and the mirror, p1 in P, p2 in A."""
    problem = get_problem("zdt1", n_var=3)
    alg = EvMOGA(n_ind_p=40, n_ind_ga=8, p_m=0.0, generations=20)
    alg.setup(problem, seed=3)
    for _ in range(5):
        alg.next()
    X_p, X_a = alg.pop.get("X"), alg.archive_X
    children = alg.ask()
    X = children.get("X")
    dd = shrinking_schedule(0.25, 0.1, alg.n_iter - 2, 20)
    n_pairs = 4
    for c1, c2 in zip(X[:n_pairs], X[n_pairs:], strict=True):
        if np.any((c1 <= 0) | (c1 >= 1) | (c2 <= 0) | (c2 >= 1)):
            continue  # clipped
        s = X_p[:, None, :] + X_a[None, :, :]  # p1 + p2 for every pair
        i, j = np.argwhere(np.all(np.abs(s - (c1 + c2)) < 1e-12, axis=2))[0]
        p1, p2 = X_p[i], X_a[j]
        k = np.argmax(np.abs(p1 - p2))
        beta = (c1[k] - p2[k]) / (p1[k] - p2[k])
        np.testing.assert_allclose(c1, beta * p1 + (1 - beta) * p2, rtol=0, atol=1e-12)
        assert -dd - 1e-12 <= beta <= 1 + dd + 1e-12


def test_same_seed_same_archive_different_seed_different():
    problem = get_problem("zdt1", n_var=4)
    settings = dict(n_ind_p=50, n_div=50, generations=150)
    res_a, _ = run(problem, 11, **settings)
    res_b, _ = run(problem, 11, **settings)
    res_c, _ = run(problem, 12, **settings)
    np.testing.assert_array_equal(res_a.X, res_b.X)
    np.testing.assert_array_equal(res_a.F, res_b.F)
    assert res_a.X.shape != res_c.X.shape or not np.array_equal(res_a.X, res_c.X)


def test_pickled_and_resumed_run_equals_uninterrupted_run():
    problem = get_problem("zdt1", n_var=4)
    settings = dict(n_ind_p=50, n_div=50, generations=120)
    res_full, _ = run(problem, 5, **settings)
    alg = EvMOGA(**settings)
    alg.setup(problem, seed=5)
    for _ in range(40):
        alg.next()
    resumed = pickle.loads(pickle.dumps(alg))
    while resumed.has_next():
        resumed.next()
    res = resumed.result()
    np.testing.assert_array_equal(res.X, res_full.X)
    np.testing.assert_array_equal(res.F, res_full.F)


def test_zdt1_reaches_exact_hypervolume():
    """ZDT1, 4 variables, 8 400 evaluations, median of 3 seeds.

    Tolerance: an archive that epsilon-dominates the true front (every front point y has a member
    a <= y + eps) loses at most the strips eps1 * 1.1 + eps2 * 1.1 of the reference box, so HV >=
    0.87667 - 1.1 * (eps1 + eps2) (0.022 for n_div = 100 on the unit square) once converged.
    """
    problem = get_problem("zdt1", n_var=4)
    hvs, bounds, igds = [], [], []
    for seed in (0, 1, 2):
        res, alg = run(problem, seed, n_ind_p=400, n_div=100, generations=1000)
        hvs.append(HV(ref_point=REF).do(res.F))
        bounds.append(ZDT1_HV - 1.1 * float(np.sum(alg.eps)))
        igds.append(IGD(problem.pareto_front()).do(res.F))
        assert hv2d(res.F, REF) == pytest.approx(hvs[-1], abs=1e-12)
        assert hvs[-1] <= ZDT1_HV + 1e-12
    k = int(np.argsort(hvs)[1])
    assert hvs[k] >= bounds[k]
    assert np.median(igds) < 0.01


def test_feasibility_first_on_constrained_toy():
    # P = 10 with seed 1 starts without a single feasible point: A is empty until violation-based
    # replacement has pushed P over the constraint
    check = InvariantCheck()
    res, alg = run(CornerProblem(), 1, check, n_ind_p=10, n_div=20, generations=300)
    assert check.sizes[0] == 0, "P should start without a feasible point (pick another seed)"
    assert np.all(res.CV <= 0.0) and np.all(alg.pop_cv <= 0.0)
    assert np.all(res.F.sum(axis=1) >= 1.5 - 1e-12)
    assert np.median(res.F.sum(axis=1)) - 1.5 < 0.01  # on the feasible front
    # a larger P also spreads along the front f1 in [0.5, 1]
    check = InvariantCheck()
    res, _ = run(CornerProblem(), 3, check, n_ind_p=40, n_div=20, generations=300)
    assert np.all(res.CV <= 0.0)
    assert np.median(res.F.sum(axis=1)) - 1.5 < 0.01
    assert res.F[:, 0].min() < 0.55 and res.F[:, 0].max() > 0.95


def test_verbose_display_before_and_after_the_first_feasible_point(capsys):
    res = minimize(
        CornerProblem(), EvMOGA(n_ind_p=10, n_div=20, generations=300), seed=1, verbose=True
    )
    out = capsys.readouterr().out
    assert "n_nds" in out and "cv_min" in out and len(out.splitlines()) >= 301
    assert res.F is not None and np.all(res.CV <= 0.0)
    # no feasible point ever: the result is empty, as in pymoo
    res = minimize(CornerProblem(), EvMOGA(n_ind_p=10, generations=1), seed=1)
    assert res.F is None


def test_nonfinite_objectives_are_infeasible():
    class Holey(Problem):
        def __init__(self):
            super().__init__(n_var=2, n_obj=2, xl=0.0, xu=1.0)

        def _evaluate(self, x, out, *args, **kwargs):
            F = np.column_stack([x[:, 0], 1.0 - x[:, 0] + x[:, 1]])
            F[x[:, 0] < 0.3] = np.nan  # a "failed evaluation"
            out["F"] = F

    check = InvariantCheck()
    res, _ = run(Holey(), 0, check, n_ind_p=20, n_div=20, generations=100)
    assert np.all(np.isfinite(res.F)) and res.F[:, 0].min() >= 0.3


def test_generations_from_termination_and_errors():
    problem = get_problem("zdt1", n_var=3)
    alg = EvMOGA(n_ind_p=20, n_ind_ga=8)
    alg.setup(problem, termination=("n_eval", 20 + 8 * 15 + 3), seed=0)
    assert alg.schedule_generations == 16
    alg = EvMOGA(n_ind_p=20)
    alg.setup(problem, termination=("n_gen", 31), seed=0)
    assert alg.schedule_generations == 30
    with pytest.raises(ValueError, match="generations"):
        EvMOGA(n_ind_p=20).setup(problem, seed=0)
    with pytest.raises(ValueError, match="even"):
        EvMOGA(n_ind_ga=7)


def test_make_algorithm():
    alg = make_algorithm("evmoga", {"n_ind_ga": 4, "n_div": 50, "generations": 10}, pop_size=30)
    assert isinstance(alg, EvMOGA) and alg.n_ind_p == 30 and alg.n_ind_ga == 4
    with pytest.raises(ValueError, match="contradicts"):
        make_algorithm("evmoga", {"n_ind_p": 10}, pop_size=30)
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.algorithms.moo.nsga3 import NSGA3

    assert isinstance(make_algorithm("NSGA2", pop_size=40), NSGA2)
    nsga3 = make_algorithm("nsga3", pop_size=92, n_obj=3)
    assert isinstance(nsga3, NSGA3) and nsga3.ref_dirs.shape == (91, 3)  # 12 partitions
    for name in ALGORITHM_NAMES:
        assert make_algorithm(name, pop_size=20, n_obj=2) is not None
    with pytest.raises(ValueError, match="nsga2"):
        make_algorithm("nsga-17")


def test_rows_read_from_individuals_equal_pymoos_get():
    """The rows ev-MOGA reads from a population (attributes, not ``Population.get``) are pymoo's
    values bit for bit: constrained problem (CV computed on demand), and one without
    constraints (empty G and H)."""
    from pymoo.core.evaluator import Evaluator
    from pymoo.core.population import Population

    from casadrone.optimise.evmoga import _rows, _violation

    for name, kwargs in (("bnh", {}), ("zdt2", {"n_var": 5})):
        problem = get_problem(name, **kwargs)
        rng = np.random.default_rng(1)
        X = problem.xl + rng.random((37, problem.n_var)) * (problem.xu - problem.xl)
        pop = Evaluator().eval(problem, Population.new("X", X))
        widths = {"X": problem.n_var, "F": problem.n_obj, "G": problem.n_ieq_constr,
                  "H": problem.n_eq_constr, "CV": 1}
        rows = _rows(pop, widths)  # CV computed here, as pop.get would
        for key, width in widths.items():
            expected = np.asarray(pop.get(key), dtype=float).reshape(len(pop), width)
            assert rows[key].shape == expected.shape
            assert rows[key].tobytes() == expected.tobytes(), (name, key)
        F, cv = _violation(pop)
        assert F.tobytes() == rows["F"].tobytes() and cv.tobytes() == rows["CV"][:, 0].tobytes()


@pytest.mark.parametrize("n_ieq", [0, 1, 7, 8, 9, 19])
@pytest.mark.parametrize("n_eq", [0, 1, 11])
def test_violation_of_rows_at_once_is_pymoos_per_member(n_ieq, n_eq):
    """The violation computed for all rows at once equals pymoo's ``Individual.CV`` (its
    ``calc_cv``, one member at a time) bit for bit, with widths on both sides of numpy's
    8-element pairwise-summation block, equality constraints near pymoo's 1e-4 tolerance, and
    members whose CV pymoo had already computed (read as they are)."""
    from pymoo.core.population import Population

    from casadrone.optimise.evmoga import _rows

    rng = np.random.default_rng(n_ieq * 100 + n_eq)
    n = 60
    G = rng.normal(size=(n, n_ieq)) * rng.choice([1e-8, 1.0, 1e6], size=(n, n_ieq))
    H = rng.normal(scale=2e-4, size=(n, n_eq))
    widths = {"X": 2, "F": 3, "G": n_ieq, "H": n_eq, "CV": 1}
    for cached in (False, True):
        pop = Population.new("X", rng.random((n, 2)), "F", rng.random((n, 3)), "G", G, "H", H)
        expected = np.array([ind.CV for ind in pop]) if cached else None
        got = _rows(pop, widths)["CV"]
        if not cached:
            expected = np.array([ind.CV for ind in pop])
        assert got.shape == (n, 1)
        assert got.tobytes() == expected.reshape(n, 1).tobytes()
    assert (got > 0).any() == (n_ieq + n_eq > 0)  # violated rows were compared, where any


def test_population_of_rows_is_what_population_new_built():
    from pymoo.core.population import Population

    from casadrone.optimise.evmoga import ROW_KEYS, _population_of_rows

    rng = np.random.default_rng(2)
    rows = {"X": rng.random((9, 3)), "F": rng.random((9, 2)), "G": rng.random((9, 1)) - 0.5,
            "H": np.empty((9, 0)), "CV": rng.random((9, 1))}
    built = _population_of_rows(rows)
    old = Population.new(*[a for k in ROW_KEYS for a in (k, rows[k])])
    assert type(built) is Population and len(built) == len(old) == 9
    for a, b in zip(built, old, strict=True):
        for key in ROW_KEYS:
            assert a.get(key).tobytes() == b.get(key).tobytes()
            assert a.get(key).shape == b.get(key).shape
        assert a.evaluated == {"F", "G", "H"}
    rows["X"][0, 0] = 99.0  # the members own their values
    assert built[0].X[0] != 99.0


def test_checkpoint_stores_the_archive_once_and_resumes_its_optimum():
    """After a generation the optimum is the archive: pickled once, the optimum comes back equal;
    an optimum that differs from the archive (the archive edited since) is pickled as it is."""
    problem = get_problem("dtlz2", n_var=6, n_obj=3)
    alg = EvMOGA(n_ind_p=60, n_ind_ga=40, n_div=15, generations=30)
    alg.setup(problem, seed=4)
    for _ in range(12):
        alg.next()
    n = len(alg.box_archive)
    assert n > 40
    archive_bytes = sum(v.nbytes for v in alg.box_archive.rows.values())
    blob = pickle.dumps(alg)
    back = pickle.loads(blob)
    assert len(blob) < 1.5 * archive_bytes + 20_000  # not twice the archive
    for key in ("X", "F", "CV"):
        assert back.opt.get(key).tobytes() == alg.opt.get(key).tobytes()
    assert back._opt_rows["F"] is not back.box_archive.rows["F"]  # its own copy
    # the archive moves on after the optimum was set: both are pickled as they are
    alg.box_archive.offer({k: v[0] for k, v in alg.box_archive.rows.items()}
                          | {"F": alg.grid_min - 1.0})  # dominates all: A = {it}
    assert len(alg.box_archive) == 1
    back = pickle.loads(pickle.dumps(alg))
    assert len(back.opt) == n and len(back.box_archive) == 1
    assert back.opt.get("F").tobytes() == alg.opt.get("F").tobytes()

