"""Limit lap: analytic oracle (double integrator), relaxation bound, re-simulation, gates, CLI.

Solves of the 16-state model take seconds to minutes on a loaded machine: those tests are
``slow``; the default run keeps the analytic oracle, the gate geometry and the CLI's bad input.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from casadrone.config.airframe import load_airframe
from casadrone.config.io import ConfigError, load
from casadrone.config.track import TrackConfig
from casadrone.evaluate import DEFAULT_TRACK
from casadrone.limit.check import target_miss
from casadrone.limit.lap import LimitLapOptions, limit_lap, track_targets
from casadrone.limit.nlp import Layout, OcpModel, build_nlp, solve, target_vector

TRACK = load(TrackConfig, DEFAULT_TRACK)


def _double_integrator() -> OcpModel:
    x = ca.SX.sym("x", 6)
    u = ca.SX.sym("u", 3)
    p = ca.SX.sym("p", 1)
    f = ca.Function("f_di", [x, u, p], [ca.vertcat(x[3:6], u)], ["x", "u", "p"], ["xdot"])
    return OcpModel("double-integrator", f, lambda s: s[3:6])


def _solve_double_integrator(points, a_max, end_at_rest=False, intervals=20):
    model = _double_integrator()
    kinds = ("ball",) * len(points)
    nlp = build_nlp(model, Layout(kinds, intervals, end_at_rest=end_at_rest))
    L, M = len(points), len(points) * intervals
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.asarray(points, float), kinds, np.zeros(L), np.zeros(L), np.zeros(L), 0.0)])
    zl, zu = np.full((M, 3, 6), -np.inf), np.full((M, 3, 6), np.inf)
    lbx = nlp.pack(np.full(L, 1e-2), np.full((M + 1, 6), -np.inf), np.full((M, 3), -a_max), zl)
    ubx = nlp.pack(np.full(L, 1e2), np.full((M + 1, 6), np.inf), np.full((M, 3), a_max), zu)
    w0 = nlp.pack(np.ones(L), np.zeros((M + 1, 6)), np.zeros((M, 3)))
    sol = solve(nlp, w0, P, lbx, ubx)
    assert sol.success, sol.return_status
    return nlp.unpack(sol.point.w)[0]


def test_double_integrator_out_and_back_matches_bang_bang():
    """Rest at 0, touch x = L, back to 0 with |a| ≤ A: +A until the peak at L (t = 2√(L/A)
    with the switch at √(L/A)), then −A back: T = (2 + √2)√(L/A)."""
    L, A = 10.0, 2.0
    T = _solve_double_integrator([[L, 0, 0], [0, 0, 0]], A)
    np.testing.assert_allclose(T.sum(), (2 + math.sqrt(2)) * math.sqrt(L / A), rtol=1e-3)
    np.testing.assert_allclose(T[0], 2 * math.sqrt(L / A), rtol=1e-3)


def test_double_integrator_rest_to_rest_through_a_point():
    """Rest to rest over D through a point at D/4 on the way: T = 2√(D/A); the point is passed
    while accelerating, at t = √(2 (D/4) / A)."""
    D, A = 12.0, 3.0
    T = _solve_double_integrator([[D / 4, 0, 0], [D, 0, 0]], A, end_at_rest=True, intervals=40)
    np.testing.assert_allclose(T.sum(), 2 * math.sqrt(D / A), rtol=1e-3)
    np.testing.assert_allclose(T[0], math.sqrt(2 * D / 4 / A), rtol=1e-3)


def _nonlinear_toy() -> OcpModel:
    """A planar 'drone' with quadratic drag, thrust along a rotating axis and a lagged thrust:
    every second derivative the quadrotor's RK4 step has (products, trig, |v|v), small."""
    x = ca.SX.sym("x", 7)  # px, py, pz, vx, vy, vz ... reused: angle x[6]
    u = ca.SX.sym("u", 2)
    p = ca.SX.sym("p", 2)
    acc = ca.vertcat(u[0] * ca.sin(x[6]), 0.3 * x[3] * x[4], u[0] * ca.cos(x[6]) - 9.81) \
        - p[0] * ca.fabs(x[3:6]) * x[3:6]
    f = ca.Function("f_toy", [x, u, p], [ca.vertcat(x[3:6], acc, p[1] * u[1])],
                    ["x", "u", "p"], ["xdot"])
    return OcpModel("toy", f, lambda s: s[3:6])


