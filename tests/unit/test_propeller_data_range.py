"""The limit lap keeps every propeller rotor inside its wind-tunnel data (J ≤ J_max): the data's
range, the NLP rows J_max n D − v_a against numpy, their place beside the compiled blocks, and
the schema's refusal of a range that is no range.

Oracles: the dataset's CSV read with the csv module; the rows recomputed with numpy from the
states (rotor positions from the airframe, the positive-inflow smoothing written out); CasADi's
own AD of the same NLP; the same NLP built without the rows."""

from __future__ import annotations

import csv
import math
from importlib import resources

import casadi as ca
import numpy as np
import pytest
from typer.testing import CliRunner

from casadrone.airframe import build_airframe
from casadrone.cli import app
from casadrone.config import load_airframe
from casadrone.config.io import resolve_config
from casadrone.limit.nlp import (
    Layout,
    OcpModel,
    advance_rows,
    build_nlp,
    quadrotor_ocp_model,
    state_scale,
)
from casadrone.model import n_params
from casadrone.propulsion.propeller import ROTOR_SPEED_UNIT_RAD_S


@pytest.fixture(scope="module")
def frame():
    return build_airframe(load_airframe("SY250-propeller"))


def _csv_rows():
    path = (resources.files("casadrone") / "data" / "propulsion"
            / "uiuc-da4022-5x3.75-3blade.csv")
    with path.open() as fh:
        lines = [ln for ln in fh if not ln.startswith("#")]
    return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(lines)]


def test_the_range_is_the_end_of_the_measured_sweep(frame):
    """The shipped frames' J_max is the last point of the 6034 rpm wind-tunnel sweep (csv module,
    not the fitting code): J = 0.854119, where the measured C_T is already negative; a paper frame
    has none; an explicit value wins."""
    sweep = [r for r in _csv_rows() if r["rpm"] == 6034.0 and r["J"] > 0]
    last = max(sweep, key=lambda r: r["J"])
    assert len(sweep) == 17 and frame.max_advance_ratio == last["J"] == 0.854119
    assert last["CT"] < 0
    assert build_airframe(load_airframe("SY250")).max_advance_ratio is None
    given = load_airframe("SY250-propeller", ["propulsion.propeller.max_advance_ratio=0.5"])
    assert build_airframe(given).max_advance_ratio == 0.5


#: The refit's stated largest residuals (SY250-propeller.yaml): over all fitted points (the
#: static scatter at J = 0 sets them) and over the sweep alone.
CT_RESIDUAL, CP_RESIDUAL = 0.0061, 0.0031
CT_SWEEP_RESIDUAL, CP_SWEEP_RESIDUAL = 0.0028, 0.0025


@pytest.mark.parametrize("name", ["SY250-propeller", "HS200-propeller", "HS210-propeller",
                                  "NSY200-propeller", "SY220-propeller",
                                  "SY250-components-propeller"])
def test_the_shipped_fit_holds_to_the_end_of_the_sweep(name):
    """The YAML's C_T(J), C_P(J) (read as YAML, not through the schema) against the raw points
    (csv module): within the stated residuals at every static point at ≥ 5000 rpm and every
    sweep point to J = 0.854; the least-squares quadratic of those points (numpy, not
    casadrone's fit) to the YAML's five digits; C_T's zero between the last two measured points,
    where the measured C_T changes sign."""
    import yaml

    prop = yaml.safe_load(resolve_config(name, "airframes").read_text("utf-8"))
    prop = prop["propulsion"]["propeller"]
    rows = [r for r in _csv_rows() if (r["J"] == 0 and r["rpm"] >= 5000)
            or (r["rpm"] == 6034.0 and r["J"] > 0)]
    J = np.array([r["J"] for r in rows])
    for key, col, worst, worst_sweep in (("ct_coefficients", "CT", CT_RESIDUAL, CT_SWEEP_RESIDUAL),
                                         ("cp_coefficients", "CP", CP_RESIDUAL, CP_SWEEP_RESIDUAL)):
        c = prop[key]
        y = np.array([r[col] for r in rows])
        res = np.abs(np.polynomial.polynomial.polyval(J, c) - y)
        assert res.max() <= worst and res[J > 0].max() <= worst_sweep, (key, res.max())
        np.testing.assert_allclose(c, np.polynomial.polynomial.polyfit(J, y, 2), rtol=2e-4)
    ct = np.polynomial.polynomial.Polynomial(prop["ct_coefficients"])
    sweep = sorted((r["J"], r["CT"]) for r in rows if r["J"] > 0)
    (j1, t1), (j2, t2) = sweep[-2:]
    assert t1 > 0 > t2 and ct(j1) > 0 > ct(j2)


