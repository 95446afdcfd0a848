"""ev-MOGA: elitist multi-objective GA with an epsilon-box archive, as a pymoo ``Algorithm``.

Implements ``design/EVMOGA.md`` (Herrero, Martínez-Iranzo, Blasco, Sanchis; MATLAB toolbox
``evMOGA.m``). Three sets: the main population P (``n_ind_p``), the archive A (the ε-Pareto set,
at most one member per ε-box, **the result**), and the children G (``n_ind_ga`` per generation).

pymoo counts the initialisation (evaluating P) as generation 1, so ev-MOGA's ``G`` generations are
``("n_gen", G + 1)``; a run costs ``n_ind_p + G * n_ind_ga`` evaluations. The crossover extension
``dd`` and the mutation σ shrink over ``G`` generations, so ``G`` must be known: it is the
``generations`` argument when given (the default termination is then ``("n_gen", G + 1)``),
otherwise it is derived from an ``("n_gen", N)`` termination (``G = N - 1``) or an
``("n_eval", E)`` termination (``G = ceil((E - n_ind_p) / n_ind_ga)``); any other termination
without ``generations`` is a ``ValueError``.

Constraints are handled feasibility-first: a feasible solution dominates an infeasible one, between
infeasible ones the smaller total violation wins. The violation is pymoo's ``CV`` (for inequality
constraints: the sum of the positive ``G``); a solution with a non-finite objective is treated as
infeasible with infinite violation. Only feasible solutions enter the archive.

All state lives in numpy arrays and pymoo ``Population`` objects, and every random draw uses
``self.random_state`` (the ``numpy.random.Generator`` pymoo creates from ``seed`` in ``setup``),
so the algorithm pickles (checkpoints) and the same seed reproduces the same archive.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from pymoo.core.algorithm import Algorithm
from pymoo.core.individual import Individual
from pymoo.core.population import Population
from pymoo.termination.max_eval import MaximumFunctionCallTermination
from pymoo.termination.max_gen import MaximumGenerationTermination
from pymoo.util.display.multi import MultiObjectiveOutput
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting
from pymoo.util.optimum import filter_optimum

__all__ = [
    "EvMOGA",
    "box_dominates",
    "box_index",
    "constrained_dominates",
    "pareto_dominates",
    "shrinking_schedule",
]


# ---------------------------------------------------------------------------------------------
# dominance and boxes (pure functions; also used by the tests)
# ---------------------------------------------------------------------------------------------


def pareto_dominates(f: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Whether ``f`` Pareto-dominates each row of ``F`` (minimisation)."""
    F = np.atleast_2d(F)
    return (f <= F).all(axis=1) & (f < F).any(axis=1)


def constrained_dominates(f: np.ndarray, cv: float, F: np.ndarray, CV: np.ndarray) -> np.ndarray:
    """Feasibility-first dominance of ``(f, cv)`` over each row of ``(F, CV)``.

    Feasible (``cv <= 0``) beats infeasible; between infeasible ones the smaller violation wins;
    between feasible ones Pareto dominance decides.
    """
    F, CV = np.atleast_2d(F), np.asarray(CV, dtype=float)
    feasible = CV <= 0.0
    if cv <= 0.0:
        return np.where(feasible, pareto_dominates(f, F), True)
    return np.where(feasible, False, cv < CV)


