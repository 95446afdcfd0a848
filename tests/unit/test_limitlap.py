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
from casadrone.config.io import CONFIG_DIR, ConfigError, load
from casadrone.config.track import TrackConfig
from casadrone.evaluate import DEFAULT_TRACK
from casadrone.limit.check import target_miss
from casadrone.limit.lap import LimitLapOptions, design_limit_lap, track_targets
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


def _toy_rows(x0, x1, u, p):
    """Interval rows with every kind of dependence: both nodes, the command, the parameters."""
    return ca.vertcat(x0[3] * u[0] + p[0] * x1[6] ** 2, ca.sin(x1[4]) * u[1])


def _nonlinear_toy(scale: tuple[float, ...] | None = None, rows: bool = False) -> OcpModel:
    """A planar 'drone' with quadratic drag, thrust along a rotating axis and a lagged thrust:
    every second derivative the quadrotor's RK4 step has (products, trig, |v|v), small;
    ``scale``: the states' units in the NLP (OcpModel.scale)."""
    x = ca.SX.sym("x", 7)  # px, py, pz, vx, vy, vz ... reused: angle x[6]
    u = ca.SX.sym("u", 2)
    p = ca.SX.sym("p", 2)
    acc = ca.vertcat(u[0] * ca.sin(x[6]), 0.3 * x[3] * x[4], u[0] * ca.cos(x[6]) - 9.81) \
        - p[0] * ca.fabs(x[3:6]) * x[3:6]
    f = ca.Function("f_toy", [x, u, p], [ca.vertcat(x[3:6], acc, p[1] * u[1])],
                    ["x", "u", "p"], ["xdot"])
    return OcpModel("toy-rows" if rows else "toy", f, lambda s: s[3:6],
                    up_z=lambda s: ca.cos(s[6]), scale=scale,
                    interval_rows=(_toy_rows, -1.0, 1.0) if rows else None)


#: Units of the toy's states in the NLP, far from 1 (as the propeller's krad/s rotor speeds).
TOY_SCALE = (1.0, 2.0, 1.0, 10.0, 1.0, 0.5, 1000.0)


@pytest.mark.parametrize("kinds, cone, scale, periodic, rows", [
    (("ball", "gate"), False, None, False, False), (("circle", "polygon"), True, None, False,
                                                    False),
    (("ball", "gate"), True, TOY_SCALE, False, False), (("ball", "gate"), True, TOY_SCALE, True,
                                                        False),
    (("ball", "gate"), True, TOY_SCALE, False, True)])
def test_assembled_derivatives_equal_casadi_ad(kinds, cone, scale, periodic, rows):
    """The constraint Jacobian and Lagrangian Hessian assembled from the compiled interval
    blocks equal CasADi's own AD of the same NLP, entry by entry (ball, gate, circle and
    polygon targets, a rest condition, the tilt cone's rows, interval rows on both nodes and the
    command, 3 intervals per leg, random point and multipliers; also with scaled states, where
    the blocks are rescaled around the compiled code)."""
    from casadrone.limit.nlp import _shooting_nlp

    model = _nonlinear_toy(scale, rows)
    layout = Layout(kinds, 3, substeps=2, end_at_rest=True, tilt_cone=cone, periodic=periodic)
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


@pytest.mark.parametrize("scale", [None, TOY_SCALE])
def test_solver_rows_are_the_symbolic_rows_to_the_bit(scale):
    """The rows IPOPT evaluates (its nlp_g and jac_g's g, with the RK4 step compiled) and the
    multipliers' gradient in P (its nlp_grad, reversed through the compiled step) equal the
    symbolic NLP's, evaluated by CasADi's virtual machine, to the last bit: compiling the step
    changes the time, not one number (random point and multipliers, two legs)."""
    layout = Layout(("ball", "gate"), 3, substeps=2, end_at_rest=True)
    nlp = build_nlp(_nonlinear_toy(scale), layout)
    sym = nlp.problem
    lam_g = ca.MX.sym("lam_g", sym["g"].numel())
    ref = ca.Function("ref", [sym["x"], sym["p"], lam_g],
                      [sym["g"], ca.gradient(sym["f"] + ca.dot(lam_g, sym["g"]), sym["p"])])
    rng = np.random.default_rng(7)
    w = rng.uniform(0.2, 1.5, sym["x"].numel())
    prm = rng.uniform(0.1, 1.0, sym["p"].numel())
    lam = rng.normal(size=lam_g.numel())
    g_ref, grad_ref = (np.array(v) for v in ref(w, prm, lam))
    assert np.abs(g_ref).max() > 0.1 and np.abs(grad_ref).max() > 0.1  # not trivially zero
    np.testing.assert_array_equal(np.array(nlp.cold.get_function("nlp_g")(w, prm)), g_ref)
    np.testing.assert_array_equal(np.array(nlp.derivatives["jac_g"](w, prm)[0]), g_ref)
    grad = nlp.cold.get_function("nlp_grad")(w, prm, 1.0, lam)
    np.testing.assert_array_equal(np.array(grad[3]), grad_ref)  # (f, g, ∂L/∂x, ∂L/∂p)