def _numpy_rows(frame, X, j_max):
    """J_max n D − v_a per rotor and node (columns of X), from the equations."""
    q = dict(zip(("D", "eps"), (0.127, 0.2), strict=True))  # the YAML's diameter, the default ε
    out = []
    for x in X.T:
        vel, om, w = x[3:6], x[6:9], x[12:16]
        for i in range(4):
            v = (vel + np.cross(om, frame.rotor_positions[i]))[2]
            v_a = 0.5 * (v + math.sqrt(v * v + q["eps"] ** 2)) - q["eps"] / 2
            out.append(j_max * w[i] / (2 * math.pi) * q["D"] - v_a)
    return np.array(out)


def _random_states(rng, M):
    X = np.zeros((16, M))
    X[3:6] = rng.uniform(-30, 30, (3, M))
    X[6:9] = rng.uniform(-10, 10, (3, M))
    X[12:16] = rng.uniform(0, 2500, (4, M))
    X[12:16, 0] = 0.0  # a stopped rotor: the row is −v_a, no division
    return X


def test_rows_equal_numpy(frame):
    """On random states (both signs of inflow, spinning body, one node with stopped rotors)."""
    rng = np.random.default_rng(7)
    M = 30
    X = _random_states(rng, M)
    g = np.array(advance_rows(quadrotor_ocp_model("propeller"), 0.6, M)(X, frame.p)).ravel()
    expected = _numpy_rows(frame, X, 0.6)
    assert (expected < 0).any() and (expected > 0).any()  # both sides of the bound are tested
    np.testing.assert_allclose(g, expected, rtol=1e-12, atol=1e-12)


def _toy_propeller_model() -> OcpModel:
    """The propeller model's state layout and parameter vector with cheap dynamics (so its
    interval blocks compile in seconds), rotor speeds in krad/s in the NLP like the real one."""
    x = ca.SX.sym("x", 16)
    u = ca.SX.sym("u", 4)
    p = ca.SX.sym("p", n_params("propeller"))
    xdot = ca.vertcat(x[3:6], 0.1 * x[6:9] * x[3:6] + u[:3] - 0.01 * x[3:6] ** 2,
                      0.2 * u[3] - 0.1 * x[6:9], 0.5 * x[6:9], 100.0 * u - 0.05 * x[12:16])
    f = ca.Function("f_toy_prop", [x, u, p], [xdot], ["x", "u", "p"], ["xdot"])
    return OcpModel("toy-propeller-layout", f, lambda s: s[3:6], rates=slice(6, 9),
                    rotor=slice(12, 16), scale=state_scale(16, slice(12, 16), "propeller"),
                    velocity=slice(3, 6))


