"""A problem's plugins (``plugins:``), imported once per process: the coordinator, each worker
and a resumed run import the same modules, and a run's manifest hashes their files
(:func:`casadrone.rundir.store.plugin_hashes`)."""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path
from types import ModuleType

from casadrone.config.io import ROOT

_PLUGINS: dict[str, ModuleType] = {}


def import_plugin(plugin: str) -> ModuleType:
    """Import a plugin once per process: a module name, or a path to a ``.py`` file (relative
    paths from the working directory, then the project root)."""
    if plugin in _PLUGINS:
        return _PLUGINS[plugin]
    if plugin.endswith(".py"):
        path = Path(plugin)
        if not path.is_file():
            path = ROOT / plugin
        if not path.is_file():
            raise FileNotFoundError(f"no such file: {plugin}")
        name = f"casadrone_plugin_{path.stem}"
        spec = importlib.util.spec_from_file_location(name, path)
        if spec is None or spec.loader is None:
            raise ImportError(f"cannot load {plugin} as a Python module")
        module = importlib.util.module_from_spec(spec)
        _PLUGINS[plugin] = module  # before exec: a failing plugin is not imported twice
        try:
            spec.loader.exec_module(module)
        except Exception:
            del _PLUGINS[plugin]
            raise
    else:
        _PLUGINS[plugin] = importlib.import_module(plugin)
    return _PLUGINS[plugin]
