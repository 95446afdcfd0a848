"""YAML configuration: pydantic v2 schemas and loading with clear, complete error reports.

Every schema is frozen and forbids unknown keys. Loading a file reports every problem at once,
one line each, as ``FILE: dotted.key: message``: field errors and cross-field (geometry) errors
together, a "did you mean" hint for misspelt keys at any depth, the line of malformed YAML, and
the name of any referenced file that does not exist. Numbers carry their unit in the key when it
is not SI-obvious (``lambda_a_mm``, ``alpha_deg``).
"""

from __future__ import annotations

import copy
import difflib
import math
from functools import cache
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter, ValidationError, model_validator

ROOT = Path(__file__).resolve().parent.parent
CONFIG_DIR = ROOT / "configs"


class ConfigError(Exception):
    """A configuration problem; ``lines`` holds one ``FILE: key: message`` line per problem."""

    def __init__(self, lines: list[str]):
        self.lines = list(dict.fromkeys(lines))
        super().__init__("\n".join(self.lines))


class Problems(ValueError):
    """Several cross-field problems found at once, each a (dotted key, message) pair."""

    def __init__(self, problems: list[tuple[str, str]]):
        self.problems = list(problems)
        super().__init__("; ".join(f"{k}: {m}" for k, m in self.problems))