def test_nlp_rows_sit_beside_the_blocks_and_their_derivatives_equal_casadi_ad(frame):
    """Shooting NLP with and without the rows: the rows with them are the rows without plus
    4 M rows, bounded below by 0, after the start rows; at a point packed from random states they
    equal numpy's J_max n D − v_a of nodes 1…M (in physical units although the NLP holds rotor
    speeds in krad/s); and the Jacobian and Hessian assembled around the compiled blocks equal
    CasADi's own AD of the whole NLP."""
    from casadrone.limit.nlp import _shooting_nlp

    model, j_max = _toy_propeller_model(), 0.6
    plain = Layout(("ball", "ball"), 3, substeps=2, end_at_rest=True)
    rows = Layout(("ball", "ball"), 3, substeps=2, end_at_rest=True, max_advance_ratio=j_max)
    (n0, lb0, ub0, _), (n1, lb1, ub1, extra) = (_shooting_nlp(model, lay) for lay in (plain, rows))
    M, nx, nu = rows.n_intervals, 16, 4
    assert n1["g"].numel() == n0["g"].numel() + 4 * M
    at = nx * M + (M - rows.n_legs) + nx  # after dynamics, tied durations and the start
    assert (lb1[at:at + 4 * M] == 0).all() and np.isinf(ub1[at:at + 4 * M]).all()

    rng = np.random.default_rng(11)
    X = _random_states(rng, M + 1).T
    w = np.concatenate([np.concatenate([[rng.uniform(0.5, 2)], rng.uniform(0, 1, nu),
                                        X[i] / np.asarray(model.scale)]) for i in range(M)]
                       + [X[M] / np.asarray(model.scale)])
    prm = np.concatenate([frame.p, rng.uniform(-1, 1, nx),
                          rng.uniform(0.1, 1, n1["p"].numel() - len(frame.p) - nx)])
    g0 = np.array(ca.Function("g", [n0["x"], n0["p"]], [n0["g"]])(w, prm)).ravel()
    g1 = np.array(ca.Function("g", [n1["x"], n1["p"]], [n1["g"]])(w, prm)).ravel()
    block = g1[at:at + 4 * M]
    np.testing.assert_array_equal(np.delete(g1, np.s_[at:at + 4 * M]), g0)
    np.testing.assert_allclose(block, _numpy_rows(frame, X[1:].T, j_max), rtol=1e-12, atol=1e-9)
    assert ROTOR_SPEED_UNIT_RAD_S > 1 and np.abs(w).max() < 100  # the NLP's units differ

    W, P = n1["x"], n1["p"]
    lam_g = ca.MX.sym("lam_g", n1["g"].numel())
    lam = rng.normal(size=lam_g.numel())
    _, J = extra["jac_g"](w, prm)
    H = extra["hess_lag"](w, prm, 1.0, lam)
    ref_J = ca.Function("J", [W, P], [ca.jacobian(n1["g"], W)])(w, prm)
    ref_H = ca.Function("H", [W, P, lam_g], [ca.triu(ca.hessian(
        n1["f"] + ca.dot(lam_g, n1["g"]), W)[0])])(w, prm, lam)
    np.testing.assert_allclose(np.array(J), np.array(ref_J), rtol=1e-10, atol=1e-11)
    np.testing.assert_allclose(np.array(H), np.array(ref_H), rtol=1e-10, atol=1e-11)
    assert np.abs(np.array(J)[at:at + 4 * M]).max() > 0.1  # the rows have a Jacobian


