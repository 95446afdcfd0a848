"""Compiled θ-derivatives of one shooting interval, for the co-design NLP's exact derivatives.

The limit lap's compiled interval blocks (:func:`casadrone.limit.nlp.interval_blocks`) give
∂x_next/∂z and ∂²(λ·x_next)/∂z² for z = [S, u, x], with the airframe vector p a fixed input. In
the co-design NLP p = p(θ) moves with the decision variables, and the derivatives with respect to
θ follow by the chain rule,

    ∂x_next/∂θ = (∂x_next/∂p) D,                       D = ∂p/∂θ (np × nθ),
    ∂²L/∂z∂θ   = (∂²L/∂z∂p) D,
    ∂²L/∂θ²    = Dᵀ (∂²L/∂p²) D + Σ_j (∂L/∂p_j) ∇²_θ p_j(θ),

where L = λ·x_next. The blocks here compute the first three in one pass as derivatives along the
nθ directions D (p + Dσ differentiated in σ at σ = 0, D an input), so the generated C grows with
nθ (4 for the Table 1 geometry), not with the ~30 entries of p; ∂L/∂p is returned for the last
term, which :mod:`casadrone.codesign.derivatives` adds with the (small, symbolic) p(θ). Without
them CasADi's virtual machine differentiates the composed RK4 graph: 63 % of a co-design solve's
CPU in its Hessian (benchmarks/RESULTS-codesign.md).

The blocks do not depend on the airframe's numbers (p and D are inputs): compiled once per model,
substeps and nθ into the disk cache (:mod:`casadrone.codegen`), like the limit lap's.
"""

from __future__ import annotations

import casadi as ca

from casadrone.codegen import compile_recipe
from casadrone.limit.nlp import (
    BLOCK_FLAGS,
    OcpModel,
    block_design,
    block_recipe,
    chained_substeps,
    chains_stages,
    rk4_stages,
    rk4_step,
    stage_functions,
)

_THETA_BLOCKS: dict[tuple, tuple[ca.Function, ca.Function]] = {}


def theta_block_functions(model: OcpModel, substeps: int, n_dir: int
                          ) -> tuple[ca.Function, ca.Function]:
    """The two interval functions, as SX (uncompiled):

    - ``jac(z, p, inv_n, D) -> Js``: (∂x_next/∂p · D)ᵀ, nθ × nx;
    - ``hess(z, p, inv_n, lam, D) -> (Hzs, Hss, gp)``: (∂²L/∂z∂p · D)ᵀ (nθ × (1+nu+nx)),
      Dᵀ ∂²L/∂p² D (nθ × nθ, full) and ∂L/∂p (np), L = lam·x_next.

    z = [S, u, x] in the model's units, h = S · inv_n (as :func:`casadrone.limit.nlp.
    interval_blocks`). Transposed outputs: a map over intervals then stacks them by rows.
    """
    nx, nu = model.nx, model.nu
    z = ca.SX.sym("z", 1 + nu + nx)
    p = ca.SX.sym("p", model.np)
    inv_n = ca.SX.sym("inv_n")
    lam = ca.SX.sym("lam", nx)
    D = ca.SX.sym("D", model.np, n_dir)
    sig = ca.SX.sym("sig", n_dir)
    step = rk4_step(model, substeps)
    x_next = step(z[1 + nu:], z[1:1 + nu], p + ca.mtimes(D, sig), z[0] * inv_n)
    L = ca.dot(lam, x_next)
    zs = ca.vertcat(z, sig)
    grad = ca.gradient(L, zs)
    Hcols = ca.jacobian(grad, sig)  # ((1+nu+nx) + nθ) × nθ: only the σ columns
    Js = ca.jacobian(x_next, sig)
    zero = ca.DM.zeros(n_dir)
    Hzs, Hss, Js = ca.substitute([Hcols[:z.numel(), :], Hcols[z.numel():, :], Js], [sig],
                                 [zero])
    x0_next = step(z[1 + nu:], z[1:1 + nu], p, z[0] * inv_n)
    gp = ca.gradient(ca.dot(lam, x0_next), p)
    tag = f"{model.name.replace('-', '_')}_rk4x{substeps}_d{n_dir}"
    jac = ca.Function(f"codesign_jac_{tag}", [z, p, inv_n, D], [ca.densify(Js.T)],
                      ["z", "p", "inv_n", "D"], ["Js"])
    hess = ca.Function(f"codesign_hess_{tag}", [z, p, inv_n, lam, D],
                       [ca.densify(Hzs.T), ca.densify(Hss), ca.densify(gp)],
                       ["z", "p", "inv_n", "lam", "D"], ["Hzs", "Hss", "gp"])
    return jac, hess


