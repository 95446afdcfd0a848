"""The build problem's loader: the schema (:mod:`casadrone.config.build`), the co-design
problem's own checks (:mod:`casadrone.codesign.checks`), and what only a build needs, each
refused as ``FILE: key: message`` before any solve: a part name the catalogue does not have, a
template that is not of the ``propeller`` kind, a season of tracks (a build races one track),
a selection with no combination at all.
"""

from __future__ import annotations

from pathlib import Path

from casadrone.build.combos import combinations
from casadrone.codesign.checks import (
    codesign_index_problems,
    codesign_track_problems,
    template_of,
)
from casadrone.config.build import BuildProblemConfig
from casadrone.config.io import ConfigError, load, problem_lines, resolve_config
from casadrone.config.parts import load_parts
from casadrone.parts import Catalogue

#: The build's selection keys and the kind of part each names.
SELECTION = {"propellers": "propeller", "motors": "motor", "packs": "pack"}


def part_problems(problem: BuildProblemConfig, catalogue: Catalogue) -> list[tuple[str, str]]:
    """Each name of ``build.propellers``/``motors``/``packs`` the catalogue lacks, as
    (key, message)."""
    found = []
    for key, kind in SELECTION.items():
        names = getattr(problem.build, key)
        if names == "all":
            continue
        for i, name in enumerate(names):
            try:
                catalogue.get(name, kind)
            except KeyError as exc:
                found.append((f"build.{key}.{i}", str(exc.args[0])))
    return found


def build_problems(problem: BuildProblemConfig, catalogue: Catalogue) -> list[tuple[str, str]]:
    """What a build cannot pose, as (key, message) (module docstring)."""
    found = part_problems(problem, catalogue)
    if problem.codesign.tracks:
        found.append(("codesign.tracks", "a build races one track: give track"))
    try:
        template = template_of(problem)
    except ConfigError:
        return found  # the airframe's own problems are reported with it
    if template.propulsion.model != "propeller":
        found.append(("airframe", f"a build needs a template of the propeller kind (its parts "
                      f"are propellers, motors and packs), not {template.propulsion.model!r}"))
    if not found and not combinations(catalogue, problem.build):
        found.append(("build", "the selection names no combination (a kind with no part)"))
    return found


def load_build_problem(path: str | Path, overrides: list[str] | None = None
                       ) -> BuildProblemConfig:
    """Load a build problem (a path, or a shipped problem's name), with overrides; ConfigError
    with one ``FILE: key: message`` line per problem."""
    source = resolve_config(path, "problems")
    problem = load(BuildProblemConfig, source, overrides)
    catalogue = load_parts(problem.build.parts_file)
    found = codesign_index_problems(problem.objectives, problem.constraints)
    found = found or codesign_track_problems(problem) or build_problems(problem, catalogue)
    if found:
        raise ConfigError(problem_lines(found, str(source), overrides))
    return problem
