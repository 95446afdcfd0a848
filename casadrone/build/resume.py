"""A build's output folder as the record it resumes from.

``casadrone build … --out F`` writes, as each combination's result is known:

- ``F/build.yaml``: the problem as resolved (every key, the overrides applied) and the race's
  laps, written before the first solve; what the folder is a build *of*;
- ``F/combinations.jsonl``: each result as a JSON line (for people and other tools);
- ``F/state/NNN.pkl``: each result whole (its co-design point, for the winners' certificates,
  and its race, the seed of its neighbours), written atomically.

Run again with the same ``--out`` after a stop (a kill, a crash, a lost machine), the build reads
``state/`` back and solves only the combinations it does not hold: a combination is done once
its result is on disk. The folder must hold a build of the *same* problem and laps
(``build.yaml`` equal, key by key), else the command exits 2 naming it: nothing of another
build is mixed in or overwritten.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from casadrone.build.solve import BuildResult
from casadrone.config.build import BuildProblemConfig
from casadrone.rundir.checkpoint import dumps, loads
from casadrone.rundir.store import atomic_write

#: The record of what the folder is a build of.
IDENTITY = "build.yaml"
#: One pickle per result, numbered in the order they were known.
STATE = "state"


def identity(problem: BuildProblemConfig, laps: int | None) -> dict[str, Any]:
    """What a resumed build must share with the folder's: the resolved problem and the laps
    asked for (None: the problem's own)."""
    return {"problem": problem.model_dump(mode="json"), "laps": laps}


def folder_problem(folder: Path, problem: BuildProblemConfig, laps: int | None) -> str | None:
    """Why ``folder`` cannot take this build (None: it can, new, empty or resumable)."""
    if not folder.exists():
        return None
    if not folder.is_dir():
        return "is not a folder"
    if not any(folder.iterdir()):
        return None
    path = folder / IDENTITY
    if not path.is_file():
        return "holds files that are not a build's (must be new, empty or a build to resume)"
    try:
        held = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        return f"{IDENTITY} cannot be read: {exc}"
    if held != identity(problem, laps):
        return (f"holds a build of another problem or race ({IDENTITY} differs); give a new "
                "folder (nothing is overwritten)")
    return None


def begin(folder: Path, problem: BuildProblemConfig, laps: int | None) -> None:
    """Make ``folder`` and write what it is a build of (kept as it is on a resume)."""
    (folder / STATE).mkdir(parents=True, exist_ok=True)
    if not (folder / IDENTITY).is_file():
        atomic_write(folder / IDENTITY, yaml.safe_dump(identity(problem, laps), sort_keys=True))


def held(folder: Path | None) -> tuple[BuildResult, ...]:
    """The results ``folder`` holds, in the order they were first known, each combination's
    latest (a ranked one raced at its dominant frame, then co-designed:
    :func:`casadrone.build.search.confirmed`); none without a folder."""
    if folder is None or not (folder / STATE).is_dir():
        return ()
    latest: dict[str, BuildResult] = {}
    for p in sorted((folder / STATE).glob("*.pkl")):
        result = loads(p.read_bytes())
        latest[result.label] = result  # a key keeps its first place in a dict
    return tuple(latest.values())


def keep(folder: Path, result: BuildResult) -> None:
    """Write ``result`` whole as the next state file (atomically: a stop leaves it or not)."""
    n = len(list((folder / STATE).glob("*.pkl")))
    atomic_write(folder / STATE / f"{n:03d}.pkl", dumps(result))