class Schema(BaseModel):
    """Base of every config schema: frozen, unknown keys rejected.

    Cross-field checks live in :meth:`problems`, which works on a plain dict of field values so
    that the loader can still run it when some fields failed (those are simply absent): a file
    with a negative mass *and* overlapping rotors gets both reported.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        """Cross-field problems as (key, message); skip a check when a key it needs is absent."""
        return []

    @model_validator(mode="after")
    def _cross_field(self) -> Schema:
        found = type(self).problems(dict(self))
        if found:
            raise Problems(found)
        return self


Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Spin = Literal[-1, 1]


def _has(v: dict[str, Any], *keys: str) -> bool:
    return all(k in v for k in keys)


# --------------------------------------------------------------------------------------------
# Airframe
# --------------------------------------------------------------------------------------------


class ThrustModelConfig(Schema):
    """Identified first-order thrust model G(s) = K / (1 + tau s) per rotor (paper Table 6)."""

    gain_n: float = Field(9.0519, gt=0, description="K, thrust per unit ESC command (N)")
    time_constant_s: float = Field(0.060538, gt=0, description="tau (s)")


ROTOR_LABELS = ("FR", "FL", "RL", "RR")


class AirframeConfig(Schema):
    """An airframe: geometry θ = (λa, λb, α, β, Ixx, Iyy, Izz) plus mass, drag and propulsion."""

    name: str
    lambda_a_mm: float = Field(gt=0, description="CoM to front motors (mm)")
    lambda_b_mm: float = Field(gt=0, description="CoM to rear motors (mm)")
    alpha_deg: float = Field(gt=0, lt=180, description="angle between the nose arms (deg)")
    beta_deg: float = Field(gt=0, lt=180, description="angle between the tail arms (deg)")
    ixx_kgm2: float = Field(gt=0, description="roll inertia, about the nose axis (kg·m²)")
    iyy_kgm2: float = Field(gt=0, description="pitch inertia (kg·m²)")
    izz_kgm2: float = Field(gt=0, description="yaw inertia (kg·m²)")
    ixy_kgm2: float = 0.0
    ixz_kgm2: float = 0.0
    iyz_kgm2: float = 0.0
    mass_kg: float = Field(gt=0)
    drag_area_m2: tuple[NonNegative, NonNegative, NonNegative] = Field(
        (0.012, 0.012, 0.025), description="C_d·A along body x, y, z (m²)"
    )
    kappa_m: float = Field(0.016, gt=0, description="rotor yaw torque per unit thrust (m)")
    battery_voltage_v: float = Field(14.8, gt=0)
    prop_diameter_mm: float = Field(127.0, gt=0)
    rotor_spins: tuple[Spin, Spin, Spin, Spin] = Field(
        (-1, 1, -1, 1),
        description="sign of each rotor's reaction yaw torque about body +z, rotors FR, FL, RL, RR",
    )
    thrust: ThrustModelConfig = ThrustModelConfig()
    air_density_kgm3: float = Field(1.225, gt=0)
    gravity_mps2: float = Field(9.81, gt=0)

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found: list[tuple[str, str]] = []
        s = v.get("rotor_spins")
        if s is not None and not (s[0] == s[2] and s[1] == s[3] and s[0] == -s[1]):
            found.append(
                ("rotor_spins", "diagonal rotors must spin alike and the two pairs opposite "
                 f"(FR with RL, FL with RR), e.g. [-1, 1, -1, 1]; got {list(s)}")
            )
        if _has(v, "lambda_a_mm", "lambda_b_mm", "alpha_deg", "beta_deg", "prop_diameter_mm"):
            found += _overlaps(v)
        if _has(v, "ixx_kgm2", "iyy_kgm2", "izz_kgm2", "ixy_kgm2", "ixz_kgm2", "iyz_kgm2"):
            J = [
                [v["ixx_kgm2"], v["ixy_kgm2"], v["ixz_kgm2"]],
                [v["ixy_kgm2"], v["iyy_kgm2"], v["iyz_kgm2"]],
                [v["ixz_kgm2"], v["iyz_kgm2"], v["izz_kgm2"]],
            ]
            if not _positive_definite(J):
                key = next(k for k in ("ixy_kgm2", "ixz_kgm2", "iyz_kgm2") if v[k] != 0)
                found.append((key, "inertia tensor is not positive definite: the products of "
                              "inertia are too large for the principal moments"))
        if _has(v, "mass_kg", "gravity_mps2", "thrust"):
            weight, full = v["mass_kg"] * v["gravity_mps2"], 4 * v["thrust"].gain_n
            if weight >= full:
                found.append(("mass_kg", f"cannot hover: weight {weight:.2f} N is not below the "
                              f"full thrust of four rotors {full:.2f} N (4 × thrust.gain_n)"))
        return found


def _overlaps(v: dict[str, Any]) -> list[tuple[str, str]]:
    """One problem per pair of rotors whose discs (prop diameter) overlap."""
    r = rotor_positions_mm(v["lambda_a_mm"], v["lambda_b_mm"], v["alpha_deg"], v["beta_deg"])
    d = v["prop_diameter_mm"]
    found = []
    for i in range(4):
        for j in range(i + 1, 4):
            gap = math.dist(r[i], r[j])
            if gap >= d:
                continue
            pair = f"rotors {ROTOR_LABELS[i]} and {ROTOR_LABELS[j]} overlap: centres {gap:.1f} mm"
            msg = f"{pair} apart, less than the prop diameter {d:.1f} mm"
            if (i, j) == (0, 1):
                key, arm = "alpha_deg", v["lambda_a_mm"]
            elif (i, j) == (2, 3):
                key, arm = "beta_deg", v["lambda_b_mm"]
            else:
                key, arm = "prop_diameter_mm", None
            if arm is not None and d < 2 * arm:
                msg += f" (needs at least {math.degrees(2 * math.asin(d / (2 * arm))):.1f} deg)"
            found.append((key, msg))
    return found


def _positive_definite(J: list[list[float]]) -> bool:
    """Sylvester's criterion for a symmetric 3×3 matrix."""
    m1 = J[0][0]
    m2 = J[0][0] * J[1][1] - J[0][1] ** 2
    m3 = (
        J[0][0] * (J[1][1] * J[2][2] - J[1][2] * J[2][1])
        - J[0][1] * (J[1][0] * J[2][2] - J[1][2] * J[2][0])
        + J[0][2] * (J[1][0] * J[2][1] - J[1][1] * J[2][0])
    )
    return m1 > 0 and m2 > 0 and m3 > 0


