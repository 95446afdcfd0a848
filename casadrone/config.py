"""YAML configuration: pydantic v2 schemas and loading with clear, complete error reports.

Every schema is frozen and forbids unknown keys. Loading a file reports every problem at once,
one line each, as ``FILE: dotted.key: message``; a misspelt key gets a "did you mean" hint.
Numbers carry their unit in the key when it is not SI-obvious (``lambda_a_mm``, ``alpha_deg``).
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any, Literal, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

ROOT = Path(__file__).resolve().parent.parent
CONFIG_DIR = ROOT / "configs"


class ConfigError(Exception):
    """A configuration problem; ``lines`` holds one ``FILE: key: message`` line per problem."""

    def __init__(self, lines: list[str]):
        self.lines = list(lines)
        super().__init__("\n".join(self.lines))


class Schema(BaseModel):
    """Base of every config schema: frozen, unknown keys rejected."""

    model_config = ConfigDict(frozen=True, extra="forbid")


# --------------------------------------------------------------------------------------------
# Airframe
# --------------------------------------------------------------------------------------------


class ThrustModelConfig(Schema):
    """Identified first-order thrust model G(s) = K / (1 + tau s) per rotor (paper Table 6)."""

    gain_n: float = Field(9.0519, gt=0, description="K, thrust per unit ESC command (N)")
    time_constant_s: float = Field(0.060538, gt=0, description="tau (s)")


class AirframeConfig(Schema):
    """An airframe: geometry θ = (λa, λb, α, β, Ixx, Iyy, Izz) plus mass, drag and propulsion."""

    name: str
    lambda_a_mm: float = Field(gt=0, description="CoM to front motors (mm)")
    lambda_b_mm: float = Field(gt=0, description="CoM to rear motors (mm)")
    alpha_deg: float = Field(gt=0, lt=180, description="angle between the nose arms (deg)")
    beta_deg: float = Field(gt=0, lt=180, description="angle between the tail arms (deg)")
    ixx_kgm2: float = Field(gt=0)
    iyy_kgm2: float = Field(gt=0)
    izz_kgm2: float = Field(gt=0)
    ixy_kgm2: float = 0.0
    ixz_kgm2: float = 0.0
    iyz_kgm2: float = 0.0
    mass_kg: float = Field(gt=0)
    drag_area_m2: tuple[float, float, float] = Field(
        (0.012, 0.012, 0.025), description="C_d·A along body x, y, z (m²)"
    )
    kappa_m: float = Field(0.016, gt=0, description="rotor yaw torque per unit thrust (m)")
    battery_voltage_v: float = Field(14.8, gt=0)
    prop_diameter_mm: float = Field(127.0, gt=0)
    rotor_spins: tuple[int, int, int, int] = Field(
        (-1, 1, -1, 1),
        description="sign of each rotor's reaction yaw torque about body +z, rotors FR, FL, RL, RR",
    )
    thrust: ThrustModelConfig = ThrustModelConfig()
    air_density_kgm3: float = Field(1.225, gt=0)
    gravity_mps2: float = Field(9.81, gt=0)

    @model_validator(mode="after")
    def _geometry(self) -> AirframeConfig:
        for name in ("drag_area_m2",):
            if any(v < 0 for v in getattr(self, name)):
                raise ValueError(f"{name}: drag areas must be non-negative")
        if any(s not in (-1, 1) for s in self.rotor_spins):
            raise ValueError("rotor_spins: each spin must be +1 or -1")
        if sum(self.rotor_spins) != 0:
            raise ValueError("rotor_spins: two rotors must spin each way (sum of spins must be 0)")
        gap = min_rotor_gap_mm(self.lambda_a_mm, self.lambda_b_mm, self.alpha_deg, self.beta_deg)
        if gap < self.prop_diameter_mm:
            raise ValueError(
                f"rotors overlap: closest rotor centres are {gap:.1f} mm apart, less than the "
                f"prop diameter {self.prop_diameter_mm:.1f} mm"
            )
        return self


def rotor_positions_mm(la: float, lb: float, alpha_deg: float, beta_deg: float) -> list[list[float]]:
    """Rotor centres (mm) in the body frame (x nose, y left): FR, FL, RL, RR (DESIGN.md §4)."""
    a, b = math.radians(alpha_deg) / 2, math.radians(beta_deg) / 2
    return [
        [la * math.cos(a), -la * math.sin(a), 0.0],
        [la * math.cos(a), la * math.sin(a), 0.0],
        [-lb * math.cos(b), lb * math.sin(b), 0.0],
        [-lb * math.cos(b), -lb * math.sin(b), 0.0],
    ]


def min_rotor_gap_mm(la: float, lb: float, alpha_deg: float, beta_deg: float) -> float:
    """Smallest centre-to-centre distance between any two rotors (mm)."""
    r = rotor_positions_mm(la, lb, alpha_deg, beta_deg)
    return min(math.dist(r[i], r[j]) for i in range(4) for j in range(i + 1, 4))


# --------------------------------------------------------------------------------------------
# Controller
# --------------------------------------------------------------------------------------------


class StateWeights(Schema):
    """Diagonal LQR state weights, one per state group (units: 1/unit² of the state)."""

    position: tuple[float, float, float] = (1.0, 1.0, 4.0)
    velocity: tuple[float, float, float] = (1.0, 1.0, 1.0)
    rates: tuple[float, float, float] = (0.1, 0.1, 0.1)
    attitude: tuple[float, float, float] = (1.0, 1.0, 4.0)
    thrust: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    @model_validator(mode="after")
    def _non_negative(self) -> StateWeights:
        for name, values in self:
            if any(v < 0 for v in values):
                raise ValueError(f"{name}: weights must be non-negative")
        return self


class RobustnessConfig(Schema):
    """Perturbed-plant ensemble of paper Appendix B."""

    n_plants: int = Field(50, ge=1)
    dynamics_pct: float = Field(30.0, ge=0, lt=100, description="mass, inertia, drag spread (%)")
    coupling_pct: float = Field(
        20.0, ge=0, lt=100, description="thrust gain, time constant, arm geometry, κ spread (%)"
    )
    seed: int = 0


class ControllerConfig(Schema):
    """LQR-I controller: discrete design at ``sample_time_s``, identical for every candidate."""

    name: str = "default"
    sample_time_s: float = Field(0.01, gt=0, le=0.1)
    q: StateWeights = StateWeights()
    q_integral: tuple[float, float, float, float] = Field(
        (0.2, 0.2, 1.0, 0.2), description="weights of ∫e for x, y, z, yaw"
    )
    r: tuple[float, float, float, float] = Field((1.0, 1.0, 1.0, 1.0))
    gain_policy: Literal["redesign", "frozen"] = "redesign"
    reference_airframe: Path | None = Field(
        None, description="airframe YAML whose gain is frozen for all (gain_policy: frozen)"
    )
    robustness: RobustnessConfig = RobustnessConfig()

    @model_validator(mode="after")
    def _policy(self) -> ControllerConfig:
        if any(v <= 0 for v in self.r):
            raise ValueError("r: input weights must be positive")
        if any(v < 0 for v in self.q_integral):
            raise ValueError("q_integral: weights must be non-negative")
        if self.gain_policy == "frozen" and self.reference_airframe is None:
            raise ValueError("reference_airframe: required when gain_policy is 'frozen'")
        return self


# --------------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------------

M = TypeVar("M", bound=BaseModel)

# Keys whose values are paths to other config files, resolved relative to the referring file.
PATH_KEYS = {"reference_airframe", "airframe", "track", "controller", "reference"}


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping; malformed YAML or a missing file raises ConfigError with the line."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError([f"{path}: file not found"])
    try:
        data = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError([f"{path}: {where}malformed YAML: {problem}"]) from None
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise ConfigError([f"{path}: top level must be a mapping of keys to values"])
    return data


def parse_value(text: str) -> Any:
    """Parse the value of a ``key=value`` override as YAML (numbers, lists, strings)."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def apply_overrides(data: dict[str, Any], overrides: list[str] | None, source: str) -> dict:
    """Apply ``dotted.key=value`` overrides to a nested dict (copy); bad syntax → ConfigError."""
    import copy

    data = copy.deepcopy(data)
    errors = []
    for item in overrides or []:
        if "=" not in item:
            errors.append(f"{source}: override '{item}': expected key=value")
            continue
        key, value = item.split("=", 1)
        node = data
        parts = key.strip().split(".")
        for part in parts[:-1]:
            if not isinstance(node.get(part), dict):
                node[part] = {}
            node = node[part]
        node[parts[-1]] = parse_value(value)
    if errors:
        raise ConfigError(errors)
    return data