def test_assembled_derivatives_equal_casadi_ad():
    """The constraint Jacobian and Lagrangian Hessian assembled from the compiled interval
    blocks equal CasADi's own AD of the same NLP, entry by entry (ball and gate targets, a
    rest condition, 3 intervals per leg, random point and multipliers)."""
    from casadrone.limit.nlp import _shooting_nlp

    model = _nonlinear_toy()
    layout = Layout(("ball", "gate"), 3, substeps=2, end_at_rest=True)
    nlp, lbg, ubg, extra = _shooting_nlp(model, layout)
    W, P = nlp["x"], nlp["p"]
    lam_g = ca.MX.sym("lam_g", nlp["g"].numel())
    ref_jac = ca.Function("J", [W, P], [ca.jacobian(nlp["g"], W)])
    ref_hess = ca.Function("H", [W, P, lam_g], [ca.triu(ca.hessian(
        nlp["f"] + ca.dot(lam_g, nlp["g"]), W)[0])])
    rng = np.random.default_rng(3)
    w = rng.uniform(0.2, 1.5, W.numel())
    prm = rng.uniform(0.1, 1.0, P.numel())
    lam = rng.normal(size=lam_g.numel())
    g, J = extra["jac_g"](w, prm)
    H = extra["hess_lag"](w, prm, 1.0, lam)
    assert len(lbg) == len(ubg) == g.numel() and np.isfinite(np.array(g)).all()
    np.testing.assert_allclose(np.array(J), np.array(ref_jac(w, prm)), rtol=1e-10, atol=1e-11)
    np.testing.assert_allclose(np.array(H), np.array(ref_hess(w, prm, lam)), rtol=1e-10,
                               atol=1e-11)
    assert np.abs(np.array(H)).max() > 1e-3  # the Hessian is not trivially zero


def test_gate_miss_geometry():
    """A gate 2 m wide (half 1 m) facing north: inside → 0; 0.5 m beside the opening → 0.5 m;
    0.3 m in front of the plane → 0.3 m."""
    tp = np.array([0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, 0.0])
    assert target_miss(np.array([0.9, 0.0, 1.5]), tp, "gate") == 0.0
    np.testing.assert_allclose(target_miss(np.array([-1.5, 0.0, 1.0]), tp, "gate"), 0.5)
    np.testing.assert_allclose(target_miss(np.array([0.0, -0.3, 1.0]), tp, "gate"), 0.3)
    ball = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5])
    np.testing.assert_allclose(target_miss(np.array([0.0, 2.0, 0.0]), ball, "ball"), 1.5)


def test_gate_track_flies_through_gate_centres():
    trk = load(TrackConfig, "configs/tracks/multigp-cdra-gates.yaml")
    assert [tuple(g.centre_m) for g in trk.gates] == [tuple(w) for w in trk.waypoints_m]
    assert all(g.width_m == pytest.approx(5 * 0.3048) for g in trk.gates)
    targets = track_targets(trk, LimitLapOptions())
    assert targets.kinds == ("gate",) * len(trk.gates)
    with pytest.raises(ConfigError):  # both ways at once is refused
        load(TrackConfig, "configs/tracks/multigp-cdra-gates.yaml",
             ["waypoints_m=[[0, 0, 1], [1, 0, 1], [2, 0, 1], [3, 0, 1], [4, 0, 1], [5, 0, 1]]"])


def test_too_small_gate_is_a_failed_result_not_an_exception():
    trk = load(TrackConfig, "configs/tracks/multigp-cdra-gates.yaml")
    lap = limit_lap(load_airframe("SY250"), trk, LimitLapOptions(gate_clearance_m=1.0))
    assert lap.status == "failed" and "clearance" in lap.reason


