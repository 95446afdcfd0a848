"""Reading config files: YAML, ``key=value`` overrides, referenced files and complete error reports.

The generic half of the configuration: :class:`Schema`, the base of every schema (the schemas
themselves are in the other modules of :mod:`casadrone.config`), and the loader that
validates a YAML file against one. Loading a file reports every problem at once, one line each,
as ``FILE: dotted.key: message``: field errors and cross-field (geometry) errors together, a "did
you mean" hint for misspelt keys at any depth, the line of malformed YAML, and the name of any
referenced file that does not exist.
"""

from __future__ import annotations

import copy
import difflib
import math
import os
import re
import types
import typing
from collections.abc import Iterator
from functools import cache
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, Literal, TypeVar

import yaml
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    TypeAdapter,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from casadrone.config import yamlsafe

#: The checkout (or, installed, site-packages): relative paths in configs resolve here too.
ROOT = Path(__file__).resolve().parents[2]
#: The shipped data (package data, so a non-editable install has it): ``configs/`` and
#: ``problems/``. The checkout's top-level ``configs`` and ``problems`` are links into it.
DATA_DIR = Path(str(resources.files("casadrone") / "data"))
CONFIG_DIR = DATA_DIR / "configs"


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


#: Largest magnitude of any number in a config. No quantity of this model comes near it in the
#: units the keys name (mm, deg, kg, s, m, N, V); beyond it the chain's arithmetic (squares,
#: products of inertias) overflows to inf, and a number that large is a typing slip (1e308).
MAX_MAGNITUDE = 1e9


def scalar_types(annotation: Any) -> set[Any]:
    """The scalar types an annotation admits (``tuple[float, float] | None`` → {float, None}),
    with Literal values as their types and models as themselves."""
    origin = typing.get_origin(annotation)
    if annotation is type(None):
        return {type(None)}
    if origin is Annotated:
        return scalar_types(typing.get_args(annotation)[0])
    if origin is Literal:
        return {type(a) for a in typing.get_args(annotation)}
    if origin in (typing.Union, types.UnionType, list, tuple, dict, set, frozenset):
        args = typing.get_args(annotation)
        if origin is dict:
            args = args[1:]
        return set().union(*(scalar_types(a) for a in args if a is not Ellipsis)) if args else {Any}
    return {annotation}


def _scalars(value: Any) -> Iterator[Any]:
    """Every scalar inside nested lists and tuples (dicts are models' business)."""
    if isinstance(value, list | tuple):
        for v in value:
            yield from _scalars(v)
    else:
        yield value


def strict_scalar_problem(leaves: set[Any], value: Any) -> str | None:
    """Why ``value`` cannot stand for a field admitting ``leaves``, or None. Numbers are numbers:
    no booleans (``true`` is not 1 kg) and no text (``"1"``) for a numeric field; every number
    finite and within :data:`MAX_MAGNITUDE`."""
    if Any in leaves:
        return None
    numeric = {float, int} & leaves
    for v in _scalars(value):
        if isinstance(v, bool):
            if bool not in leaves and numeric:
                return f"expected a number, got the boolean {str(v).lower()}"
        elif isinstance(v, str):
            if numeric and not ({str} | {t for t in leaves if isinstance(t, type)
                                         and issubclass(t, str | Path)}) & leaves:
                return f"expected a number, got the text {v!r}"
        elif isinstance(v, int | float):
            if float in leaves and not math.isfinite(v):
                return f"expected a finite number, got {v}"
            if numeric and abs(v) > MAX_MAGNITUDE:
                return (f"{v:g} is beyond any physical value here (|x| <= {MAX_MAGNITUDE:g}); "
                        "check the unit and the exponent")
    return None


class Schema(BaseModel):
    """Base of every config schema: frozen, unknown keys rejected, numbers strict.

    Cross-field checks live in :meth:`problems`, which works on a plain dict of field values so
    that the loader can still run it when some fields failed (those are simply absent): a file
    with a negative mass *and* overlapping rotors gets both reported. Every numeric field takes
    numbers only (no booleans, no text), finite and within :data:`MAX_MAGNITUDE`, whichever way
    the value came in (file, ``key=value`` override, a problem's ``fixed:`` or bounds).
    """

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    @field_validator("*", mode="before")
    @classmethod
    def _strict_numbers(cls, value: Any, info: ValidationInfo) -> Any:
        field = cls.model_fields.get(info.field_name or "")
        if field is not None:
            problem = strict_scalar_problem(scalar_types(field.annotation), value)
            if problem:
                raise ValueError(problem)
        return value

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


