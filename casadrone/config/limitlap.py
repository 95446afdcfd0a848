"""The limit lap's settings (docs/concepts/limit-lap.md): every choice the command line
(``casadrone limit-lap … key=value``), a problem file (its ``limit_lap:`` section) and the limit
lap itself (:class:`casadrone.limit.result.LimitLapOptions`, built from this schema by
:func:`casadrone.limit.search.lap_options`) share, each declared once here with its allowed
values, its default and what it means.

The choices' names are the types the limit lap's code is written in (:data:`Solver`,
:data:`Attitude`, ...): this floor comes before the limit lap's, so the limit lap imports them
from here. The measurements behind each default are in the limit lap's option docs
(:class:`casadrone.limit.result.LimitLapOptions`) and in ``benchmarks/``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal, get_args, get_origin

from pydantic import Field

from casadrone.config.io import ConfigError, Schema, apply_overrides, validate_data

#: The starts of the limit lap (:mod:`casadrone.limit.starts`): the cold starts, and
#: ``library``, the shipped best laps of the track (:mod:`casadrone.limit.library`).
Start = Literal["closed-loop", "point-mass", "coarse-grid", "fine-grid", "relaxed-tolerance",
                "library"]
#: The attitude models of the limit lap, and the ways it limits the tilt.
Attitude = Literal["euler", "quaternion"]
TiltLimit = Literal["axes", "cone", "none"]
#: What the re-simulation check flies (LimitLapOptions.resimulation).
Resimulation = Literal["lap", "legs"]
#: NLP solvers of the full model (casadrone.limit.nlp.solve).
Solver = Literal["ipopt", "fatrop"]
#: Steps of the rotor states (LimitLapOptions.rotor_step).
RotorStep = Literal["rk4", "exponential"]
#: The command's searches (casadrone.limit.search.SEARCHES): the fast path and the certificate.
Search = Literal["fast", "certify"]

SOLVERS: tuple[str, ...] = get_args(Solver)
ROTOR_STEPS: tuple[str, ...] = get_args(RotorStep)
STARTS: tuple[str, ...] = get_args(Start)

#: Most intervals per leg. Grid refinement moved SY250's lap by 0.02 % from 40 to 80 intervals
#: (LimitLapOptions.intervals), so 400 is ten times finer than any measured need; the NLP's
#: memory grows in proportion (20 000 intervals reached 5.8 GB and failed to allocate), so 400
#: stays near 0.1 GB.
MAX_INTERVALS = 400
#: Most integration steps per shooting interval: each one adds to the compiled interval
#: blocks (4 exponential steps of the propeller model: an 11 MB Hessian block of C).
MAX_SUBSTEPS = 20
#: At most this many grid-continuation rounds (each about four solves).
MAX_GRID_ROUNDS = 5
#: Grid rounds of ``casadrone limit-lap --certify`` unless ``grid_rounds`` says otherwise
#: (casadrone.limit.search; the fast path runs none): a certificate answers one frame's
#: question, so it pays 1.2-2.9x the CPU (median 1.8x) for the best optimum
#: it can reach. Measured on the five reference frames over the paper, gate and split-S tracks
#: (benchmarks/RESULTS-limitlap-issue19.md, "Grid rounds as the command's default"): 9 of 15
#: laps 0.04-1.19 % faster (never slower: the fastest verified start wins), every frame's paper
#: lap the best known for it, and SY250's the same (3.8795 s) on two VMs whose starts alone had
#: stopped at 3.8800 and 3.8914 s. Rounds stop when one gains less than CERTAIN_REL; none of
#: the calls measured ran a third.
COMMAND_GRID_ROUNDS = 3


class LimitLapConfig(Schema):
    """How a limit lap is searched and checked (every key optional; the defaults are the
    command's fast path). On the command line each key is a ``key=value`` argument beside the
    airframe's (``casadrone limit-lap SY250 solver=fatrop``) or its option (``--solver
    fatrop``); in a problem file, a key of its ``limit_lap:`` section."""

    search: Search = Field(
        "fast", description="fast: one solve from the best lap shipped for the track "
        "(the library start; the coarse-grid and fine-grid starts where none is shipped or it "
        "gives no verified lap), no grid rounds; certify (--certify): solve from every start "
        "and run grid rounds: whether they agree (certainty, spread) and how uncertain the "
        "sensitivities are over the optima found")
    intervals: int | None = Field(
        None, ge=2, le=MAX_INTERVALS, description="time steps of the lap per leg: more is "
        "finer, slower and needs more memory; default 40 with the paper propulsion model, 80 "
        "with propeller (its rotors change speed faster)")
    attitude: Attitude = Field(
        "euler", description="euler (ZYX angles) or quaternion (no singularity: split-S, "
        "loops)")
    tilt: TiltLimit = Field(
        "axes", description="tilt limit at the track's max_tilt_deg: axes (|φ|, |θ| each; "
        "euler only), cone (total tilt) or none")
    solver: Solver | None = Field(
        None, description="optimiser: ipopt (the reference) or fatrop (the same problem, "
        "solved step by step along the lap; ipopt solves again where it fails; not with a "
        "periodic track); default: the search's (ipopt)")
    starts: tuple[Start, ...] | None = Field(
        None, description="the starts solved (closed-loop, point-mass, coarse-grid, "
        "fine-grid, relaxed-tolerance; library: the laps shipped for the track); default: the "
        "search's. An optimisation's "
        "evaluations start warm from the study's references and fall back to closed-loop and "
        "point-mass")
    grid_rounds: int | None = Field(
        None, ge=0, le=MAX_GRID_ROUNDS, description="rounds that solve the lap again on a "
        "coarser and a finer grid to escape a slower local optimum, stopping at the first "
        f"round that gains less than 0.1 %; default 0 on the fast path, {COMMAND_GRID_ROUNDS} "
        "with certify")
    rotor_step: RotorStep = Field(
        "rk4", description="how the rotor speeds are stepped: rk4 (like every other state) or "
        "exponential (their decay followed exactly, which allows coarser time steps; opt-in, "
        "see the propulsion concept page)")
    substeps: int = Field(
        3, ge=1, le=MAX_SUBSTEPS, description="integration steps per shooting interval; a new "
        "combination of steps and rotor step compiles its derivative blocks once per machine "
        "(minutes)")
    resimulation: Resimulation = Field(
        "lap", description="what the re-simulation check flies: lap (the whole lap's commands "
        "open loop from the start) or legs (each leg from the lap's own state at the leg's "
        "start: accepts an accurate lap that drifts open loop)")

    @classmethod
    def problems(cls, v: dict[str, Any]) -> list[tuple[str, str]]:
        found = []
        if v.get("attitude") == "quaternion" and v.get("tilt") == "axes":
            found.append(("tilt", "axes bounds Euler angles: with attitude quaternion use cone "
                                  "or none"))
        if v.get("starts") == ():
            found.append(("starts", "give at least one start (or leave it out: the search's)"))
        return found


def choices(key: str) -> tuple[str, ...]:
    """The values a one-word key of :class:`LimitLapConfig` takes (its Literal's, None aside;
    empty for a number or a list)."""
    annotation = LimitLapConfig.model_fields[key].annotation
    args = (annotation,) if get_origin(annotation) is Literal else get_args(annotation)
    return tuple(v for a in args if get_origin(a) is Literal for v in get_args(a))


def lap_key(override: str) -> bool:
    """Whether a ``key=value`` argument sets a limit-lap key (else it is the airframe's)."""
    return override.partition("=")[0].strip().split(".")[0] in LimitLapConfig.model_fields


def read_limit_lap(given: dict[str, Any], overrides: list[str] | None = None,
                   source: str = "limit-lap") -> LimitLapConfig:
    """The limit lap's settings from ``given`` (the command's options: key → value) and
    ``key=value`` overrides; a bad key or value, or a key given both ways, raises ConfigError
    with one ``SOURCE: key: message`` line each."""
    twice = [o.partition("=")[0].strip() for o in overrides or []
             if o.partition("=")[0].strip() in given]
    if twice:
        raise ConfigError([f"{source}: {key}: given as an option and as {key}=…; give one"
                           for key in twice])
    data = apply_overrides(given, overrides, source)
    return validate_data(LimitLapConfig, data, source, Path.cwd(), overrides)
