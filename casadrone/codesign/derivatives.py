"""Exact first and second derivatives of the co-design NLP, assembled from compiled blocks.

Each track's rows are the limit lap's, g_k(w_k, P_k(θ)) with P_k = [p(θ), x_start(θ), targets].
Their derivatives are put together by the chain rule, never by differentiating the composed RK4
graph:

- with respect to w_k: the limit lap's own ``jac_g`` and ``hess_lag`` (its compiled interval
  blocks, :func:`casadrone.limit.nlp.interval_blocks`), evaluated at P_k(θ);
- with respect to θ (and the mixed w–θ terms): the compiled θ-direction blocks
  (:mod:`casadrone.codesign.blocks`) for the dynamics rows, the start rows' x_start(θ) (hover
  thrusts), and CasADi's AD for the target rows where they depend on P (the propeller kind's
  advance-ratio rows read p; with ``paper`` none do);
- the curvature of p(θ) and x_start(θ) themselves, Σ_j (∂L/∂P_j) ∇²_θ P_j, from the frame's
  small symbolic function;
- the rows after the tracks' (feasibility, ``worst`` epigraph, ε rows, the lifted effort) and the
  objective: CasADi's AD of their own small graphs.

So a co-design iteration costs about what the limit laps' iterations cost plus nθ directions per
interval. tests/unit/test_codesign_derivatives.py checks both functions against CasADi's AD of
the symbolic NLP (the oracle) at random points.
"""

from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from casadrone.codesign.blocks import theta_blocks
from casadrone.propulsion import PAPER, PROPELLER

#: Propulsion kinds whose co-design NLP takes its derivatives from the compiled θ-blocks: both.
#: Generated C and compile (measured at -O1 on the shared 2-core machine, load ~7; now
#: casadrone.limit.nlp.BLOCK_FLAGS): ``paper`` 2.3 MB (Hessian) + 0.7 MB (Jacobian), 100 s of
#: CPU; ``propeller`` 6.7 MB + 1.7 MB, 105 s of CPU.
#: A kind left out is differentiated by CasADi's AD of the composed graph (the same values).
COMPILED_KINDS: tuple[str, ...] = (PAPER.name, PROPELLER.name)


def uses_blocks(propulsion: str, parts) -> bool:
    """Whether the co-design NLP of ``parts`` takes its derivatives from compiled blocks: the
    propulsion kind's θ-blocks are compiled and every track is a shooting NLP with the limit
    lap's compiled blocks (collocation has none)."""
    return propulsion in COMPILED_KINDS and all(part.nlp.derivatives for part in parts)


def _place(A: Any, r0: int, c0: int, nrow: int, ncol: int) -> ca.MX:
    """``A`` placed at (r0, c0) of an nrow × ncol matrix of structural zeros."""
    A = ca.MX(A)
    r, c = A.size1(), A.size2()
    row = ca.horzcat(ca.MX(r, c0), A, ca.MX(r, ncol - c0 - c))
    return ca.vertcat(ca.MX(r0, ncol), row, ca.MX(nrow - r0 - r, ncol))


def _sum_blocks(stacked: ca.MX, n: int) -> ca.MX:
    """Σ_i of the n × n blocks side by side in ``stacked`` (n × n·M)."""
    M = stacked.size2() // n
    return ca.mtimes(stacked, ca.DM(np.tile(np.eye(n), (M, 1))))