def has_keys(v: dict[str, Any], *keys: str) -> bool:
    """True when every key is present (for :meth:`Schema.problems`, which skips a check then)."""
    return all(k in v for k in keys)


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


class _UniqueKeyLoader(yamlsafe.BaseLoader):
    """SafeLoader (libyaml's where installed) that rejects a key given twice in one mapping (the
    second would win silently)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
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


# PyYAML follows YAML 1.1, where ``1e-3`` (no dot) is a string; read it as the number it is.
_UniqueKeyLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
    |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
    |\.[0-9_]+(?:[eE][-+][0-9]+)?
    |[-+]?\.(?:inf|Inf|INF)
    |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."),
)


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping; malformed YAML or a missing file raises ConfigError with the line."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError([f"{path}: {not_a_file(path)}"])
    try:
        yamlsafe.check_size(path.stat().st_size)
        text = path.read_text(encoding="utf-8")
        data = yamlsafe.safe_load(text, _UniqueKeyLoader)
    except yamlsafe.TooCostly as exc:
        raise ConfigError([f"{path}: {exc}"]) from None
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


def not_a_file(path: Path) -> str:
    """Why ``path`` (not a regular file) cannot be read: missing, a folder, a link loop."""
    import errno

    try:
        path.stat()
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            return "symbolic link loop (the link points back at itself); not read"
        if path.is_symlink():
            return f"broken symbolic link (to {os.readlink(path)}); not read"
        return "file not found"
    return "is a folder, not a file" if path.is_dir() else "not a regular file; not read"


def parse_value(text: str) -> Any:
    """Parse the value of a ``key=value`` override as YAML (numbers, lists, strings); one
    beyond :mod:`casadrone.config.yamlsafe`'s limits raises TooCostly."""
    try:
        return yamlsafe.safe_load(text, _UniqueKeyLoader)
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
            parsed = parse_value(value)
        except yamlsafe.TooCostly as exc:
            errors.append(f"{source}: override '{key.strip()}=…': {exc}")
            continue
        try:
            for part in parts[:-1]:
                if isinstance(node, list):  # list item by position: objectives.0.index=J3
                    node = node[int(part)]
                    continue
                if not isinstance(node.get(part), dict | list):
                    node[part] = {}
                node = node[part]
            if isinstance(node, list):
                node[int(parts[-1])] = parsed
            else:
                node[parts[-1]] = parsed
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
    # tuple too short: one error per missing item; report the length once
    n_expected: dict[tuple, int] = {}
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
def field_adapter(model: type[BaseModel], name: str) -> TypeAdapter:
    """Validates one field of ``model`` on its own, as strictly as the model does."""
    field = model.model_fields[name]
    leaves = scalar_types(field.annotation)

    def strict(value: Any) -> Any:
        problem = strict_scalar_problem(leaves, value)
        if problem:
            raise ValueError(problem)
        return value

    annotated = Annotated[field.annotation, *field.metadata, BeforeValidator(strict)]  # type: ignore[name-defined]
    if _model_in(field.annotation) is None:
        return TypeAdapter(annotated, config=ConfigDict(allow_inf_nan=False))
    return TypeAdapter(annotated)


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
            values[name] = field_adapter(model, name).validate_python(data[name])
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
    candidates = [p] if p.is_absolute() else [base / p, ROOT / p, DATA_DIR / p]
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


def first_line(exc: Exception) -> str:
    """The first line of a ConfigError (the others counted), or the exception's text: a
    referenced file's problems said in one line of the file that references it."""
    lines = getattr(exc, "lines", None) or [str(exc)]
    return lines[0] + (f" (and {len(lines) - 1} more)" if len(lines) > 1 else "")


def problem_lines(pairs: list[tuple[str, str]], source: str,
                  overrides: list[str] | None = None) -> list[str]:
    """``FILE: dotted.key: message`` per (key, message); a key set by a ``key=value`` override
    says so."""
    set_by = {o.partition("=")[0].strip(): o for o in overrides or [] if "=" in o}
    lines = []
    for key, msg in dict.fromkeys(pairs):
        origin = next((o for k, o in set_by.items() if key == k or key.startswith(k + ".")), None)
        lines.append(f"{source}: {key}: {msg}" + (f" [override {origin}]" if origin else ""))
    return lines


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
    errors += problem_lines(pairs, source, overrides)
    if errors or return_value is None:
        raise ConfigError(errors)
    return return_value


