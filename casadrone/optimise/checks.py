"""A problem checked against the optimiser that runs it, when the problem is loaded.

:mod:`casadrone.config.problem` checks a problem against the other configs (airframe keys,
referenced files, the search box) and imports neither CasADi nor pymoo. What only the optimiser
knows is checked here, beside it: the plugins import, every objective and constraint names a
registered index (:data:`casadrone.indices.INDICES`, after the plugins have registered theirs),
and the algorithm is one casadrone can run, with settings its class accepts
(:mod:`casadrone.optimise.algorithms`). :func:`load_problem` (``cd.load_problem``, ``casadrone
run``) and :func:`validate_file` (``cd.validate_file``, ``casadrone validate``) run both halves.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from casadrone.airframe import THETA_KEYS as CODESIGN_KEYS  # co-design's variables
from casadrone.airframe import build_airframe, with_theta
from casadrone.codesign.checks import codesign_index_problems, codesign_track_problems
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.codesign import POLISH_INDICES, CodesignProblemConfig
from casadrone.config.io import CONFIG_DIR, ConfigError, load, problem_lines, resolve_config
from casadrone.config.problem import ProblemConfig, read_problem
from casadrone.config.track import TrackConfig
from casadrone.config.validation import check_config_file
from casadrone.indices import INDICES, limit_index_names
from casadrone.limit.lap import LimitLapOptions, check_inputs, frame_clearance_m
from casadrone.optimise.algorithms import ALGORITHM_NAMES, REFUSED, settings_problems
from casadrone.rundir.plugins import import_plugin
from casadrone.simulate import INTEGRATORS


def problem_problems(problem: ProblemConfig) -> list[tuple[str, str]]:
    """What keeps the optimiser from running ``problem``, as (dotted key, message) pairs."""
    found: list[tuple[str, str]] = []
    for i, plugin in enumerate(problem.plugins):
        try:
            import_plugin(plugin)
        except Exception as exc:  # noqa: BLE001 - any import failure is a config problem
            found.append((f"plugins.{i}", f"cannot import '{plugin}': {exc}"))
    if problem.test_problem is None:
        found += _name_problems("integrator", problem.integrator, INTEGRATORS)
        for group in ("objectives", "constraints"):
            for i, o in enumerate(getattr(problem, group)):
                if o.index not in INDICES:
                    close = difflib.get_close_matches(o.index, list(INDICES), 1)
                    hint = f"did you mean '{close[0]}'? " if close else ""
                    found.append((f"{group}.{i}.index", f"unknown index '{o.index}' ({hint}"
                                  f"known: {', '.join(INDICES)})"))
    if problem.test_problem is None and not found:
        found += _limit_problems(problem)
    return found + _algorithm_problems(problem)


def _name_problems(key: str, name: str, registry: Iterable[str]) -> list[tuple[str, str]]:
    """``name`` not in ``registry``, as a (key, message) pair with the closest name."""
    known = list(registry)
    if name in known:
        return []
    close = difflib.get_close_matches(name, known, 1)
    hint = f"did you mean '{close[0]}'? " if close else ""
    return [(key, f"unknown {key} '{name}' ({hint}known: {', '.join(known)})")]


def _limit_problems(problem: ProblemConfig) -> list[tuple[str, str]]:
    """What makes a limit-lap index impossible before any solve (a gate narrower than twice the
    limit lap's clearance, :func:`casadrone.limit.lap.check_inputs`): a problem optimising or
    constraining one could only fill its budget with failed evaluations, so it is refused at
    load, like a bad value."""
    names = [o.index for o in problem.objectives] + [c.index for c in problem.constraints]
    used = limit_index_names(names)
    if not used:
        return []

    try:
        track = load(TrackConfig, problem.track or CONFIG_DIR / "tracks" / "paper-rectangle.yaml")
    except ConfigError:
        return []  # the track's own problems are reported with it
    why = check_inputs(track, LimitLapOptions(), smallest_frame_clearance(problem))
    found = [("track", f"{why}: no limit lap can pass it, so {', '.join(used)} cannot be "
              "computed for any candidate")] if why else []
    return found


def smallest_frame_clearance(problem: ProblemConfig) -> float | None:
    """The smallest gate clearance a candidate of ``problem`` needs (the limit lap shrinks each
    gate by the frame's own size, :func:`casadrone.limit.lap.frame_clearance_m`), over the
    search box's centre and corners (a frame grows with its arms, so its smallest is at a
    corner); None when no such point is a valid airframe."""
    import itertools

    if problem.airframe is None:
        return None
    template = load_airframe(problem.airframe)
    if problem.fixed:
        template = AirframeConfig.model_validate({**template.model_dump(), **problem.fixed})
    names = [v.name for v in problem.variables]
    points = [{v.name: (v.lower + v.upper) / 2 for v in problem.variables}]
    if len(names) <= 10:
        points += [dict(zip(names, c, strict=True)) for c in
                   itertools.product(*[(v.lower, v.upper) for v in problem.variables])]
    clearances = []
    for point in points:
        try:
            cfg = with_theta(template, point)
            clearances.append(frame_clearance_m(build_airframe(cfg), cfg.prop_diameter_mm / 1000))
        except (ConfigError, ValueError):
            continue
    return min(clearances) if clearances else None


def _algorithm_problems(problem: ProblemConfig) -> list[tuple[str, str]]:
    """The algorithm section against the algorithm's own parameters (and the objectives)."""
    a = problem.algorithm
    key = a.name.strip().lower()
    if key not in ALGORITHM_NAMES:
        return [("algorithm.name", m) for _, m in _name_problems("algorithm", a.name,
                                                                 ALGORITHM_NAMES)]
    if key in REFUSED:
        return [("algorithm.name", f"{key} cannot run a casadrone problem: {REFUSED[key]}")]
    test = problem.test_problem
    if test is not None:
        n_obj = test.n_obj if test.name == "dtlz2" else 2
    elif problem.objectives:
        n_obj = len(problem.objectives)
    else:
        return []
    found = [(f"algorithm.settings.{k}" if not k.startswith("(") else "algorithm.settings", m)
             for k, m in settings_problems(key, a.settings, a.population, n_obj)]
    if "polish" in a.settings and not found:
        found += polish_problems(problem)
    return found


def polish_problems(problem: ProblemConfig) -> list[tuple[str, str]]:
    """Why the co-design NLP cannot polish ``problem``'s front members
    (``algorithm.settings.polish``, :mod:`casadrone.codesign.polish`): an objective or constraint
    on an index it cannot hold (a closed-loop J1–J5, Jp), no limit lap to minimise, a variable
    it does not vary. Each under the polish key."""
    key = "algorithm.settings.polish"
    if problem.test_problem is not None:
        return [(key, "polish needs an airframe problem with the limit lap, not a test problem")]
    found = []
    groups: tuple[tuple[str, list[Any]], ...] = (("objectives", list(problem.objectives)),
                                                 ("constraints", list(problem.constraints)))
    for group, items in groups:
        for i, o in enumerate(items):
            if o.index not in POLISH_INDICES:
                kind = ("a closed-loop index (it needs a simulated lap with the controller)"
                        if o.index in INDICES and INDICES[o.index].source == "lap" else
                        "not an index the co-design NLP can hold")
                found.append((key, f"{group}.{i}.index '{o.index}' is {kind}; the co-design "
                              f"NLP polishes {' and '.join(POLISH_INDICES)} only"))
            elif group == "objectives" and (o.sense or "min") != "min":
                found.append((key, f"{group}.{i}: polish minimises {o.index}, not its maximum"))
    if "J3_limit" not in [o.index for o in problem.objectives]:
        found.append((key, "polish minimises the limit lap: J3_limit must be an objective"))
    bad = [v.name for v in problem.variables if v.name not in CODESIGN_KEYS]
    if bad:
        found.append((key, f"the co-design NLP varies {', '.join(CODESIGN_KEYS)}; not "
                      f"{', '.join(bad)}"))
    # both propulsion models are posed, effort included (casadrone.model.rotor_thrusts)
    return found


def check_problem(problem: ProblemConfig, source: str | Path,
                  overrides: list[str] | None = None) -> ProblemConfig:
    """``problem`` when the optimiser can run it; else ConfigError, one ``FILE: key: message``
    line per problem (``source`` names the file). A co-design problem is checked against what
    the co-design NLP can hold (:func:`casadrone.codesign.checks.codesign_index_problems`)."""
    if isinstance(problem, CodesignProblemConfig):
        found = codesign_index_problems(problem.objectives, problem.constraints)
        found = found or codesign_track_problems(problem)
    else:
        found = problem_problems(problem)
    if found:
        raise ConfigError(problem_lines(found, str(source), overrides))
    return problem


def load_problem(path: str | Path, overrides: list[str] | None = None) -> ProblemConfig:
    """Load a problem YAML (a path, or a shipped problem's name: ``quick``) with
    ``dotted.key=value`` overrides (``algorithm.generations=20``), checked against the configs
    and the optimiser; ConfigError lists every problem."""
    problem = read_problem(path, overrides)
    return check_problem(problem, resolve_config(path, "problems"), overrides)


def validate_file(path: str | Path) -> BaseModel:
    """Validate any known config file and the files it references
    (:func:`casadrone.config.validation.check_config_file`), and a problem also against the
    optimiser; ConfigError lists every problem."""
    config = check_config_file(path)

    if isinstance(config, CodesignProblemConfig):  # checked against what co-design can hold
        found = codesign_index_problems(config.objectives, config.constraints)
        if found:
            raise ConfigError(problem_lines(found, str(path)))
    elif isinstance(config, ProblemConfig):
        check_problem(config, path)
    return config