def rotor_positions_mm(
    la: float, lb: float, alpha_deg: float, beta_deg: float
) -> list[list[float]]:
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

    position: tuple[NonNegative, NonNegative, NonNegative] = (0.5, 0.5, 1.0)
    velocity: tuple[NonNegative, NonNegative, NonNegative] = (0.2, 0.2, 0.2)
    rates: tuple[NonNegative, NonNegative, NonNegative] = (0.05, 0.05, 0.05)
    attitude: tuple[NonNegative, NonNegative, NonNegative] = (2.0, 2.0, 4.0)
    thrust: tuple[NonNegative, NonNegative, NonNegative, NonNegative] = (0.0, 0.0, 0.0, 0.0)


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
    q_integral: tuple[NonNegative, NonNegative, NonNegative, NonNegative] = Field(
        (0.05, 0.05, 0.1, 0.05), description="weights of ∫e for x, y, z, yaw"
    )
    r: tuple[Positive, Positive, Positive, Positive] = Field((10.0, 10.0, 10.0, 10.0))
    gain_policy: Literal["redesign", "frozen"] = "redesign"
    reference_airframe: Path | None = Field(
        None, description="airframe YAML whose gain is frozen for all (gain_policy: frozen)"
    )
    robustness: RobustnessConfig = RobustnessConfig()

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        if v.get("gain_policy") == "frozen" and v.get("reference_airframe", 0) is None:
            return [("reference_airframe", "required when gain_policy is 'frozen'")]
        return []


# --------------------------------------------------------------------------------------------
# Reading YAML
# --------------------------------------------------------------------------------------------

M = TypeVar("M", bound=BaseModel)

#: Keys whose values name other config files, and the ``configs/`` folder a bare name (``SY250``)
#: is looked up in. Paths resolve relative to the referring file, then to the project root.
PATH_KEYS = {
    "reference_airframe": "airframes",
    "airframe": "airframes",
    "track": "tracks",
    "controller": "controllers",
    "reference": "references",
}


class _UniqueKeyLoader(yaml.SafeLoader):
    """SafeLoader that rejects a key given twice in one mapping (the second would win silently)."""

    def construct_mapping(self, node, deep=False):
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                first = seen.setdefault(key, key_node.start_mark.line)
            except TypeError:  # unhashable key: let SafeLoader report it
                continue
            if first != key_node.start_mark.line:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key '{key}' (first given on line {first + 1})",
                    key_node.start_mark,
                )
        return super().construct_mapping(node, deep=deep)


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping; malformed YAML or a missing file raises ConfigError with the line."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError([f"{path}: file not found"])
    try:
        text = path.read_text(encoding="utf-8")
        data = yaml.load(text, Loader=_UniqueKeyLoader)  # noqa: S506 (a SafeLoader subclass)
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError([f"{path}: cannot read: {exc}"]) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        context, cmark = getattr(exc, "context", None), getattr(exc, "context_mark", None)
        detail = problem
        if context and "duplicate" not in problem:
            started = f" started on line {cmark.line + 1}" if cmark and cmark is not mark else ""
            detail += f" ({context}{started})"
        raise ConfigError([f"{path}: {where}malformed YAML: {detail}"]) from None
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
    data = copy.deepcopy(data)
    errors = []
    for item in overrides or []:
        key, sep, value = item.partition("=")
        parts = key.strip().split(".")
        if not sep or not all(parts):
            errors.append(f"{source}: override '{item}': expected key=value (e.g. alpha_deg=75)")
            continue
        node: Any = data
        try:
            for part in parts[:-1]:
                if isinstance(node, list):  # list item by position: objectives.0.index=J3
                    node = node[int(part)]
                    continue
                if not isinstance(node.get(part), dict | list):
                    node[part] = {}
                node = node[part]
            if isinstance(node, list):
                node[int(parts[-1])] = parse_value(value)
            else:
                node[parts[-1]] = parse_value(value)
        except (ValueError, IndexError):
            errors.append(f"{source}: override '{item}': {key.strip()}: no such list item")
    if errors:
        raise ConfigError(errors)
    return data


# --------------------------------------------------------------------------------------------
# Error formatting
# --------------------------------------------------------------------------------------------


def _model_in(annotation: Any) -> type[BaseModel] | None:
    """The pydantic model inside an annotation (``Model``, ``Model | None``), if any."""
    for c in (annotation, *getattr(annotation, "__args__", ())):
        if isinstance(c, type) and issubclass(c, BaseModel):
            return c
    return None


