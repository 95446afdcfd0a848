"""The checks of a co-design problem that need the index registry, and its loader.

The schema is :class:`casadrone.config.codesign.CodesignProblemConfig` (light, with every other
schema); what co-design can optimise is checked here: ``J3_limit`` and at most one front measure
(:data:`casadrone.config.codesign.FRONT_MEASURES`), each minimised (``sense: max`` is refused:
co-design minimises the lap, and a front lowers its measure); a closed-loop index is refused by
name; a track whose gate no frame of the box can pass (narrower than twice the clearance the NLP
poses every frame with) is refused as ``validate``, ``run`` and ``limit-lap`` refuse it.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from casadrone.airframe import build_airframe, with_theta
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.codesign import (
    DEFAULT_LAP_STARTS,
    FRONT_MEASURES,
    LAP_INDEX,
    CodesignProblemConfig,
)
from casadrone.config.io import ConfigError, load, problem_lines, resolve_config
from casadrone.config.track import TrackConfig

if TYPE_CHECKING:  # the limit lap's options are imported when built (CasADi)
    from casadrone.limit.result import LimitLapOptions


def codesign_index_problems(objectives, constraints) -> list[tuple[str, str]]:
    """Objectives and constraints the co-design NLP cannot hold, as (key, message)."""
    from casadrone.indices import INDICES

    found = []
    for group, items in (("objectives", objectives), ("constraints", constraints)):
        for i, o in enumerate(items):
            if group == "objectives" and o.index in (LAP_INDEX, *FRONT_MEASURES):
                if o.sense == "max":
                    what = ("co-design minimises the limit lap" if o.index == LAP_INDEX else
                            "a design front lowers its measure from the fastest frame's")
                    found.append((f"{group}.{i}.sense", f"'max' cannot be honoured: {what} "
                                  f"({o.index} is minimised; give sense: min or none)"))
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


def template_of(problem: CodesignProblemConfig) -> AirframeConfig:
    """The problem's airframe with its ``fixed:`` values."""
    assert problem.airframe is not None  # the schema requires it
    cfg = load_airframe(problem.airframe)
    if problem.fixed:
        cfg = AirframeConfig.model_validate({**cfg.model_dump(), **problem.fixed})
    return cfg


def gate_clearance(template: AirframeConfig, lower: np.ndarray, upper: np.ndarray,
                   keys: tuple[str, ...]) -> float:
    """The gate clearance (m) every frame of the box is posed with: the largest of the limit
    lap's own clearances (the frame's size, :func:`casadrone.limit.lap.frame_clearance_m`) over
    the box's valid corners, where the farthest rotor is farthest. One clearance for every frame
    keeps the targets independent of θ (they are NLP parameters); the fixed-frame checks use the
    same, so a frame is never compared on a different track."""
    import itertools

    from casadrone.limit.lap import frame_clearance_m

    sizes = []
    for corner in itertools.product(*zip(lower, upper, strict=True)):
        try:
            frame = build_airframe(with_theta(template, dict(zip(keys, corner, strict=True))))
        except ConfigError:
            continue
        sizes.append(frame_clearance_m(frame, template.prop_diameter_mm / 1000))
    return max(sizes, default=frame_clearance_m(build_airframe(template),
                                                template.prop_diameter_mm / 1000))


def codesign_lap_options(problem: CodesignProblemConfig, template: AirframeConfig,
                         gate_clearance_m: float) -> LimitLapOptions:
    """The limit lap's options co-design poses every lap with, from the problem's ``limit_lap:``
    section: its ``intervals`` (default: the limit lap's own grid for the template's propulsion
    kind, :data:`~casadrone.limit.result.DEFAULT_INTERVALS`: a propeller lap on the paper's 40
    intervals misses its re-simulation), its ``resimulation`` (every lap's check and the
    certificate's: the whole lap, or each leg from its own node) and its ``starts`` for the
    template's lap and the certificate's cold re-solve (default: co-design's
    :data:`DEFAULT_LAP_STARTS`); no sensitivities, no point-mass reference unless a start needs
    it (:func:`casadrone.codesign.driver.template_lap`) and no grid refinement inside the limit lap:
    every lap here is on the co-design NLP's grid, which co-design refines itself (design.py).
    Every frame is posed with ``gate_clearance_m`` (:func:`gate_clearance`). The settings
    co-design cannot honour were refused with the problem
    (:func:`casadrone.config.codesign.codesign_lap_problems`)."""
    from casadrone.limit.result import DEFAULT_INTERVALS, LimitLapOptions

    lap = problem.limit_lap
    return LimitLapOptions(intervals=lap.intervals or DEFAULT_INTERVALS[template.propulsion.model],
                           sensitivities=False, starts=lap.starts or DEFAULT_LAP_STARTS,
                           point_mass_reference=False, gate_clearance_m=gate_clearance_m,
                           refinements=0, resimulation=lap.resimulation)


def codesign_track_problems(problem: CodesignProblemConfig) -> list[tuple[str, str]]:
    """Each track no frame of the box can fly, as (key, message): a gate narrower than twice
    the clearance the co-design NLP poses every frame with (the largest over the box's corners,
    :func:`gate_clearance`), or more intervals than a limit lap takes
    (:func:`casadrone.limit.problem.check_inputs`, the check of ``limit-lap``). Found before any
    solve: co-design only learnt it when every start failed ("start frame has no limit lap")."""
    from casadrone.limit.problem import check_inputs

    try:
        template = template_of(problem)
    except ConfigError:
        return []  # the airframe's own problems are reported with it
    keys = tuple(v.name for v in problem.variables)
    lower = np.array([v.lower for v in problem.variables])
    upper = np.array([v.upper for v in problem.variables])
    options = codesign_lap_options(problem, template,
                                   gate_clearance(template, lower, upper, keys))
    tracks: dict[str, Path | None] = {f"codesign.tracks.{k}.track": t.track
                                      for k, t in problem.codesign.tracks.items()}
    tracks = tracks or {"track": problem.track}
    found = []
    for key, path in tracks.items():
        if path is None:
            continue  # the schema requires a track or tracks
        try:
            why = check_inputs(load(TrackConfig, resolve_config(path, "tracks")), options)
        except ConfigError:
            continue  # the track's own problems are reported with it
        if why:
            found.append((key, f"{why}: no limit lap can pass it, so co-design cannot "
                          f"compute {LAP_INDEX} for any frame"))
    return found


def load_codesign_problem(path: str | Path, overrides: list[str] | None = None
                          ) -> CodesignProblemConfig:
    """Load a co-design problem (a path, or a shipped problem's name), with overrides."""
    source = resolve_config(path, "problems")
    problem = load(CodesignProblemConfig, source, overrides)
    found = codesign_index_problems(problem.objectives, problem.constraints)
    found = found or codesign_track_problems(problem)
    if found:
        raise ConfigError(problem_lines(found, str(source), overrides))
    return problem