@pytest.mark.parametrize("method", ["shooting", "collocation"])
def test_scaled_states_pose_the_same_problem(method):
    """Scaling is a change of units only: at the same physical point (w = pack of the same
    durations, states and commands) the scaled NLP's rows are the unscaled rows with each
    dynamics and start row divided by its state's unit, every other row equal; and unpack
    gives back the physical states. Oracle: the unscaled NLP, a different symbolic graph."""
    from casadrone.limit.nlp import _collocation_nlp, _shooting_nlp

    make = _shooting_nlp if method == "shooting" else _collocation_nlp
    layout = Layout(("ball", "gate"), 3, substeps=2, end_at_rest=True, tilt_cone=True,
                    method=method)
    plain, scaled = (build_nlp(_nonlinear_toy(s), layout) for s in (None, TOY_SCALE))
    g_plain, g_scaled = (make(n.model, layout)[0] for n in (plain, scaled))
    rng = np.random.default_rng(5)
    M, nx = layout.n_intervals, 7
    T = rng.uniform(0.5, 2.0, 2)
    X = rng.uniform(0.2, 1.5, (M + 1, nx)) * np.asarray(TOY_SCALE)
    U = rng.uniform(0.1, 1.0, (M, 2))
    Z = None if method == "shooting" else rng.uniform(0.2, 1.5, (M, 3, nx)) * np.asarray(
        TOY_SCALE)
    prm = rng.uniform(0.1, 1.0, g_plain["p"].numel())
    w_plain, w_scaled = plain.pack(T, X, U, Z), scaled.pack(T, X, U, Z)
    assert not np.allclose(w_plain, w_scaled)  # the decision vectors differ
    np.testing.assert_allclose(scaled.unpack(w_scaled)[1], X, rtol=1e-15)
    rows_plain = np.array(ca.Function("g", [g_plain["x"], g_plain["p"]], [g_plain["g"]])(
        w_plain, prm)).ravel()
    rows_scaled = np.array(ca.Function("g", [g_scaled["x"], g_scaled["p"]], [g_scaled["g"]])(
        w_scaled, prm)).ravel()
    unit = np.ones_like(rows_plain)
    n_model = M * nx * (1 + layout.n_coll)  # dynamics rows (collocation: points, then ends)
    unit[:n_model] = np.tile(TOY_SCALE, n_model // nx)
    start = n_model + (M - layout.n_legs)  # after the tied durations
    unit[start:start + nx] = TOY_SCALE
    assert np.abs(rows_plain[:n_model]).max() > 1.0  # the rows are not trivially zero
    np.testing.assert_allclose(rows_scaled * unit, rows_plain, rtol=1e-12, atol=1e-9)


def test_scaled_double_integrator_keeps_its_analytic_time():
    """The out-and-back double integrator with its velocities in units of 100 m/s in the NLP
    still takes T = (2 + √2)√(L/A) (the analytic bang-bang time)."""
    L, A, intervals = 10.0, 2.0, 20
    base = _double_integrator()
    model = OcpModel("double-integrator-scaled", base.f, base.world_velocity,
                     scale=(1.0, 1.0, 1.0, 100.0, 100.0, 100.0))
    kinds = ("ball", "ball")
    nlp = build_nlp(model, Layout(kinds, intervals))
    M = 2 * intervals
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.array([[L, 0, 0], [0, 0, 0]], float), kinds, np.zeros(2), np.zeros(2), np.zeros(2),
        0.0)])
    lbx = nlp.pack(np.full(2, 1e-2), np.full((M + 1, 6), -np.inf), np.full((M, 3), -A))
    ubx = nlp.pack(np.full(2, 1e2), np.full((M + 1, 6), np.inf), np.full((M, 3), A))
    sol = solve(nlp, nlp.pack(np.ones(2), np.zeros((M + 1, 6)), np.zeros((M, 3))), P, lbx, ubx)
    assert sol.success, sol.return_status
    T, X, _ = nlp.unpack(sol.point.w)
    np.testing.assert_allclose(T.sum(), (2 + math.sqrt(2)) * math.sqrt(L / A), rtol=1e-3)
    assert np.abs(X[:, 3]).max() > 3.0  # physical m/s come back, not hundreds of m/s


def test_interval_rows_speed_limit_keeps_the_analytic_time():
    """Rest to rest over D with |a| ≤ A (box) and a speed limit |v_x| ≤ V that only interval
    rows impose (OcpModel.interval_rows on both end nodes of every interval): accelerate to V,
    cruise, brake, T = D/V + V/A (D > V²/A); without the rows the bang-bang 2√(D/A) is faster."""
    D, A, V, intervals = 20.0, 2.0, 4.0, 40
    base = _double_integrator()

    def rows(x0, x1, u, p):
        return ca.vertcat(x0[3], x1[3])

    model = OcpModel("double-integrator-speed-rows", base.f, base.world_velocity,
                     interval_rows=(rows, -V, V))
    kinds = ("ball",)
    nlp = build_nlp(model, Layout(kinds, intervals, end_at_rest=True))
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.array([[D, 0, 0]], float), kinds, np.zeros(1), np.zeros(1), np.zeros(1), 0.0)])
    lbx = nlp.pack([1e-2], np.full((intervals + 1, 6), -np.inf), np.full((intervals, 3), -A))
    ubx = nlp.pack([1e2], np.full((intervals + 1, 6), np.inf), np.full((intervals, 3), A))
    sol = solve(nlp, nlp.pack([5.0], np.zeros((intervals + 1, 6)), np.zeros((intervals, 3))),
                P, lbx, ubx)
    assert sol.success, sol.return_status
    T, X, _ = nlp.unpack(sol.point.w)
    assert 2 * math.sqrt(D / A) < D / V + V / A  # the rows bind
    np.testing.assert_allclose(T.sum(), D / V + V / A, rtol=2e-3)
    assert np.abs(X[:, 3]).max() <= V + 1e-6


