"""ev-MOGA: elitist multi-objective GA with an epsilon-box archive, as a pymoo ``Algorithm``.

Implements ev-MOGA as ``docs/concepts/evmoga.md`` states it (Herrero, Martínez-Iranzo, Blasco,
Sanchis; MATLAB toolbox ``evMOGA.m``). Three sets: the main population P (``n_ind_p``), the archive
A (the ε-Pareto set, at most one member per ε-box, **the result**), and the children G
(``n_ind_ga`` per generation).

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

The archive lives in plain numpy arrays (:class:`~casadrone.optimise.boxarchive.BoxArchive`: its
update costs O(|A|) numpy work per child, and a grid move one vectorised rebuild), and so does P
(row arrays of fixed length): a pymoo ``Population`` of either is built only when a caller asks
for one (``opt``, ``archive_pop``, ``pop``, ``result()``). The children are the only pymoo
``Individual`` objects a generation makes (pymoo's evaluator needs them), and they are dropped
after it; at paper scale (P 850, archive ~7 700) keeping P and the archive as Individuals held
~45 000 objects that every full garbage collection walked. Every random draw uses
``self.random_state`` (the ``numpy.random.Generator`` pymoo creates from ``seed`` in ``setup``),
so the algorithm pickles (checkpoints) cheaply and the same seed reproduces the same archive.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from pymoo.core.algorithm import Algorithm
from pymoo.core.individual import Individual
from pymoo.core.population import Population
from pymoo.termination.max_eval import MaximumFunctionCallTermination
from pymoo.termination.max_gen import MaximumGenerationTermination
from pymoo.util.display.multi import MultiObjectiveOutput
from pymoo.util.nds.non_dominated_sorting import NonDominatedSorting
from pymoo.util.optimum import filter_optimum

from casadrone.optimise.bitsets import points_below, unpack
from casadrone.optimise.boxarchive import BoxArchive, pareto_dominates

__all__ = [
    "EvMOGA",
    "constrained_dominance_matrix",
    "constrained_dominates",
    "replacements",
    "shrinking_schedule",
]

#: The row arrays the archive and the pickled P keep of each solution (pymoo's attributes).
ROW_KEYS = ("X", "F", "G", "H", "CV")
#: Pickled in place of the optimum's rows when they equal the archive's.
_ARCHIVE = "box_archive"


def _same_rows(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> bool:
    """Whether two sets of row arrays are equal bit for bit (same keys, shapes and bytes)."""
    return a.keys() == b.keys() and all(
        a[k].shape == b[k].shape and a[k].tobytes() == b[k].tobytes() for k in a)


# ---------------------------------------------------------------------------------------------
# dominance and schedules (pure functions; also used by the tests)
# ---------------------------------------------------------------------------------------------


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


def constrained_dominance_matrix(F: np.ndarray, cv: np.ndarray, F_b: np.ndarray,
                                 cv_b: np.ndarray) -> np.ndarray:
    """``D[i, j]``: whether ``(F[i], cv[i])`` dominates ``(F_b[j], cv_b[j])`` feasibility-first,
    i.e. ``constrained_dominates(F[i], cv[i], F_b, cv_b)[j]`` (same comparisons, elementwise).

    "All objectives <=" between feasible ones is found as bitsets
    (:func:`~casadrone.optimise.bitsets.points_below` on the negated objectives: 64 columns a
    word), then "some <" is tested on the few pairs found."""
    feasible, feasible_b = cv <= 0.0, cv_b <= 0.0
    D = np.empty((len(F), len(F_b)), dtype=bool)
    ok, bad = np.flatnonzero(feasible), np.flatnonzero(~feasible)
    if len(ok):  # Pareto dominance; "some <" only where "all <=" holds
        Fa = F[ok]
        if np.isfinite(Fa).all() and np.isfinite(F_b[feasible_b]).all():
            # a column that is not feasible is dominated whatever its objectives (NaN included):
            # give it -inf, so that the bitsets, which need comparable values, leave it alone
            F_c = np.where(feasible_b[:, None], F_b, -np.inf)
            le = unpack(points_below(-Fa, -F_c), len(F_b))
        else:
            le = Fa[:, None, 0] <= F_b[None, :, 0]
            for j in range(1, F.shape[1]):
                le &= Fa[:, None, j] <= F_b[None, :, j]
        ia, ib = np.nonzero(le)
        le[ia, ib] = (Fa[ia] < F_b[ib]).any(axis=1)
        D[ok] = le | ~feasible_b
    if len(bad):
        D[bad] = ~feasible_b & (cv[bad, None] < cv_b[None, :])
    return D


def replacements(pop_F: np.ndarray, pop_cv: np.ndarray, F: np.ndarray, cv: np.ndarray,
                 random_state: np.random.Generator) -> dict[int, int]:
    """ev-MOGA's "update P with each child" (docs/concepts/evmoga.md#generation), for the children
    ``(F, cv)`` in order: each draws a start index in P (``random_state.integers(len(P))``, one
    draw per child, in order), scans P circularly from it for the first member it strictly
    dominates (feasibility first) and takes its slot; if none, it is dropped. Returns ``{slot of P:
    child now in it}``; P is not edited.

    Vectorised: the child-over-P and child-over-child dominance matrices are computed once; the
    row a child scans is P's row of the matrix with each taken slot's column replaced by its
    child's column, so each child costs a few O(|P|) operations.
    """
    n = len(pop_F)
    starts = [int(random_state.integers(n)) for _ in range(len(F))]
    hits = constrained_dominance_matrix(F, cv, pop_F, pop_cv)  # hits[i, j]: child i beats slot j
    over_child = constrained_dominance_matrix(F, cv, F, cv)
    taken: dict[int, int] = {}
    # a child that dominates no member of P and no earlier child never finds a slot (its row
    # only ever gains the columns of earlier children): the others are scanned
    active = hits.any(axis=1) | np.tril(over_child, -1).any(axis=1)
    for i in np.flatnonzero(active).tolist():
        start = starts[i]
        row = hits[i]
        j = start + int(row[start:].argmax())  # the first hit at or after start, else the first
        if not row[j]:
            j = int(row[:start].argmax()) if start else 0
            if not row[j]:
                continue
        hits[:, j] = over_child[:, i]  # later children now meet child i in slot j
        taken[j] = i
    return taken


def _violation(pop: Population) -> tuple[np.ndarray, np.ndarray]:
    """Objectives and total constraint violation of an evaluated population.

    Rows with a non-finite objective or violation get an infinite violation (infeasible).
    """
    return _violation_of_rows({"F": _column(pop, "F", -1), "CV": _column(pop, "CV", -1)})


def _violation_of_rows(rows: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_violation` of solutions held as row arrays (``"F"``, ``"CV"``)."""
    F = rows["F"]
    cv = rows["CV"].reshape(len(F), -1)[:, 0].copy()
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
    """ev-MOGA (``docs/concepts/evmoga.md``): main population P, ε-box archive A, children G.

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

    After ``setup`` the archive is ``box_archive`` (numpy arrays), also exposed as ``archive_X``,
    ``archive_F`` (objectives), ``archive_box`` (box indices), ``archive_pop`` (a Population built
    on each call), and the grid as ``grid_min``, ``grid_max``, ``eps`` (``None`` until a feasible
    solution has been seen).
    """

    # set by pymoo's __init__ through the ``pop`` and ``opt`` setters, and by pymoo's advance
    pop_rows: dict[str, np.ndarray] | None
    _opt: Population | None
    _opt_rows: dict[str, np.ndarray] | None
    is_initialized: bool
    archive: Any

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
        output: Any = None,
        **kwargs: Any,
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
        self.box_archive: BoxArchive | None = None  # A and its grid
        self._n_seen = 0  # solutions evaluated so far: the next one's id
        # P: its row arrays (ROW_KEYS), set through the ``pop`` property, which pymoo's __init__
        # has already called

    # ---- the archive as the runner (algorithms.KeepsFront), pymoo and the tests see it ---------

    @property
    def _box(self) -> BoxArchive:
        """The archive, once ``_setup`` has made it."""
        if self.box_archive is None:
            raise RuntimeError("ev-MOGA has no archive before setup")
        return self.box_archive

    def front_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """X, F (minimised) and CV of the archive; None while it is empty (or not yet set up)."""
        a = self.box_archive
        if a is None or not len(a):
            return None
        return a.rows["X"], a.F, a.rows["CV"]

    def front_size(self) -> int:
        """Members of the archive (feasible solutions only)."""
        return len(self.box_archive) if self.box_archive is not None else 0

    @property
    def archive_F(self) -> np.ndarray:
        """Objectives (minimised) of the archive members, in archive order."""
        return self._box.F

    @property
    def archive_X(self) -> np.ndarray:
        return self._box.rows["X"]

    @property
    def archive_box(self) -> np.ndarray:
        return self._box.box

    @property
    def grid_min(self) -> np.ndarray | None:
        return self._box.grid_min

    @property
    def grid_max(self) -> np.ndarray | None:
        return self._box.grid_max

    @property
    def eps(self) -> np.ndarray | None:
        return self._box.eps

    @property
    def archive_pop(self) -> Population:
        """The archive as a new pymoo ``Population`` (built on each call: O(|A|) objects)."""
        return _population_of_rows(self._box.rows)

    @property
    def pop(self) -> Population | None:
        """P as a new pymoo ``Population`` (built on each call; P itself is ``pop_rows``)."""
        rows = self.__dict__.get("pop_rows")
        return None if rows is None else _population_of_rows(rows)

    @pop.setter
    def pop(self, value: Population | None) -> None:
        """pymoo sets P (empty in ``setup``, the evaluated initial population in ``advance``)."""
        empty = value is None or len(value) == 0
        self.pop_rows = None if empty else _rows(value, self._widths(with_id=False))

    @property
    def pop_F(self) -> np.ndarray:
        """Objectives (minimised) of P: its ``F`` rows (the array itself, not a copy)."""
        rows = self.__dict__.get("pop_rows")
        return np.empty((0, 0)) if rows is None else rows["F"]

    @property
    def pop_cv(self) -> np.ndarray:
        """Total constraint violation of P, infinite for a non-finite objective or violation
        (:func:`_violation_of_rows`; a new array)."""
        rows = self.__dict__.get("pop_rows")
        return np.empty(0) if rows is None else _violation_of_rows(rows)[1]

    @property
    def opt(self) -> Population | None:
        """pymoo's optimum: the archive at the end of the last generation (built on demand,
        once per generation)."""
        if self._opt is None and self._opt_rows is not None:
            self._opt = _population_of_rows(self._opt_rows)
        return self._opt

    @opt.setter
    def opt(self, value: Population | None) -> None:
        self._opt, self._opt_rows = value, None

    def __getstate__(self) -> dict:
        """Drop the built optimum (a checkpoint of Individual objects costs ~0.05 ms per
        individual) and the last children (``history.sqlite`` holds them), and store the
        optimum's rows only when they are not the archive's (after a generation they are: the
        archive would be pickled twice)."""
        state = self.__dict__.copy()
        opt_rows = state.get("_opt_rows")
        if opt_rows is not None:
            state["_opt"] = None
            if _same_rows(opt_rows, self._box.rows):
                state["_opt_rows"] = _ARCHIVE
        if isinstance(state.get("off"), Population):
            state["off"] = None
        return state

    def __setstate__(self, state: dict) -> None:
        for key in ("_individuals", "pop_F", "pop_cv"):  # git 6094a45 and before: P's cache
            state.pop(key, None)  # of Individuals, and P's objectives and violation (now derived)
        pop = state.pop("pop", None)  # P of git 6094a45 and before: its rows or a Population
        if isinstance(state.get("off"), dict):
            state["off"] = _population_of_rows(state["off"])
        if isinstance(state.get("_opt_rows"), str) and state["_opt_rows"] == _ARCHIVE:
            state["_opt_rows"] = {k: v.copy() for k, v in state["box_archive"].rows.items()}
        legacy = "box_archive" not in state and "archive_pop" in state
        if legacy:  # a checkpoint of the sequential archive (git 683f05d and before): convert it
            archive = {k: state.pop(k) for k in ("archive_pop", "archive_F", "archive_box",
                                                 "grid_min", "grid_max", "eps")}
            state["_opt"], state["_opt_rows"] = state.pop("opt", None), None
        self.__dict__.update(state)
        if isinstance(pop, dict):
            self.pop_rows = pop
        elif pop is not None:
            self.pop = pop
        if legacy:
            self._n_seen = int(self.evaluator.n_eval)
            assert self.n_div is not None  # set up before any checkpoint
            self.box_archive = BoxArchive(self.n_div, self._widths())
            pop = archive["archive_pop"]
            if len(pop):  # the old members get ids below zero: new ones count up from n_eval
                rows = _rows(pop, self._widths(with_id=False))
                rows["id"] = -1.0 - np.arange(len(pop), dtype=float)[:, None]
                self._box._set(rows, np.asarray(archive["archive_box"]).T)
            if archive["grid_min"] is not None:
                self._box.grid_min = archive["grid_min"]
                self._box.grid_max = archive["grid_max"]
                self._box.eps = archive["eps"]

    # ---- pymoo hooks --------------------------------------------------------------------------

    def _setup(self, problem: Any, **kwargs: Any) -> None:
        m = problem.n_obj
        n_div = np.broadcast_to(np.asarray(self.n_div_setting, dtype=np.int64), (m,)).copy()
        if np.any(n_div < 1):
            raise ValueError(f"n_div must be >= 1 per objective, got {self.n_div_setting}")
        self.n_div = n_div
        xl, xu = problem.bounds()
        if xl is None or xu is None or not (np.all(np.isfinite(xl)) and np.all(np.isfinite(xu))):
            raise ValueError("ev-MOGA needs finite lower and upper bounds on every variable")
        self.schedule_generations = self._resolve_generations()
        self.box_archive = BoxArchive(n_div, self._widths())

    def _widths(self, with_id: bool = True) -> dict[str, int]:
        """Columns of the row arrays kept per solution (``id``: its serial number)."""
        p = self.problem
        widths = {"X": p.n_var, "F": p.n_obj, "G": p.n_ieq_constr, "H": p.n_eq_constr, "CV": 1}
        return {**widths, "id": 1} if with_id else widths

    def _rows_of_children(self, infills: Population) -> dict[str, np.ndarray]:
        rows = _rows(infills, self._widths(with_id=False))
        rows["id"] = (self._n_seen + np.arange(len(infills), dtype=float))[:, None]
        self._n_seen += len(infills)
        return rows

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

    def advance(self, infills: Population | None = None, **kwargs: Any) -> None:
        """pymoo's ``Algorithm.advance`` (0.6.1–0.6.2, the same steps in the same order), except
        that it returns ``None`` where pymoo returns ``self.opt`` (or ``self.result()`` after the
        last generation): either builds a population of the whole archive (~7 700 Individuals
        at paper scale, ~30 ms a generation, and garbage for the collector), which
        ``Algorithm.next()``, ``Algorithm.run()`` and the runner drop unread. ``opt`` and
        ``result()`` build it when asked."""
        self.off = infills
        if not self.is_initialized:
            self.n_iter = 1
            self._initialize_advance(infills=infills, **kwargs)
            self.is_initialized = True
            self._post_advance()
        else:
            self._advance(infills=infills, **kwargs)  # pymoo: a None or true return → post
            self._post_advance()
        if self.termination.has_terminated():
            self.finalize()
        if self.archive is not None and infills is not None:
            self.archive = self.archive.add(infills)

    def _initialize_advance(self, infills: Population | None = None, **kwargs: Any) -> None:
        rows = self._rows_of_children(infills)
        self.pop_rows = {k: rows[k].copy() for k in ROW_KEYS}
        F, cv = _violation_of_rows(rows)
        feasible = np.flatnonzero(cv <= 0.0)
        if len(feasible) == 0:
            return
        nd = feasible[NonDominatedSorting().do(F[feasible], only_non_dominated_front=True)]
        nd = np.sort(nd)
        F_nd = F[nd]
        self._box.set_grid(F_nd.min(axis=0), F_nd.max(axis=0))
        self._box.fill({k: v[nd] for k, v in rows.items()})

    def _infill(self) -> Population:
        rs = self.random_state
        t = self.n_iter - 2  # pymoo's generation 2 is ev-MOGA's generation t = 0
        assert self.pop_rows is not None and self.schedule_generations is not None  # set up
        dd = shrinking_schedule(self.dd_ini, self.dd_fin, t, self.schedule_generations)
        sigma = shrinking_schedule(self.sigma_ini, self.sigma_fin, t, self.schedule_generations)
        xl, xu = self.problem.bounds()
        n_pairs, n_var = self.n_ind_ga // 2, self.problem.n_var

        X_p = self.pop_rows["X"]
        p1 = X_p[rs.integers(len(X_p), size=n_pairs)]
        if len(self._box):
            p2 = self.archive_X[rs.integers(len(self._box), size=n_pairs)]
        else:  # A empty: both parents from P
            p2 = X_p[rs.integers(len(X_p), size=n_pairs)]
        mutate = rs.random(n_pairs) < self.p_m
        beta = rs.uniform(-dd, 1.0 + dd, size=(n_pairs, 1))
        noise = rs.normal(0.0, 1.0, size=(2, n_pairs, n_var)) * (sigma / 100.0) * (xu - xl)

        c1 = np.where(mutate[:, None], p1 + noise[0], beta * p1 + (1.0 - beta) * p2)
        c2 = np.where(mutate[:, None], p2 + noise[1], (1.0 - beta) * p1 + beta * p2)
        X = np.clip(np.concatenate([c1, c2]), xl, xu)
        return Population.new("X", X)

    def _advance(self, infills: Population | None = None, **kwargs: Any) -> None:
        rows = self._rows_of_children(infills)
        F, cv = _violation_of_rows(rows)
        feasible = np.flatnonzero(cv <= 0.0)
        self._box.offer_many({k: v[feasible] for k, v in rows.items()})
        taken = replacements(self.pop_F, self.pop_cv, F, cv, self.random_state)
        if taken:  # slot j of P takes child i
            assert self.pop_rows is not None
            j = np.fromiter(taken.keys(), dtype=np.intp, count=len(taken))
            i = np.fromiter(taken.values(), dtype=np.intp, count=len(taken))
            for key in ROW_KEYS:
                self.pop_rows[key][j] = rows[key][i]

    def offer_solutions(self, X: np.ndarray, F: np.ndarray, G: np.ndarray) -> None:
        """Offer solutions evaluated outside the generations (a polish, :mod:`casadrone.optimise.
        hybrid`) to the archive A by its rules (P is left as it is): ``F`` minimised, ``G`` the
        inequality constraints (≤ 0 feasible); infeasible ones are dropped, as for children."""
        n = len(X)
        rows = {"X": np.asarray(X, float).reshape(n, -1), "F": np.asarray(F, float).reshape(n, -1),
                "G": np.asarray(G, float).reshape(n, -1), "H": np.zeros((n, 0))}
        rows["CV"] = _default_cv(rows["G"], rows["H"])
        rows["id"] = (self._n_seen + np.arange(n, dtype=float))[:, None]
        self._n_seen += n
        _, cv = _violation_of_rows(rows)
        feasible = np.flatnonzero(cv <= 0.0)
        self._box.offer_many({k: v[feasible] for k, v in rows.items()})
        self._set_optimum()

    def _set_optimum(self) -> None:
        if len(self._box):  # a snapshot: A is edited in place later
            self._opt, self._opt_rows = None, {k: v.copy()
                                               for k, v in self._box.rows.items()}
        else:  # nothing feasible yet: pymoo's convention, the least infeasible member of P
            self.opt = filter_optimum(self.pop, least_infeasible=True)


