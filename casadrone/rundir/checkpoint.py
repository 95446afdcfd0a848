"""Checkpoint pickling: the algorithm's whole state, including pymoo's decorated functions.

pymoo 0.6.2 wraps module-level functions in ``default_random_state``, whose wrapper is a local
function; plain :mod:`pickle` cannot store one ("Can't pickle local object ..."), which broke the
first checkpoint of NSGA-III, U-NSGA-III, SMS-EMOA and C-TAEA. The module-level name of the
decorated function *is* the wrapper, so it is stored here by that name and looked up again on
load, as pickle does for any module-level function.
"""

from __future__ import annotations

import importlib
import io
import pickle
import types
from typing import Any


def _resolve(module: str, qualname: str) -> Any:
    obj: Any = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def _by_name(obj: types.FunctionType) -> tuple | None:
    """(module, qualname) of the module-level name a local wrapper is bound to, if any."""
    for cell in obj.__closure__ or ():
        try:
            inner = cell.cell_contents
        except ValueError:  # empty cell
            continue
        if isinstance(inner, types.FunctionType) and "<locals>" not in inner.__qualname__:
            try:
                if _resolve(inner.__module__, inner.__qualname__) is obj:
                    return inner.__module__, inner.__qualname__
            except (ImportError, AttributeError):
                continue
    return None


class _Pickler(pickle.Pickler):
    def reducer_override(self, obj: Any) -> Any:
        if isinstance(obj, types.FunctionType) and "<locals>" in obj.__qualname__:
            name = _by_name(obj)
            if name is not None:
                return _resolve, name
        return NotImplemented


def dumps(state: Any) -> bytes:
    """Pickle ``state`` (highest protocol); decorated pymoo functions by their module name."""
    buf = io.BytesIO()
    _Pickler(buf, protocol=pickle.HIGHEST_PROTOCOL).dump(state)
    return buf.getvalue()


def loads(data: bytes) -> Any:
    """Unpickle a checkpoint written by :func:`dumps`."""
    return pickle.loads(data)  # noqa: S301 (the run's own checkpoint)