def test_interval_rows_refused_by_collocation():
    base = _double_integrator()
    model = OcpModel("double-integrator-rows-colloc", base.f, base.world_velocity,
                     interval_rows=(lambda x0, x1, u, p: u, -1.0, 1.0))
    with pytest.raises(ValueError, match="shooting"):
        build_nlp(model, Layout(("ball",), 4, method="collocation"))


def test_gate_miss_geometry():
    """A gate 2 m wide (half 1 m) facing north: inside → 0; 0.5 m beside the opening → 0.5 m;
    0.3 m in front of the plane → 0.3 m; the same gate given by its frame (rpy) or heading."""
    from casadrone.limit.gates import gate_frame

    tp = target_vector(np.array([[0.0, 0.0, 1.0]]), ("gate",), np.array([math.pi / 2]),
                       np.array([1.0]), np.array([1.0]), 0.0)
    assert target_miss(np.array([0.9, 0.0, 1.5]), tp, "gate") < 1e-15
    np.testing.assert_allclose(target_miss(np.array([-1.5, 0.0, 1.0]), tp, "gate"), 0.5)
    np.testing.assert_allclose(target_miss(np.array([0.0, -0.3, 1.0]), tp, "gate"), 0.3)
    same = target_vector(np.array([[0.0, 0.0, 1.0]]), ("gate",), np.zeros(1), np.array([1.0]),
                         np.array([1.0]), 0.0, frames=[gate_frame(0, 0, math.pi / 2)])
    np.testing.assert_allclose(same, tp, atol=1e-15)
    ball = target_vector(np.zeros((1, 3)), ("ball",), np.zeros(1), np.zeros(1), np.zeros(1),
                         0.5)
    np.testing.assert_allclose(target_miss(np.array([0.0, 2.0, 0.0]), ball, "ball"), 1.5)


def test_gate_track_targets_are_the_gate_openings():
    """The shipped gate track: its waypoints are the gate centres, every gate is a MultiGP 5 ft
    opening, the limit lap targets every gate's opening (not a ball), and gates and waypoints
    given both at once are refused. (The flight through the openings: test_limitlap_slow.)"""
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
    lap = design_limit_lap(load_airframe("SY250"), trk, LimitLapOptions(gate_clearance_m=1.0))
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

    assert BUILTIN_LIMIT_NAMES == ("J3_limit", "effort")
    assert INDICES["J3_limit"].source == "limit" and INDICES["J3_limit"].sense == "min"
    assert limit_index_names(["J1", "J3_limit", "J5"]) == ("J3_limit",)