def _fields_at(model: type[BaseModel], loc: tuple) -> list[str]:
    """Field names of the (nested) model reached by ``loc``, for "did you mean" hints."""
    current: type[BaseModel] | None = model
    for part in loc:
        if isinstance(part, int):
            continue
        field = current.model_fields.get(part) if current else None
        current = _model_in(field.annotation) if field else None
        if current is None:
            return []
    return list(current.model_fields) if current else []


def _unknown_key(model: type[BaseModel], loc: tuple) -> str:
    known = _fields_at(model, loc[:-1])
    close = difflib.get_close_matches(str(loc[-1]), known, n=1, cutoff=0.6)
    if close:
        return f"unknown key (did you mean '{close[0]}'?)"
    return "unknown key" + (f"; known keys: {', '.join(known)}" if known else "")


def _short(value: Any) -> str | None:
    if isinstance(value, str | int | float | bool) or value is None:
        text = repr(value)
        return text if len(text) <= 40 else text[:37] + "..."
    return None


def error_pairs(exc: ValidationError, model: type[BaseModel]) -> list[tuple[str, str]]:
    """(dotted key, message) for every error of a pydantic ValidationError."""
    pairs = []
    n_expected = {}  # tuple too short: one error per missing item; report the length once
    for err in exc.errors():
        loc = tuple(err["loc"])
        if err["type"] == "missing" and loc and isinstance(loc[-1], int):
            n_expected[loc[:-1]] = max(n_expected.get(loc[:-1], 0), loc[-1] + 1)
    for err in exc.errors():
        loc = tuple(err["loc"])
        prefix = ".".join(str(p) for p in loc)
        kind, msg = err["type"], err["msg"]
        problems = (err.get("ctx") or {}).get("error")
        if isinstance(problems, Problems):
            pairs += [(f"{prefix}.{k}" if prefix else k, m) for k, m in problems.problems]
            continue
        if kind == "extra_forbidden":
            msg = _unknown_key(model, loc)
        elif kind == "missing" and loc and isinstance(loc[-1], int):
            prefix = ".".join(str(p) for p in loc[:-1])
            msg = f"expected {n_expected[loc[:-1]]} values, got {len(err['input'])}"
        elif kind == "missing":
            msg = "required key missing"
        else:
            msg = msg.removeprefix("Value error, ")
            field, sep, rest = msg.partition(": ")
            if kind == "value_error" and sep and field in _fields_at(model, loc):
                prefix, msg = f"{prefix}.{field}" if prefix else field, rest  # "key: message"
            got = _short(err.get("input"))
            if got is not None and kind not in ("value_error", "assertion_error"):
                msg += f" (got {got})"
        pairs.append((prefix or "(top level)", msg))
    return pairs


def format_errors(exc: ValidationError, source: str, model: type[BaseModel]) -> list[str]:
    """One ``FILE: dotted.key: message`` line per pydantic error."""
    return list(dict.fromkeys(f"{source}: {k}: {m}" for k, m in error_pairs(exc, model)))


@cache
def _field_adapter(model: type[BaseModel], name: str) -> TypeAdapter:
    field = model.model_fields[name]
    if not field.metadata:
        return TypeAdapter(field.annotation)
    return TypeAdapter(Annotated[field.annotation, *field.metadata])


def partial_problems(model: type[BaseModel], data: Any) -> list[tuple[str, str]]:
    """Cross-field problems of ``data`` using only the fields that are valid on their own.

    Pydantic skips a model's cross-field validator when any field fails; this runs it anyway so
    that one load reports field errors and geometry errors together.
    """
    if not isinstance(data, dict) or not issubclass(model, Schema):
        return []
    values, found = {}, []
    for name, field in model.model_fields.items():
        if name not in data:
            if not field.is_required():
                values[name] = field.get_default(call_default_factory=True)
            continue
        try:
            values[name] = _field_adapter(model, name).validate_python(data[name])
        except ValidationError:
            sub, value = _model_in(field.annotation), data[name]
            if sub is None:
                continue
            items = enumerate(value) if isinstance(value, list) else [(None, value)]
            for i, item in items:  # a nested model, or a list of them
                at = name if i is None else f"{name}.{i}"
                found += [(f"{at}.{k}", m) for k, m in partial_problems(sub, item)]
    return found + model.problems(values)


