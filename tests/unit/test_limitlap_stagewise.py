"""The limit-lap NLP in stage order and fatrop on it (casadrone.limit.stagewise).

Oracles: the stage-ordered functions against the original NLP's, evaluated and permuted by
numpy (not by the module's own gathers); fatrop's structure rules checked on the permuted
Jacobian directly; the double integrator's analytic bang-bang time; IPOPT on the same NLP.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from casadrone.config.io import CONFIG_DIR
from casadrone.limit.nlp import Layout, build_nlp, solve, target_vector
from casadrone.limit.stagewise import (
    StageError,
    fatrop_solver,
    stage_order,
    stagewise_functions,
)
from tests.unit.test_limitlap import _double_integrator, _nonlinear_toy


def _order(nlp):
    pr = nlp.problem
    return stage_order(ca.jacobian_sparsity(pr["g"], pr["x"]), nlp.layout.intervals,
                       nlp.layout.n_intervals, nlp.model.nx, nlp.model.nu)


@pytest.mark.parametrize("kinds, cone", [(("ball", "gate"), False),
                                         (("circle", "polygon"), True)])
def test_permuted_nlp_evaluates_identically_to_the_original(kinds, cone):
    """At a random point and multipliers: f equal; g, the Jacobian and the full Hessian equal
    the original's (Hessian: its upper triangle mirrored by numpy) permuted by numpy indexing,
    to the last bit; the Lagrangian gradient equals ∇f + Jᵀλ by numpy (observed agreement
    ~1e-15)."""
    model = _nonlinear_toy()
    nlp = build_nlp(model, Layout(kinds, 3, substeps=2, end_at_rest=True, tilt_cone=cone))
    order = _order(nlp)
    fns = stagewise_functions(nlp.problem, nlp.derivatives["jac_g"],
                              nlp.derivatives["hess_lag"], order)
    rng = np.random.default_rng(5)
    w = rng.uniform(0.2, 1.5, nlp.problem["x"].numel())
    prm = rng.uniform(0.1, 1.0, nlp.problem["p"].numel())
    lam = rng.normal(size=len(nlp.lbg))
    col, row = order.col, order.row
    assert sorted(col) == list(range(len(w))) and sorted(row) == list(range(len(lam)))
    g0, J0 = (np.array(ca.densify(a)) for a in nlp.derivatives["jac_g"](w, prm))
    Hu = np.array(ca.densify(nlp.derivatives["hess_lag"](w, prm, 1.0, lam)))
    H0 = Hu + Hu.T - np.diag(np.diag(Hu))
    f0 = float(ca.Function("f", [nlp.problem["x"], nlp.problem["p"]], [nlp.problem["f"]])(w, prm))
    ws, lam_s = w[col], lam[row]
    assert float(fns["nlp_f"](ws, prm)) == f0
    np.testing.assert_array_equal(np.array(fns["nlp_g"](ws, prm)).ravel(), g0.ravel()[row])
    g, J = fns["nlp_jac_g"](ws, prm)
    np.testing.assert_array_equal(np.array(g).ravel(), g0.ravel()[row])
    np.testing.assert_array_equal(np.array(ca.densify(J)), J0[np.ix_(row, col)])
    grad, H = fns["nlp_hess_l"](ws, prm, 1.0, lam_s)
    np.testing.assert_array_equal(np.array(ca.densify(H)), H0[np.ix_(col, col)])
    grad_f = np.array(ca.densify(fns["nlp_grad_f"](ws, prm))).ravel()
    np.testing.assert_allclose(np.array(grad).ravel(), grad_f + J0[np.ix_(row, col)].T @ lam_s,
                               rtol=1e-13, atol=1e-13)
    assert np.abs(H0).max() > 1e-3


def test_a_fatrop_solve_beats_for_its_guard_at_every_iteration(monkeypatch):
    """The guard of a forked fatrop solve (casadrone.limit.watchdog) ends a child that has not
    beaten for ``stall_s``: a solve must beat at least once per iteration, or a slow but healthy
    solve would be killed. Counted on a real fatrop solve (unguarded, the beat function
    replaced by a counter): at least as many beats as fatrop's own iteration count."""
    from casadrone.limit import stagewise

    beats = []
    monkeypatch.setattr(stagewise, "beat", lambda: beats.append(1))
    nlp, w0, P, lbx, ubx = out_and_back()
    ok, status, _, _, iterations = stagewise.solve_stagewise(
        fatrop_solver(nlp, nlp.tol, nlp.max_iter), w0, P, lbx, ubx, nlp.lbg, nlp.ubg, False)
    assert ok, status
    assert iterations >= 5 and len(beats) >= iterations, (iterations, len(beats))