def _column(pop: Population, key: str, width: int) -> np.ndarray:
    """``pop.get(key)`` as a (len(pop), width) float array (``width`` -1: as it comes), read
    from the attributes pymoo's ``Individual.get`` reads (~0.2 µs a member instead of ~2)."""
    return np.array([getattr(ind, key) for ind in pop], dtype=float).reshape(len(pop), width)


def _rows(pop: Population, widths: dict[str, int]) -> dict[str, np.ndarray]:
    """The row arrays ``ROW_KEYS`` of a population, each (len(pop), width) float.

    ``CV`` is pymoo's ``Individual.CV``: computed here for all rows at once from G and H
    (:func:`_default_cv`) when no member has one yet and every member has pymoo's default
    configuration (the case of the children ev-MOGA makes: ~10 µs a member saved), else read
    from each member."""
    rows = {k: _column(pop, k, widths[k]) for k in ROW_KEYS if k != "CV"}
    default = Individual.default_config()
    # pymoo 0.6 caches a member's CV in ``_CV``; any other layout takes the member-by-member path
    if all(getattr(ind, "_CV", False) is None and ind.config == default for ind in pop):
        rows["CV"] = _default_cv(rows["G"], rows["H"])
    else:
        rows["CV"] = _column(pop, "CV", widths["CV"])
    return {k: rows[k] for k in ROW_KEYS}