# --------------------------------------------------------------------------------------------
# Loading and validating
# --------------------------------------------------------------------------------------------


def _resolve_reference(value: str, kind: str, base: Path) -> Path | None:
    """A referenced config: a path (relative to ``base``, then the project root) or a bare name
    of a file in ``configs/<kind>/``. None when nothing exists."""
    p = Path(value)
    candidates = [p] if p.is_absolute() else [base / p, ROOT / p]
    if not p.suffix and len(p.parts) == 1:
        candidates.append(CONFIG_DIR / kind / f"{value}.yaml")
    return next((c for c in candidates if c.is_file()), None)


def check_paths(data: dict[str, Any], base: Path, source: str) -> tuple[dict, list[str]]:
    """Resolve path-valued keys relative to ``base``; name every referenced file that is missing."""
    errors: list[str] = []

    def walk(node: Any, prefix: str) -> Any:
        if not isinstance(node, dict):
            return node
        out = {}
        for k, v in node.items():
            key = f"{prefix}.{k}" if prefix else str(k)
            if k in PATH_KEYS and isinstance(v, str):
                found = _resolve_reference(v, PATH_KEYS[k], base)
                looks_like_path = v.endswith((".yaml", ".yml")) or "/" in v
                if found is not None:
                    out[k] = str(found)
                    continue
                if looks_like_path:
                    errors.append(f"{source}: {key}: referenced file not found: {v}")
                elif (CONFIG_DIR / PATH_KEYS[k]).is_dir():
                    names = [f.stem for f in (CONFIG_DIR / PATH_KEYS[k]).glob("*.yaml")]
                    close = difflib.get_close_matches(v, names, n=1, cutoff=0.6)
                    hint = f" (did you mean '{close[0]}'?)" if close else ""
                    errors.append(f"{source}: {key}: referenced file not found: {v} is neither a "
                                  f"file nor a name in configs/{PATH_KEYS[k]}/{hint}")
            out[k] = walk(v, key)
        return out

    return walk(data, ""), errors


def validate_data(
    model: type[M],
    data: dict[str, Any],
    source: str,
    base: Path,
    overrides: list[str] | None = None,
) -> M:
    """Validate a dict against ``model``, raising ConfigError listing every problem.

    A problem whose key was set by a ``key=value`` override says so.
    """
    data, errors = check_paths(data, base, source)
    try:
        return_value = model.model_validate(data)
        pairs = []
    except ValidationError as exc:
        pairs = error_pairs(exc, model) + partial_problems(model, data)
        return_value = None
    set_by = {o.partition("=")[0].strip(): o for o in overrides or [] if "=" in o}
    for key, msg in dict.fromkeys(pairs):
        origin = next((o for k, o in set_by.items() if key == k or key.startswith(k + ".")), None)
        errors.append(f"{source}: {key}: {msg}" + (f" [override {origin}]" if origin else ""))
    if errors:
        raise ConfigError(errors)
    return return_value


def load(model: type[M], path: str | Path, overrides: list[str] | None = None) -> M:
    """Load and validate a YAML file, with optional ``key=value`` overrides."""
    path = Path(path)
    data = apply_overrides(read_yaml(path), overrides, str(path))
    return validate_data(model, data, str(path), path.parent, overrides)


def resolve_config(name: str | Path, kind: str) -> Path:
    """A path as given if it exists, else ``configs/<kind>/<name>.yaml`` (e.g. ``SY250``).

    Raises ConfigError naming the known configs when neither exists.
    """
    p = Path(name)
    for candidate in (p, ROOT / p):
        if candidate.is_file():
            return candidate
    candidate = CONFIG_DIR / kind / f"{p.stem}.yaml"
    if len(p.parts) == 1 and p.suffix in ("", ".yaml", ".yml") and candidate.is_file():
        return candidate
    if len(p.parts) > 1:
        raise ConfigError([f"{name}: file not found"])
    known = sorted(f.stem for f in (CONFIG_DIR / kind).glob("*.yaml"))
    close = difflib.get_close_matches(p.stem, known, n=1, cutoff=0.6)
    hint = f"did you mean '{close[0]}'? " if close else ""
    raise ConfigError([f"{name}: file not found, and no configs/{kind}/{p.stem}.yaml "
                       f"({hint}known: {', '.join(known) or 'none'})"])