def test_limit_lap_problem_sets_up_limit_options_and_references():
    from casadrone.optimise.checks import load_problem
    from casadrone.optimise.problem import limit_setup

    problem = load_problem("limit-lap")
    template = load_airframe(problem.airframe)
    extra = limit_setup(problem, template)
    assert extra["limit"] is not None
    # per candidate: the closed-loop start and the references' warm starts, never the command's
    # fallback to the grid-continuation starts (a minute of CPU for each candidate that fails)
    assert extra["limit"].starts == ("closed-loop",) and extra["limit"].fallback_starts == ()
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
    lap = LimitLap(status="completed", reason="", leg_times_s=T, t=node_times(T, 4), x=X, u=U,
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


def test_double_integrator_with_rate_limit_and_floor_matches_its_analytic_time():
    """Vertical out and back under |a| ≤ A and |v| ≤ V (the rate limit) with a floor at z = 0:
    rest at H = 3V²/A, touch the floor, climb back to H (free end). Down, rest to rest:
    accelerate V/A, cruise 2V/A, brake V/A (4V/A); up from rest: V/A then cruise (H − V²/2A)/V
    = 2.5V/A: T = 7.5 V/A (without the rate limit it would be (2√3 + √6) V/A = 5.9 V/A). With
    28 intervals per leg every switch falls on a node, so the grid's optimum is the analytic
    one. A floor 1 cm above the target makes it unreachable: IPOPT says infeasible."""
    A, V = 2.0, 3.0
    H = 3 * V**2 / A
    model = _double_integrator()
    kinds = ("ball", "ball")
    N, L = 28, 2
    M = N * L
    nlp = build_nlp(model, Layout(kinds, N))
    P = np.concatenate([[0.0], [0, 0, H, 0, 0, 0], target_vector(
        np.array([[0, 0, 0], [0, 0, H]], float), kinds, np.zeros(L), np.zeros(L), np.zeros(L),
        0.0)])

    def run(floor):
        xl, xu = np.full((M + 1, 6), -np.inf), np.full((M + 1, 6), np.inf)
        xl[:, 3:6], xu[:, 3:6] = -V, V
        xl[:, 2] = floor
        xl[0] = xu[0] = [0, 0, H, 0, 0, 0]
        lbx = nlp.pack(np.full(L, 1e-2), xl, np.full((M, 3), -A))
        ubx = nlp.pack(np.full(L, 1e2), xu, np.full((M, 3), A))
        X0 = np.zeros((M + 1, 6))
        X0[:, 2] = np.r_[np.linspace(H, 0, N + 1), np.linspace(0, H, N + 1)[1:]]
        return solve(nlp, nlp.pack(np.full(L, 3.0), X0, np.zeros((M, 3))), P, lbx, ubx)

    sol = run(0.0)
    assert sol.success, sol.return_status
    T, X, _ = nlp.unpack(sol.point.w)
    np.testing.assert_allclose(T, [4 * V / A, 3.5 * V / A], rtol=1e-6)  # observed 1e-9
    assert X[:, 2].min() >= -1e-6 and np.abs(X[:, 5]).max() <= V * (1 + 1e-7)  # IPOPT relaxes
    # its bounds by 1e-8 relative
    assert not run(0.01).success


def test_quaternion_model_equals_euler_model_where_both_hold():
    """On random states away from θ = ±90° the quaternion model's derivative equals the Euler
    model's: positions, body velocities, rates and rotors directly, the quaternion's rate
    against the central difference of q(Euler angles) along the Euler rates."""
    from casadrone.airframe import build_airframe
    from casadrone.limit.attitude import (
        euler_rotation_np,
        euler_states_to_quat,
        euler_to_quat,
        quat_rotation,
        quat_states_to_euler,
        quaternion_f,
    )
    from casadrone.model import quadrotor_model

    frame = build_airframe(load_airframe("SY250"))
    rng = np.random.default_rng(7)
    fe, fq = quadrotor_model().f, quaternion_f()
    same = [*range(9), 12, 13, 14, 15]
    for _ in range(20):
        x = rng.normal(size=16)
        x[9:12] = rng.uniform(-3, 3), rng.uniform(-1.4, 1.4), rng.uniform(-3, 3)
        x[12:16] = rng.uniform(0, 8, 4)
        u = rng.uniform(0, 1, 4)
        de = np.array(fe(x, u, frame.p)).ravel()
        xq = euler_states_to_quat(x)[0]
        dq = np.array(fq(xq, u, frame.p)).ravel()
        np.testing.assert_allclose(dq[[*range(9), 13, 14, 15, 16]], de[same], rtol=1e-12,
                                   atol=1e-11)  # observed 4e-15
        h = 1e-6
        fd = (euler_to_quat(*(x[9:12] + h * de[9:12]))
              - euler_to_quat(*(x[9:12] - h * de[9:12]))) / (2 * h)
        np.testing.assert_allclose(dq[9:13], fd, atol=1e-7)  # observed 1e-9
        np.testing.assert_allclose(np.array(quat_rotation(xq[9:13])),
                                   euler_rotation_np(*x[9:12]), atol=1e-14)
        np.testing.assert_allclose(quat_states_to_euler(xq)[0], x, atol=1e-12)
    # R(q) is a rotation for any non-zero q (normalised inside)
    R = np.array(quat_rotation(3.0 * np.array([0.3, -0.5, 0.7, 0.1])))
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)


def test_track_limits_enter_the_bounds_and_targets():
    """floor_m, ceiling_m, max_body_rate_rad_s and tolerance_m land on the right entries of the
    decision vector's box and the targets; laps repeat the waypoints; the tilt cone rows get
    cos(max tilt) and the end rows the end velocity."""
    from casadrone.airframe import build_airframe
    from casadrone.limit.lap import bounds, row_bounds
    from casadrone.limit.nlp import TARGET_SIZE, quaternion_ocp_model

    trk = load(TrackConfig, DEFAULT_TRACK, [
        "floor_m=-0.5", "ceiling_m=30", "max_body_rate_rad_s={roll_pitch: 12, yaw: 3}",
        "tolerance_m=[0.3, 0.4, 0.5, 0.6]", "laps=2", "end=velocity",
        "end_velocity_mps=[1, 2, 3]"])
    opts = LimitLapOptions(attitude="quaternion", tilt_limit="cone", intervals=2)
    tg = track_targets(trk, opts)
    assert len(tg.kinds) == 1 + 4 + 4  # climb, two laps of four
    radii = tg.vector.reshape(-1, TARGET_SIZE)[:, 14]
    np.testing.assert_allclose(radii, [1.0, 0.3, 0.4, 0.5, 0.6, 0.3, 0.4, 0.5, 0.6])
    assert tg.lap_ends == (4, 8)
    frame = build_airframe(load_airframe("SY250"))
    # collocation: the same rows and box, built without compiling the shooting blocks
    nlp = build_nlp(quaternion_ocp_model(), Layout(tg.kinds, 2, degree=1, method="collocation",
                                                   end_at_rest=True, tilt_cone=True))
    lbx, ubx = bounds(nlp, frame, trk, opts, point_mass=False)
    _, xl, ul = nlp.unpack(lbx)
    _, xu, uu = nlp.unpack(ubx)
    assert np.all(xl[1:, 2] == -0.5) and np.all(xu[1:, 2] == 30)
    np.testing.assert_array_equal(xu[1:, 6:9], np.tile([12, 12, 3], (len(xu) - 1, 1)))
    np.testing.assert_array_equal(xl[1:, 13:17], 0.0)
    np.testing.assert_allclose(xu[1:, 13:17], frame.thrust_gain)
    np.testing.assert_allclose(np.linalg.norm(xl[0, 9:13]), 1.0)  # the start's quaternion
    assert np.all(ul == 0) and np.all(uu == 1)
    lbg, ubg = row_bounds(nlp, trk, opts)
    M = nlp.layout.n_intervals
    np.testing.assert_allclose(lbg[-M:], math.cos(math.radians(80.0)))
    np.testing.assert_allclose(lbg[-M - 3:-M], [1, 2, 3])
    np.testing.assert_allclose(ubg[-M - 3:-M], [1, 2, 3])


