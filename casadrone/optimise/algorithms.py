"""Build an optimisation algorithm by name: casadrone's ev-MOGA or one of pymoo's.

Used by problem files (``algorithm: {name: ..., settings: {...}}``) and by the benchmarks, so that
ev-MOGA and pymoo's algorithms are compared on the same budget through the same call.
"""

from __future__ import annotations

import contextlib
import importlib
from collections.abc import Callable, Iterator, Mapping
from math import comb
from typing import Any, Protocol, runtime_checkable

import numpy as np
from pymoo.core.algorithm import Algorithm

from casadrone.config.codesign import PolishSettings
from casadrone.optimise.evmoga import EvMOGA

__all__ = ["ALGORITHM_NAMES", "REFUSED", "make_algorithm", "reference_directions",
           "seeded_defaults", "settings_problems"]

# name -> (module, class, takes reference directions, takes pop_size)
_PYMOO: dict[str, tuple[str, str, bool, bool]] = {
    "nsga2": ("pymoo.algorithms.moo.nsga2", "NSGA2", False, True),
    "nsga3": ("pymoo.algorithms.moo.nsga3", "NSGA3", True, True),
    "unsga3": ("pymoo.algorithms.moo.unsga3", "UNSGA3", True, True),
    "smsemoa": ("pymoo.algorithms.moo.sms", "SMSEMOA", False, True),
    "spea2": ("pymoo.algorithms.moo.spea2", "SPEA2", False, True),
    "moead": ("pymoo.algorithms.moo.moead", "MOEAD", True, False),
    "rvea": ("pymoo.algorithms.moo.rvea", "RVEA", True, True),
    "ctaea": ("pymoo.algorithms.moo.ctaea", "CTAEA", True, False),
}

ALGORITHM_NAMES: tuple[str, ...] = ("evmoga", *_PYMOO)

#: Algorithms ``make_algorithm`` builds but a casadrone problem cannot use, with the reason.
REFUSED: dict[str, str] = {
    "moead": "pymoo's MOEA/D handles no constraints, and every casadrone problem has the "
    "always-on lap-completed constraint (failed candidates are infeasible); use nsga3 or rvea "
    "for a reference-direction algorithm",
}


#: Ceiling of every whole-number setting (counts of individuals, offspring, neighbours,
#: divisions): over ten times the paper's largest (850 individuals, 200 divisions, Table 6),
#: low enough that no setting can ask for more memory than a workstation has.
MAX_COUNT = 10_000


def _int(lo: int, even: bool = False) -> Callable[[Any], str | None]:
    def check(v: Any) -> str | None:
        if isinstance(v, bool) or not isinstance(v, int):
            return f"expected a whole number, got {v!r}"
        if v < lo:
            return f"must be >= {lo}, got {v}"
        if v > MAX_COUNT:
            return f"must be <= {MAX_COUNT} (far beyond any use; memory grows with it), got {v}"
        if even and v % 2:
            return f"must be even (children come in pairs), got {v}"
        return None
    return check


def _float(lo: float, hi: float = float("inf"), lo_open: bool = False
           ) -> Callable[[Any], str | None]:
    def check(v: Any) -> str | None:
        if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v):
            return f"expected a finite number, got {v!r}"
        if v < lo or (lo_open and v == lo) or v > hi:
            left = "(" if lo_open else "["
            return f"must be in {left}{lo:g}, {hi:g}], got {v}"
        return None
    return check


def _bool(v: Any) -> str | None:
    return None if isinstance(v, bool) else f"expected true or false, got {v!r}"


def _polish(v: Any) -> str | None:
    """The polish settings (:class:`casadrone.config.codesign.PolishSettings`), as one line."""
    from pydantic import ValidationError

    if not isinstance(v, dict):
        return f"expected a mapping such as {{members: 5}}, got {v!r}"
    try:
        PolishSettings.model_validate(v)
    except ValidationError as exc:
        e = exc.errors()[0]
        return f"{'.'.join(map(str, e['loc']))}: {e['msg']}"
    return None


#: Settings the runner acts on, never passed to the algorithm's constructor.
RUNNER_SETTINGS = ("polish",)


def _n_div(v: Any) -> str | None:
    if isinstance(v, list):
        bad = [_int(1)(x) for x in v]
        return next((f"item {i}: {b}" for i, b in enumerate(bad) if b), None)
    return _int(1)(v)


