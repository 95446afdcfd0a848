"""The check of any config file (``casadrone validate``): find its schema, validate it and the
config files it references, report every problem as ``FILE: dotted.key: message``.

It sits above the schemas it checks (:mod:`casadrone.config`, :mod:`casadrone.problemconfig`); the
schemas of heavier modules (tracks, Table 4 references) are named as ``"module:Class"`` and imported
only when a file of that kind is validated.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pydantic import BaseModel

from casadrone.config import AirframeConfig, ControllerConfig
from casadrone.configio import (
    PATH_KEYS,
    ConfigError,
    check_paths,
    load,
    read_yaml,
    validate_data,
)
from casadrone.problemconfig import ProblemConfig

# Schemas by config folder name, for ``casadrone validate``; later layers register theirs. A
# value is a schema class, or "module:Class" for a schema defined in a heavier module (imported
# only when a file of that kind is validated).
SCHEMAS_BY_FOLDER: dict[str, type[BaseModel] | str] = {
    "airframes": AirframeConfig,
    "controllers": ControllerConfig,
    "tracks": "casadrone.guidance:TrackConfig",
    "references": "casadrone.benchmark:Table4Reference",
    "problems": ProblemConfig,
}
# Fallback when the folder says nothing: a key that only that schema has.
SCHEMAS_BY_KEY: dict[str, type[BaseModel] | str] = {
    "lambda_a_mm": AirframeConfig,
    "sample_time_s": ControllerConfig,
    "gain_policy": ControllerConfig,
    "waypoints_m": "casadrone.guidance:TrackConfig",
    "objectives": ProblemConfig,
}


def schema_class(entry: type[BaseModel] | str) -> type[BaseModel]:
    """A registered schema: the class itself, or imported from its "module:Class" string."""
    if isinstance(entry, str):
        import importlib

        module, _, name = entry.partition(":")
        return getattr(importlib.import_module(module), name)
    return entry


def detect_schema(path: Path, data: dict[str, Any]) -> type[BaseModel] | None:
    """The schema of a config file: from its folder (``airframes/`` …), else a telling key,
    else the known schema sharing the most top-level keys (so misspelt files are still checked)."""
    for part in reversed(Path(path).resolve().parts[:-1]):
        if part in SCHEMAS_BY_FOLDER:
            return schema_class(SCHEMAS_BY_FOLDER[part])
    for key, entry in SCHEMAS_BY_KEY.items():
        if key in data:
            return schema_class(entry)
    entries = dict.fromkeys(e for e in (*SCHEMAS_BY_FOLDER.values(), *SCHEMAS_BY_KEY.values())
                            if not isinstance(e, str))  # never import heavy modules to guess
    scored = sorted(((len(set(data) & set(m.model_fields)), m) for m in entries),
                    key=lambda t: -t[0])
    if scored and scored[0][0] > 0 and (len(scored) == 1 or scored[0][0] > scored[1][0]):
        return scored[0][1]
    return None


def validate_file(path: str | Path) -> BaseModel:
    """Validate any known config file, and the config files it references; ConfigError lists
    every problem."""
    path = Path(path)
    data = read_yaml(path)
    model = detect_schema(path, data)
    if model is None:
        kinds = ", ".join(SCHEMAS_BY_FOLDER)
        raise ConfigError([f"{path}: (top level): cannot tell what kind of config this is; put it "
                           f"in a folder named after its kind ({kinds})"])
    errors: list[str] = []
    try:
        obj = validate_data(model, data, str(path), path.parent)
    except ConfigError as exc:
        errors += exc.lines
        obj = None
    resolved, _ = check_paths(data, path.parent, str(path))
    for key, kind in PATH_KEYS.items():
        ref = resolved.get(key)
        if isinstance(ref, str) and Path(ref).is_file() and kind in SCHEMAS_BY_FOLDER:
            try:
                load(schema_class(SCHEMAS_BY_FOLDER[kind]), ref)
            except ConfigError as exc:
                errors += [f"{path}: {key}: referenced file is invalid"] + exc.lines
    if errors:
        raise ConfigError(errors)
    return obj