def load_airframe(path: str | Path, overrides: list[str] | None = None) -> AirframeConfig:
    """Load an airframe: a YAML path or a reference name (``SY250``), with ``key=value``
    overrides (``alpha_deg=75``) validated like the file."""
    return load(AirframeConfig, resolve_config(path, "airframes"), overrides)


def load_controller(
    path: str | Path | None = None, overrides: list[str] | None = None
) -> ControllerConfig:
    """Load a controller YAML or name; ``None`` gives ``configs/controllers/default.yaml``."""
    return load(ControllerConfig, resolve_config(path or "default", "controllers"), overrides)


# Schemas by config folder name, for ``casadrone validate``; later layers register theirs. A
# value is a schema class, or "module:Class" for a schema defined in a heavier module (imported
# only when a file of that kind is validated).
SCHEMAS_BY_FOLDER: dict[str, type[BaseModel] | str] = {
    "airframes": AirframeConfig,
    "controllers": ControllerConfig,
    "tracks": "casadrone.guidance:TrackConfig",
    "references": "casadrone.benchmark:Table4Reference",
}
# Fallback when the folder says nothing: a key that only that schema has.
SCHEMAS_BY_KEY: dict[str, type[BaseModel] | str] = {
    "lambda_a_mm": AirframeConfig,
    "sample_time_s": ControllerConfig,
    "gain_policy": ControllerConfig,
    "waypoints_m": "casadrone.guidance:TrackConfig",
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


# --------------------------------------------------------------------------------------------
# Optimisation problems (problems/*.yaml)
# --------------------------------------------------------------------------------------------


class VariableConfig(Schema):
    """A decision variable: an airframe config key (with its unit) and its bounds."""

    name: str
    lower: float
    upper: float

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found = []
        if _has(v, "lower", "upper") and not v["lower"] < v["upper"]:
            found.append(("lower", f"lower bound {v['lower']} is not below upper bound "
                          f"{v['upper']}"))
        if "name" in v and v["name"] not in AirframeConfig.model_fields:
            close = difflib.get_close_matches(v["name"], list(AirframeConfig.model_fields), 1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            found.append(("name", f"'{v['name']}' is not an airframe key{hint}"))
        return found


def _table1_variables() -> list[VariableConfig]:
    from casadrone.airframe import TABLE1_BOUNDS

    return [VariableConfig(name=k, lower=lo, upper=hi) for k, (lo, hi) in TABLE1_BOUNDS.items()]


class ObjectiveConfig(Schema):
    """An objective: a registered index and its sense (default: the index's own)."""

    index: str
    sense: Literal["min", "max"] | None = None


class ConstraintConfig(Schema):
    """A limit on an index (the lap-completed constraint is always on)."""

    index: str
    min: float | None = None
    max: float | None = None

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        if v.get("min") is None and v.get("max") is None:
            return [("max", "give min or max (or both)")]
        if v.get("min") is not None and v.get("max") is not None and v["min"] > v["max"]:
            return [("min", f"min {v['min']} is above max {v['max']}")]
        return []


class AlgorithmConfig(Schema):
    """The optimiser: ``evmoga`` or any pymoo algorithm by name, with its settings."""

    name: str = "evmoga"
    population: int = Field(100, ge=2, description="ev-MOGA n_ind_p / pymoo pop_size")
    generations: int = Field(50, ge=1, description="generations after the initial population")
    settings: dict[str, Any] = Field(default_factory=dict, description="algorithm keywords")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        if "name" not in v:
            return []
        from casadrone.optimise.algorithms import ALGORITHM_NAMES as ALGORITHMS

        if v["name"].strip().lower() not in ALGORITHMS:
            close = difflib.get_close_matches(v["name"], list(ALGORITHMS), 1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            return [("name", f"unknown algorithm '{v['name']}' ({hint}known: "
                     f"{', '.join(ALGORITHMS)})")]
        return []


class BackendConfig(Schema):
    """Where candidates are evaluated: this process, a process pool, or a Dask cluster."""

    name: Literal["serial", "processes", "dask"] = "serial"
    workers: int = Field(1, ge=1, description="processes (or LocalCluster workers)")
    scheduler: str | None = Field(None, description="Dask scheduler address; None: LocalCluster")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        import importlib.util

        if v.get("name") == "dask" and importlib.util.find_spec("distributed") is None:
            return [("name", "backend 'dask' needs the dask extra: pip install 'casadrone[dask]'")]
        return []


class PymooProblemConfig(Schema):
    """A pymoo test problem with a known front, to check algorithm settings."""

    name: Literal["zdt1", "zdt2", "zdt3", "dtlz2"]
    n_var: int = Field(4, ge=2)
    n_obj: int = Field(3, ge=2, description="dtlz2 only")


class ProblemConfig(Schema):
    """An optimisation problem (DESIGN.md §9): what varies, what is flown, what is optimised."""

    name: str
    description: str = ""
    airframe: Path | None = Field(None, description="template airframe YAML (fixed parameters)")
    variables: list[VariableConfig] = Field(default_factory=_table1_variables, min_length=1)
    fixed: dict[str, Any] = Field(default_factory=dict, description="airframe key overrides")
    track: Path | None = None
    controller: Path | None = None
    integrator: Literal["rk4", "cvodes", "idas"] = "rk4"
    objectives: list[ObjectiveConfig] = Field(default_factory=list)
    constraints: list[ConstraintConfig] = Field(default_factory=list)
    algorithm: AlgorithmConfig = Field(default_factory=AlgorithmConfig)
    seed: int = 1
    backend: BackendConfig = Field(default_factory=BackendConfig)
    test_problem: PymooProblemConfig | None = None
    plugins: list[str] = Field(
        default_factory=list,
        description="modules or .py files imported in every process before evaluation "
        "(e.g. to register custom indices)",
    )

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found: list[tuple[str, str]] = []
        for i, plugin in enumerate(v.get("plugins") or []):
            try:
                import_plugin(plugin)
            except Exception as exc:  # noqa: BLE001 - any import failure is a config problem
                found.append((f"plugins.{i}", f"cannot import '{plugin}': {exc}"))
        test = v.get("test_problem")
        if test is None:
            if v.get("airframe", 0) is None:
                found.append(("airframe", "required (or give test_problem)"))
            if "objectives" in v and len(v["objectives"]) < 1:
                found.append(("objectives", "give at least one objective"))
            from casadrone.indices import INDICES

            for group in ("objectives", "constraints"):
                for i, o in enumerate(v.get(group) or []):
                    if o.index not in INDICES:
                        close = difflib.get_close_matches(o.index, list(INDICES), 1)
                        hint = f"did you mean '{close[0]}'? " if close else ""
                        found.append((f"{group}.{i}.index", f"unknown index '{o.index}' ({hint}"
                                      f"known: {', '.join(INDICES)})"))
            names = [o.index for o in v.get("objectives") or []]
            for dup in sorted({n for n in names if names.count(n) > 1}):
                found.append(("objectives", f"objective '{dup}' is listed twice"))
            vnames = [x.name for x in v.get("variables") or []]
            for dup in sorted({n for n in vnames if vnames.count(n) > 1}):
                found.append(("variables", f"variable '{dup}' is listed twice"))
            for key in v.get("fixed") or {}:
                if key not in AirframeConfig.model_fields:
                    found.append((f"fixed.{key}", "not an airframe key"))
        return found


_PLUGINS: dict[str, Any] = {}


def import_plugin(plugin: str) -> Any:
    """Import a plugin once per process: a module name, or a path to a ``.py`` file (relative
    paths from the working directory, then the project root)."""
    import importlib
    import importlib.util

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


SCHEMAS_BY_FOLDER["problems"] = ProblemConfig
SCHEMAS_BY_KEY["objectives"] = ProblemConfig
PATH_KEYS.setdefault("reference_airframe", "airframes")


def load_problem(path: str | Path, overrides: list[str] | None = None) -> ProblemConfig:
    """Load a problem YAML with ``dotted.key=value`` overrides (``algorithm.generations=20``)."""
    return load(ProblemConfig, path, overrides)