def _track_terms(part, w: ca.MX, p: ca.MX, x0: ca.MX, P: ca.MX, D: ca.MX, dx0: ca.MX,
                 lam_f: ca.MX, lam: ca.MX):
    """One track's pieces: (g, ∂g/∂w, ∂g/∂θ, H_ww (triu), H_wθ, H_θθ part, ∂L/∂p, ∂L/∂x_start)
    with L = lam·g (model units for p and x_start)."""
    nlp = part.nlp
    model, layout = nlp.model, nlp.layout
    N, M, nx, nu = layout.intervals, layout.n_intervals, model.nx, model.nu
    per = 1 + nu + nx
    nd = D.size2()
    n_dyn, n_same = nx * M, M - layout.n_legs
    n_fixed = n_dyn + n_same + nx
    d = None if model.scale is None else np.asarray(model.scale, float)
    dz = np.ones(per) if d is None else np.r_[np.ones(1 + nu), d]
    Zb = ca.reshape(w[:M * per], per, M)
    Zp = Zb if d is None else Zb * ca.DM(np.tile(dz[:, None], (1, M)))
    jac, hess = theta_blocks(model, layout.substeps, nd)

    g, Jw = nlp.derivatives["jac_g"](w, P)
    Hw = nlp.derivatives["hess_lag"](w, P, lam_f, lam)

    # dynamics rows x_s,i+1 − step(d_z z_s)/d: ∂/∂θ = −(∂x_next/∂p D)/d
    Js_dyn = jac.map("codesign_jac_map", "serial", M, [1, 2, 3], [])(Zp, p, 1.0 / N, D).T
    if d is not None:
        Js_dyn = Js_dyn / ca.DM(np.tile(d, M))
    lam_dyn = -ca.reshape(lam[:n_dyn], nx, M)
    if d is not None:
        lam_dyn = lam_dyn / ca.DM(np.tile(d[:, None], (1, M)))
    Hzs, Hss, gp = hess.map("codesign_hess_map", "serial", M, [1, 2, 4], [1, 2])(
        Zp, p, 1.0 / N, lam_dyn, D)
    Hzs = Hzs.T  # (per·M) × nθ, in the model's units of z
    if d is not None:
        Hzs = Hzs * ca.DM(np.tile(dz, M))
    # start rows X_0 − x_start/d
    unit = np.ones(nx) if d is None else d
    lam_start = lam[n_dyn + n_same:n_fixed]
    Js_start = -dx0 / ca.DM(unit)
    g_x0 = -lam_start / ca.DM(unit)
    # target rows: where they read P (CasADi's AD of their own graph)
    sym = nlp.problem
    gt = sym["g"][n_fixed:]
    # the target rows read the targets (fixed); only p and x_start move with θ
    p_sym, x0_sym, _ = sym["p"].primitives()
    dPds = ca.vertcat(D, dx0)
    n_mov = dPds.size1()
    blocks_s = [-Js_dyn, ca.MX(n_same, nd), Js_start]
    cross = ca.vertcat(Hzs, ca.MX(nx, nd))
    Hss_t: Any = Hss
    gP_t: Any = ca.MX(n_mov, 1)
    if gt.numel() and ca.depends_on(gt, ca.vertcat(p_sym, x0_sym)):
        # their own graph expanded to SX (the slice prunes the dynamics: ~2·10³ nodes on the
        # short track) and differentiated there; MX AD of the slice went through the mapped
        # rows' derivative functions at ~0.4 s per Hessian
        gfun = ca.Function("codesign_target_rows", [sym["x"], sym["p"]], [gt]).expand()
        xs, Ps = ca.SX.sym("w", sym["x"].numel()), ca.SX.sym("P", sym["p"].numel())
        lam_t = ca.SX.sym("lam_t", gt.numel())
        gts, mov = gfun(xs, Ps), Ps[:n_mov]
        gPs = ca.gradient(ca.dot(lam_t, gts), mov)
        jt = ca.Function("codesign_target_jac", [xs, Ps], [ca.jacobian(gts, mov)])
        ht = ca.Function("codesign_target_hess", [xs, Ps, lam_t],
                         [ca.jacobian(gPs, xs).T, ca.jacobian(gPs, mov), gPs])
        HwP, HPP, gP = ht(w, P, lam[n_fixed:])
        blocks_s.append(ca.mtimes(jt(w, P), dPds))
        cross = cross + ca.mtimes(HwP, dPds)
        Hss_t = Hss_t + ca.mtimes(dPds.T, ca.mtimes(HPP, dPds))
        gP_t = gP
    else:
        blocks_s.append(ca.MX(gt.numel(), nd))
    Js = ca.vertcat(*blocks_s)
    np_ = p.numel()
    return (g, Jw, Js, Hw, cross, Hss_t, gp + gP_t[:np_], g_x0 + gP_t[np_:np_ + nx])