def _fields_at(model: type[BaseModel], loc: tuple) -> list[str]:
    """Field names of the (nested) model reached by ``loc``, for "did you mean" hints."""
    current: Any = model
    for part in loc:
        if isinstance(part, int) or not (isinstance(current, type) and issubclass(current, BaseModel)):
            continue
        field = current.model_fields.get(part)
        if field is None:
            break
        ann = field.annotation
        candidates = [ann, *getattr(ann, "__args__", ())]
        current = next(
            (c for c in candidates if isinstance(c, type) and issubclass(c, BaseModel)), None
        )
        if current is None:
            return []
    if isinstance(current, type) and issubclass(current, BaseModel):
        return list(current.model_fields)
    return []


def format_errors(exc: ValidationError, source: str, model: type[BaseModel]) -> list[str]:
    """One ``FILE: dotted.key: message`` line per pydantic error."""
    lines = []
    for err in exc.errors():
        loc = tuple(err["loc"])
        key = ".".join(str(p) for p in loc) or "(top level)"
        msg = err["msg"]
        if err["type"] == "extra_forbidden":
            known = _fields_at(model, loc[:-1])
            close = difflib.get_close_matches(str(loc[-1]), known, n=1, cutoff=0.6)
            msg = "unknown key" + (f" (did you mean '{close[0]}'?)" if close else "")
            if not close and known:
                msg += f"; known keys: {', '.join(known)}"
        elif err["type"] == "missing":
            msg = "required key missing"
        elif msg.startswith("Value error, "):
            msg = msg[len("Value error, ") :]
        lines.append(f"{source}: {key}: {msg}")
    return lines


