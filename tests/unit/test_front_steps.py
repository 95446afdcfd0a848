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


def _solver(reach: float, calls: list):
    def solve_from(prep, z0, epsilon, warm=None, step=False):
        eps = epsilon["effort"]
        start = warm.epsilon["effort"]
        calls.append((start, eps, step))
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