def test_mumps_working_space_changes_no_iterate():
    """casadrone gives MUMPS 20 % working space above its estimate (MUMPS_MEM_PERCENT) where
    IPOPT's default gives 1000 %: the space must change the time only. The solve with the
    shipped settings equals IPOPT's default space to the last bit (point, multipliers,
    iteration count)."""
    from casadrone.limit.nlp import MUMPS_MEM_PERCENT, ipopt_solver

    nlp, w0, P, lbx, ubx = out_and_back()
    args = {"x0": w0, "p": P, "lbx": lbx, "ubx": ubx, "lbg": nlp.lbg, "ubg": nlp.ubg}
    ours, default = nlp.cold, ipopt_solver(nlp, "default_space", {"mumps_mem_percent": 1000})
    a, b = ours(**args), default(**args)
    assert MUMPS_MEM_PERCENT < 1000 and ours.stats()["success"], ours.stats()["return_status"]
    for key in ("x", "lam_g", "lam_x"):
        np.testing.assert_array_equal(np.array(a[key]), np.array(b[key]))
    assert ours.stats()["iter_count"] == default.stats()["iter_count"] >= 5


def test_stage_order_has_fatrop_structure():
    """Checked on the permuted Jacobian's pattern, not on the module's bookkeeping: every row
    lies within one stage's columns or is a gap row of stage k whose only stage-(k+1) entry is
    a state of k+1 with coefficient +1; gap rows come first in each stage, in the order of the
    states they define; the dimensions add up."""
    model = _nonlinear_toy()
    nlp = build_nlp(model, Layout(("ball", "gate"), 3, substeps=2, end_at_rest=True))
    o = _order(nlp)
    fns = stagewise_functions(nlp.problem, nlp.derivatives["jac_g"],
                              nlp.derivatives["hess_lag"], o)
    rng = np.random.default_rng(1)
    J = np.array(ca.densify(fns["nlp_jac_g"](rng.uniform(0.2, 1, len(o.col)),
                                             rng.uniform(0.1, 1, nlp.problem["p"].numel()))[1]))
    nxu = np.add(o.nx, o.nu)
    start = np.concatenate([[0], np.cumsum(nxu)])
    assert start[-1] == J.shape[1] and sum(o.ng) + sum(o.nx[1:]) == J.shape[0]
    r = 0
    for k in range(o.n_stages):
        if k + 1 < o.n_stages:
            for i in range(o.nx[k + 1]):
                nz = np.flatnonzero(J[r])
                later = nz[nz >= start[k + 1]]
                assert list(later) == [start[k + 1] + i] and J[r, later[0]] == 1.0
                assert nz.min() >= start[k]
                r += 1
        for _ in range(o.ng[k]):
            nz = np.flatnonzero(J[r])
            assert nz.min() >= start[k] and nz.max() < start[k + 1]
            r += 1
    assert r == J.shape[0]
    # inside a leg the duration is a state (nx + 1), at a leg's start a control
    assert o.nx[1] == model.nx + 1 and o.nx[3] == model.nx and o.nu[3] == model.nu + 1


def test_stage_order_refuses_a_row_coupling_distant_stages():
    """A row tying the first node to the last (a periodic lap, say) has no stage: refused."""
    nlp = build_nlp(_double_integrator(), Layout(("ball", "ball"), 4))
    pr = nlp.problem
    x = pr["x"]
    g = ca.vertcat(pr["g"], x[0] - x[x.numel() - 1])
    with pytest.raises(StageError, match="couples stages"):
        stage_order(ca.jacobian_sparsity(g, pr["x"]), 4, 8, 6, 3)
    stage_order(ca.jacobian_sparsity(pr["g"], pr["x"]), 4, 8, 6, 3)  # without it: accepted


