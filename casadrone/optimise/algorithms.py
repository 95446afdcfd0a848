"""Build an optimisation algorithm by name: casadrone's ev-MOGA or one of pymoo's.

Used by problem files (``algorithm: {name: ..., settings: {...}}``) and by the benchmarks, so that
ev-MOGA and pymoo's algorithms are compared on the same budget through the same call.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from math import comb
from typing import Any

import numpy as np
from pymoo.core.algorithm import Algorithm

from casadrone.optimise.evmoga import EvMOGA

__all__ = ["ALGORITHM_NAMES", "make_algorithm", "reference_directions"]

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


def reference_directions(n_obj: int, n_points: int) -> np.ndarray:
    """Das-Dennis reference directions: the most partitions giving at most ``n_points`` (>= 1)."""
    from pymoo.util.ref_dirs import get_reference_directions

    partitions = 1
    while comb(partitions + 1 + n_obj - 1, n_obj - 1) <= n_points:
        partitions += 1
    return get_reference_directions("das-dennis", n_obj, n_partitions=partitions)


def make_algorithm(
    name: str,
    settings: Mapping[str, Any] | None = None,
    pop_size: int | None = None,
    n_obj: int = 2,
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

    Raises:
        ValueError: for an unknown name, or a ``pop_size`` that contradicts ``settings``.
    """
    key = name.strip().lower()
    kwargs = dict(settings or {})
    if key == "evmoga":
        _merge_pop_size(kwargs, "n_ind_p", pop_size)
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