@pytest.mark.parametrize("override, key", [
    (["tolerance_m=[0.3, 0.4]"], "tolerance_m"),
    (["floor_m=2", "ceiling_m=1"], "ceiling_m"),
    (["floor_m=1"], "floor_m"),
    (["max_body_rate_rad_s={roll_pitch: -1, yaw: 3}"], "roll_pitch"),
    (["end=upside-down"], "end"),
    (["laps=0"], "laps"),
    (["tolerance_m=0"], "tolerance_m"),  # a zero ball (acceptance_radius_m must be > 0 too)
    (["end_velocity_mps=[1, 0, 0]"], "end_velocity_mps"),  # end: free would ignore it
    (["end=rest", "end_velocity_mps=[0, 2, 0]"], "end_velocity_mps"),
    (["start={velocity_mps: [1e8, 0, 0]}"], "start.velocity_mps"),  # beyond Mach 0.3
    (["end=velocity", "end_velocity_mps=[72.8, 72.8, 0]"], "end_velocity_mps"),  # 103.0
    (["speed_mps=150"], "speed_mps"),
    (["ceiling_m=18.5"], "ceiling_m"),  # every waypoint at 20 m, its ball 1 m: above 18.5
    (["tolerance_m=0.3", "ceiling_m=19.6"], "ceiling_m"),  # 20 − 0.3 > 19.6
    (["straight=[true, 'no', true, false]"], "straight"),  # text is not a switch
])
def test_bad_track_limits_are_refused_naming_the_key(override, key):
    with pytest.raises(ConfigError) as err:
        load(TrackConfig, DEFAULT_TRACK, override)
    assert key in str(err.value)


def test_track_limits_that_hold_are_kept():
    """The edges of the refusals above: a ceiling the balls reach (20 − 1 ≤ 19.5), an end
    velocity just below Mach 0.3 (102.8 m/s against 0.3 × 343 = 102.9), a zero end velocity
    with end: free."""
    from casadrone.config.track import MAX_SPEED_MPS

    trk = load(TrackConfig, DEFAULT_TRACK, ["ceiling_m=19.5", "end=velocity",
                                             "end_velocity_mps=[72.7, 72.7, 0]"])
    assert trk.ceiling_m == 19.5 and math.hypot(*trk.end_velocity_mps) < MAX_SPEED_MPS
    assert load(TrackConfig, DEFAULT_TRACK, ["end_velocity_mps=[0, 0, 0]"]).end == "free"


GATES = CONFIG_DIR / "tracks" / "multigp-cdra-gates.yaml"
#: A pentagram: every vertex a left turn (the convexity test of consecutive edges passes), but
#: the edges wind twice around the centre.
STAR = [[1.0, 0.0], [-0.809, 0.588], [0.309, -0.951], [0.309, 0.951], [-0.809, -0.588]]


@pytest.mark.parametrize("override, key", [
    (["tolerance_m=0.3"], "tolerance_m"),  # nothing to apply to: the targets are openings
    (["ceiling_m=0.1"], "ceiling_m"),  # gates at 1.2 m, half-diagonal 1.08 m
    (["gates.0.shape=polygon", f"gates.0.vertices_m={STAR}", "gates.0.width_m=2",
      "gates.0.height_m=1.902"], "vertices_m"),
    (["gates.0.shape=polygon", "gates.0.vertices_m=[[0.2, 0.1], [1, 0.1], [1, 1], [0.2, 1]]",
      "gates.0.width_m=2", "gates.0.height_m=2"], "vertices_m"),  # the centre is outside
    (["gates.0.shape=polygon", "gates.0.vertices_m=[[-1, -1], [1, -1], [1, 1], [-1, 1]]",
      "gates.0.width_m=100", "gates.0.height_m=0.01"], "width_m"),  # the box is 2 x 2
])
def test_bad_gate_tracks_are_refused_naming_the_key(override, key):
    with pytest.raises(ConfigError) as err:
        load(TrackConfig, GATES, override)
    assert key in str(err.value)


def test_polygon_gate_given_its_own_box_is_kept():
    """The square of the last refusal above, with width_m and height_m its 2 x 2 m box."""
    trk = load(TrackConfig, GATES, [
        "gates.0.shape=polygon", "gates.0.vertices_m=[[-1, -1], [1, -1], [1, 1], [-1, 1]]",
        "gates.0.width_m=2", "gates.0.height_m=2"])
    assert trk.gates is not None and trk.gates[0].shape == "polygon"


def test_too_many_intervals_over_the_course_are_refused_before_any_solve():
    """5 000 waypoints × 20 laps ran out of memory; the input check names the waypoints and
    the interval count (legs × intervals per leg against MAX_TOTAL_INTERVALS)."""
    from casadrone.limit.problem import check_inputs
    from casadrone.limit.result import MAX_TOTAL_INTERVALS

    trk = load(TrackConfig, DEFAULT_TRACK, ["laps=20"])  # 4 × 20 + the climb: 81 legs
    assert check_inputs(trk, LimitLapOptions(intervals=40)) == ""  # 3 240 intervals
    why = check_inputs(trk, LimitLapOptions(intervals=80))  # 6 480
    assert why.startswith("waypoints_m: 81 legs") and str(MAX_TOTAL_INTERVALS) in why
    assert "6480 intervals" in why