def _double_integrator_bounds(nlp, L, M, a_max):
    lbx = nlp.pack(np.full(L, 1e-2), np.full((M + 1, 6), -np.inf), np.full((M, 3), -a_max))
    ubx = nlp.pack(np.full(L, 1e2), np.full((M + 1, 6), np.inf), np.full((M, 3), a_max))
    return lbx, ubx


def out_and_back():
    """The double integrator out to x = 10 m and back under |a| ≤ 2 m/s², 10 intervals per leg:
    (nlp, start, P, lbx, ubx)."""
    kinds, N, L = ("ball", "ball"), 10, 2
    M = N * L
    nlp = build_nlp(_double_integrator(), Layout(kinds, N))
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.array([[10.0, 0, 0], [0, 0, 0]]), kinds, np.zeros(L), np.zeros(L), np.zeros(L), 0.0)])
    lbx, ubx = _double_integrator_bounds(nlp, L, M, 2.0)
    return nlp, nlp.pack(np.ones(L), np.zeros((M + 1, 6)), np.zeros((M, 3))), P, lbx, ubx


@pytest.mark.parametrize("end_at_rest", [False, True])
def test_fatrop_and_ipopt_reach_the_analytic_double_integrator_time(end_at_rest):
    """Out to x = L and back under |a| ≤ A: T = (2 + √2)√(L/A) with a free end, 2·2√(L/A) at
    rest (rest to rest each way). fatrop and IPOPT from the same start agree to 1e-7 relative
    (observed 1.4e-8) and both match the analytic time to 1e-3 (the grid's error); fatrop's
    parameter multipliers (∂T/∂P) match IPOPT's (observed 4e-9)."""
    L_m, A = 10.0, 2.0
    kinds, N, L = ("ball", "ball"), 20, 2
    M = N * L
    nlp = build_nlp(_double_integrator(), Layout(kinds, N, end_at_rest=end_at_rest))
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.array([[L_m, 0, 0], [0, 0, 0]]), kinds, np.zeros(L), np.zeros(L), np.zeros(L), 0.0)])
    lbx, ubx = _double_integrator_bounds(nlp, L, M, A)
    w0 = nlp.pack(np.ones(L), np.zeros((M + 1, 6)), np.zeros((M, 3)))
    ip = solve(nlp, w0, P, lbx, ubx)
    fa = solve(nlp, w0, P, lbx, ubx, solver="fatrop")
    assert ip.success and fa.success and fa.solver == "fatrop", (ip.return_status,
                                                                   fa.return_status)
    exact = (2 + math.sqrt(2)) * math.sqrt(L_m / A) if not end_at_rest else \
        4 * math.sqrt(L_m / A)
    np.testing.assert_allclose(fa.objective, exact, rtol=1e-3)
    np.testing.assert_allclose(fa.objective, ip.objective, rtol=1e-7)
    np.testing.assert_allclose(fa.point.lam_p, ip.point.lam_p, atol=1e-6)
    T_fa = nlp.unpack(fa.point.w)[0]
    np.testing.assert_allclose(T_fa, nlp.unpack(ip.point.w)[0], rtol=1e-4)


def test_fatrop_failure_falls_back_to_ipopt():
    """fatrop with one iteration (it counts the start as well) cannot converge: the solve says
    so and returns IPOPT's point from the same start (IPOPT's optimum, fatrop's status kept)."""
    from dataclasses import replace

    from casadrone.limit import stagewise

    kinds, N, L = ("ball", "ball"), 10, 2
    M = N * L
    nlp = build_nlp(_double_integrator(), Layout(kinds, N))
    short = replace(nlp, max_iter=1)
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.array([[10.0, 0, 0], [0, 0, 0]]), kinds, np.zeros(L), np.zeros(L), np.zeros(L), 0.0)])
    lbx, ubx = _double_integrator_bounds(nlp, L, M, 2.0)
    w0 = nlp.pack(np.ones(L), np.zeros((M + 1, 6)), np.zeros((M, 3)))
    sol = solve(short, w0, P, lbx, ubx, solver="fatrop")
    assert fatrop_solver(short, short.tol, 1) is stagewise._FATROP[
        (short.model.name, short.layout, short.tol, 1)]
    assert sol.solver == "ipopt" and sol.success and sol.fatrop is not None
    assert sol.fatrop[1] <= 2 and sol.fatrop[0] != "Solve_Succeeded"
    ref = solve(nlp, w0, P, lbx, ubx)
    np.testing.assert_allclose(sol.objective, ref.objective, rtol=1e-9)


