"""The exponential rotor step (ETDRK4, casadrone.limit.nlp.etdrk4_step) against independent
oracles: the exact solution of a linear lag, the closed-form solution of a forced lag (its order
of convergence), classical RK4 where the rate is zero, and the φ functions in exact rational
arithmetic."""

from __future__ import annotations

import math
from fractions import Fraction

import casadi as ca
import numpy as np
import pytest

from casadrone.limit.nlp import PHI_SERIES_BELOW, OcpModel, etdrk4_step, phi_functions, rk4_step


def toy(rate: float, forcing: str) -> OcpModel:
    """States (x, y): x' = −x, y the rotor: y' = −λ y + (u, or x²). u (1), p = [λ] (1)."""
    x, u, p = ca.SX.sym("x", 2), ca.SX.sym("u", 1), ca.SX.sym("p", 1)
    drive = u[0] if forcing == "command" else x[0] ** 2
    f = ca.Function("f", [x, u, p], [ca.vertcat(-x[0], -p[0] * x[1] + drive)])
    return OcpModel(f"toy-{forcing}", f, lambda s: ca.vertcat(s, 0), rotor=slice(1, 2),
                    rotor_rate=lambda q: q[0] if rate is None else rate)


def step(model: OcpModel, substeps: int, x0, u, lam, h) -> np.ndarray:
    return np.array(etdrk4_step(model, substeps)(x0, u, lam, h)).ravel()


@pytest.mark.parametrize("h", [1e-4, 0.01, 0.3, 5.0])
def test_linear_lag_is_exact(h):
    """y' = −λ (y − u/λ) with u held: y(h) = u/λ + (y₀ − u/λ) e^{−λh}, for any step length
    (RK4 would be off by (λh)⁵/120 and unstable beyond λh ≈ 2.8). Observed ≤ 4.5e-16 relative."""
    lam, y0, u = 40.0, 2.5, 80.0
    got = step(toy(None, "command"), 1, [0.0, y0], [u], [lam], h)[1]
    exact = u / lam + (y0 - u / lam) * math.exp(-lam * h)
    assert got == pytest.approx(exact, rel=4e-15, abs=0)


def forced_exact(t: float, lam: float, x0: float, y0: float) -> float:
    """y(t) of x' = −x, y' = −λ y + x²: y = (y₀ − c) e^{−λt} + c e^{−2t}, c = x₀²/(λ − 2)."""
    c = x0**2 / (lam - 2)
    return (y0 - c) * math.exp(-lam * t) + c * math.exp(-2 * t)


def test_fourth_order_on_a_forced_lag():
    """Global error at t = 1 of the forced lag (nonlinear forcing x², closed form above) falls
    16-fold per halving of the step: order 4 (observed ratios 13.9, 15.7, 16.3)."""
    lam, x0, y0 = 30.0, 1.5, 0.2
    model = toy(None, "forced")
    errors = []
    for n in (4, 8, 16, 32):
        got = step(model, n, [x0, y0], [0.0], [lam], 1.0)
        errors.append(abs(got[1] - forced_exact(1.0, lam, x0, y0)))
        assert got[0] == pytest.approx(x0 * math.exp(-1.0), rel=1e-3)  # RK4 on x
    ratios = [a / b for a, b in zip(errors, errors[1:], strict=False)]
    assert all(13 < r < 19 for r in ratios), ratios


def test_more_accurate_than_rk4_on_a_fast_lag():
    """At λh = 0.75 per step (the propeller rotor's on 40 intervals) the exponential step's error
    is far below classical RK4's (observed 1.0e-10 against 1.2e-8: 0.0084)."""
    lam, x0, y0 = 100.0, 1.5, 0.2
    exp_model, rk4_model = toy(None, "forced"), toy(None, "forced")
    rk4_model = OcpModel("toy-rk4", rk4_model.f, rk4_model.world_velocity, rotor=slice(1, 2))
    h, n = 0.3, 40
    exact = forced_exact(h, lam, x0, y0)
    e_exp = abs(step(exp_model, n, [x0, y0], [0.0], [lam], h)[1] - exact)
    e_rk4 = abs(np.array(rk4_step(rk4_model, n)([x0, y0], [0.0], [lam], h)).ravel()[1] - exact)
    assert e_exp < 0.05 * e_rk4, (e_exp, e_rk4)


def test_zero_rate_is_classical_rk4():
    """With λ = 0 ETDRK4 is classical RK4 (Cox & Matthews' limit), to rounding (observed
    2.2e-16)."""
    lam_zero = toy(0.0, "forced")
    plain = OcpModel("toy-plain", lam_zero.f, lam_zero.world_velocity, rotor=slice(1, 2))
    args = ([1.5, 0.2], [0.0], [0.0], 0.7)
    a = step(lam_zero, 3, *args)
    b = np.array(rk4_step(plain, 3)(*args)).ravel()
    np.testing.assert_allclose(a, b, rtol=2e-15, atol=1e-15)


