"""Optimisation problems (``problems/*.yaml``, docs/concepts/chain.md#optimise): what varies, what
is flown, what is optimised, and with which algorithm and backend.

Schemas like the airframe's (frozen, unknown keys rejected), checked here against the other configs
only: the airframe keys, the referenced files and the search box. The checks against the optimiser
(index and algorithm names, algorithm settings, plugins) need its registries, so they live beside
it, in :mod:`casadrone.optimise.checks`, whose ``load_problem`` runs both; :func:`read_problem`
is this half alone.
"""

from __future__ import annotations

import difflib
import itertools
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationError, model_validator

from casadrone.config.airframe import MASS_KEYS, TABLE1_BOUNDS, AirframeConfig, load_airframe
from casadrone.config.controller import load_controller
from casadrone.config.io import (
    ConfigError,
    Schema,
    error_pairs,
    field_adapter,
    first_line,
    has_keys,
    load,
    read_yaml,
    resolve_config,
    scalar_types,
)
from casadrone.config.limitlap import LimitLapConfig
from casadrone.config.track import TrackConfig


class VariableConfig(Schema):
    """A decision variable: an airframe config key (with its unit) and its bounds."""

    name: str = Field(
        description="an airframe key, with its unit (lambda_a_mm, alpha_deg, ixx_kgm2, ...)",
    )
    lower: float = Field(description="lower bound, in the key's unit")
    upper: float = Field(description="upper bound, in the key's unit (above lower)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found = []
        if has_keys(v, "lower", "upper") and not v["lower"] < v["upper"]:
            found.append(("lower", f"lower bound {v['lower']} is not below upper bound "
                          f"{v['upper']}"))
        if "name" in v and v["name"] not in AirframeConfig.model_fields:
            close = difflib.get_close_matches(v["name"], list(AirframeConfig.model_fields), 1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            found.append(("name", f"'{v['name']}' is not an airframe key{hint}"))
        elif "name" in v and scalar_types(AirframeConfig.model_fields[v["name"]].annotation) - {
                type(None)} != {float}:
            found.append(("name", f"'{v['name']}' is not a number the search can vary"))
        elif "name" in v:  # each bound must itself be a value the airframe key accepts
            for bound in ("lower", "upper"):
                if bound not in v:
                    continue
                try:
                    field_adapter(AirframeConfig, v["name"]).validate_python(v[bound])
                except ValidationError as exc:
                    msg = exc.errors()[0]["msg"].removeprefix("Value error, ")
                    found.append((bound, f"{v[bound]} is not a possible {v['name']}: {msg}"))
        return found


def _table1_variables() -> list[VariableConfig]:
    return [VariableConfig(name=k, lower=lo, upper=hi) for k, (lo, hi) in TABLE1_BOUNDS.items()]


class ObjectiveConfig(Schema):
    """An objective: a registered index and its sense (default: the index's own)."""

    index: str = Field(description="a registered index (J1…J5, Jp, J3_limit, or a plugin's)")
    sense: Literal["min", "max"] | None = Field(
        None,
        description="min or max (default: the index's own sense)",
    )


class ConstraintConfig(Schema):
    """A limit on an index (the lap-completed constraint is always on)."""

    index: str = Field(description="a registered index")
    min: float | None = Field(None, description="lower limit, in the index's unit")
    max: float | None = Field(None, description="upper limit, in the index's unit")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        if v.get("min") is None and v.get("max") is None:
            return [("max", "give min or max (or both)")]
        if v.get("min") is not None and v.get("max") is not None and v["min"] > v["max"]:
            return [("min", f"min {v['min']} is above max {v['max']}")]
        return []


class AlgorithmConfig(Schema):
    """The optimiser: ``evmoga`` or any pymoo algorithm by name, with its settings (both checked
    against the optimiser by :func:`casadrone.optimise.checks.problem_problems`)."""

    name: str = Field(
        "evmoga",
        description="evmoga, or a pymoo algorithm by name (nsga2, nsga3, ...)",
    )
    # Ceilings: over ten times the paper's budget (850 individuals, 350 generations, Table 6);
    # each candidate is a trim, an LQR design and a lap (~0.1-1 s), so more is months of
    # computing: a typing slip, refused at load.
    population: int = Field(100, ge=2, le=10_000,
                            description="ev-MOGA n_ind_p / pymoo pop_size (at most 10 000)")
    generations: int = Field(50, ge=1, le=100_000, description="generations after the initial "
                             "population (at most 100 000)")
    settings: dict[str, Any] = Field(default_factory=dict, description="algorithm keywords")


class BackendConfig(Schema):
    """Where candidates are evaluated: this process, a process pool, or a Dask cluster."""

    name: Literal["serial", "processes", "dask"] = Field(
        "serial",
        description="serial (this process), processes (a local pool) or dask (a cluster)",
    )
    workers: int = Field(1, ge=1, le=1024, description="processes (or LocalCluster workers)")
    scheduler: str | None = Field(None, description="Dask scheduler address; None: LocalCluster")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        import importlib.util

        if v.get("name") == "dask" and importlib.util.find_spec("distributed") is None:
            return [("name", "backend 'dask' needs the dask extra: pip install 'casadrone[dask]'")]
        return []


class PymooProblemConfig(Schema):
    """A pymoo test problem with a known front, to check algorithm settings."""

    name: Literal["zdt1", "zdt2", "zdt3", "dtlz2"] = Field(description="the pymoo test problem")
    n_var: int = Field(4, ge=2, le=1000, description="number of decision variables, at most 1000 "
                       "(the test problems' fronts are known for any size; beyond is memory, "
                       "not a test)")
    n_obj: int = Field(3, ge=2, le=10, description="dtlz2 only; at most 10 (reference "
                       "directions grow combinatorially with the objectives)")


class ProblemConfig(Schema):
    """An optimisation problem (docs/concepts/chain.md#optimise): what varies, what is flown, what
    is optimised."""

    name: str = Field(description="name of the problem, shown in the run's manifest and report")
    description: str = Field("", description="free text: what the problem studies")
    airframe: Path | None = Field(None, description="template airframe YAML (fixed parameters)")
    variables: list[VariableConfig] = Field(
        default_factory=_table1_variables, min_length=1,
        description="decision variables and their bounds (default: the paper's Table 1)",
    )
    fixed: dict[str, Any] = Field(default_factory=dict, description="airframe key overrides")
    track: Path | None = Field(
        None,
        description="track YAML or shipped name (default: the paper's track)",
    )
    controller: Path | None = Field(
        None,
        description="controller YAML or shipped name (default: configs/controllers/default.yaml)",
    )
    integrator: str = Field(
        "rk4",
        description="closed-loop integrator, a name in casadrone.simulate.INTEGRATORS: rk4 "
        "(compiled, fast), cvodes or idas (SUNDIALS)",
    )
    objectives: list[ObjectiveConfig] = Field(
        default_factory=list,
        description="indices to optimise, each with its sense",
    )
    constraints: list[ConstraintConfig] = Field(
        default_factory=list,
        description="limits on indices (the lap-completed constraint is always on)",
    )
    limit_lap: LimitLapConfig = Field(
        default_factory=LimitLapConfig,
        description="how the limit-lap indices (J3_limit) fly their limit lap: the keys of "
        "casadrone limit-lap (solver, attitude, tilt, intervals, ...)",
    )
    algorithm: AlgorithmConfig = Field(
        default_factory=AlgorithmConfig,
        description="the optimiser and its budget",
    )

    @model_validator(mode="before")
    @classmethod
    def _legacy_limit_solver(cls, data: Any) -> Any:
        """``limit_solver: NAME``, the one limit-lap setting a problem had before the
        ``limit_lap:`` section, read as ``limit_lap.solver``: every run directory written before
        stores it in its config.yaml, and such a run must still resume. Given beside
        ``limit_lap.solver`` it is refused naming both."""
        if not isinstance(data, dict) or "limit_solver" not in data:
            return data
        section = data.get("limit_lap") or {}
        if not isinstance(section, dict):
            return data
        if section.get("solver") is not None:
            raise ValueError("limit_solver: give limit_lap.solver alone (limit_solver is its "
                             "older name)")
        rest = {k: v for k, v in data.items() if k != "limit_solver"}
        return {**rest, "limit_lap": {**section, "solver": data["limit_solver"]}}
    seed: int = Field(1, ge=0, le=2**32 - 1, description="random seed (numpy: 0 … 2³² − 1)")
    backend: BackendConfig = Field(
        default_factory=BackendConfig,
        description="where candidates are evaluated",
    )
    test_problem: PymooProblemConfig | None = Field(
        None,
        description="a pymoo test problem with a known front instead of the drone chain",
    )
    plugins: list[str] = Field(
        default_factory=list,
        description="modules or .py files imported in every process before evaluation "
        "(e.g. to register custom indices)",
    )

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found: list[tuple[str, str]] = []
        test = v.get("test_problem")
        if test is None:
            if v.get("airframe", 0) is None:
                found.append(("airframe", "required (or give test_problem)"))
            if "objectives" in v and len(v["objectives"]) < 1:
                found.append(("objectives", "give at least one objective"))
            names = [o.index for o in v.get("objectives") or []]
            for dup in sorted({n for n in names if names.count(n) > 1}):
                found.append(("objectives", f"objective '{dup}' is listed twice"))
            vnames = [x.name for x in v.get("variables") or []]
            for dup in sorted({n for n in vnames if vnames.count(n) > 1}):
                found.append(("variables", f"variable '{dup}' is listed twice"))
            for key in v.get("fixed") or {}:
                if key not in AirframeConfig.model_fields:
                    found.append((f"fixed.{key}", "not an airframe key"))
                elif key in vnames:
                    found.append((f"fixed.{key}", "also a decision variable: fix it or vary it"))
            found += _computed_variables(v)
            if not found and v.get("airframe") is not None:
                found += _input_problems(v)
        return found


def _input_problems(v: dict[str, Any]) -> list[tuple[str, str]]:
    """The referenced airframe, track and controller valid, ``fixed:`` values valid on the
    template, and the search box able to produce an airframe: every bound a possible value on
    its own (checked per variable), and the full airframe schema met at the box's centre or at
    one of its corners (a box where neither holds would only give failed evaluations)."""
    found: list[tuple[str, str]] = []
    try:
        template = load_airframe(v["airframe"])
    except ConfigError as exc:
        return [("airframe", f"referenced file is invalid: {first_line(exc)}")]
    for key in ("controller", "track"):
        if v.get(key) is not None:
            try:
                if key == "track":
                    _load_track(v[key])
                    continue
                reference = load_controller(v[key]).reference_airframe
                if reference is not None:
                    load_airframe(reference)
            except ConfigError as exc:
                found.append((key, f"referenced file is invalid: {first_line(exc)}"))
    base = template.model_dump()
    if v.get("fixed"):
        try:
            template = AirframeConfig.model_validate({**base, **v["fixed"]})
        except ValidationError as exc:
            return found + [(f"fixed.{k}", m) for k, m in error_pairs(exc, AirframeConfig)]
        base = template.model_dump()
    variables = v.get("variables") or []
    if not variables:
        return found
    points = [{x.name: (x.lower + x.upper) / 2 for x in variables}]
    if len(variables) <= 10:  # 2^n corners (Table 1: 128); more would be slow to list
        points += [dict(zip([x.name for x in variables], c, strict=True)) for c in
                   itertools.product(*[(x.lower, x.upper) for x in variables])]
    first_problem = None
    for point in points:
        try:
            AirframeConfig.model_validate({**base, **point})
            return found
        except ValidationError as exc:
            if first_problem is None:
                k, m = error_pairs(exc, AirframeConfig)[0]
                first_problem = f"{k}: {m}"
    return found + [("variables", "the search box cannot produce a valid airframe (neither its "
                     f"centre nor any corner is one); at the centre: {first_problem}")]


def _load_track(path: str | Path) -> TrackConfig:
    return load(TrackConfig, path)


def _computed_variables(v: dict[str, Any]) -> list[tuple[str, str]]:
    """Decision variables that the airframe's mass model computes (mass and inertia keys under
    ``mass_model: components``): refused, never silently ignored."""
    if not v.get("airframe") or "variables" not in v:
        return []
    try:
        template = {**read_yaml(v["airframe"]), **(v.get("fixed") or {})}
    except ConfigError:
        return []  # the airframe file's own problems are reported with it
    if template.get("mass_model") != "components":
        return []
    computed = [x.name for x in v["variables"] if x.name in MASS_KEYS]
    if computed and [x.model_dump() for x in v["variables"]] == [
            x.model_dump() for x in _table1_variables()]:  # not written in the file
        return [("variables", f"not given, so the default (paper Table 1) applies, and it "
                 f"varies {', '.join(computed)}, which the airframe's mass_model: components "
                 "computes from the parts; list the geometry variables (lambda_a_mm, "
                 "lambda_b_mm, alpha_deg, beta_deg) under variables")]
    return [(f"variables.{i}.name", f"'{x.name}' is computed from the parts with the airframe's "
             "mass_model: components, so it cannot be a decision variable; list the geometry "
             "variables (lambda_a_mm, lambda_b_mm, alpha_deg, beta_deg) under variables")
            for i, x in enumerate(v["variables"]) if x.name in MASS_KEYS]


def read_problem(path: str | Path, overrides: list[str] | None = None) -> ProblemConfig:
    """Read a problem YAML (a path, or a shipped problem's name: ``quick``) with
    ``dotted.key=value`` overrides (``algorithm.generations=20``), checked against the other
    configs; :func:`casadrone.optimise.checks.load_problem` adds the optimiser's checks."""
    return load(ProblemConfig, resolve_config(path, "problems"), overrides)