def box_index(F: np.ndarray, f_min: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """ε-box indices ``ceil((f - min) / ε)`` per objective (0 where ε = 0), rows of ``F``.

    The ratio is rounded to 1e-6 before the ceiling so that floating noise does not move a point
    across a box edge.
    """
    F = np.atleast_2d(F)
    positive = eps > 0.0
    ratio = np.where(positive, (F - f_min) / np.where(positive, eps, 1.0), 0.0)
    return np.ceil(np.round(ratio, 6)).astype(np.int64)


def box_dominates(b: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Whether box ``b`` dominates each row of ``B`` (``b <= B`` componentwise, ``b != B``)."""
    B = np.atleast_2d(B)
    return (b <= B).all(axis=1) & (b != B).any(axis=1)


def _violation(pop: Population) -> tuple[np.ndarray, np.ndarray]:
    """Objectives and total constraint violation of an evaluated population.

    Rows with a non-finite objective or violation get an infinite violation (infeasible).
    """
    F = np.asarray(pop.get("F"), dtype=float)
    cv = np.asarray(pop.get("CV"), dtype=float).reshape(len(pop), -1)[:, 0].copy()
    bad = ~np.isfinite(F).all(axis=1) | np.isnan(cv)
    cv[bad] = np.inf
    return F, cv


def shrinking_schedule(v_ini: float, v_fin: float, t: int, n_gen: int) -> float:
    """``v_t = v_ini / sqrt(1 + t ((v_ini/v_fin)^2 - 1) / (G - 1))``: v_ini at t=0, v_fin at G-1."""
    if n_gen <= 1:
        return v_ini
    t = min(max(t, 0), n_gen - 1)
    return v_ini / math.sqrt(1.0 + t * ((v_ini / v_fin) ** 2 - 1.0) / (n_gen - 1))


# ---------------------------------------------------------------------------------------------
# the algorithm
# ---------------------------------------------------------------------------------------------


class EvMOGA(Algorithm):
    """ev-MOGA (``design/EVMOGA.md``): main population P, ε-box archive A, children G.

    Args:
        n_ind_p: Size of the main population P (paper: 850).
        n_ind_ga: Children per generation (even; MATLAB default 8).
        n_div: Boxes per objective, an int or one int per objective (paper: 200).
        p_m: Mutation probability; crossover happens with probability ``1 - p_m``.
        dd_ini, dd_fin: Extended-line-crossover extension at the first and last generation.
        sigma_ini, sigma_fin: Gaussian mutation standard deviation at the first and last generation,
            in % of each variable's range.
        generations: Number of ev-MOGA generations G (drives the dd/σ schedule). If ``None`` it is
            derived from the termination (see the module docstring).
        **kwargs: Passed to ``pymoo.core.algorithm.Algorithm`` (termination, callback, ...).

    The result (``self.opt``, ``minimize(...).X / .F``) is the archive A; while A is empty (no
    feasible solution yet) ``self.opt`` is the least infeasible member of P, as in pymoo, and the
    result's X / F are ``None`` unless ``return_least_infeasible=True``.

    After ``setup`` the archive is exposed as ``archive_pop`` (Population), ``archive_F``
    (objectives), ``archive_box`` (box indices), and the grid as ``grid_min``, ``grid_max``,
    ``eps`` (``None`` until a feasible solution has been seen).
    """

    def __init__(
        self,
        n_ind_p: int = 100,
        n_ind_ga: int = 8,
        n_div: int | Sequence[int] = 200,
        p_m: float = 0.2,
        dd_ini: float = 0.25,
        dd_fin: float = 0.1,
        sigma_ini: float = 20.0,
        sigma_fin: float = 0.1,
        generations: int | None = None,
        output=None,
        **kwargs,
    ) -> None:
        if generations is not None and kwargs.get("termination") is None:
            kwargs["termination"] = ("n_gen", int(generations) + 1)
        super().__init__(output=MultiObjectiveOutput() if output is None else output, **kwargs)
        if int(n_ind_p) < 1:
            raise ValueError(f"n_ind_p must be >= 1, got {n_ind_p}")
        if int(n_ind_ga) < 2 or int(n_ind_ga) % 2:
            raise ValueError(f"n_ind_ga must be even and >= 2, got {n_ind_ga}")
        if not 0.0 <= p_m <= 1.0:
            raise ValueError(f"p_m must be in [0, 1], got {p_m}")
        if min(dd_ini, dd_fin) < 0.0 or min(sigma_ini, sigma_fin) <= 0.0 or dd_fin == 0.0:
            raise ValueError("dd_ini >= 0, dd_fin > 0, sigma_ini > 0 and sigma_fin > 0 required")
        if generations is not None and int(generations) < 1:
            raise ValueError(f"generations must be >= 1, got {generations}")
        self.n_ind_p = int(n_ind_p)
        self.n_ind_ga = int(n_ind_ga)
        self.n_div_setting = n_div
        self.p_m = float(p_m)
        self.dd_ini, self.dd_fin = float(dd_ini), float(dd_fin)
        self.sigma_ini, self.sigma_fin = float(sigma_ini), float(sigma_fin)
        self.generations = None if generations is None else int(generations)
        # resolved in _setup
        self.schedule_generations: int | None = None
        self.n_div: np.ndarray | None = None
        # archive A and grid
        self.archive_pop = Population.empty()
        self.archive_F = np.empty((0, 0))
        self.archive_box = np.empty((0, 0), dtype=np.int64)
        self.grid_min: np.ndarray | None = None
        self.grid_max: np.ndarray | None = None
        self.eps: np.ndarray | None = None
        # objectives and violation of P, kept in step with self.pop
        self.pop_F = np.empty((0, 0))
        self.pop_cv = np.empty(0)

    # ---- pymoo hooks --------------------------------------------------------------------------

    def _setup(self, problem, **kwargs) -> None:
        m = problem.n_obj
        n_div = np.broadcast_to(np.asarray(self.n_div_setting, dtype=np.int64), (m,)).copy()
        if np.any(n_div < 1):
            raise ValueError(f"n_div must be >= 1 per objective, got {self.n_div_setting}")
        self.n_div = n_div
        xl, xu = problem.bounds()
        if xl is None or xu is None or not (np.all(np.isfinite(xl)) and np.all(np.isfinite(xu))):
            raise ValueError("ev-MOGA needs finite lower and upper bounds on every variable")
        self.schedule_generations = self._resolve_generations()
        self.archive_F = np.empty((0, m))
        self.archive_box = np.empty((0, m), dtype=np.int64)

    def _resolve_generations(self) -> int:
        if self.generations is not None:
            return self.generations
        term = self.termination
        if isinstance(term, MaximumGenerationTermination) and np.isfinite(term.n_max_gen):
            return max(int(term.n_max_gen) - 1, 1)
        if isinstance(term, MaximumFunctionCallTermination) and np.isfinite(term.n_max_evals):
            return max(math.ceil((term.n_max_evals - self.n_ind_p) / self.n_ind_ga), 1)
        raise ValueError(
            "EvMOGA needs its number of generations G for the dd/sigma schedule: pass "
            "generations=G, or a termination ('n_gen', G + 1) or ('n_eval', E)"
        )

    def _initialize_infill(self) -> Population:
        xl, xu = self.problem.bounds()
        X = xl + self.random_state.random((self.n_ind_p, self.problem.n_var)) * (xu - xl)
        return Population.new("X", X)

    def _initialize_advance(self, infills=None, **kwargs) -> None:
        self.pop = infills
        self.pop_F, self.pop_cv = _violation(infills)
        feasible = np.flatnonzero(self.pop_cv <= 0.0)
        if len(feasible) == 0:
            return
        nd = feasible[NonDominatedSorting().do(self.pop_F[feasible], only_non_dominated_front=True)]
        nd = np.sort(nd)
        F_nd = self.pop_F[nd]
        self._set_grid(F_nd.min(axis=0), F_nd.max(axis=0))
        for i in nd:
            self._insert(infills[i], self.pop_F[i])

    def _infill(self) -> Population:
        rs = self.random_state
        t = self.n_iter - 2  # pymoo's generation 2 is ev-MOGA's generation t = 0
        dd = shrinking_schedule(self.dd_ini, self.dd_fin, t, self.schedule_generations)
        sigma = shrinking_schedule(self.sigma_ini, self.sigma_fin, t, self.schedule_generations)
        xl, xu = self.problem.bounds()
        n_pairs, n_var = self.n_ind_ga // 2, self.problem.n_var

        source_2 = self.archive_pop if len(self.archive_pop) else self.pop  # A empty: both from P
        p1 = np.asarray(self.pop[rs.integers(len(self.pop), size=n_pairs)].get("X"), dtype=float)
        p2 = np.asarray(source_2[rs.integers(len(source_2), size=n_pairs)].get("X"), dtype=float)
        mutate = rs.random(n_pairs) < self.p_m
        beta = rs.uniform(-dd, 1.0 + dd, size=(n_pairs, 1))
        noise = rs.normal(0.0, 1.0, size=(2, n_pairs, n_var)) * (sigma / 100.0) * (xu - xl)

        c1 = np.where(mutate[:, None], p1 + noise[0], beta * p1 + (1.0 - beta) * p2)
        c2 = np.where(mutate[:, None], p2 + noise[1], (1.0 - beta) * p1 + beta * p2)
        X = np.clip(np.concatenate([c1, c2]), xl, xu)
        return Population.new("X", X)

    def _advance(self, infills=None, **kwargs) -> None:
        F, cv = _violation(infills)
        for i in range(len(infills)):
            if cv[i] <= 0.0:
                self._archive(infills[i], F[i])
        n = len(self.pop)
        for i in range(len(infills)):
            start = int(self.random_state.integers(n))
            order = (start + np.arange(n)) % n
            hit = np.flatnonzero(
                constrained_dominates(F[i], cv[i], self.pop_F[order], self.pop_cv[order])
            )
            if len(hit):
                j = order[hit[0]]
                self.pop[j] = infills[i]
                self.pop_F[j], self.pop_cv[j] = F[i], cv[i]

    def _set_optimum(self) -> None:
        if len(self.archive_pop):
            self.opt = self.archive_pop.copy()  # a snapshot: A is edited in place later
        else:  # nothing feasible yet: pymoo's convention, the least infeasible member of P
            self.opt = filter_optimum(self.pop, least_infeasible=True)

    # ---- archive ------------------------------------------------------------------------------

    def _set_grid(self, f_min: np.ndarray, f_max: np.ndarray) -> None:
        self.grid_min = np.array(f_min, dtype=float)
        self.grid_max = np.array(f_max, dtype=float)
        self.eps = (self.grid_max - self.grid_min) / self.n_div

    def _set_archive(self, pop: Population, F: np.ndarray, box: np.ndarray) -> None:
        self.archive_pop, self.archive_F, self.archive_box = pop, F, box

    def _archive(self, ind: Individual, f: np.ndarray) -> None:
        """Offer a feasible child to A, recomputing the grid when it moves the extremes."""
        m = len(f)
        if len(self.archive_pop) == 0 and self.grid_min is None:
            self._set_grid(f, f)
            self._set_archive(
                Population.create(ind), f[None, :].copy(), np.zeros((1, m), dtype=np.int64)
            )
            return
        a = int(np.sum(f >= self.grid_max))
        b = int(np.sum(f <= self.grid_min))
        if a == 0 and b == 0:
            self._insert(ind, f)
        elif a == m and b == 0:
            return
        elif a == 0 and b == m:
            eps = self.eps
            self._set_grid(f, f)
            self.eps = eps
            self._set_archive(
                Population.create(ind), f[None, :].copy(), box_index(f, self.grid_min, self.eps)
            )
        else:
            if np.any(pareto_dominates_rows(self.archive_F, f)):
                return
            keep = ~pareto_dominates(f, self.archive_F)
            pop, F = self.archive_pop[keep], self.archive_F[keep]
            both = np.vstack([F, f])
            self._set_grid(both.min(axis=0), both.max(axis=0))
            self._set_archive(Population.empty(), np.empty((0, m)), np.empty((0, m), np.int64))
            for k in range(len(pop)):
                self._insert(pop[k], F[k])
            self._insert(ind, f)

    def _insert(self, ind: Individual, f: np.ndarray) -> bool:
        """Insert into A with the current grid (EVMOGA.md cases 1-4); return whether x entered."""
        b = box_index(f, self.grid_min, self.eps)[0]
        B = self.archive_box
        if len(B) and np.any(box_dominates_rows(B, b)):
            return False  # case 1: x's box is dominated
        same = np.flatnonzero((B == b).all(axis=1)) if len(B) else np.empty(0, dtype=int)
        if len(same):  # case 3 (the invariant leaves nothing for case 2 to delete)
            k = int(same[0])
            f_k = self.archive_F[k]
            if pareto_dominates(f, f_k)[0]:
                replace = True
            elif pareto_dominates(f_k, f)[0] or np.array_equal(f, f_k):
                replace = False
            else:
                replace = self._centre_distance(f, b) < self._centre_distance(f_k, b)
            if replace:
                self.archive_pop[k] = ind
                self.archive_F[k] = f
            return replace
        keep = ~box_dominates(b, B) if len(B) else np.ones(0, dtype=bool)  # case 2
        self._set_archive(  # case 4
            Population.merge(self.archive_pop[keep], Population.create(ind)),
            np.vstack([self.archive_F[keep], f]),
            np.vstack([B[keep], b]),
        )
        return True

    def _centre_distance(self, f: np.ndarray, b: np.ndarray) -> float:
        """Distance from ``f`` to the centre of box ``b``, in units of ε (0 where ε = 0)."""
        centre = self.grid_min + (b - 0.5) * self.eps
        positive = self.eps > 0.0
        d = np.where(positive, (f - centre) / np.where(positive, self.eps, 1.0), 0.0)
        return float(np.linalg.norm(d))


def pareto_dominates_rows(F: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Whether each row of ``F`` Pareto-dominates ``f`` (minimisation)."""
    F = np.atleast_2d(F)
    return (F <= f).all(axis=1) & (F < f).any(axis=1)


def box_dominates_rows(B: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Whether each row of ``B`` box-dominates ``b``."""
    B = np.atleast_2d(B)
    return (B <= b).all(axis=1) & (B != b).any(axis=1)
