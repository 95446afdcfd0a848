"""Warm starts of the limit-lap NLP (casadrone.limit.nlp: ``near`` and far IPOPT settings).

Oracles: the double integrator's analytic bang-bang time, out to x = L and back under
|a| ≤ A in T = (2 + √2)√(L/A); IPOPT from a cold start on the same NLP; and the property that
a primal-dual start at an optimum is already one (a warm solve must return it at once).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from casadrone.limit.nlp import (
    NEAR_VIOLATION,
    Layout,
    build_nlp,
    ipopt_options,
    solve,
    start_violation,
    target_vector,
    warm_solver,
)
from casadrone.propulsion import PROPELLER
from tests.unit.test_limitlap import _double_integrator

A_MAX = 2.0


def _problem(distance_m: float, intervals: int = 20, propulsion: str = "paper"):
    kinds, L = ("ball", "ball"), 2
    M = intervals * L
    nlp = build_nlp(replace(_double_integrator(), propulsion=propulsion), Layout(kinds, intervals))
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.array([[distance_m, 0, 0], [0, 0, 0]]), kinds, np.zeros(L), np.zeros(L),
        np.zeros(L), 0.0)])
    lbx = nlp.pack(np.full(L, 1e-2), np.full((M + 1, 6), -np.inf), np.full((M, 3), -A_MAX))
    ubx = nlp.pack(np.full(L, 1e2), np.full((M + 1, 6), np.inf), np.full((M, 3), A_MAX))
    w0 = nlp.pack(np.ones(L), np.zeros((M + 1, 6)), np.zeros((M, 3)))
    return nlp, P, lbx, ubx, w0


def _exact(distance_m: float) -> float:
    return (2 + math.sqrt(2)) * math.sqrt(distance_m / A_MAX)


def test_warm_solve_from_the_optimum_returns_it_at_once():
    """A primal-dual start at the cold solve's optimum is near (violation ~0, the ``near``
    solver), and the warm solve returns the same lap in at most 3 iterations (observed 2, at tol
    1e-8) with the same multipliers (observed 2e-12); the far setting, asked directly, returns
    it as well (on the quadrotor lap it takes ~10 iterations there against 0 for ``near``:
    RESULTS-limitlap-solvers.md)."""
    nlp, P, lbx, ubx, w0 = _problem(10.0)
    cold = solve(nlp, w0, P, lbx, ubx)
    assert cold.success, cold.return_status
    np.testing.assert_allclose(cold.objective, _exact(10.0), rtol=1e-3)
    w = np.clip(cold.point.w, lbx, ubx)
    assert start_violation(nlp, w, P, nlp.lbg, nlp.ubg) <= 1e-6
    assert warm_solver(nlp, w, P, nlp.lbg, nlp.ubg) is nlp.near
    again = solve(nlp, w0, P, lbx, ubx, warm=cold.point, near=True)
    assert again.success and again.iterations <= 3, (again.return_status, again.iterations)
    np.testing.assert_allclose(again.objective, cold.objective, rtol=1e-9)
    np.testing.assert_allclose(again.point.lam_p, cold.point.lam_p, rtol=1e-6, atol=1e-9)
    far = nlp.warm(x0=w, p=P, lbx=lbx, ubx=ubx, lbg=nlp.lbg, ubg=nlp.ubg,
                   lam_x0=cold.point.lam_x, lam_g0=cold.point.lam_g)
    np.testing.assert_allclose(float(far["f"]), cold.objective, rtol=1e-7)


def test_warm_solve_after_a_parameter_change_reaches_the_analytic_time():
    """The target moved from 10 m to 10.1 m (a parameter of the same NLP): from the old
    optimum (near: violation (0.1 m)² ≤ NEAR_VIOLATION) the warm solve reaches the analytic time
    of the new distance to the grid's error (1e-3, as the cold solve) and the cold solve's lap
    to 1e-7 (observed 4e-16), in fewer iterations than the cold solve (observed 16 against 30);
    from the optimum of 10 m for 14 m (violation 16 m²: far) it gets there too, with the far
    setting."""
    nlp, P, lbx, ubx, w0 = _problem(10.0)
    base = solve(nlp, w0, P, lbx, ubx)
    for distance_m, which in ((10.1, "near"), (14.0, "warm")):
        _, P2, *_ = _problem(distance_m)
        cold = solve(nlp, w0, P2, lbx, ubx)
        w = np.clip(base.point.w, lbx, ubx)
        moved = start_violation(nlp, w, P2, nlp.lbg, nlp.ubg)
        # the ball row is |p − c|² ≤ r² (r = 0 here): the violation is the squared miss
        np.testing.assert_allclose(moved, (distance_m - 10.0) ** 2, rtol=1e-2)  # observed 2e-3
        assert warm_solver(nlp, w, P2, nlp.lbg, nlp.ubg) is getattr(nlp, which)
        assert (moved <= NEAR_VIOLATION) == (which == "near")
        warm = solve(nlp, w0, P2, lbx, ubx, warm=base.point, near=True)
        assert cold.success and warm.success, (cold.return_status, warm.return_status)
        np.testing.assert_allclose(warm.objective, _exact(distance_m), rtol=1e-3)
        np.testing.assert_allclose(warm.objective, cold.objective, rtol=1e-7)
        if which == "near":
            assert warm.iterations < cold.iterations, (warm.iterations, cold.iterations)


def test_per_kind_warm_settings_leave_paper_and_the_other_solvers_alone():
    """Only the far warm setting of a kind with warm IPOPT settings (``warm_ipopt``) changes:
    ``paper``'s options (and so its solves) are those without a kind, the cold and near ones the
    same for every kind."""
    base = ipopt_options(1e-6, 100, True)
    assert ipopt_options(1e-6, 100, True, propulsion="paper") == base
    for kind in ("paper", "propeller"):
        assert ipopt_options(1e-6, 100, False, propulsion=kind) == ipopt_options(1e-6, 100, False)
        assert ipopt_options(1e-6, 100, True, near=True, propulsion=kind) == \
            ipopt_options(1e-6, 100, True, near=True)
    prop = ipopt_options(1e-6, 100, True, propulsion="propeller")["ipopt"]
    assert prop == base["ipopt"] | dict(PROPELLER.warm_ipopt) != base["ipopt"]


def test_propeller_warm_setting_reaches_the_same_optimum():
    """The ``propeller`` far warm setting (σ_min) changes IPOPT's path, not its convergence
    test: from the optimum of 10 m, the 14 m problem reaches the analytic time to the grid's
    error (observed 5e-6) and the cold solve's lap to 1e-7 (observed 4e-16), as the common setting
    does."""
    for kind in ("paper", "propeller"):
        nlp, P, lbx, ubx, w0 = _problem(10.0, propulsion=kind)
        base = solve(nlp, w0, P, lbx, ubx)
        _, P2, *_ = _problem(14.0, propulsion=kind)
        cold = solve(nlp, w0, P2, lbx, ubx)
        warm = solve(nlp, w0, P2, lbx, ubx, warm=base.point)
        assert cold.success and warm.success, (kind, cold.return_status, warm.return_status)
        np.testing.assert_allclose(warm.objective, _exact(14.0), rtol=1e-3)
        np.testing.assert_allclose(warm.objective, cold.objective, rtol=1e-7)