def test_cli_unknown_solver_exits_2(cli_runner):
    from casadrone.cli import app

    r = cli_runner.invoke(app, ["limit-lap", "SY250", "--solver", "snopt", "--json"])
    assert r.exit_code == 2 and "Traceback" not in r.output and "--solver" in r.stderr


def test_problem_yaml_limit_lap_solver_is_validated_and_reaches_the_options(tmp_path):
    from casadrone.config.airframe import load_airframe
    from casadrone.config.io import ConfigError
    from casadrone.optimise.checks import load_problem
    from casadrone.optimise.problem import limit_setup

    problem = load_problem("limit-lap", ["limit_lap.solver=fatrop"])
    extra = limit_setup(problem, load_airframe(problem.airframe))
    assert extra["limit"].solver == "fatrop"
    assert extra["limit"].starts == ("closed-loop",) and not extra["limit"].sensitivities
    assert limit_setup(load_problem("limit-lap"), load_airframe(problem.airframe))[
        "limit"].solver == "ipopt"
    with pytest.raises(ConfigError, match=r"limit_lap\.solver"):
        load_problem("limit-lap", ["limit_lap.solver=snopt"])


@pytest.mark.slow
def test_fatrop_and_ipopt_give_the_same_quadrotor_lap():
    """SY250 on the paper track, 40 intervals per leg, the closed-loop start only: fatrop's lap
    (no IPOPT fallback used) equals IPOPT's within 0.01 % and passes the same re-simulation
    check (CVODES, the independent oracle of a lap)."""
    from dataclasses import replace

    from casadrone.config.airframe import load_airframe
    from casadrone.config.io import load
    from casadrone.config.track import TrackConfig
    from casadrone.evaluate import DEFAULT_TRACK
    from casadrone.limit.lap import LimitLapOptions, design_limit_lap

    track = load(TrackConfig, DEFAULT_TRACK)
    opts = LimitLapOptions(intervals=40, starts=("closed-loop",), point_mass_reference=False,
                           sensitivities=False, fallback_reference=None)
    ip = design_limit_lap(load_airframe("SY250"), track, opts)
    fa = design_limit_lap(load_airframe("SY250"), track, replace(opts, solver="fatrop"))
    assert ip.completed and fa.completed, (ip.reason, fa.reason)
    assert [s.solver for s in fa.starts] == ["fatrop"]
    assert abs(fa.lap_time_s - ip.lap_time_s) <= 1e-4 * ip.lap_time_s
    assert fa.resimulation_miss_m <= opts.max_miss_m


@pytest.mark.parametrize("setting", [["--solver", "fatrop"], ["solver=fatrop"]])
def test_cli_fatrop_on_a_periodic_track_names_the_key(cli_runner, tmp_path, setting):
    """fatrop cannot take the periodic rows: the refusal names the solver key (to change) and
    the track, in one line, before any solve, whether the option or the key set it."""
    from casadrone.cli import app

    src = (CONFIG_DIR / "tracks" / "paper-rectangle.yaml").read_text()
    track = tmp_path / "periodic.yaml"
    track.write_text(src + "\nend: periodic\n")
    r = cli_runner.invoke(app, ["limit-lap", "SY250", "--track", str(track), *setting,
                                "--json"])
    assert r.exit_code == 2 and "Traceback" not in r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{track}: solver 'fatrop'"), lines
    assert "periodic" in lines[0] and "before any solve" in lines[0]