def test_cli_bad_track_and_heavy_frame_exit_2(cli_runner, tmp_path):
    from casadrone.cli import app

    bad = tmp_path / "bad.yaml"
    bad.write_text("name: bad\nwaypoints_m: [[0, 0, 1]]\nstraight: [true, false]\n")
    r = cli_runner.invoke(app, ["limit-lap", "SY250", "--track", str(bad), "--json"])
    assert r.exit_code == 2 and "Traceback" not in r.output
    assert "straight" in r.stderr
    r = cli_runner.invoke(app, ["limit-lap", "SY250", "mass_kg=4", "--json"])
    assert r.exit_code == 2 and "cannot hover" in r.stderr and "Traceback" not in r.output


def test_j3_limit_is_a_limit_index_outside_closed_loop_indices():
    from casadrone.indices import BUILTIN_LIMIT_NAMES, INDICES, limit_index_names

    assert BUILTIN_LIMIT_NAMES == ("J3_limit",)
    assert INDICES["J3_limit"].source == "limit" and INDICES["J3_limit"].sense == "min"
    assert limit_index_names(["J1", "J3_limit", "J5"]) == ("J3_limit",)


def test_limit_lap_problem_sets_up_limit_options_and_references():
    from casadrone.optimise.checks import load_problem
    from casadrone.optimise.problem import limit_setup

    problem = load_problem("limit-lap")
    template = load_airframe(problem.airframe)
    extra = limit_setup(problem, template)
    assert extra["limit"] is not None
    assert len(extra["limit_references"]) == 2  # the template and the centre of the box
    assert extra["limit_references"][1]["alpha_deg"] == pytest.approx(77.5)
    assert limit_setup(load_problem("quick"), template) == {}


def test_resampled_start_keeps_the_coarse_lap_on_a_finer_grid():
    """Grid refinement's start: on twice the intervals, every other node is a coarse node (same
    state), both halves of a coarse interval hold its command, and the leg durations stay."""
    from casadrone.limit.lap import LimitLap, guess_from_lap, node_times

    model = _double_integrator()
    coarse = build_nlp(model, Layout(("ball", "ball"), 4))
    fine = build_nlp(model, Layout(("ball", "ball"), 8))
    rng = np.random.default_rng(0)
    T = np.array([1.5, 0.7])
    X, U = rng.normal(size=(9, 6)), rng.normal(size=(8, 3))
    lap = LimitLap(status="optimal", reason="", leg_times_s=T, t=node_times(T, 4), x=X, u=U,
                   layout=coarse.layout)
    Tf, Xf, Uf = fine.unpack(guess_from_lap(fine, lap, X[0]))
    np.testing.assert_allclose(Tf, T)
    np.testing.assert_allclose(Xf[::2], X, atol=1e-12)
    np.testing.assert_allclose(Xf[1::2], 0.5 * (X[:-1] + X[1:]), atol=1e-12)
    np.testing.assert_allclose(Uf[::2], U)
    np.testing.assert_allclose(Uf[1::2], U)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_assemble_sums_duplicate_triplets_like_numpy(seed):
    """The sparse assembly of the NLP's Jacobian and Hessian (values gathered into a CasADi
    sparsity) equals numpy's accumulation of the same triplets: duplicates (up to 4 per entry)
    are summed, every other entry is zero, and the pattern is the triplets' own."""
    from casadrone.limit.nlp import _assemble

    rng = np.random.default_rng(seed)
    nrow, ncol, n = 7, 9, 60
    rows, cols = rng.integers(nrow, size=n), rng.integers(ncol, size=n)
    values = ca.MX.sym("v", n)
    A = _assemble(nrow, ncol, rows, cols, values)
    v = rng.normal(size=n)
    got = np.array(ca.Function("a", [values], [ca.densify(A)])(v))
    expected = np.zeros((nrow, ncol))
    np.add.at(expected, (rows, cols), v)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-14)
    assert A.nnz() == len(set(zip(rows.tolist(), cols.tolist(), strict=True)))
    assert np.bincount(rows * ncol + cols).max() >= 3  # duplicates were exercised