def load(model: type[M], path: str | Path, overrides: list[str] | None = None) -> M:
    """Load and validate a YAML file, with optional ``key=value`` overrides."""
    path = Path(path)
    data = apply_overrides(read_yaml(path), overrides, str(path))
    try:
        return validate_data(model, data, str(path), path.parent, overrides)
    except ConfigError:
        other = other_kind(model, data)
        if other:  # a problem given for an airframe: one line, not every missing key
            raise ConfigError([f"{path}: {other}"]) from None
        raise


#: Keys that only one kind of config has (the kind is its schema's name without ``Config``),
#: to tell a file given for the wrong kind: ``massprops problems/quick.yaml``.
TELLING_KEYS = {
    "airframe": ("lambda_a_mm", "lambda_b_mm", "mass_model"),
    "problem": ("objectives", "variables", "algorithm"),
    "track": ("waypoints_m", "gates"),
    "controller": ("sample_time_s", "gain_policy"),
    "parts": ("propellers", "motors", "packs"),
}


def other_kind(model: type[BaseModel], data: dict[str, Any]) -> str | None:
    """When ``data`` (which failed ``model``) is plainly another kind of config (its telling keys
    there, none of ``model``'s), one line that says so; else None."""
    ours = model.__name__.removesuffix("Config").lower()
    if ours not in TELLING_KEYS or any(k in data for k in TELLING_KEYS[ours]):
        return None
    theirs = next((kind for kind, keys in TELLING_KEYS.items()
                   if kind != ours and any(k in data for k in keys)), None)
    if theirs is None:
        return None
    article = "an" if ours[0] in "aeiou" else "a"
    return (f"this is {'an' if theirs[0] in 'aeiou' else 'a'} {theirs}, not {article} {ours}; "
            f"give {article} {ours} here (a YAML file or a shipped name)")


#: Kinds of shipped files that are not under ``configs/``, and their suffix: the problems, and
#: the example thrust-stand logs of ``casadrone fit-propulsion`` (CSV).
TOP_KINDS = {"problems": ".yaml", "thruststand": ".csv"}


def kind_dir(kind: str) -> Path:
    """The shipped folder of one kind of config: ``airframes`` … or ``problems`` (or
    ``thruststand``, the example stand logs)."""
    return DATA_DIR / kind if kind in TOP_KINDS else CONFIG_DIR / kind


def resolve_config(name: str | Path, kind: str) -> Path:
    """A path as given if it exists, else the shipped ``configs/<kind>/<name>.yaml`` (e.g.
    ``SY250``; kind ``problems`` looks in the shipped ``problems/``, e.g. ``quick``; kind
    ``thruststand`` in the shipped ``thruststand/`` for ``<name>.csv``, e.g. ``example-5in``).

    Raises ConfigError naming the known configs when neither exists.
    """
    folder = kind_dir(kind)
    where = kind if kind in TOP_KINDS else f"configs/{kind}"
    suffix = TOP_KINDS.get(kind, ".yaml")
    if not str(name).strip():  # an unset shell variable: Path("") would read as "."
        listed = ", ".join(_names_in(folder, suffix)) or "none"
        raise ConfigError([f"{str(name)!r}: an empty name: give a YAML file or the name of a "
                           f"shipped {where} file (known: {listed})"])
    p = Path(name)
    for candidate in (p, ROOT / p, DATA_DIR / p):
        if candidate.is_file():
            return candidate
    candidate = folder / f"{p.stem}{suffix}"
    suffixes = ("", ".yaml", ".yml") if suffix == ".yaml" else ("", suffix)
    if len(p.parts) == 1 and p.suffix in suffixes and candidate.is_file():
        return candidate
    # something there that is not a file (a folder in the working directory, a dangling link):
    # say what it is, not "file not found"
    if len(p.parts) > 1 or p.is_symlink() or p.exists():
        raise ConfigError([f"{name}: {not_a_file(p)}"])
    known = _names_in(folder, suffix)
    close = difflib.get_close_matches(p.stem, known, n=1, cutoff=0.6)
    hint = f"did you mean '{close[0]}'? " if close else ""
    raise ConfigError([f"{name}: file not found, and no shipped {where}/{p.stem}{suffix} "
                       f"({hint}known: {', '.join(known) or 'none'})"])


def _names_in(folder: Path, suffix: str = ".yaml") -> list[str]:
    """The names of the shipped configs in ``folder`` (what the refusals list)."""
    return sorted(f.stem for f in folder.glob(f"*{suffix}"))