def chained_theta_block_functions(model: OcpModel, substeps: int, n_dir: int
                                  ) -> tuple[ca.Function, ca.Function]:
    """:func:`theta_block_functions` in the ``substep-chain`` design
    (:data:`casadrone.limit.nlp.BLOCK_DESIGNS`), uncompiled:

    - ``jac(z, p, inv_n, D) -> Js``: (∂x_next/∂p · D)ᵀ, nθ × nx;
    - ``hess(z, p, inv_n, lam, D) -> (Hzs, Hss, gp)``: (∂²L/∂z∂p · D)ᵀ (nθ × (1+nu+nx)),
      Dᵀ ∂²L/∂p² D (nθ × nθ, full) and ∂L/∂p (np), L = lam·x_next.

    z = [S, u, x] in the model's units, h = S · inv_n (as :func:`casadrone.limit.nlp.
    interval_blocks`). Transposed outputs: a map over intervals then stacks them by rows.

    Built as the limit lap's blocks are (:func:`casadrone.limit.nlp.chained_substeps`): one RK4
    step's derivatives on v = [S, u, σ, x] (p + Dσ the step's parameters; its Hessian only
    along the nθ directions σ), generated once and chained over the ``substeps`` steps, at
    σ = 0; ∂L/∂p sums each step's p-gradient along the adjoints. The same numbers as CasADi's
    symbolic derivatives of the whole step, to rounding (tests/unit/test_codegen.py), in a
    fraction of its C (benchmarks/RESULTS-limitlap-compile.md)."""
    nx, nu = model.nx, model.nu
    n_head = 1 + nu + n_dir
    sub_jac, sub_hess, sub_gp = staged_theta_substep_functions(model, substeps, n_dir)
    z = ca.MX.sym("z", 1 + nu + nx)
    p = ca.MX.sym("p", model.np)
    inv_n = ca.MX.sym("inv_n")
    lam = ca.MX.sym("lam", nx)
    D = ca.MX.sym("D", model.np, n_dir)
    v = ca.vertcat(z[:1 + nu], ca.MX(n_dir, 1), z[1 + nu:])
    args = (p, inv_n, D)
    sig = list(range(1 + nu, n_head))
    _, J, Hs, chain = chained_substeps(sub_jac, sub_hess, v, n_head, args, lam, substeps, sig)
    zi = list(range(1 + nu)) + list(range(n_head, n_head + nx))
    gp = sum((sub_gp(y_k, *args, mu) for y_k, mu in chain), ca.MX(model.np, 1))
    tag = _theta_tag(model, substeps, n_dir)
    jac = ca.Function(f"codesign_jac_{tag}", [z, p, inv_n, D], [ca.densify(J[:, sig].T)],
                      ["z", "p", "inv_n", "D"], ["Js"])
    hess = ca.Function(f"codesign_hess_{tag}", [z, p, inv_n, lam, D],
                       [ca.densify(Hs[zi, :].T), ca.densify(Hs[sig, :]), ca.densify(gp)],
                       ["z", "p", "inv_n", "lam", "D"], ["Hzs", "Hss", "gp"])
    return jac, hess


def _theta_tag(model: OcpModel, substeps: int, n_dir: int) -> str:
    """The θ-blocks' name tag: model, RK4 steps per interval and directions."""
    return f"{model.name.replace('-', '_')}_rk4x{substeps}_d{n_dir}"


def _step_symbols(sym, model: OcpModel, n_dir: int) -> tuple:
    """The inputs of one step's θ-derivatives, as ``sym`` (ca.SX or ca.MX): y = [S, u, σ, x],
    p, inv_n, the directions D, the adjoint mu and the Hessian's directions V."""
    y = sym.sym("y", 1 + model.nu + n_dir + model.nx)
    return (y, sym.sym("p", model.np), sym.sym("inv_n"), sym.sym("D", model.np, n_dir),
            sym.sym("mu", model.nx), sym.sym("V", y.numel(), n_dir))


