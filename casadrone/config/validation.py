"""The check of any config file: find its schema, validate it and the config files it references,
report every problem as ``FILE: dotted.key: message``.

Every schema is in this package, so checking any file imports neither CasADi nor pymoo. A problem
file is checked here against the other configs; ``casadrone validate`` and ``cd.validate_file``
(:func:`casadrone.optimise.checks.validate_file`) add the optimiser's checks.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from casadrone.config.airframe import AirframeConfig
from casadrone.config.build import BuildProblemConfig
from casadrone.config.codesign import CodesignProblemConfig
from casadrone.config.controller import ControllerConfig
from casadrone.config.io import (
    PATH_KEYS,
    ConfigError,
    apply_overrides,
    check_paths,
    load,
    read_yaml,
    validate_data,
)
from casadrone.config.parts import PartsConfig
from casadrone.config.problem import ProblemConfig
from casadrone.config.reference import Table4Reference
from casadrone.config.track import TrackConfig
from casadrone.results import AsDict

#: Schemas by config folder name, for ``casadrone validate``.
SCHEMAS_BY_FOLDER: dict[str, type[BaseModel]] = {
    "airframes": AirframeConfig,
    "controllers": ControllerConfig,
    "tracks": TrackConfig,
    "references": Table4Reference,
    "problems": ProblemConfig,
    "parts": PartsConfig,
}
#: Fallback when the folder says nothing: a key that only that schema has.
SCHEMAS_BY_KEY: dict[str, type[BaseModel]] = {
    "lambda_a_mm": AirframeConfig,
    "sample_time_s": ControllerConfig,
    "gain_policy": ControllerConfig,
    "waypoints_m": TrackConfig,
    "gates": TrackConfig,
    "build": BuildProblemConfig,
    "codesign": CodesignProblemConfig,
    "objectives": ProblemConfig,
    "propellers": PartsConfig,
    "motors": PartsConfig,
    "packs": PartsConfig,
}


def detect_schema(path: Path, data: dict[str, Any]) -> type[BaseModel] | None:
    """The schema of a config file: from its folder (``airframes/`` …), else a telling key,
    else the known schema sharing the most top-level keys (so misspelt files are still checked)."""
    for part in reversed(Path(path).resolve().parts[:-1]):
        if part in SCHEMAS_BY_FOLDER:
            if SCHEMAS_BY_FOLDER[part] is ProblemConfig and "build" in data:
                return BuildProblemConfig  # a problem with a build: section
            if SCHEMAS_BY_FOLDER[part] is ProblemConfig and "codesign" in data:
                return CodesignProblemConfig  # a problem with a codesign: section
            return SCHEMAS_BY_FOLDER[part]
    for key, entry in SCHEMAS_BY_KEY.items():
        if key in data:
            return entry
    entries = dict.fromkeys((*SCHEMAS_BY_FOLDER.values(), *SCHEMAS_BY_KEY.values()))
    scored = sorted(((len(set(data) & set(m.model_fields)), m) for m in entries),
                    key=lambda t: -t[0])
    if scored and scored[0][0] > 0 and (len(scored) == 1 or scored[0][0] > scored[1][0]):
        return scored[0][1]
    return None


@dataclass(frozen=True)
class FileReport(AsDict):
    """What ``casadrone validate`` found in one file: valid, or its problems (one line each,
    ``FILE: key: message``)."""

    file: str
    valid: bool
    problems: tuple[str, ...] = ()


def check_config_file(path: str | Path, overrides: list[str] | None = None) -> BaseModel:
    """Validate any known config file (with ``key=value`` overrides applied), and the config
    files it references; ConfigError lists every problem."""
    path = Path(path)
    data = apply_overrides(read_yaml(path), overrides, str(path))
    model = detect_schema(path, data)
    if model is None:
        kinds = ", ".join(SCHEMAS_BY_FOLDER)
        raise ConfigError([f"{path}: (top level): cannot tell what kind of config this is; put it "
                           f"in a folder named after its kind ({kinds})"])
    errors: list[str] = []
    try:
        obj = validate_data(model, data, str(path), path.parent, overrides)
    except ConfigError as exc:
        errors += exc.lines
        obj = None
    resolved, _ = check_paths(data, path.parent, str(path))
    for key, kind in PATH_KEYS.items():
        ref = resolved.get(key)
        if isinstance(ref, str) and Path(ref).is_file() and kind in SCHEMAS_BY_FOLDER:
            try:
                load(SCHEMAS_BY_FOLDER[kind], ref)
            except ConfigError as exc:
                errors += [f"{path}: {key}: referenced file is invalid"] + exc.lines
    if errors or obj is None:
        raise ConfigError(errors)
    return obj