_COMMON = {"eliminate_duplicates": _bool, "n_offsprings": _int(1)}
#: The settings a problem file may give each algorithm, with their checks (the constructors'
#: other arguments are operator objects, which YAML cannot express; population and generations
#: have their own keys).
SETTINGS: dict[str, dict[str, Any]] = {
    "evmoga": {"n_ind_ga": _int(2, even=True), "n_div": _n_div, "p_m": _float(0.0, 1.0),
               "dd_ini": _float(0.0), "dd_fin": _float(0.0, lo_open=True),
               "sigma_ini": _float(0.0, lo_open=True), "sigma_fin": _float(0.0, lo_open=True),
               "n_ind_p": _int(1), "polish": _polish},
    "nsga2": dict(_COMMON), "nsga3": dict(_COMMON), "unsga3": dict(_COMMON),
    "smsemoa": {**_COMMON, "normalize": _bool}, "spea2": dict(_COMMON),
    "moead": {"n_neighbors": _int(1), "prob_neighbor_mating": _float(0.0, 1.0)},
    "rvea": {**_COMMON, "alpha": _float(0.0, lo_open=True),
             "adapt_freq": _float(0.0, 1.0, lo_open=True)},
    "ctaea": {"eliminate_duplicates": _bool},
}
#: Settings that have a key of their own in the problem's ``algorithm`` section.
_OWN_KEYS = {"generations": "algorithm.generations", "pop_size": "algorithm.population",
             "n_ind_p": "algorithm.population", "ref_dirs": "algorithm.population",
             "seed": "seed", "termination": "algorithm.generations"}


def settings_problems(
    name: str, settings: Mapping[str, Any], population: int, n_obj: int
) -> list[tuple[str, str]]:
    """Problems of an algorithm's settings, as (key under ``settings``, message): unknown keys
    (with a "did you mean"), wrong types and ranges, contradictions with the population, and
    whatever the algorithm's own constructor then refuses. Empty when it can be built."""
    import difflib

    key = name.strip().lower()
    if key not in SETTINGS:
        return []
    known = SETTINGS[key]
    found: list[tuple[str, str]] = []
    for k, v in settings.items():
        if k in known:
            problem = known[k](v)
            if problem:
                found.append((k, problem))
            elif k == "n_ind_p" and v != population:
                found.append((k, f"contradicts algorithm.population ({population}); give the "
                              "population there only"))
            elif k == "n_div" and isinstance(v, list) and len(v) != n_obj:
                found.append((k, f"needs one value per objective ({n_obj}), got {len(v)}"))
        elif k in _OWN_KEYS:
            found.append((k, f"set by {_OWN_KEYS[k]}, not in settings"))
        else:
            close = difflib.get_close_matches(str(k), list(known), n=1, cutoff=0.6)
            hint = f"did you mean '{close[0]}'? " if close else ""
            found.append((k, f"unknown setting of {key} ({hint}known: "
                          f"{', '.join(known) or 'none'})"))
    if key == "spea2" and settings.get("eliminate_duplicates", True) is not False:
        found.append(("eliminate_duplicates", "spea2 with duplicate elimination (pymoo's default) "
                      "is not reproducible from its seed in pymoo 0.6.2 (the survivors' order "
                      "varies between identical runs), so a run could neither be repeated nor "
                      "resumed identically; set eliminate_duplicates: false"))
    if found:
        return found
    if key == "ctaea" and len(reference_directions(n_obj, population)) < 2:
        return [("(population)", "too small for ctaea's reference directions")]
    try:
        kw = algorithm_settings(settings)
        if key == "evmoga":
            kw["generations"] = 1
        make_algorithm(key, kw, pop_size=population, n_obj=n_obj)
    except (ValueError, TypeError) as exc:
        found.append(("(algorithm)", f"{key} refuses these settings: {exc}"))
    return found


def algorithm_settings(settings: Mapping[str, Any]) -> dict[str, Any]:
    """The settings the algorithm's constructor takes (:data:`RUNNER_SETTINGS` left out)."""
    return {k: v for k, v in settings.items() if k not in RUNNER_SETTINGS}


def reference_directions(n_obj: int, n_points: int) -> np.ndarray:
    """Das-Dennis reference directions: the most partitions giving at most ``n_points`` (>= 1)."""
    from pymoo.util.ref_dirs import get_reference_directions

    partitions = 1
    while comb(partitions + 1 + n_obj - 1, n_obj - 1) <= n_points:
        partitions += 1
    return get_reference_directions("das-dennis", n_obj, n_partitions=partitions)