def _default_cv(G: np.ndarray, H: np.ndarray) -> np.ndarray:
    """pymoo's constraint violation under its default configuration (``calc_cv``), rows at
    once: the sum of the inequality constraints above their tolerance (0) plus the sum of the
    equality constraints' magnitudes above theirs (1e-4), as a (n, 1) column. Each row is summed
    along its own contiguous axis, as pymoo sums a member's 1-D array, so the values agree bit
    for bit (tested against ``Individual.CV``)."""
    config = Individual.default_config()

    def part(c: np.ndarray, eps: float) -> np.ndarray:  # pymoo's constr_to_cv, per row
        return np.maximum(0.0, c - eps).sum(axis=1) if c.shape[1] else np.zeros(len(c))

    return (part(G, config["cv_ieq"]["eps"]) + part(np.abs(H), config["cv_eq"]["eps"]))[:, None]


def _population_of_rows(rows: dict[str, np.ndarray]) -> Population:
    """A pymoo population of evaluated solutions from row arrays (each member its own copies,
    as ``Population.new`` makes them, set directly: ~4 µs a member instead of ~15)."""
    pop = Population.empty(len(rows["X"]))
    columns = [np.array(rows[k], dtype=float) for k in ROW_KEYS]
    for ind, *values in zip(pop, *columns, strict=True):
        ind.X, ind.F, ind.G, ind.H, ind.CV = (v.copy() for v in values)
        ind.evaluated = {"F", "G", "H"}
    return pop