@pytest.mark.parametrize("value", ["0", "-0.3"])
def test_a_range_that_is_no_range_exits_2_naming_file_and_key(tmp_path, value):
    text = resolve_config("SY250-propeller", "airframes").read_text()
    path = tmp_path / "bad.yaml"
    path.write_text(text.replace("    data: uiuc-da4022-5x3.75-3blade\n",
                                 "    data: uiuc-da4022-5x3.75-3blade\n"
                                 f"    max_advance_ratio: {value}\n"))
    result = CliRunner().invoke(app, ["massprops", str(path)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and str(path) in lines[0]
    assert "max_advance_ratio" in lines[0]


def test_a_trim_beyond_the_data_says_so():
    """The trim solves the model as it is and says when a rotor flies beyond the data: at 30 m/s
    level SY250-propeller's rotors meet J = v_a/(nD) ≈ 0.59 (numpy from the trimmed state), beyond
    a range set to 0.5 and inside the shipped 0.854; at 10 m/s (J ≈ 0.19) nothing is said (the
    paper's per-axis drag, whose pitch gives these J)."""
    from casadrone.trim import trim

    tight = build_airframe(load_airframe("SY250-propeller", [
        "propulsion.propeller.max_advance_ratio=0.5", "drag_model=per-axis"]))
    shipped = build_airframe(load_airframe("SY250-propeller", ["drag_model=per-axis"]))
    for frame, speed, beyond in ((tight, 30.0, True), (tight, 10.0, False),
                                 (shipped, 30.0, False)):
        tp = trim(frame, "forward", speed)
        x = tp.x0
        v = np.array([(x[3:6] + np.cross(x[6:9], r))[2] for r in frame.rotor_positions])
        v_a = 0.5 * (v + np.sqrt(v * v + 0.04)) - 0.1
        J = v_a / (x[12:16] / (2 * math.pi) * 0.127)
        assert tp.success and (J.max() > frame.max_advance_ratio) == beyond
        assert ("beyond the propeller data" in tp.message) == beyond, tp.message


def test_limit_lap_text_names_the_data_range_only_for_rotor_speeds():
    """The text summary gives the advance ratio against the data's range with ``propeller``
    and says nothing of rotors with ``paper`` (whose figures are NaN: no rotor speed)."""
    from casadrone.cli.limit import _rotor_text

    prop = {"max_advance_ratio": 0.618, "data_advance_ratio": 0.618247, "beyond_data_share": 0.0,
            "min_thrust_ratio": 0.34}
    assert _rotor_text(prop) == ("; lowest thrust / thrust without inflow 0.34; highest advance "
                                 "ratio 0.62 (propeller data to 0.62, 0.0 % of rotor-nodes "
                                 "beyond)")
    paper = dict.fromkeys(prop, math.nan) | {"min_thrust_ratio": 1.0}
    assert _rotor_text(paper) == ""
    unbounded = prop | {"data_advance_ratio": math.nan}  # e.g. the linear-inflow form
    assert "propeller data" not in _rotor_text(unbounded)


def test_rows_take_their_node_s_stage_in_fatrop_s_order():
    """fatrop's stage order accepts the rows (no StageError), and on the NLP's own Jacobian
    pattern each of node i's four rows depends on node i's states alone (so it is a path row of
    stage i, which fatrop takes: no coupling between stages)."""
    from casadrone.limit.stagewise import stage_order

    model = _toy_propeller_model()
    nlp = build_nlp(model, Layout(("ball", "ball"), 3, substeps=2, max_advance_ratio=0.6))
    pr = nlp.problem
    sp = ca.jacobian_sparsity(pr["g"], pr["x"])
    order = stage_order(sp, 3, 6, 16, 4)
    M, nx, nu = 6, 16, 4
    per = 1 + nu + nx
    at = nx * M + (M - 2) + nx
    dense = np.array(ca.DM(sp, 1)) != 0
    for k in range(4 * M):
        node = k // 4 + 1
        cols = np.flatnonzero(dense[at + k])
        first = node * per + 1 + nu if node < M else M * per
        assert len(cols) and ((cols >= first) & (cols < first + nx)).all()  # node's states
    assert sum(order.ng) >= 4 * M


def _capped_shuttle_model() -> OcpModel:
    """A point that accelerates along the rotor axis (body z) at A u₀ (|u₀| ≤ 1) with four
    first-order rotors, ω̇ = (ω_max u_i − ω)/τ: the propeller kind's state layout (rotor speeds
    in krad/s in the NLP), dynamics cheap enough to compile in seconds."""
    x = ca.SX.sym("x", 16)
    u = ca.SX.sym("u", 5)
    p = ca.SX.sym("p", n_params("propeller"))
    xdot = ca.vertcat(x[3:6], 0, 0, SHUTTLE["A"] * u[0], ca.SX.zeros(6),
                      (SHUTTLE["w_max"] * u[1:5] - x[12:16]) / SHUTTLE["tau"])
    f = ca.Function("f_capped_shuttle", [x, u, p], [xdot], ["x", "u", "p"], ["xdot"])
    return OcpModel("capped-shuttle-propeller-layout", f, lambda s: s[3:6], rates=slice(6, 9),
                    rotor=slice(12, 16), scale=state_scale(16, slice(12, 16), "propeller"),
                    velocity=slice(3, 6))


SHUTTLE = {"A": 10.0, "w_max": 1000.0, "tau": 0.05, "L": 30.0, "j_max": 0.6, "N": 30}


def _capped_shuttle_lap(frame, method: str):
    """Rest to rest over L along z with the rotors at ω_max from the start; the data-range rows
    cap the axial speed at v_a(v) = J_max ω_max D / 2π. (T, X, U) of the solved lap."""
    from casadrone.limit.nlp import solve, target_vector

    s = SHUTTLE
    nlp = build_nlp(_capped_shuttle_model(), Layout(("ball",), s["N"], method=method,
                                                    substeps=2, end_at_rest=True,
                                                    max_advance_ratio=s["j_max"]))
    M, nx = s["N"], 16
    x0 = np.zeros(nx)
    x0[12:16] = s["w_max"]
    P = np.concatenate([frame.p, x0, target_vector(np.array([[0.0, 0.0, s["L"]]]), ("ball",),
                                                   np.zeros(1), np.zeros(1), np.zeros(1), 0.0)])
    zl, zu = np.full((M, 3, nx), -np.inf), np.full((M, 3, nx), np.inf)
    lo_u, hi_u = np.tile([-1.0, 0, 0, 0, 0], (M, 1)), np.ones((M, 5))
    lbx = nlp.pack(np.full(1, 1e-2), np.full((M + 1, nx), -np.inf), lo_u, zl)
    ubx = nlp.pack(np.full(1, 1e2), np.full((M + 1, nx), np.inf), hi_u, zu)
    X0 = np.tile(x0, (M + 1, 1))
    X0[:, 2] = np.linspace(0, s["L"], M + 1)
    U0 = np.tile([0.0, 1, 1, 1, 1], (M, 1))
    sol = solve(nlp, nlp.pack(np.array([4.0]), X0, U0), P, lbx, ubx)
    assert sol.success, sol.return_status
    return nlp.unpack(sol.point.w)


def test_collocation_with_the_data_range_rows_flies_the_shooting_lap(frame):
    """A solve of the collocation transcription with the data-range rows, on a problem where
    they bind: rest to rest over 30 m along the rotor axis at |a| ≤ 10 m/s² with the rotors at
    1000 rad/s, J_max = 0.6. Oracles: (1) the shooting transcription's lap of the same problem;
    (2) the analytic optimum: accelerate to the cruise speed v_c where the row binds
    (v_a(v_c) = J_max ω_max D / 2π, with v_a's smoothing ½(v + √(v² + ε²)) − ε/2 solved for v),
    cruise, brake: T = L/v_c + v_c/A, against T = 2√(L/A) = 3.46 s without the rows; (3) the
    rows recomputed with numpy (:func:`_numpy_rows`) hold at every node of the returned lap and
    bind on the cruise."""
    s = SHUTTLE
    cap = s["j_max"] * s["w_max"] / (2 * math.pi) * 0.127
    eps = 0.2
    # ½(v + √(v² + ε²)) − ε/2 = c  ⇔  √(v² + ε²) = 2c + ε − v  ⇔  v = ((2c + ε)² − ε²)/(2(2c + ε))
    v_c = ((2 * cap + eps) ** 2 - eps**2) / (2 * (2 * cap + eps))
    analytic = s["L"] / v_c + v_c / s["A"]
    assert analytic > 2 * math.sqrt(s["L"] / s["A"]) + 0.2  # the rows cost 0.2 s: they bind

    laps = {m: _capped_shuttle_lap(frame, m) for m in ("shooting", "collocation")}
    T_s, T_c = (float(laps[m][0].sum()) for m in ("shooting", "collocation"))
    # observed: shooting and collocation agree to 9e-10 s (the z dynamics are linear: both
    # integrate them exactly), both 2.7e-4 s above the analytic time (the first switch falls
    # between nodes: one interval at u₀ = 0.98)
    assert abs(T_c - T_s) <= 1e-8, (T_c, T_s)
    assert analytic - 1e-8 <= T_c <= analytic + 3e-3, (T_c, analytic)
    _, X, _ = laps["collocation"]
    rows = _numpy_rows(frame, X.T, s["j_max"])
    assert rows.min() >= -6e-8, rows.min()  # observed −6e-9 (IPOPT's tolerance)
    assert np.abs(rows).min() < 1e-4 and abs(X[:, 5].max() - v_c) < 1e-6  # observed 1.2e-7
