"""The checks of a co-design problem that need the index registry, and its loader.

The schema is :class:`casadrone.config.codesign.CodesignProblemConfig` (light, with every other
schema); what co-design can optimise is checked here: ``J3_limit`` and at most one front measure
(:data:`casadrone.config.codesign.FRONT_MEASURES`); a closed-loop index is refused by name.
"""

from __future__ import annotations

from pathlib import Path

from casadrone.config.codesign import FRONT_MEASURES, LAP_INDEX, CodesignProblemConfig
from casadrone.config.io import ConfigError, load, problem_lines, resolve_config


def codesign_index_problems(objectives, constraints) -> list[tuple[str, str]]:
    """Objectives and constraints the co-design NLP cannot hold, as (key, message)."""
    from casadrone.indices import INDICES

    found = []
    for group, items in (("objectives", objectives), ("constraints", constraints)):
        for i, o in enumerate(items):
            if o.index in FRONT_MEASURES and group == "objectives":
                continue
            if o.index == LAP_INDEX and group == "objectives":
                continue
            kind = ("a closed-loop index (it needs a simulated lap with the controller)"
                    if o.index in INDICES and INDICES[o.index].source == "lap" else
                    "not an index the co-design NLP can hold")
            found.append((f"{group}.{i}.index", f"'{o.index}' is {kind}; co-design optimises "
                          f"{LAP_INDEX} against {', '.join(FRONT_MEASURES)}"))
    names = [o.index for o in objectives]
    if names and LAP_INDEX not in names:
        found.append(("objectives", f"co-design needs {LAP_INDEX} among the objectives"))
    if len([n for n in names if n in FRONT_MEASURES]) > 1:
        found.append(("objectives", "a design front takes one measure beside the lap"))
    return found


def load_codesign_problem(path: str | Path, overrides: list[str] | None = None
                          ) -> CodesignProblemConfig:
    """Load a co-design problem (a path, or a shipped problem's name), with overrides."""
    source = resolve_config(path, "problems")
    problem = load(CodesignProblemConfig, source, overrides)
    found = codesign_index_problems(problem.objectives, problem.constraints)
    if found:
        raise ConfigError(problem_lines(found, str(source), overrides))
    return problem