def codesign_derivatives(parts, ws: list, s: ca.MX, z: ca.MX, eps: ca.MX, frame_fun: ca.Function,
                         x0s: list, P_list: list, objective: ca.MX, rest: ca.MX,
                         offsets: tuple[int, ...]) -> dict[str, ca.Function]:
    """``{"jac_g": ..., "hess_lag": ...}`` for ``nlpsol`` (the co-design NLP whose rows are each
    track's limit-lap rows, then ``rest``; decision vector ``z`` = [w_1 … w_K, s, …])."""
    nz, nd = z.numel(), s.numel()
    s_at = offsets[-1]
    p, hover = frame_fun(s)[:2]
    D = ca.jacobian(p, s)
    dhover = ca.jacobian(hover, s)
    lam_f = ca.MX.sym("lam_f")
    n_rows = [int(part.lbg.size) for part in parts]
    ng = sum(n_rows) + rest.numel()
    lam_g = ca.MX.sym("lam_g", ng)
    gs, jrows, H = [], [], ca.MX(nz, nz)
    Hss: Any = ca.MX(nd, nd)
    c_p: Any = ca.MX(p.numel(), 1)
    c_h: Any = ca.MX(hover.numel(), 1)
    at = 0
    for k, part in enumerate(parts):
        nx = part.nlp.model.nx
        rotor = part.nlp.model.rotor
        dx0 = ca.MX(nx, nd)
        if part.hover_start:
            dx0 = ca.vertcat(ca.MX(rotor.start, nd), dhover, ca.MX(nx - rotor.stop, nd))
        lam = lam_g[at:at + n_rows[k]]
        at += n_rows[k]
        g, Jw, Js, Hw, cross, Hss_k, gp, gx0 = _track_terms(part, ws[k], p, x0s[k], P_list[k], D,
                                                            dx0, lam_f, lam)
        gs.append(g)
        n0, n1 = offsets[k], offsets[k + 1]
        jrows.append(ca.horzcat(ca.MX(n_rows[k], n0), Jw, ca.MX(n_rows[k], s_at - n1), Js,
                                ca.MX(n_rows[k], nz - s_at - nd)))
        H = H + _place(Hw, n0, n0, nz, nz) + _place(cross, n0, s_at, nz, nz)
        Hss = Hss + Hss_k
        c_p = c_p + gp
        if part.hover_start:
            c_h = c_h + gx0[rotor]
    # the curvature of p(θ) and the hover thrusts: Σ_j c_j ∇²_θ P_j(θ) (the frame's SX graph)
    ss = ca.SX.sym("s", nd)
    cps, chs = ca.SX.sym("cp", p.numel()), ca.SX.sym("ch", hover.numel())
    ps, hs = frame_fun(ss)[:2]
    curv = ca.Function("codesign_frame_curvature", [ss, cps, chs],
                       [ca.hessian(ca.dot(cps, ps) + ca.dot(chs, hs), ss)[0]])
    Hss = Hss + curv(s, c_p, c_h)
    H = H + _place(ca.triu(Hss), s_at, s_at, nz, nz)
    # the rows after the tracks' and the objective: their own AD (small graphs)
    lam_r = lam_g[at:]
    if rest.numel():
        H = H + ca.triu(ca.hessian(lam_f * objective + ca.dot(lam_r, rest), z)[0])
        jrows.append(ca.jacobian(rest, z))
        gs.append(rest)
    else:
        H = H + ca.triu(ca.hessian(lam_f * objective, z)[0])
    jac_g = ca.Function("nlp_jac_g", [z, eps], [ca.vertcat(*gs), ca.vertcat(*jrows)],
                        ["x", "p"], ["g", "jac_g_x"])
    hess_lag = ca.Function("nlp_hess_l", [z, eps, lam_f, lam_g], [H],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    return {"jac_g": jac_g, "hess_lag": hess_lag}