def check_paths(data: dict[str, Any], base: Path, source: str) -> tuple[dict, list[str]]:
    """Resolve path-valued keys relative to ``base``; name every referenced file that is missing."""
    errors: list[str] = []

    def walk(node: Any, prefix: str) -> Any:
        if isinstance(node, dict):
            out = {}
            for k, v in node.items():
                key = f"{prefix}.{k}" if prefix else str(k)
                if k in PATH_KEYS and isinstance(v, str) and v.endswith((".yaml", ".yml")):
                    p = Path(v)
                    if not p.is_absolute():
                        p = (base / p) if (base / p).exists() else (ROOT / p)
                    if not p.is_file():
                        errors.append(f"{source}: {key}: referenced file not found: {v}")
                    out[k] = str(p)
                else:
                    out[k] = walk(v, key)
            return out
        return node

    return walk(data, ""), errors


def validate_data(model: type[M], data: dict[str, Any], source: str, base: Path) -> M:
    """Validate a dict against ``model``, raising ConfigError listing every problem."""
    data, errors = check_paths(data, base, source)
    try:
        obj = model.model_validate(data)
    except ValidationError as exc:
        errors.extend(format_errors(exc, source, model))
        obj = None
    if errors:
        raise ConfigError(errors)
    return obj


def load(model: type[M], path: str | Path, overrides: list[str] | None = None) -> M:
    """Load and validate a YAML file, with optional ``key=value`` overrides."""
    path = Path(path)
    data = apply_overrides(read_yaml(path), overrides, str(path))
    return validate_data(model, data, str(path), path.parent)


def load_airframe(path: str | Path, overrides: list[str] | None = None) -> AirframeConfig:
    """Load an airframe YAML (``configs/airframes/*.yaml``)."""
    return load(AirframeConfig, resolve_config(path, "airframes"), overrides)


def load_controller(path: str | Path | None = None, overrides: list[str] | None = None):
    """Load a controller YAML; ``None`` gives ``configs/controllers/default.yaml``."""
    return load(ControllerConfig, resolve_config(path or "default", "controllers"), overrides)


def resolve_config(name: str | Path, kind: str) -> Path:
    """A path as given if it exists, else ``configs/<kind>/<name>.yaml`` (e.g. ``SY250``)."""
    p = Path(name)
    if p.is_file():
        return p
    candidate = CONFIG_DIR / kind / f"{p.stem if p.suffix else p.name}.yaml"
    return candidate if candidate.is_file() else p


# Schemas by config folder name, for ``casadrone validate``; later layers register theirs.
SCHEMAS_BY_FOLDER: dict[str, type[BaseModel]] = {
    "airframes": AirframeConfig,
    "controllers": ControllerConfig,
}
# Fallback when the folder says nothing: a key that only that schema has.
SCHEMAS_BY_KEY: dict[str, type[BaseModel]] = {
    "lambda_a_mm": AirframeConfig,
    "sample_time_s": ControllerConfig,
    "gain_policy": ControllerConfig,
}


def detect_schema(path: Path, data: dict[str, Any]) -> type[BaseModel] | None:
    """The schema of a config file, from its folder (``airframes/`` …) or a telling key."""
    for part in reversed(Path(path).resolve().parts[:-1]):
        if part in SCHEMAS_BY_FOLDER:
            return SCHEMAS_BY_FOLDER[part]
    for key, model in SCHEMAS_BY_KEY.items():
        if key in data:
            return model
    return None


def validate_file(path: str | Path) -> BaseModel:
    """Validate any known config file; ConfigError lists every problem."""
    path = Path(path)
    data = read_yaml(path)
    model = detect_schema(path, data)
    if model is None:
        raise ConfigError([f"{path}: cannot tell what kind of config this is (folder or keys)"])
    return validate_data(model, data, str(path), path.parent)
