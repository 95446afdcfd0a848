"""The limit-lap NLP reordered stage by stage, for a structure-exploiting solver (fatrop).

fatrop (Vanroye et al., "FATROP: A Fast Constrained Optimal Control Problem Solver for Robot
Trajectory Optimization and Control", IROS 2023; shipped with casadi ≥ 3.6 as the ``fatrop``
nlpsol plugin) factorises the KKT system by a Riccati recursion over the stages of an
optimal-control problem instead of a general sparse LDLᵀ (MUMPS): cost linear in the number of
stages with dense stage blocks. CasADi's interface needs the NLP in stage order:

- variables ``[x_0, u_0, x_1, u_1, ..., x_N, u_N]`` (states first in each stage);
- rows ``[gap_0, path_0, gap_1, path_1, ..., path_N]``, where the gap rows of stage k read
  ``x_{k+1} − F_k(x_k, u_k)`` with coefficient exactly +1 on each state of stage k+1 and depend
  on nothing else of stage k+1, and the path rows of stage k depend on stage k only;
- a Lagrangian Hessian inside the stage blocks, given in full (symmetric), and the Lagrangian
  gradient beside it.

This module builds that NLP as a *permutation* of the limit-lap NLP of :mod:`casadrone.limit.nlp`
(no new variable, row or symbolic block): the IPOPT NLP stays the one source of truth, its
compiled interval blocks are reused (no recompile), and a point maps back bit-for-bit. The
stages are the shooting intervals: stage i holds node x_i, then its interval's leg duration S_i,
then its command u_i. S_i is a *state* inside a leg (the NLP's tie row ``S_i − S_{i−1} = 0`` is
its gap row) and a *control* on a leg's first interval (a new leg's duration is free); the last
stage is the last node. The rows are sorted from the constraint Jacobian's sparsity, so a row
added to the NLP lands in its stage by itself, and a row that couples non-neighbouring stages is
refused by name (:class:`StageError`).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from casadrone.limit.watchdog import beat


class StageError(ValueError):
    """The NLP cannot be put in stage order (a row couples stages fatrop cannot take)."""


@dataclass(frozen=True)
class StageOrder:
    """Permutation of an NLP into stage order: ``col[j]`` is the original index of the j-th
    variable in stage order, ``row[i]`` that of the i-th row; ``nx``, ``nu``, ``ng`` the states,
    controls and path rows of each of the N + 1 stages (fatrop's manual structure)."""

    col: np.ndarray
    row: np.ndarray
    nx: tuple[int, ...]
    nu: tuple[int, ...]
    ng: tuple[int, ...]
    #: (variable, row) pairs in stage order of the path rows that depend on one variable alone
    #: (e.g. x_0 − x_start): where such a row is an equality and the box fixes the same variable,
    #: :meth:`free_box` drops the box (fatrop counts each as an equation of the stage: two
    #: equations on one unknown make its KKT matrix singular; IPOPT removes fixed variables).
    single: tuple[tuple[int, int], ...] = ()

    @property
    def n_stages(self) -> int:
        return len(self.nx)

    def to_stage(self, v: np.ndarray, rows: bool = False) -> np.ndarray:
        """A vector over the variables (or rows) in stage order."""
        return np.asarray(v, float)[self.row if rows else self.col]

    def free_box(self, lbx: np.ndarray, ubx: np.ndarray, lbg: np.ndarray, ubg: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
        """Stage-ordered box (lbx, ubx) without the fixings an equality row already makes."""
        lbx, ubx = lbx.copy(), ubx.copy()
        for j, i in self.single:
            if lbx[j] == ubx[j] and lbg[i] == ubg[i]:
                lbx[j], ubx[j] = -np.inf, np.inf
        return lbx, ubx

    def from_stage(self, v: np.ndarray, rows: bool = False) -> np.ndarray:
        """A stage-ordered vector over the variables (or rows) back in the NLP's order."""
        idx = self.row if rows else self.col
        out = np.empty(len(idx))
        out[idx] = np.asarray(v, float).ravel()
        return out


def _variable_stages(intervals: int, n_intervals: int, nx: int, nu: int
                     ) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """(stage of each variable, states of each stage, controls of each stage) of the shooting
    NLP's decision vector ``[S_i, u_i, x_i]`` per interval, then the last node."""
    per = 1 + nu + nx
    M = n_intervals
    stage = np.concatenate([np.repeat(np.arange(M), per), np.full(nx, M)])
    states, controls = [], []
    for i in range(M):
        base = i * per
        x = base + 1 + nu + np.arange(nx)
        s = np.array([base])
        u = base + 1 + np.arange(nu)
        if i % intervals:  # inside a leg: the duration is carried as a state
            states.append(np.concatenate([x, s]))
            controls.append(u)
        else:  # a leg's first interval: its duration is chosen here
            states.append(x)
            controls.append(np.concatenate([s, u]))
    states.append(M * per + np.arange(nx))
    controls.append(np.zeros(0, dtype=int))
    return stage, states, controls


def stage_order(jac_sparsity: ca.Sparsity, intervals: int, n_intervals: int, nx: int, nu: int
                ) -> StageOrder:
    """The stage order of the shooting NLP whose constraint Jacobian has ``jac_sparsity``.

    Raises :class:`StageError` when a row depends on two stages that are not neighbours, or is
    a gap row that does not define exactly one state of the next stage."""
    stage, states, controls = _variable_stages(intervals, n_intervals, nx, nu)
    n_st = n_intervals + 1
    rows_of_col = jac_sparsity.T  # column i: the variables of row i
    colind, rowidx = np.array(rows_of_col.colind()), np.array(rows_of_col.row())
    state_pos = np.full(len(stage), -1)
    for st in states[1:]:
        state_pos[st] = np.arange(len(st))
    gap: list[list[tuple[int, int]]] = [[] for _ in range(n_st)]
    path: list[list[int]] = [[] for _ in range(n_st)]
    for r in range(jac_sparsity.size1()):
        cols = rowidx[colind[r]:colind[r + 1]]
        stages = np.unique(stage[cols])
        if len(stages) == 0:
            path[0].append(r)
        elif len(stages) == 1:
            path[stages[0]].append(r)
        elif len(stages) == 2 and stages[1] == stages[0] + 1:
            later = cols[stage[cols] == stages[1]]
            if len(later) != 1 or state_pos[later[0]] < 0:
                raise StageError(f"row {r} ties stages {stages[0]} and {stages[1]} but is not a "
                                 "gap-closing row x_(k+1) - F(x_k, u_k) of one state")
            gap[stages[0]].append((int(state_pos[later[0]]), r))
        else:
            raise StageError(f"row {r} couples stages {stages.tolist()}")
    row_order: list[int] = []
    single: list[tuple[int, int]] = []  # (variable, row), original indices
    for k in range(n_st):
        for r in path[k]:
            cols = rowidx[colind[r]:colind[r + 1]]
            if len(cols) == 1:
                single.append((int(cols[0]), r))
        defined = sorted(gap[k])
        if k + 1 < n_st and [p for p, _ in defined] != list(range(len(states[k + 1]))):
            raise StageError(f"the gap rows of stage {k} do not define each state of stage "
                             f"{k + 1} once")
        row_order += [r for _, r in defined] + path[k]
    col = np.concatenate([np.concatenate([states[k], controls[k]]) for k in range(n_st)])
    row = np.array(row_order, dtype=int)
    at_col, at_row = np.argsort(col), np.argsort(row)
    return StageOrder(col=col.astype(int), row=row,
                      nx=tuple(len(s) for s in states), nu=tuple(len(c) for c in controls),
                      ng=tuple(len(p) for p in path),
                      single=tuple((int(at_col[c]), int(at_row[r])) for c, r in single))


def _stage_of_position(order: StageOrder) -> np.ndarray:
    """Stage of each variable position in stage order."""
    return np.repeat(np.arange(order.n_stages), np.add(order.nx, order.nu))


def _permuted(A: ca.MX, rows: list[int], cols: list[int], symmetric: bool = False,
              upper: bool = False) -> ca.MX:
    """``A[rows, cols]`` (of ``triu2symm(A)`` if ``symmetric``; its upper triangle if ``upper``)
    as one gather of A's nonzeros:
    the index map is worked out once on numbers, so each evaluation only copies values."""
    sp = A.sparsity()
    tag = ca.DM(sp, ca.DM(np.arange(1, sp.nnz() + 1, dtype=float)))
    if symmetric:
        tag = ca.triu2symm(tag)
    tag = tag[rows, cols]
    if upper:
        tag = ca.triu(tag)
    return ca.sparsity_cast(A.nz[(np.array(tag.nonzeros(), dtype=int) - 1).tolist()],
                            tag.sparsity())


def stagewise_functions(problem: dict, jac_g: ca.Function, hess_lag: ca.Function,
                        order: StageOrder) -> dict[str, ca.Function]:
    """The functions fatrop's interface calls, on the NLP in stage order.

    ``problem`` is the NLP as given to IPOPT, ``jac_g(x, p) -> (g, J)`` and
    ``hess_lag(x, p, lam_f, lam_g) -> triu(H)`` its derivatives (the compiled interval blocks).
    Returns ``nlp_f``, ``nlp_g``, ``nlp_grad_f``, ``nlp_jac_g`` (rows and columns permuted),
    ``nlp_hess_l`` (the Lagrangian gradient and the full Hessian, permuted) and ``nlp_grad``
    (f, g and the Lagrangian gradient in x and p: the multipliers after a solve). Raises
    :class:`StageError` when the Hessian couples two stages (fatrop would drop those entries
    silently).
    """
    W, P = problem["x"], problem["p"]
    nw, ng = W.numel(), problem["g"].numel()
    inv_col, inv_row = np.argsort(order.col).tolist(), np.argsort(order.row).tolist()
    col, row = order.col.tolist(), order.row.tolist()
    # f alone (the lap time: a sum of durations), so that f and ∇f do not evaluate g
    f_of = ca.Function("nlp_f_of", [W, P], [problem["f"]])
    g_of = ca.Function("nlp_g_of", [W, P], [problem["g"]])
    x = ca.MX.sym("x", nw)
    p = ca.MX.sym("p", P.numel())
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", ng)
    xo, lam_go = x[inv_col], lam_g[inv_row]
    f, g = f_of(xo, p), g_of(xo, p)
    g_o, J_o = jac_g(xo, p)
    J = _permuted(J_o, row, col)
    grad_f = ca.densify(ca.gradient(f, x))  # the interface reads gradients as dense vectors
    # ∇ₓL and ∂L/∂p by CasADi's reverse mode over the NLP's graph (the compiled step's own
    # reverse function), as IPOPT's nlp_grad does: 1.7 ms at 200 intervals, where ∇f + Jᵀλ needs
    # the Jacobian blocks again (3.5 ms) or a copy of the last Jacobian kept between two calls
    lagrangian = lam_f * f + ca.dot(lam_go, g)
    grad_x = ca.densify(ca.gradient(lagrangian, x))
    H = _permuted(hess_lag(xo, p, lam_f, lam_go), col, col, symmetric=True)
    at = _stage_of_position(order)
    r_, c_ = (np.array(a, dtype=int) for a in H.sparsity().get_triplet())
    if np.any(at[r_] != at[c_]):
        k = int(np.flatnonzero(at[r_] != at[c_])[0])
        raise StageError(f"the Lagrangian Hessian couples stages {at[r_[k]]} and {at[c_[k]]}")
    grad_p = ca.densify(ca.gradient(lagrangian, p))
    xp = ["x", "p"]
    lag = ["x", "p", "lam_f", "lam_g"]
    return {
        "nlp_f": ca.Function("nlp_f", [x, p], [f], xp, ["f"]),
        "nlp_g": ca.Function("nlp_g", [x, p], [g[row]], xp, ["g"]),
        "nlp_grad_f": ca.Function("nlp_grad_f", [x, p], [grad_f], xp, ["grad_f_x"]),
        "nlp_jac_g": ca.Function("nlp_jac_g", [x, p], [g_o[row], J], xp, ["g", "jac_g_x"]),
        "nlp_hess_l": ca.Function("nlp_hess_l", [x, p, lam_f, lam_g], [grad_x, H], lag,
                                  ["grad_gamma_x", "hess_gamma_x_x"]),
        "nlp_grad": ca.Function("nlp_grad", [x, p, lam_f, lam_g], [f, g[row], grad_x, grad_p],
                                lag, ["f", "g", "grad_gamma_x", "grad_gamma_p"]),
        # the full Hessian alone (benchmarks/bench_limitlap_sqp.py)
        "hess_only": ca.Function("nlp_hess_only", [x, p, lam_f, lam_g], [H], lag,
                                 ["hess_gamma_x_x"]),
        # IPOPT's signatures (to measure IPOPT on the stage order: MUMPS's fill-in)
        "nlp_grad_f:2": ca.Function("nlp_grad_f", [x, p], [f, grad_f], xp, ["f", "grad_f_x"]),
        "nlp_hess_l:1": ca.Function("nlp_hess_l", [x, p, lam_f, lam_g],
                                    [_permuted(hess_lag(xo, p, lam_f, lam_go), col, col,
                                               symmetric=True, upper=True)],
                                    lag, ["triu_hess_gamma_x_x"]),
    }


class StageOracle(ca.Callback):
    """An NLP oracle ``(x, p) -> (f, g)`` whose derivative functions are given, not derived:
    CasADi's nlpsol asks its oracle's factory for each function it needs by name, and this one
    answers with :func:`stagewise_functions`' (the compiled interval blocks, permuted)."""

    def __init__(self, name: str, functions: dict[str, ca.Function]):
        ca.Callback.__init__(self)
        self.functions = functions
        self.construct(name, {"enable_fd": False})

    def get_n_in(self) -> int:
        return 2

    def get_n_out(self) -> int:
        return 2

    def get_name_in(self, i: int) -> str:
        return ("x", "p")[i]

    def get_name_out(self, i: int) -> str:
        return ("f", "g")[i]

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return self.functions["nlp_g"].sparsity_in(i)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return (self.functions["nlp_f"].sparsity_out(0),
                self.functions["nlp_g"].sparsity_out(0))[i]

    def eval(self, arg):
        return [self.functions["nlp_f"](*arg), self.functions["nlp_g"](*arg)]

    def get_factory(self, name, s_in, s_out, aux, opts):
        for key in (name, f"{name}:{len(s_out)}"):
            fn = self.functions.get(key)
            if fn is not None and fn.n_out() == len(s_out):
                return fn
        raise NotImplementedError(f"the stage-ordered NLP does not provide {name} -> {s_out}")


class _Wrapped(ca.Callback):
    """A callback with the inputs and outputs of ``fn`` (its names and sparsities)."""

    def __init__(self, name: str, fn: ca.Function):
        ca.Callback.__init__(self)
        self.fn = fn
        self.construct(name, {"enable_fd": False})

    def get_n_in(self) -> int:
        return self.fn.n_in()

    def get_n_out(self) -> int:
        return self.fn.n_out()

    def get_name_in(self, i: int) -> str:
        return self.fn.name_in(i)

    def get_name_out(self, i: int) -> str:
        return self.fn.name_out(i)

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return self.fn.sparsity_in(i)

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return self.fn.sparsity_out(i)


class Beating(_Wrapped):
    """``fn`` that tells the guard of a forked solve that the solve is alive
    (:func:`casadrone.limit.watchdog.beat`) each time it is called. Given to the objective and
    the rows (``nlp_f``, ``nlp_g``), which fatrop evaluates at every iteration and line-search
    trial: a Python call with a small result, where the derivative functions stay CasADi's own
    (a Python callback around them copied the Jacobian's 10⁵ nonzeros on every call)."""

    def eval(self, arg):
        beat()  # the solve is alive (casadrone.limit.watchdog)
        return self.fn.call(list(arg))


def beating_functions(functions: dict[str, ca.Function], name: str) -> dict[str, ca.Function]:
    """:func:`stagewise_functions` with ``nlp_f`` and ``nlp_g`` :class:`Beating`."""
    return functions | {key: Beating(f"{name}_{key}", functions[key])
                        for key in ("nlp_f", "nlp_g")}


@dataclass(frozen=True)
class FatropSolver:
    """fatrop on a stage-ordered NLP: the order, the oracle (kept alive with the solvers) and
    the cold and warm solvers (warm: a smaller initial barrier parameter and bound push; CasADi's
    fatrop interface takes no initial multipliers, so a warm start is a primal one)."""

    order: StageOrder
    oracle: StageOracle
    cold: ca.Function
    warm: ca.Function


#: fatrop settings. tol as IPOPT's; ``mu_init``/``bound_push`` of a warm start as IPOPT's warm
#: start (1e-2 and 1e-4: casadrone.limit.nlp.ipopt_options).
def fatrop_options(tol: float, max_iter: int, warm: bool) -> dict:
    """fatrop's options (quiet) in CasADi's ``fatrop`` dictionary."""
    opts: dict = {"tol": tol, "max_iter": max_iter, "print_level": 0}
    if warm:
        opts.update({"mu_init": 1e-2, "bound_push": 1e-4})
    return opts


_FATROP: dict[tuple, FatropSolver] = {}


def fatrop_solver(nlp, tol: float, max_iter: int) -> FatropSolver:
    """The fatrop solvers of a shooting :class:`casadrone.limit.nlp.Nlp` (built once per NLP and
    process: the permutation is worked out from the Jacobian's sparsity, no symbolic block is
    rebuilt or compiled). Raises :class:`StageError` for an NLP without stage structure."""
    layout, model = nlp.layout, nlp.model
    key = (model.name, layout, tol, max_iter)
    if key in _FATROP:
        return _FATROP[key]
    if layout.method != "shooting" or not {"jac_g", "hess_lag"} <= set(nlp.derivatives):
        raise StageError("fatrop needs the multiple-shooting NLP (method: shooting)")
    symbolic = nlp.problem
    order = stage_order(ca.jacobian_sparsity(symbolic["g"], symbolic["x"]), layout.intervals,
                        layout.n_intervals, model.nx, model.nu)
    # the rows as IPOPT evaluates them, on the compiled step (8x cheaper than the SX step in
    # CasADi's virtual machine: 3.1 → 0.4 ms per evaluation at 200 intervals)
    problem = nlp.oracle or symbolic
    tag = f"stage_{model.name.replace('-', '_')}"
    oracle = StageOracle(tag, beating_functions(
        stagewise_functions(problem, nlp.derivatives["jac_g"], nlp.derivatives["hess_lag"],
                            order), tag))
    structure = {"structure_detection": "manual", "N": layout.n_intervals,
                 "nx": list(order.nx), "nu": list(order.nu), "ng": list(order.ng),
                 "print_time": False, "error_on_fail": False, "show_eval_warnings": False}
    name = f"fatrop_{model.name.replace('-', '_')}_{layout.n_legs}x{layout.intervals}"
    built = FatropSolver(order, oracle,
                         ca.nlpsol(name, "fatrop", oracle,
                                   structure | {"fatrop": fatrop_options(tol, max_iter, False)}),
                         ca.nlpsol(name + "_warm", "fatrop", oracle,
                                   structure | {"fatrop": fatrop_options(tol, max_iter, True)}))
    _FATROP[key] = built
    return built


def solve_stagewise(fs: FatropSolver, x0: np.ndarray, P: np.ndarray, lbx: np.ndarray,
                    ubx: np.ndarray, lbg: np.ndarray, ubg: np.ndarray, warm: bool
                    ) -> tuple[bool, str, float, tuple[np.ndarray, ...], int]:
    """One fatrop solve in the NLP's own order: (success, status, objective, (w, lam_x, lam_g,
    lam_p), iterations). Raises RuntimeError on an evaluation error (as nlpsol does)."""
    o = fs.order
    lg, ug = o.to_stage(lbg, rows=True), o.to_stage(ubg, rows=True)
    lx, ux = o.free_box(o.to_stage(lbx), o.to_stage(ubx), lg, ug)
    solver = fs.warm if warm else fs.cold
    out = solver(x0=o.to_stage(x0), p=P, lbx=lx, ubx=ux, lbg=lg, ubg=ug)
    stats = solver.stats()
    status = {0: "Solve_Succeeded"}.get(int(stats.get("return_status", -1)),
                                         f"fatrop return flag {stats.get('return_status')}")
    point = (o.from_stage(np.array(out["x"]).ravel()),
             o.from_stage(np.array(out["lam_x"]).ravel()),
             o.from_stage(np.array(out["lam_g"]).ravel(), rows=True),
             np.array(out["lam_p"]).ravel())
    return (bool(stats.get("success", False)) and bool(np.isfinite(float(out["f"]))), status,
            float(out["f"]), point, int(stats.get("iter_count", 0)))
