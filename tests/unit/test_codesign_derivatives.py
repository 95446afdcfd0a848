"""The co-design NLP's derivatives assembled from compiled blocks (casadrone.codesign.derivatives).

Oracle: CasADi's AD of the same symbolic NLP (the composed graph, p = p(θ) substituted: what the
co-design used before the blocks), Jacobian and Lagrangian Hessian at perturbed points with
random multipliers; observed agreement ~1e-16 relative, asserted to 1e-10. The propeller case
(rotor speeds scaled in the NLP, advance-ratio rows that read p) runs the uncompiled θ-blocks
through the same assembly, so no compile is needed for it.
"""

from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import casadrone.codesign.derivatives as cdd
from casadrone.airframe import build_airframe, with_theta
from casadrone.codesign.blocks import theta_block_functions
from casadrone.codesign.driver import _part, template_of
from casadrone.codesign.frame import SymbolicFrame
from casadrone.codesign.nlp import build_codesign_nlp
from casadrone.config.codesign import CodesignProblemConfig
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.limit.lap import LimitLapOptions
from casadrone.propulsion import hover_rotors

ROOT = Path(__file__).resolve().parents[2]
SHORT = ROOT / "tests" / "data" / "codesign" / "short-track.yaml"
BOX = [("lambda_a_mm", 100.0, 150.0), ("lambda_b_mm", 100.0, 150.0), ("alpha_deg", 65.0, 90.0),
       ("beta_deg", 65.0, 90.0)]


def _built(airframe: str, epsilon: tuple[str, ...], intervals: int = 4):
    problem = CodesignProblemConfig.model_validate({
        "name": "derivatives", "airframe": str(ROOT / "configs/airframes" / airframe),
        "track": str(SHORT), "objectives": [{"index": "J3_limit"}],
        "variables": [{"name": k, "lower": lo, "upper": hi} for k, lo, hi in BOX],
        "limit_lap": {"intervals": intervals}, "codesign": {"starts": 0}})
    template = template_of(problem)
    options = LimitLapOptions(intervals=intervals, sensitivities=False, gate_clearance_m=0.3)
    track = load(TrackConfig, SHORT)
    part = _part(template, track, options, 1.0)
    frame = SymbolicFrame(template, tuple(k for k, _, _ in BOX), np.array([b[1] for b in BOX]),
                          np.array([b[2] for b in BOX]))
    return build_codesign_nlp((part,), frame, "sum", epsilon), part


def _point(cd, part, rng) -> np.ndarray:
    """A hover-like trajectory through the legs, perturbed, with a random θ in the box."""
    nlp = part.nlp
    M = nlp.layout.n_intervals
    X = np.repeat(part.x_start[None, :], M + 1, axis=0)
    X[:, :3] += np.linspace(0, 1, M + 1)[:, None] * rng.normal(0, 3, 3)
    w = nlp.pack(np.full(nlp.layout.n_legs, 0.8), X, np.full((M, nlp.model.nu), 0.5))
    w = w * (1 + 0.05 * rng.standard_normal(len(w)))
    z = np.concatenate([w, rng.uniform(0.2, 0.8, cd.n_theta)])
    return cd.full(z)


def _compare(cd, part, seed: int) -> None:
    sym = cd.problem
    z, eps = sym["x"], sym["p"]
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", sym["g"].numel())
    ad_jac = ca.Function("ad_jac", [z, eps], [ca.jacobian(sym["g"], z)])
    ad_hess = ca.Function("ad_hess", [z, eps, lam_f, lam_g], [ca.triu(ca.hessian(
        lam_f * sym["f"] + ca.dot(lam_g, sym["g"]), z)[0])])
    rng = np.random.default_rng(seed)
    for _ in range(2):
        zz = _point(cd, part, rng)
        ee = np.full(eps.numel(), 10.0)
        lf, lg = 1.3, rng.standard_normal(sym["g"].numel())
        g, J = cd.derivatives["jac_g"](zz, ee)
        np.testing.assert_allclose(np.asarray(g).ravel(),
                                   np.asarray(ca.Function("g", [z, eps], [sym["g"]])(zz, ee)
                                              ).ravel(), rtol=0, atol=1e-12)
        Ja = ad_jac(zz, ee).full()
        assert np.max(np.abs(J.full() - Ja)) <= 1e-10 * np.max(np.abs(Ja))
        Ha = ad_hess(zz, ee, lf, lg).full()
        H = cd.derivatives["hess_lag"](zz, ee, lf, lg).full()
        assert np.max(np.abs(H - Ha)) <= 1e-10 * np.max(np.abs(Ha))
        # the θ columns are not empty: the test would pass vacuously without them
        assert np.max(np.abs(Ha[:, cd.offsets[-1]:cd.offsets[-1] + cd.n_theta])) > 1e-6


@pytest.mark.parametrize("epsilon", [(), ("effort",), ("mass_kg",)])
def test_compiled_derivatives_equal_casadi_ad_paper(epsilon):
    cd, part = _built("SY250-components.yaml", epsilon)
    assert cd.derivatives, "the paper co-design NLP should take its derivatives from the blocks"
    _compare(cd, part, seed=len(epsilon))


@pytest.mark.slow  # ~20 s: the uncompiled propeller blocks on CasADi's virtual machine
def test_block_derivatives_equal_casadi_ad_propeller(monkeypatch):
    # the assembly with the propeller's scaled rotor speeds and p-reading advance rows; the
    # θ-blocks uncompiled (SX on CasADi's virtual machine: the same functions, no compile)
    monkeypatch.setattr(cdd, "COMPILED_KINDS", ("paper", "propeller"))
    monkeypatch.setattr(cdd, "theta_blocks", theta_block_functions)
    cd, part = _built("SY250-components-propeller.yaml", ("mass_kg",))
    assert cd.derivatives and part.nlp.model.scale is not None
    assert part.nlp.layout.max_advance_ratio is not None  # rows that read p
    _compare(cd, part, seed=7)


def test_propeller_hover_states_are_the_limit_laps_start():
    """The symbolic hover rotor speeds of p(θ) equal the limit lap's own start (numeric:
    casadrone.propulsion.hover_rotors of the built airframe) at random frames."""
    cfg = template_of(CodesignProblemConfig.model_validate({
        "name": "h", "airframe": str(ROOT / "configs/airframes/SY250-components-propeller.yaml"),
        "track": str(SHORT), "objectives": [{"index": "J3_limit"}],
        "variables": [{"name": k, "lower": lo, "upper": hi} for k, lo, hi in BOX]}))
    frame = SymbolicFrame(cfg, tuple(k for k, _, _ in BOX), np.array([b[1] for b in BOX]),
                          np.array([b[2] for b in BOX]))
    rng = np.random.default_rng(3)
    for s in rng.uniform(0.3, 1.0, (3, 4)):
        theta = {k: float(v) for k, v in frame.theta(s).items()}
        af = build_airframe(with_theta(cfg, theta))
        p, hover, *_ = frame.function(s)
        np.testing.assert_allclose(np.asarray(p).ravel(), af.p, rtol=1e-12, atol=1e-15)
        want, _ = hover_rotors(af, af.hover_thrusts())
        np.testing.assert_allclose(np.asarray(hover).ravel(), want, rtol=1e-10)