def _gate_lap(kind, half, edges=None, centre=(5.0, 6.0, 0.0), half_height=None):
    """Double integrator (|a| ≤ 2 per axis) from rest at the origin through a gate of half
    width ``half`` and half height ``half_height`` (default ``half``) at ``centre`` (default
    x = 5, 6 m to the left, flown east: the sideways flight sets the time) to (10, 0, 0)."""
    from casadrone.limit.gates import MAX_EDGES

    model = _double_integrator()
    kinds = (kind, "ball")
    N, L = 20, 2
    M = N * L
    nlp = build_nlp(model, Layout(kinds, N))
    E = np.tile([0.0, 0.0, 1.0], (L, MAX_EDGES, 1))
    if edges is not None:
        E[0] = edges
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.array([centre, [10, 0, 0]], float), kinds, np.zeros(L), np.array([half, 0]),
        np.array([half if half_height is None else half_height, 0]), 0.0, edges=E)])
    lbx = nlp.pack(np.full(L, 1e-2), np.r_[np.zeros((1, 6)), np.full((M, 6), -np.inf)],
                   np.full((M, 3), -2.0))
    ubx = nlp.pack(np.full(L, 1e2), np.r_[np.zeros((1, 6)), np.full((M, 6), np.inf)],
                   np.full((M, 3), 2.0))
    X0 = np.zeros((M + 1, 6))
    X0[:, 0] = np.linspace(0, 10, M + 1)
    sol = solve(nlp, nlp.pack(np.full(L, 1.5), X0, np.zeros((M, 3))), P, lbx, ubx)
    assert sol.success, sol.return_status
    return nlp.unpack(sol.point.w)


def test_polygon_gate_equal_to_its_bounding_rectangle():
    """A polygon gate whose vertices are a rectangle's corners gives the rectangle's lap (the
    same constraint set, other rows); the opening binds (a wide gate is faster), and the lap
    passes at the opening's edge nearest the line (y = 6 − 0.5)."""
    from casadrone.limit.gates import polygon_edges

    T_rect, X_rect, _ = _gate_lap("gate", 0.5)
    square = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    T_poly, X_poly, _ = _gate_lap("polygon", 0.5, polygon_edges(square, 0.0))
    np.testing.assert_allclose(T_poly, T_rect, rtol=1e-7)  # observed 1e-10
    np.testing.assert_allclose(X_poly[20, 1], X_rect[20, 1], atol=1e-6)  # x has slack: only
    # the time and the sideways pass are unique
    np.testing.assert_allclose(X_rect[20, 1], 5.5, atol=1e-6)  # on the opening's edge
    T_wide, _, _ = _gate_lap("gate", 3.0)
    assert T_wide.sum() < T_rect.sum() - 1e-3
    # the inscribed circle: a subset of the square touching it where the lap passes, so no
    # faster and barely slower (observed 1.7 mm off the touching point, 1e-6 relative slower)
    T_circle, X_circle, _ = _gate_lap("circle", 0.5)
    assert X_circle[20, 1] >= 5.5 - 1e-6
    assert T_rect.sum() * (1 - 1e-8) <= T_circle.sum() <= T_rect.sum() * (1 + 1e-4)


@pytest.mark.parametrize("z_gate", [2.0, -2.0])
def test_wide_low_gate_equal_to_its_polygon_and_passed_at_its_height_edge(z_gate):
    """A gate 2 m wide and 0.6 m tall, 2 m above (or below) the straight line: its height rows
    bind (the lap passes at the opening's edge nearest the line, z = ±(2 − 0.3), a fact of the
    geometry), its width rows do not, and the rectangle gives the same lap as the polygon of
    its corners (rows built from the vertices, not from the half height). A rectangle whose
    height rows read its half width (1 m) would pass at ±1 m and be faster."""
    from casadrone.limit.gates import polygon_edges

    centre, hw, hh = (5.0, 0.0, z_gate), 1.0, 0.3
    T_rect, X_rect, _ = _gate_lap("gate", hw, centre=centre, half_height=hh)
    np.testing.assert_allclose(X_rect[20, 2], np.sign(z_gate) * (abs(z_gate) - hh), atol=1e-6)
    corners = np.array([[-hw, -hh], [hw, -hh], [hw, hh], [-hw, hh]])
    T_poly, X_poly, _ = _gate_lap("polygon", hw, polygon_edges(corners, 0.0), centre=centre,
                                  half_height=hh)
    np.testing.assert_allclose(T_poly, T_rect, rtol=1e-7)
    np.testing.assert_allclose(X_poly[20, 2], X_rect[20, 2], atol=1e-6)


def test_certainty_counts_the_laps_on_other_grids():
    """Starts that agree on this grid are not "agreed" when a grid-continuation start's own grid
    found a lap more than 0.1 % away (another local optimum); within 0.1 % they still agree."""
    from casadrone.limit.choose import certainty
    from casadrone.limit.nlp import NlpPoint, NlpSolution

    pt = NlpPoint(np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1))

    def sol(t):
        return NlpSolution(True, "Solve_Succeeded", t, pt, 10, 0.1)

    good = [("closed-loop", sol(3.900)), ("point-mass", sol(3.901))]
    assert certainty(good) == ("agreed", pytest.approx(0.001))
    assert certainty(good, (3.9025,))[0] == "agreed"
    verdict, spread = certainty(good, (3.880,))
    assert verdict == "spread" and spread == pytest.approx(0.021)
    assert certainty(good[:1]) == ("single", pytest.approx(np.nan, nan_ok=True))