@runtime_checkable
class KeepsFront(Protocol):
    """What the runner asks of an algorithm that keeps its set of solutions as arrays (ev-MOGA's
    archive) instead of pymoo's ``opt`` population. Any other pymoo algorithm is read through
    ``opt``; the runner knows no algorithm's internals (:func:`front_rows`, :func:`front_size`)."""

    def front_rows(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """X, F (minimised) and CV of the kept set, rows alike; None while it is empty."""
        ...

    def front_size(self) -> int:
        """How many solutions the kept set holds (all feasible), without building it."""
        ...


def front_rows(algorithm: Algorithm) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """X, F (minimised) and CV of the algorithm's result set; None when it has none."""
    rows = algorithm.front_rows() if isinstance(algorithm, KeepsFront) else None
    if rows is not None:
        return rows
    opt = algorithm.opt
    if opt is None or len(opt) == 0:
        return None
    return opt.get("X"), opt.get("F"), opt.get("CV")


def front_size(algorithm: Algorithm) -> int | None:
    """The size of the algorithm's kept set where it knows it without building it, else None."""
    return algorithm.front_size() if isinstance(algorithm, KeepsFront) else None


def make_algorithm(
    name: str,
    settings: Mapping[str, Any] | None = None,
    pop_size: int | None = None,
    n_obj: int = 2,
    generations: int | None = None,
) -> Algorithm:
    """Return a configured algorithm.

    Args:
        name: ``"evmoga"`` or a pymoo algorithm name (see ``ALGORITHM_NAMES``); case-insensitive.
        settings: Keyword arguments of the algorithm's constructor (for ev-MOGA: ``n_ind_ga``,
            ``n_div``, ``p_m``, ``dd_ini``, ``dd_fin``, ``sigma_ini``, ``sigma_fin``,
            ``generations``, ...). For reference-direction algorithms, ``ref_dirs`` may be given;
            otherwise Das-Dennis directions for ``n_obj`` objectives are built, as many as fit in
            ``pop_size`` (100 if not given).
        pop_size: Population size: ev-MOGA's ``n_ind_p`` (P), pymoo's ``pop_size``.
        n_obj: Number of objectives (for reference directions).
        generations: The run's generations after initialisation: ev-MOGA's dd and σ schedules
            run over them (its ``generations`` setting); pymoo's algorithms ignore it.

    Raises:
        ValueError: for an unknown name, or a ``pop_size`` that contradicts ``settings``.
    """
    key = name.strip().lower()
    kwargs = dict(settings or {})
    if key == "evmoga":
        _merge_pop_size(kwargs, "n_ind_p", pop_size)
        if generations is not None:
            kwargs["generations"] = generations
        return EvMOGA(**kwargs)
    if key not in _PYMOO:
        raise ValueError(
            f"unknown algorithm {name!r}; known algorithms: {', '.join(ALGORITHM_NAMES)}"
        )
    module, cls_name, needs_ref_dirs, takes_pop_size = _PYMOO[key]
    if needs_ref_dirs and "ref_dirs" not in kwargs:
        kwargs["ref_dirs"] = reference_directions(n_obj, pop_size or 100)
    if takes_pop_size:
        _merge_pop_size(kwargs, "pop_size", pop_size)
    cls = getattr(importlib.import_module(module), cls_name)
    return cls(**kwargs)


def _merge_pop_size(kwargs: dict[str, Any], key: str, pop_size: int | None) -> None:
    if pop_size is None:
        return
    if key in kwargs and kwargs[key] != pop_size:
        raise ValueError(f"pop_size={pop_size} contradicts settings {key}={kwargs[key]}")
    kwargs[key] = pop_size


class _SeededRandom:
    """``numpy.random`` whose ``default_rng()`` (no seed) is one given generator."""

    def __init__(self, generator: np.random.Generator):
        self._generator = generator

    def default_rng(self, seed: Any = None) -> np.random.Generator:
        return self._generator if seed is None else np.random.default_rng(seed)

    def __getattr__(self, name: str) -> Any:
        return getattr(np.random, name)


class _SeededNumpy:
    def __init__(self, generator: np.random.Generator):
        self.random = _SeededRandom(generator)

    def __getattr__(self, name: str) -> Any:
        return getattr(np, name)


@contextlib.contextmanager
def seeded_defaults(algorithm: Algorithm) -> Iterator[None]:
    """Make pymoo's unseeded random draws come from the algorithm's own generator.

    pymoo 0.6.2 decorates its random functions with ``default_random_state``, which draws a
    fresh, OS-seeded generator when a caller passes no ``random_state``; the tournament
    tie-breaks of NSGA-III, U-NSGA-III, SMS-EMOA and SPEA2 do exactly that (equal constraint
    violations, common when candidates fail at the same stage), so those runs were neither
    reproducible from their seed nor resumable to the same end. Inside this block such draws
    use ``algorithm.random_state`` (seeded, and saved in every checkpoint) instead.
    """
    import pymoo.util

    generator = getattr(algorithm, "random_state", None)
    if generator is None:
        yield
        return
    saved = pymoo.util.np
    pymoo.util.np = _SeededNumpy(generator)
    try:
        yield
    finally:
        pymoo.util.np = saved