def phi_exact(z: Fraction, j: int) -> float:
    """φ_j(z) = Σ z^k/(k + j)! summed in exact rational arithmetic (60 terms, |z| ≤ 3)."""
    return float(sum(z**k / math.factorial(k + j) for k in range(60)))


@pytest.mark.parametrize("z", ["-3", "-1", "-1/5", "-199/1000", "-201/1000", "-1/100",
                               "-1/100000", "0", "1/1000", "1/5", "2"])
def test_phi_functions_against_exact_series(z):
    """Both branches (series below |z| = 0.2, closed form above) match the exact rational sum
    to 1e-13 relative (observed ≤ 2.4e-14, the closed form's cancellation at z = −3)."""
    zq = Fraction(z)
    e, *phis = (float(v) for v in phi_functions(ca.DM(float(zq))))
    assert e == pytest.approx(math.exp(float(zq)), rel=1e-15, abs=0)
    for j, got in enumerate(phis, start=1):
        assert got == pytest.approx(phi_exact(zq, j), rel=1e-13, abs=0)
    assert PHI_SERIES_BELOW == 0.2  # the switch the parameters straddle


def test_derivatives_continuous_across_the_switch():
    """d/dz of the weights just below and above |z| = 0.2 agree (both branches are the same
    analytic function), to their change over the 2e-9 between the points: a smooth step for
    IPOPT's exact Hessian (observed 1.6e-9)."""
    z = ca.SX.sym("z")
    d = ca.Function("d", [z], [ca.jacobian(ca.vertcat(*phi_functions(z)), z)])
    below = np.array(d(-0.2 + 1e-9)).ravel()
    above = np.array(d(-0.2 - 1e-9)).ravel()
    np.testing.assert_allclose(below, above, rtol=0, atol=1e-8)


def test_cli_rotor_step_and_substeps_reach_the_options(monkeypatch, cli_runner):
    """`casadrone limit-lap --rotor-step exponential --substeps 4` reaches the limit lap as
    those options (the grid the propeller kind's exponential step is measured on); without them
    the library's defaults (classical RK4, 3 steps) are kept."""
    import casadrone.limit.race as race_module
    from casadrone.cli import app
    from casadrone.limit.result import LimitLap, LimitLapOptions

    seen = []

    def fake(cfg, track, options, seeds=None, frame=None, pool=None):
        seen.append((options.rotor_step, options.substeps, options.intervals))
        return LimitLap(status="failed", reason="not solved: the options were recorded")

    monkeypatch.setattr(race_module, "design_limit_lap", fake)
    for args in ([], ["--rotor-step", "exponential", "--substeps", "4", "--intervals", "40"]):
        r = cli_runner.invoke(app, ["limit-lap", "SY250-propeller", "--json", *args])
        assert r.exit_code == 0, r.output
    defaults = LimitLapOptions()
    assert seen == [(defaults.rotor_step, defaults.substeps, None), ("exponential", 4, 40)]
    assert (defaults.rotor_step, defaults.substeps) == ("rk4", 3)


@pytest.mark.parametrize("args, key", [
    (["--rotor-step", "euler"], "--rotor-step"),
    (["--substeps", "0"], "--substeps"),
    (["--substeps", "21"], "--substeps"),
])
def test_cli_bad_rotor_step_or_substeps_exit_2(cli_runner, args, key):
    """A step that is not one of the two, or a number of steps outside 1…MAX_SUBSTEPS: exit 2
    naming the option, before any solve."""
    from casadrone.cli import app

    r = cli_runner.invoke(app, ["limit-lap", "SY250", "--json", *args])
    assert r.exit_code == 2 and "Traceback" not in r.output and key in r.stderr


def test_library_refuses_an_unknown_rotor_step():
    """check_inputs names a rotor step the NLP does not know (the API's guard, as the CLI's)."""
    from dataclasses import replace

    from casadrone.config.io import load
    from casadrone.config.track import TrackConfig
    from casadrone.evaluate import DEFAULT_TRACK
    from casadrone.limit.problem import check_inputs
    from casadrone.limit.result import LimitLapOptions

    track = load(TrackConfig, DEFAULT_TRACK)
    assert check_inputs(track, LimitLapOptions()) == ""
    bad = replace(LimitLapOptions(), rotor_step="euler")  # type: ignore[arg-type]
    assert "rotor_step" in check_inputs(track, bad)
    assert "substeps" in check_inputs(track, replace(LimitLapOptions(), substeps=21))