def _periodic_shuttle(points, a_max, intervals, method="shooting"):
    """The double integrator from x = 0 through balls of radius 0 at ``points`` (on the x axis)
    and back to 0, with ``end: periodic`` (x(T) = x(0), the start velocity free, the start
    position fixed; y and z held at rest): (leg durations, node states)."""
    model = _double_integrator()
    kinds = ("ball",) * len(points)
    nlp = build_nlp(model, Layout(kinds, intervals, method=method, periodic=True))
    L, M = len(points), len(points) * intervals
    P = np.concatenate([[0.0], np.zeros(6), target_vector(
        np.asarray(points, float), kinds, np.zeros(L), np.zeros(L), np.zeros(L), 0.0)])
    xl, xu = np.full((M + 1, 6), -np.inf), np.full((M + 1, 6), np.inf)
    xl[:, [1, 2, 4, 5]] = xu[:, [1, 2, 4, 5]] = 0.0
    xl[0, 0:3] = xu[0, 0:3] = 0.0  # the start position (the last target is that point)
    ul, uu = np.full((M, 3), -a_max), np.full((M, 3), a_max)
    ul[:, 1:] = uu[:, 1:] = 0.0
    d = nlp.layout.n_coll
    zl, zu = np.repeat(xl[1:, None, :], d, axis=1), np.repeat(xu[1:, None, :], d, axis=1)
    lbx = nlp.pack(np.full(L, 1e-2), xl, ul, zl)
    ubx = nlp.pack(np.full(L, 1e2), xu, uu, zu)
    lbg, ubg = nlp.row_bounds(periodic_position=True)
    X0 = np.zeros((M + 1, 6))
    X0[:, 0] = np.interp(np.linspace(0, L, M + 1), np.arange(L + 1),
                         np.r_[0.0, np.asarray(points, float)[:, 0]])
    sol = solve(nlp, nlp.pack(np.ones(L), X0, np.zeros((M, 3))), P, lbx, ubx, lbg=lbg, ubg=ubg)
    assert sol.success, sol.return_status
    T, X, _ = nlp.unpack(sol.point.w)
    return T, X


@pytest.mark.parametrize("method", ["shooting", "collocation"])
def test_periodic_shuttle_matches_the_bang_bang_oscillation(method):
    """``end: periodic`` on a 1-D shuttle 0 → D1 → −D2 → 0 under |a| ≤ A (D1 < D2): the
    periodic optimum is the bang-bang oscillation between D1 and −D2 (span S = D1 + D2), each
    swing rest to rest in 2√(S/A): the period is 4√(S/A), wherever 0 lies; 0 is on the
    braking half of the upward swing, passed at √(2 A D1). Legs: √(2 D1/A) (braking to D1),
    2√(S/A), and the rest of the period, 2√(S/A) − √(2 D1/A). With A = 2, D1 = 1, D2 = 7: legs
    1, 4, 3 s, start speed 2 m/s; every switch falls on a node with 12 intervals per leg, so
    the grid's optimum is the analytic one. Bugs fail here: without the periodic rows the last
    leg accelerates from −D2 all the way (√7 s, lap 7.65 s, and end speed √28 ≠ 2 m/s); with
    the start state not freed the lap starts at rest (leg 1 alone 2 s). Two laps: two
    oscillations, 16 s."""
    A, D1, D2 = 2.0, 1.0, 7.0
    route = [[D1, 0, 0], [-D2, 0, 0], [0, 0, 0]]
    T, X = _periodic_shuttle(route, A, 12, method)
    # observed 5e-5 (a ball of radius 0 is |p − c|² ≤ 0, met to IPOPT's 1e-8: ~1e-4 m)
    np.testing.assert_allclose(T, [1.0, 4.0, 3.0], rtol=5e-4)
    np.testing.assert_allclose(X[0, 3], math.sqrt(2 * A * D1), rtol=5e-4)
    np.testing.assert_allclose(X[-1], X[0], atol=1e-8)
    if method == "shooting":
        T2, X2 = _periodic_shuttle(route * 2, A, 12)
        np.testing.assert_allclose(T2.sum(), 16.0, rtol=5e-4)
        np.testing.assert_allclose(X2[-1], X2[0], atol=1e-8)


