"""Every YAML file casadrone reads: its pydantic schema, its loader and its check.

One module per kind of file, all light (pydantic, PyYAML, NumPy; never CasADi or pymoo), so that
``casadrone validate`` and a documentation build import no solver:

- :mod:`~casadrone.config.io`: the base :class:`Schema`, YAML reading, ``key=value`` overrides,
  shipped-name lookup and the ``FILE: dotted.key: message`` error lines;
- :mod:`~casadrone.config.airframe`, :mod:`~casadrone.config.controller`,
  :mod:`~casadrone.config.track`, :mod:`~casadrone.config.reference`,
  :mod:`~casadrone.config.problem`: the schemas of ``configs/airframes``, ``configs/controllers``,
  ``configs/tracks``, ``configs/references`` and ``problems/``;
- :mod:`~casadrone.config.validation`: the check of any config file by its kind.

The names below are the ones most code needs, so ``from casadrone.config import AirframeConfig``
works; each is defined in the module named above. A problem's checks against the optimiser (index
and algorithm names, plugins) live beside it, in :mod:`casadrone.optimise.checks`.
"""

from casadrone.config.airframe import (
    MASS_KEYS,
    ROTOR_LABELS,
    TABLE1_BOUNDS,
    AirframeConfig,
    ComponentsConfig,
    ThrustModelConfig,
    inertia_problems,
    load_airframe,
    min_rotor_gap_mm,
)
from casadrone.config.controller import ControllerConfig, GainPolicy, load_controller
from casadrone.config.io import (
    CONFIG_DIR,
    DATA_DIR,
    ConfigError,
    Schema,
    load,
    read_yaml,
    resolve_config,
)
from casadrone.config.problem import BackendConfig, ProblemConfig, read_problem
from casadrone.config.reference import DEFAULT_REFERENCE, Table4Reference, load_reference
from casadrone.config.track import DEFAULT_TRACK, TrackConfig, load_track
from casadrone.config.validation import SCHEMAS_BY_FOLDER, check_config_file

__all__ = [
    "CONFIG_DIR",
    "DATA_DIR",
    "DEFAULT_REFERENCE",
    "DEFAULT_TRACK",
    "MASS_KEYS",
    "ROTOR_LABELS",
    "SCHEMAS_BY_FOLDER",
    "TABLE1_BOUNDS",
    "AirframeConfig",
    "BackendConfig",
    "ComponentsConfig",
    "ConfigError",
    "ControllerConfig",
    "GainPolicy",
    "ProblemConfig",
    "Schema",
    "Table4Reference",
    "ThrustModelConfig",
    "TrackConfig",
    "check_config_file",
    "inertia_problems",
    "load",
    "load_airframe",
    "load_controller",
    "load_reference",
    "load_track",
    "min_rotor_gap_mm",
    "read_problem",
    "read_yaml",
    "resolve_config",
]
