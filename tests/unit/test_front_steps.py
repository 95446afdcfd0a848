"""The ε-continuation's step control (casadrone.codesign.front.continued), against a solver
whose convergence region is known: a warm solve converges only when its ε is within a factor
``reach`` of the point it starts from (the property that makes shorter continuation steps
work). The oracle is the sequence of ε a step-halving continuation must visit: geometric
midpoints, each solved from the last converged point."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

import casadrone.codesign.front as front


def _solver(reach: float, calls: list, budgets: list | None = None):
    def solve_from(prep, z0, epsilon, warm=None, step=False, budget_s=None):
        eps = epsilon["effort"]
        start = warm.epsilon["effort"]
        calls.append((start, eps, step))
        if budgets is not None:
            budgets.append(budget_s)
        ok = abs(math.log(eps / start)) <= math.log(reach) + 1e-12
        return ok, "Solve_Succeeded" if ok else "Maximum_Iterations_Exceeded", \
            SimpleNamespace(z=None, epsilon={"effort": eps})
    return solve_from


def _point(eps: float):
    return SimpleNamespace(z=None, epsilon={"effort": eps})


def test_a_step_within_reach_is_one_capped_solve(monkeypatch):
    calls: list = []
    monkeypatch.setattr(front, "solve_from", _solver(1.5, calls))
    ok, status, pt = front.continued(None, _point(100.0), "effort", 100.0, 80.0)
    assert ok and pt.epsilon["effort"] == 80.0
    assert calls == [(100.0, 80.0, True)]  # the step solver (iteration cap), not the plain warm


def test_a_step_out_of_reach_is_halved_geometrically(monkeypatch):
    """100 → 64 is a factor 1.5625: beyond reach 1.3, its halves (100 → 80 → 64, factor 1.25
    each) are within it."""
    calls: list = []
    monkeypatch.setattr(front, "solve_from", _solver(1.3, calls))
    ok, _, pt = front.continued(None, _point(100.0), "effort", 100.0, 64.0)
    assert ok and pt.epsilon["effort"] == 64.0
    assert [(a, pytest.approx(b)) for a, b, _ in calls] == [(100.0, 64.0), (100.0, 80.0),
                                                            (80.0, 64.0)]


def test_two_levels_of_halving_then_the_sweep_stops(monkeypatch):
    """A factor 16 needs four steps of 2 (two levels of halving); a factor 256 would need
    three levels, more than MAX_SPLITS = 2: the step fails, named with where it was halved."""
    calls: list = []
    monkeypatch.setattr(front, "solve_from", _solver(2.0, calls))
    ok, _, pt = front.continued(None, _point(256.0), "effort", 256.0, 16.0)
    assert ok and pt.epsilon["effort"] == pytest.approx(16.0)
    visited = [b for _, b, _ in calls]
    for eps in (128.0, 64.0, 32.0, 16.0):
        assert any(v == pytest.approx(eps) for v in visited)
    calls.clear()
    ok, status, _ = front.continued(None, _point(256.0), "effort", 256.0, 1.0)
    assert not ok
    assert "halved at ε = 16" in status
    assert front.MAX_SPLITS == 2


def test_a_step_budget_follows_the_slowest_converged_step():
    """No budget without history (the solver's own guard holds); then a few times the slowest
    solve so far, never below the floor: a paper front's lost step is cut at tens of seconds,
    a propeller front's 109 s steps get several minutes (a fixed 120 s cap stopped one)."""
    from casadrone.codesign import nlp

    assert front.step_budget([]) is None
    assert front.step_budget([1.0, 2.0]) == nlp.STEP_MIN_CPU_S  # 3 × 2 s is below the floor
    slow = 2 * nlp.STEP_MIN_CPU_S
    assert front.step_budget([1.0, slow, 3.0]) == pytest.approx(nlp.STEP_CPU_FACTOR * slow)
    assert front.step_budget([10.7, 6.4]) < 40.0  # the paper front: its lost step took 128 s
    assert front.step_budget([79.0, 109.3]) > 120.0  # the propeller front's next step
    assert front.step_budget([109.3]) < nlp.STEP_MAX_CPU_S  # the solver's guard stays above


def _rosenbrock(budget=None):
    import casadi as ca

    x = ca.MX.sym("x", 2)
    options = {"ipopt": {"print_level": 0, "sb": "yes"}, "print_time": False,
               "error_on_fail": False}
    if budget is not None:
        options["iteration_callback"] = budget
    f = (1 - x[0]) ** 2 + 100 * (x[1] - x[0] ** 2) ** 2
    return ca.nlpsol("rosen", "ipopt", {"x": x, "f": f}, options)


def test_the_cpu_budget_stops_ipopt_and_otherwise_leaves_it_alone():
    """Rosenbrock's function from (−1.2, 1) (minimum at (1, 1), about 20 IPOPT iterations):
    with an unlimited budget the solve is bit-identical to one without the callback; a spent
    budget stops IPOPT at its first iteration with the status the driver reads."""
    import numpy as np

    from casadrone.codesign.budget import STOPPED, CpuBudget

    plain = _rosenbrock()
    reference = np.array(plain(x0=[-1.2, 1.0])["x"]).ravel()
    assert plain.stats()["success"] and np.allclose(reference, [1.0, 1.0], atol=1e-6)
    budget = CpuBudget("budget", 2, 0, 0)
    solver = _rosenbrock(budget)
    budget.start(None)
    x = np.array(solver(x0=[-1.2, 1.0])["x"]).ravel()
    assert solver.stats()["success"] and np.array_equal(x, reference)
    assert solver.stats()["iter_count"] == plain.stats()["iter_count"]
    budget.start(0.0)
    solver(x0=[-1.2, 1.0])
    assert solver.stats()["return_status"] == STOPPED
    assert solver.stats()["iter_count"] <= 1


def test_every_solve_of_a_halved_step_gets_the_step_budget(monkeypatch):
    calls: list = []
    budgets: list = []
    monkeypatch.setattr(front, "solve_from", _solver(1.3, calls, budgets))
    ok, _, _ = front.continued(None, _point(100.0), "effort", 100.0, 64.0, budget_s=7.0)
    assert ok and len(calls) == 3 and budgets == [7.0, 7.0, 7.0]
