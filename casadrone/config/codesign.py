"""The co-design problem file (``problems/codesign-*.yaml``): an optimisation problem whose
decision variables become variables of the limit-lap NLP (:mod:`casadrone.codesign`).

A problem file with a ``codesign:`` section; every other key is a problem's
(:class:`casadrone.config.problem.ProblemConfig`), so an ordinary problem (``limit-lap``) can be
handed to ``casadrone codesign`` too. Objectives: ``J3_limit`` (the limit lap, on one track or
combined over ``codesign.tracks``) and the measures the NLP holds as ε-constraints for a design
front (:data:`FRONT_MEASURES`); a closed-loop index (J1–J5, Jp) is refused by name when the
problem is loaded for co-design (:func:`casadrone.codesign.checks.load_codesign_problem`, beside
the index registry, as :mod:`casadrone.optimise.checks` does for the optimiser).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

from pydantic import Field, model_validator

from casadrone.config.io import Problems, Schema
from casadrone.config.limitlap import LimitLapConfig, Start
from casadrone.config.problem import ProblemConfig

#: Front objectives the co-design NLP holds as ε-constraints, with their units and why.
FRONT_MEASURES = {
    "mass_kg": "total mass (kg) from the components mass model: what the frame weighs",
    "span_m": "tip-to-tip span (m): the longer rotor diagonal plus one prop diameter, the size "
              "class a frame races in and the gap it fits through",
    "effort": "the limit lap's effort, the integral of the sum of T_i^1.5 over the lap "
              "(N^1.5 s): the rotors' ideal induced energy by momentum theory times "
              "sqrt(2 rho A) (casadrone.codesign.nlp.effort)",
}
#: The limit lap's cold starts (declared once, :data:`casadrone.config.limitlap.Start`).
LapStart = Start
#: The template's lap from these cold starts unless a problem names others
#: (``limit_lap.starts``), and where those give no verified lap: co-design's default, not the
#: limit lap's fast-path two (coarse-grid, fine-grid). Not the fine-grid start:
#: with it as well, the certificate's cold re-solve of the short-track frame
#: (tests/integration/test_codesign.py) found a lap 0.86 % faster than the co-design point
#: (0.7849 against 0.7918 s): co-design's NLP stops in a slower local optimum there.
DEFAULT_LAP_STARTS: tuple[LapStart, ...] = ("closed-loop", "point-mass", "coarse-grid")
#: The limit lap's own index (the co-design objective).
LAP_INDEX = "J3_limit"
#: The optimiser's objectives a polish (``algorithm.settings.polish``) can hold: the limit lap,
#: and the front measures that are registered indices of the evaluation chain (mass and span are
#: co-design measures only).
POLISH_INDICES = (LAP_INDEX, "effort")
#: Keys of ``codesign:`` that moved to the problem's ``limit_lap:`` section (one declaration of
#: the limit lap's settings, :class:`casadrone.config.limitlap.LimitLapConfig`), and where to.
MOVED_KEYS = {"intervals": "limit_lap.intervals", "lap_starts": "limit_lap.starts"}
#: The limit lap's settings the co-design NLP poses its laps with and cannot change, each with
#: the values it takes and why. Co-design builds one NLP of the limit lap's transcription around
#: θ (:mod:`casadrone.codesign.nlp`) with its θ-derivative blocks compiled for rk4 steps
#: (:mod:`casadrone.codesign.blocks`), solves it with IPOPT, refines its own grid
#: (:mod:`casadrone.codesign.design`) and checks its point with its own certificate
#: (:mod:`casadrone.codesign.certificate`, the whole lap re-simulated).
CODESIGN_LAP_FIXED: dict[str, tuple[tuple[Any, ...], str]] = {
    "search": (("fast",), "co-design checks its point with its own certificate"),
    "attitude": (("euler",), "co-design flies euler only"),
    "tilt": (("axes",), "co-design limits the tilt per axis (axes) only"),
    "solver": ((None, "ipopt"), "co-design solves its one NLP with ipopt"),
    "grid_rounds": ((None, 0), "co-design refines its own grid instead"),
    "rotor_step": (("rk4",), "co-design's θ-derivative blocks step the rotors with rk4"),
    "substeps": ((3,), "co-design's θ-derivative blocks take 3 steps per interval"),
}


def codesign_lap_problems(lap: LimitLapConfig) -> list[tuple[str, str]]:
    """The ``limit_lap:`` settings co-design cannot honour (:data:`CODESIGN_LAP_FIXED`), as
    (key, message); co-design reads ``intervals``, ``starts`` and ``resimulation``."""
    return [(f"limit_lap.{key}", f"{why} (give {' or '.join(give)} or leave it out)")
            for key, (allowed, why) in CODESIGN_LAP_FIXED.items()
            if getattr(lap, key) not in allowed
            for give in [[str(a) for a in allowed if a is not None]]]


class TrackWeight(Schema):
    """One track of a season and its weight in the combined objective."""

    track: Path = Field(description="track YAML, or a shipped track's name")
    weight: float = Field(1.0, gt=0, le=1e6, description="weight of this track's lap")


class FrontConfig(Schema):
    """A design front by ε-continuation: the lap against one measure."""

    points: int = Field(15, ge=2, le=200, description="points of the front")
    lowest: float = Field(0.5, gt=0, lt=1, description="the sweep ends at this fraction of "
                          "the fastest frame's measure (geometric steps)")


class PolishSettings(Schema):
    """ev-MOGA's polish (``algorithm.settings.polish``): after the last generation, front members
    improved by the co-design NLP with their other objectives as ε-constraints
    (:mod:`casadrone.codesign.polish`)."""

    members: int = Field(5, ge=1, le=1000, description="front members polished, spread evenly "
                         "along the lap (both ends included; all when the front is smaller); "
                         "each is one co-design solve (11-21 s of CPU on the paper track, "
                         "benchmarks/RESULTS-codesign.md)")


class CodesignSettings(Schema):
    """How the co-design NLP is posed and started."""

    tracks: dict[str, TrackWeight] = Field(
        default_factory=dict, description="a season: tracks by label, each with a weight "
        "(empty: the problem's track alone)")
    combine: Literal["sum", "worst"] = Field(
        "sum", description="sum: Σ weight·lap; worst: the largest weight·lap")
    starts: int = Field(5, ge=0, le=100, description="random feasible frames started from, "
                        "beside the template's own geometry")
    expand: bool = Field(False, description="expand the co-design NLP to CasADi SX before "
                         "solving: a one-off build cost per process for cheaper iterations "
                         "(short test track, 8 intervals: build 12.6 s, solve 1.6 s instead of "
                         "3.5 s CPU, same 35 iterations and optimum)")
    front: FrontConfig = Field(default_factory=FrontConfig,
                               description="the design front (a measure among the objectives)")

    @model_validator(mode="before")
    @classmethod
    def _moved(cls, data: Any) -> Any:
        """Refuse a key that moved to ``limit_lap:`` (:data:`MOVED_KEYS`), naming its place."""
        moved = [(k, f"moved: use {new}") for k, new in MOVED_KEYS.items()
                 if isinstance(data, dict) and k in data]
        if moved:
            raise Problems(moved)
        return data


class CodesignProblemConfig(ProblemConfig):
    """A problem with a ``codesign:`` section (see the module docstring)."""

    codesign: CodesignSettings = Field(default_factory=CodesignSettings,
                                       description="how the co-design NLP is posed and started")
    limit_lap: LimitLapConfig = Field(
        default_factory=LimitLapConfig,
        description="the limit lap's settings co-design reads: intervals (default: the limit "
        "lap's for the airframe's propulsion, 40 paper, 80 propeller) and starts, the cold "
        "starts of the template's lap (the co-design's first start and every other frame's warm "
        "start; the default three where the given ones fail) and of the certificate's cold "
        "fixed-frame re-solve. Co-design's default starts differ from the limit lap's: "
        "closed-loop, point-mass, coarse-grid (with fine-grid as well, the certificate found a "
        "0.86 % faster lap than the co-design point on the short test track: the NLP stops in a "
        "slower local optimum there); which start leads to the best optimum depends on the track "
        "(benchmarks/RESULTS-codesign.md). Every other key is refused unless it is the one "
        "value co-design poses (euler, axes, ipopt, rk4, 3 substeps, lap, fast, no grid rounds)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found = ProblemConfig.problems(v)
        settings = v.get("codesign")
        if settings is not None and not settings.tracks and v.get("track") is None:
            found.append(("track", "give track (or codesign.tracks)"))
        if settings is not None and settings.tracks and v.get("track") is not None:
            found.append(("codesign.tracks", "give track or codesign.tracks, not both"))
        if v.get("limit_lap") is not None:
            found += codesign_lap_problems(v["limit_lap"])
        return found