def test_periodic_track_key_is_validated_and_poses_the_periodic_lap():
    """``end: periodic`` reaches the layout and the bounds. On a track that closes (start on
    the last waypoint, no climb) the whole start state is free (box and start rows) and all
    periodic rows bind; with a climb point the start position stays the given one and the
    periodic rows of position are free. A flying start given with it is refused."""
    from casadrone.airframe import build_airframe
    from casadrone.limit.problem import bounds, closes, row_bounds
    from casadrone.limit.starts import periodic_guess, prepare

    frame = build_airframe(load_airframe("SY250"))
    closed = load(TrackConfig, DEFAULT_TRACK, ["climb_to_m=null", "start_position_m=[0, 0, 20]",
                                               "end=periodic"])
    climb = load(TrackConfig, DEFAULT_TRACK, ["end=periodic"])
    assert closes(closed) and not closes(climb)
    opts = LimitLapOptions(intervals=4)
    pb = prepare(frame, closed, opts, 0.0)
    assert pb.layout.periodic and not pb.layout.end_at_rest
    nx, s = pb.full.model.nx, pb.full.start_row
    for trk, pinned in ((closed, False), (climb, True)):
        lo, hi = bounds(pb.full, frame, trk, opts, point_mass=False)
        X_lo, X_hi = pb.full.unpack(lo)[1], pb.full.unpack(hi)[1]
        assert np.isinf(X_lo[0, 3:9]).all() and (X_lo[0, 3:] < X_hi[0, 3:]).all()
        assert (X_lo[0, :3] == X_hi[0, :3]).all() == pinned
        lbg, ubg = row_bounds(pb.full, trk, opts)
        assert np.isinf(lbg[s + 3:s + nx]).all() and np.isinf(ubg[s + 3:s + nx]).all()
        assert (lbg[s:s + 3] == 0).all() == pinned
        # no tilt cone: the periodic rows are the last
        assert (lbg[-nx + 3:] == 0).all() and (ubg[-nx + 3:] == 0).all()
        assert (lbg[-nx:-nx + 3] == 0).all() != pinned
    # the starts' guesses begin where they end (the guessed trajectory's own end state)
    M = pb.layout.n_intervals
    rng = np.random.default_rng(0)
    X = rng.normal(size=(M + 1, nx))
    T, X2, U = pb.full.unpack(periodic_guess(pb.full, pb.full.pack(
        np.ones(pb.layout.n_legs), X, rng.uniform(size=(M, 4)))))
    np.testing.assert_allclose(X2[0], X[-1])
    np.testing.assert_allclose(X2[1:], X[1:])
    with pytest.raises(ConfigError, match="start"):
        load(TrackConfig, DEFAULT_TRACK, ["end=periodic", "start={velocity_mps: [5, 0, 0]}"])


def test_periodic_attitude_rows_admit_full_turns_and_nothing_else():
    """The periodic rows hold where the end attitude is the start attitude after full turns
    (Euler: each angle + 2π k; quaternion: q(T) = ±q(0), any positive scale of q(T)) and not
    after a half turn (Euler ψ + π; quaternion a rotation by π about z), checked numerically;
    the quaternion's start must be a unit quaternion (its norm row)."""
    from casadrone.limit.attitude import QUAT, euler_to_quat
    from casadrone.limit.nlp import _periodic_rows, quadrotor_ocp_model, quaternion_ocp_model

    rng = np.random.default_rng(5)
    for model in (quadrotor_ocp_model(), quaternion_ocp_model()):
        a, b = ca.SX.sym("a", model.nx), ca.SX.sym("b", model.nx)
        rows = _periodic_rows(model, a, b)
        g = ca.Function("g", [a, b], [ca.vertcat(*[r[0] for r in rows])])
        target = np.concatenate([np.full(r[0].numel(), r[1]) for r in rows])
        assert len(target) == model.nx
        x0 = rng.normal(size=model.nx)
        if model.attitude == "euler":
            turned = [x0 + np.r_[np.zeros(9), 2 * np.pi * np.array(k), np.zeros(4)]
                      for k in ([1, 0, 0], [0, -1, 2])]
            half = x0 + np.r_[np.zeros(11), np.pi, np.zeros(4)]
        else:
            x0[QUAT] = euler_to_quat(0.3, -0.2, 1.0)
            turned = [x0 * np.r_[np.ones(9), [s] * 4, np.ones(4)] for s in (-1.0, 1.7)]
            half = x0.copy()
            w, v = 0.0, np.array([0.0, 0.0, 1.0])  # q ⊗ (0, ẑ): a half turn about body z
            q = x0[QUAT]
            half[QUAT] = np.r_[q[0] * w - q[1:] @ v, q[0] * v + w * q[1:] + np.cross(q[1:], v)]
        for x1 in turned:
            np.testing.assert_allclose(np.array(g(x0, x1)).ravel(), target, atol=1e-12)
        assert np.abs(np.array(g(x0, half)).ravel() - target).max() > 0.5
        if model.attitude == "quaternion":
            scaled = x0 * np.r_[np.ones(9), [2.0] * 4, np.ones(4)]
            assert abs(float(g(scaled, scaled)[-1]) - 1.0) > 1.0  # |q(0)|² = 4, not 1


def test_limit_lap_text_gives_the_start_state_it_flew():
    """The plain-text summary states the start state (the optimised one with ``end: periodic``):
    the numbers read back from the line are the result's, with the Euler angles in degrees
    (yaw π/2 must read 90.00), and a result without a start state prints no such line."""
    import re

    from casadrone.cli.limit import _start_text

    x = [1.0, -2.5, 3.25, 12.0, -0.5, 0.125, 0.1, -0.2, 0.3, 0.0, -math.pi / 6, math.pi / 2,
         2.2, 2.3, 2.4, 2.5]
    (line,) = _start_text({"start_state": x})
    groups = re.findall(r"\(([^)]*)\)", line)
    read = [float(v) for g in groups for v in g.split(",")]
    expected = x[:9] + [0.0, -30.0, 90.0] + x[12:]
    np.testing.assert_allclose(read, expected, atol=5e-3)
    assert _start_text({"start_state": None}) == [] and _start_text({}) == []