def theta_substep_functions(model: OcpModel, substeps: int, n_dir: int
                            ) -> tuple[ca.Function, ca.Function, ca.Function]:
    """One of an interval's ``substeps`` RK4 steps (h = S · inv_n / substeps) on
    y = [S, u, σ, x] with parameters p + Dσ, as SX: ``sub_jac(y, p, inv_n, D) -> (x_next, A)``
    (A = ∂x_next/∂y, dense), ``sub_hess(y, p, inv_n, D, mu, V) -> ∇²_y(mu·x_next) V`` (V:
    nθ directions in y) and
    ``sub_gp(y, p, inv_n, D, mu) -> ∂(mu·x_next)/∂p``."""
    nu = model.nu
    y, p, inv_n, D, mu, V = _step_symbols(ca.SX, model, n_dir)
    sig = y[1 + nu:1 + nu + n_dir]
    x_next = rk4_step(model, 1)(y[1 + nu + n_dir:], y[1:1 + nu], p + ca.mtimes(D, sig),
                                y[0] * inv_n / substeps)
    L = ca.dot(mu, x_next)
    tag = _theta_tag(model, substeps, n_dir)
    ins, names = [y, p, inv_n, D], ["y", "p", "inv_n", "D"]
    return (ca.Function(f"codesign_subjac_{tag}", ins, [x_next, ca.densify(ca.jacobian(
                x_next, y))], names, ["x_next", "A"]),
            ca.Function(f"codesign_subhess_{tag}", [*ins, mu, V], [ca.jtimes(
                ca.gradient(L, y), y, V)], [*names, "mu", "V"], ["HV"]),
            ca.Function(f"codesign_subgp_{tag}", [*ins, mu], [ca.substitute(
                ca.gradient(L, p), sig, ca.DM.zeros(n_dir))], [*names, "mu"], ["gp"]))


def staged_theta_substep_functions(model: OcpModel, substeps: int, n_dir: int
                                   ) -> tuple[ca.Function, ca.Function, ca.Function]:
    """:func:`theta_substep_functions` built from the four stages of classical RK4
    (:func:`casadrone.limit.nlp.rk4_stages`, each stage's derivatives generated once): the same
    ``sub_jac``, ``sub_hess`` and ``sub_gp``; the right-hand side on w = [ξ, u, σ] with
    parameters p + Dσ, where :func:`casadrone.limit.nlp.chains_stages`; otherwise
    :func:`theta_substep_functions`."""
    if not chains_stages(model):
        return theta_substep_functions(model, substeps, n_dir)
    nx, nu = model.nx, model.nu
    tag = _theta_tag(model, substeps, n_dir)
    wx = ca.SX.sym("w", nx + nu + n_dir)
    ps = ca.SX.sym("p", model.np)
    Ds = ca.SX.sym("D", model.np, n_dir)
    g = ca.Function("g", [wx, ps, Ds], [model.f(wx[:nx], wx[nx:nx + nu],
                                                 ps + ca.mtimes(Ds, wx[nx + nu:]))],
                    ["w", "p", "D"], ["k"])
    stage_jac, stage_hess, stage_gp = stage_functions(g, f"codesign_{tag}", with_gp=True)
    y, p, inv_n, D, mu, V = _step_symbols(ca.MX, model, n_dir)
    x_next, A, H, stages = rk4_stages(stage_jac, stage_hess, y, nu + n_dir, (p, D),
                                      inv_n / substeps, mu)
    assert H is not None  # given mu
    gp = sum((stage_gp(w, p, D, a) for w, a in stages), ca.MX(model.np, 1))
    ins, names = [y, p, inv_n, D], ["y", "p", "inv_n", "D"]
    return (ca.Function(f"codesign_subjac_{tag}", ins, [x_next, ca.densify(A)], names,
                        ["x_next", "A"]),
            ca.Function(f"codesign_subhess_{tag}", [*ins, mu, V], [ca.mtimes(H, V)],
                        [*names, "mu", "V"], ["HV"]),
            ca.Function(f"codesign_subgp_{tag}", [*ins, mu], [gp], [*names, "mu"], ["gp"]))


def theta_blocks(model: OcpModel, substeps: int, n_dir: int, design: str | None = None
                 ) -> tuple[ca.Function, ca.Function]:
    """:func:`theta_block_functions` compiled (once per machine, disk-cached; once per process
    in memory), in ``design`` (default :func:`casadrone.limit.nlp.block_design`)."""
    design = block_design() if design is None else design
    key = (model.name, model.scale, substeps, n_dir, design)
    if key not in _THETA_BLOCKS:
        tag = _theta_tag(model, substeps, n_dir)
        fingerprint, build = block_recipe(
            design, rk4_step(model, substeps), theta_block_functions,
            (chained_theta_block_functions, staged_theta_substep_functions, chains_stages,
             stage_functions, rk4_stages, theta_substep_functions, _theta_tag, _step_symbols,
             chained_substeps))
        jac, hess = compile_recipe(
            (f"codesign_jac_{tag}", f"codesign_hess_{tag}"), fingerprint,
            lambda: build(model, substeps, n_dir), BLOCK_FLAGS)
        _THETA_BLOCKS[key] = (jac, hess)
    return _THETA_BLOCKS[key]
