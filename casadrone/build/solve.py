"""One combination of a build: its frame geometry co-designed (:func:`casadrone.codesign.
codesign`, the problem's ``variables`` and ``codesign`` settings, the combination's parts), then
the co-designed frame raced over the build's laps with its pack (:func:`casadrone.limit.race.
race`): the race time, and what the race leaves of the pack.

Every function here is picklable and runs in a worker process as in this one: a combination
that fails (no co-design start converged, a race the pack cannot fly) is a result with its
reason, never an exception.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from casadrone.airframe import build_airframe, with_theta
from casadrone.build.combos import Combination, hover_of, start_airframe
from casadrone.codesign.checks import codesign_lap_options, gate_clearance, template_of
from casadrone.config.airframe import AirframeConfig
from casadrone.config.build import BuildProblemConfig
from casadrone.config.codesign import CodesignProblemConfig
from casadrone.config.io import ConfigError, load
from casadrone.config.track import TrackConfig
from casadrone.limit.race import account_of, race, with_open_circuit_voltage
from casadrone.limit.result import LapSeeds, LimitLapOptions
from casadrone.propulsion.electric import pack_of
from casadrone.results import AsDict

#: What became of a combination: refused before any solve, pruned by its bound, co-designed and
#: raced (feasible or not: ``feasible``), or failed (no co-design start converged).
Outcome = Literal["refused", "pruned", "raced", "failed"]


@dataclass(frozen=True)
class BuildResult(AsDict):
    """A combination's result (NaN where the stage that gives a figure was not reached)."""

    combination: Combination
    outcome: Outcome
    reason: str = ""
    bound_s: float = math.nan
    race_s: float = math.nan
    lap_s: float = math.nan  # the co-designed lap (the track as given; a dominant frame's:
    # its race's first pass, at the full pack's voltage)
    laps: int = 0
    feasible: bool = False  # the pack flies the race within its limits
    theta: dict[str, float] = field(default_factory=dict)
    mass_kg: float = math.nan
    thrust_to_weight: float = math.nan
    hover_throttle: float = math.nan
    hover_pack_current_a: float = math.nan
    peak_pack_current_a: float = math.nan
    peak_motor_current_a: float = math.nan
    pack_current_margin_a: float = math.nan
    motor_current_margin_a: float = math.nan
    energy_used_wh: float = math.nan
    energy_left_wh: float = math.nan
    end_soc: float = math.nan
    #: the state of charge whose open-circuit voltage the race's last pass flew (its end's
    #: within casadrone.limit.race.SOC_TOL): a race of a nearby frame flown at the same
    #: voltage is comparable with this one to the solver's tolerance
    flown_soc: float = math.nan
    #: (pack, motor) factors on the current limits the race was solved under (None: the
    #: parts' own; :func:`current_derate`); its account is against the parts' own
    derate: tuple[float, float] | None = None
    cpu_s: float = 0.0
    #: how the frame's geometry was found: co-designed, the box's dominant frame raced without
    #: a co-design (:mod:`casadrone.build.dominance`), or that frame moved by its race's
    #: gradient (:mod:`casadrone.build.descent`)
    geometry_by: Literal["co-design", "dominance", "descent"] = "co-design"
    #: dT/dθ of a dominant frame's race (s per unit of each geometry key, by the envelope
    #: theorem: casadrone.limit.check.theta_sensitivities); empty for a co-designed frame
    race_gradient: dict[str, float] = field(default_factory=dict)
    point: Any = None  # casadrone.codesign.driver.CodesignPoint, for the certificate
    certificate: Any = None  # casadrone.codesign.certificate.Certificate of a ranked build
    race_lap: Any = None  # casadrone.limit.result.LimitLap of the race: a neighbour's seed

    _omit = ("point", "certificate", "race_lap")
    _properties = ("label", "bound_ratio", "certified", "certificate_report")

    @property
    def label(self) -> str:
        return self.combination.label

    @property
    def bound_ratio(self) -> float:
        """The bound over the race time: at most 1 where the bound holds (NaN unraced)."""
        return self.bound_s / self.race_s if self.race_s > 0 else math.nan

    @property
    def certificate_report(self) -> dict[str, Any] | None:
        """The certificate as ``casadrone codesign --json`` gives it (None: not certified)."""
        return None if self.certificate is None else self.certificate.as_dict()

    @property
    def certified(self) -> bool | None:
        """Whether the co-design point's certificate passed (None: not certified)."""
        return None if self.certificate is None else bool(self.certificate.passed)


def geometry_box(problem: CodesignProblemConfig) -> tuple[tuple[str, ...], np.ndarray,
                                                          np.ndarray]:
    """(keys, lower, upper) of the problem's geometry variables."""
    return (tuple(v.name for v in problem.variables),
            np.array([v.lower for v in problem.variables], float),
            np.array([v.upper for v in problem.variables], float))


def race_track(problem: CodesignProblemConfig, laps: int | None) -> TrackConfig:
    """The problem's track flown ``laps`` times (its own laps when None)."""
    assert problem.track is not None  # a build names one track (BuildProblemConfig)
    track = load(TrackConfig, problem.track)
    return track if laps is None else track.model_copy(update={"laps": laps})


def lap_options(problem: CodesignProblemConfig, template: AirframeConfig) -> LimitLapOptions:
    """The limit lap as co-design poses it for ``template`` (a combination's airframe;
    :func:`casadrone.codesign.driver.prepare`): the problem's grid and lap starts, one gate
    clearance for every frame of the box, no point-mass reference, no grid refinement; where
    the starts are the shipped lap alone, the point-mass start where it gives none (a race of
    ``--laps`` N on a track whose shipped lap is one lap: no lap of N is shipped)."""
    keys, lower, upper = geometry_box(problem)
    options = codesign_lap_options(problem, template, gate_clearance(template, lower, upper,
                                                                     keys))
    if tuple(options.starts) == ("library",) and not options.fallback_starts:
        options = replace(options, fallback_starts=("point-mass",))
    return options


def codesign_problem(problem: BuildProblemConfig, cfg: AirframeConfig) -> CodesignProblemConfig:
    """The co-design problem of one combination: the build's problem with the combination's
    airframe as its ``fixed`` values (every key of it but the decision variables, which start
    at the template's values)."""
    data = problem.model_dump(exclude={"build"})
    keys = {v.name for v in problem.variables}
    data["fixed"] = {k: v for k, v in cfg.model_dump(exclude_none=True).items() if k not in keys}
    data["name"] = f"{problem.name}:{cfg.name}"
    return CodesignProblemConfig.model_validate(data)


def combination_start(problem: BuildProblemConfig, combo: Combination) -> AirframeConfig:
    """The combination's airframe the co-design starts from (the template's geometry, or the
    box's largest corner where its propellers overlap there)."""
    keys, lower, upper = geometry_box(problem)
    return start_airframe(template_of(problem), combo, problem.build, keys, lower, upper)


def solve_combination(problem: BuildProblemConfig, combo: Combination, laps: int | None,
                      bound_s: float = math.nan, seeds: LapSeeds = LapSeeds(),
                      start: dict[str, float] | None = None) -> BuildResult:
    """Co-design ``combo``'s frame and race it (module docstring); the CPU of this process.
    With ``seeds`` and ``start`` (a neighbouring combination's race and co-designed geometry),
    the co-design starts from that geometry, its first lap and the race's from that race, and
    from the problem's starts only where they give no verified lap (and the combination is
    solved alone where the co-design so started finds no frame); without, it is solved alone."""
    from casadrone.codesign.design import codesign
    c0 = time.process_time()
    base = BuildResult(combo, "failed", bound_s=bound_s)
    try:
        cfg = combination_start(problem, combo)
        result = codesign(codesign_problem(problem, cfg), certify=False, seeds=seeds,
                          start=start)
        if result.best is None and (seeds.warm_starts or start):
            seeds = LapSeeds()
            result = codesign(codesign_problem(problem, cfg), certify=False)
    except ConfigError as exc:
        return replace(base, reason=exc.lines[0], cpu_s=time.process_time() - c0)
    if result.best is None:
        return replace(base, reason=result.reason, cpu_s=time.process_time() - c0)
    best = result.best
    # the race's first pass is the co-design's lap at its θ (the same NLP, θ fixed): from that
    # point alone (a few iterations), the problem's starts only where it gives no verified lap;
    # the neighbour's race where the co-design returned no lap
    out = raced(problem, cfg, dict(best.theta), laps, LapSeeds(
        warm_starts=result.laps or seeds.warm_starts),
        replace(base, lap_s=best.objective, mass_kg=best.mass_kg, point=best))
    return replace(out, cpu_s=time.process_time() - c0)


def derated(cfg: AirframeConfig, pack: float, motor: float) -> AirframeConfig:
    """``cfg`` with its pack's C rating and its motor's current limit scaled by ``pack`` and
    ``motor`` (factors ≤ 1): the limits a race is solved under where its re-simulation broke
    the parts' own between the solve's nodes."""
    section = cfg.propulsion
    assert section.battery is not None and section.motor is not None
    battery = section.battery if section.battery.c_rating is None else \
        section.battery.model_copy(update={"c_rating": section.battery.c_rating * pack})
    motor_cfg = section.motor if section.motor.max_current_a is None else \
        section.motor.model_copy(update={"max_current_a": section.motor.max_current_a * motor})
    return cfg.model_copy(update={"propulsion": section.model_copy(
        update={"battery": battery, "motor": motor_cfg})})


#: How much a derate lowers a limit its race broke, in units of the excess: the excess itself,
#: the least that can clear it where the overshoot between the nodes scales with the limit
#: (a race still over it is derated again, :data:`MAX_DERATES`). Each tenth of a percent of
#: current costs the race about as much time: build-small's DA4022 + 2550 KV + 4S 1300 mAh,
#: 0.146 % over its motor's limit at its dominant frame raced alone, races 4.3929 s lowered
#: by 1 × that, 4.3926 s by 1.25 ×, 4.4008 s by 2 ×, all flown; co-designed alone 4.3954 s.
DERATE_OVER = 1.0
#: Most derated races of one combination (each from the excess the one before still left).
MAX_DERATES = 3


def current_derate(r: BuildResult, most: float = 0.05) -> tuple[float, float] | None:
    """(pack, motor) factors that lower each current limit a race's re-simulation broke by
    :data:`DERATE_OVER` times what it broke it by (1 for a limit it kept), on top of the
    race's own derate where it was raced derated already (its account is against the parts'
    own limits: the excess left); None where the race broke none, ran the pack out, or broke
    one by more than ``most`` of it (not a matter of the solve's nodes:
    :data:`casadrone.limit.nlp.CURRENT_MARGIN` is 1 %)."""
    if r.race_lap is None or r.feasible or not r.end_soc > 0:
        return None
    excess = []
    for peak, margin in ((r.peak_pack_current_a, r.pack_current_margin_a),
                         (r.peak_motor_current_a, r.motor_current_margin_a)):
        limit = peak + margin
        excess.append(-margin / limit if math.isfinite(margin) and limit > 0 and margin < 0
                      else 0.0)
    if all(e == 0.0 for e in excess) or max(excess) > most:
        return None
    before = r.derate or (1.0, 1.0)
    pack, motor = (b * (1.0 - DERATE_OVER * e) for b, e in zip(before, excess, strict=True))
    return pack, motor


def race_dominant(problem: BuildProblemConfig, combo: Combination, laps: int | None,
                  theta: dict[str, float], bound_s: float = math.nan,
                  seeds: LapSeeds = LapSeeds(), soc: float | None = None,
                  derate: tuple[float, float] | None = None) -> BuildResult:
    """Race ``combo`` at ``theta``, the dominant frame of its box
    (:func:`casadrone.build.dominance.dominant_theta`), without a co-design: its race is the
    co-design's answer where the dominance holds. ``seeds``: a neighbouring race to start from
    (the problem's starts where it gives no verified lap). The lap (``lap_s``) is the race's
    first pass, at the full pack's voltage: the co-design's lap of that frame (at ``soc``'s
    voltage where given: the neighbour's end state of charge, :func:`casadrone.limit.race.
    race`'s first pass); ``derate``: the race's pack and motor current limits scaled by
    these factors for the solve, its account against the parts' own (:func:`raced`)."""
    c0 = time.process_time()
    base = BuildResult(combo, "failed", bound_s=bound_s, geometry_by="dominance",
                       derate=derate)
    try:
        cfg = combination_start(problem, combo)
        out = raced(problem, cfg, theta, laps, seeds, base, gradient=True, soc=soc,
                    derate=derate)
    except ConfigError as exc:
        return replace(base, reason=exc.lines[0], cpu_s=time.process_time() - c0)
    return replace(out, cpu_s=time.process_time() - c0)


def raced(problem: BuildProblemConfig, cfg: AirframeConfig, theta: dict[str, float],
          laps: int | None, seeds: LapSeeds, base: BuildResult,
          gradient: bool = False, soc: float | None = None,
          derate: tuple[float, float] | None = None) -> BuildResult:
    """``base`` with the race of ``cfg`` at ``theta`` over the build's laps (its ``lap_s``,
    where NaN, the race's first pass), the frame's hover and the pack's account; with
    ``gradient``, the race's dT/dθ over the box's keys (``race_gradient``); ``soc``: the state
    of charge the race's first pass flies (None: the full pack); ``derate``: (pack, motor)
    factors on the current limits the race is solved under (:func:`derated`), its account
    then made against the parts' own limits."""
    frame = with_theta(cfg, theta)
    track = race_track(problem, laps)
    run = race(derated(frame, *derate) if derate else frame, track,
               replace(lap_options(problem, cfg), sensitivities=gradient), seeds=seeds, soc=soc)
    if derate and run.lap.completed and run.passes:
        at = with_open_circuit_voltage(frame, run.passes[-1].open_circuit_voltage_v)
        pack = pack_of(frame.propulsion.battery)
        assert pack is not None  # a combination's pack has a capacity
        run = replace(run, energy=account_of(at, run.lap, pack))
    keys = geometry_box(problem)[0]
    hover = hover_of(frame)
    lap_s = base.lap_s if math.isfinite(base.lap_s) or not run.passes else \
        run.passes[0].race_time_s
    out = replace(base, outcome="raced", laps=track.laps, theta=dict(theta), lap_s=lap_s,
                  race_gradient={k: float(v) for k, v in run.lap.sensitivities.items()
                                 if k in keys},
                  mass_kg=base.mass_kg if math.isfinite(base.mass_kg) else
                  build_airframe(frame).mass,
                  thrust_to_weight=hover.thrust_to_weight, hover_throttle=hover.throttle,
                  hover_pack_current_a=hover.pack_current_a)
    if not run.lap.completed:
        return replace(out, reason=f"race: {run.reason}")
    e = run.energy
    assert e is not None  # a combination's pack has a capacity (combination_airframe)
    flown = run.passes[-1].soc_flown if run.passes else math.nan
    return replace(out, race_s=run.lap.lap_time_s, feasible=run.feasible, race_lap=run.lap,
                   flown_soc=flown,
                   reason=run.reason, peak_pack_current_a=e.peak_pack_current_a,
                   peak_motor_current_a=e.peak_motor_current_a,
                   pack_current_margin_a=e.pack_current_margin_a,
                   motor_current_margin_a=e.motor_current_margin_a,
                   energy_used_wh=e.energy_used_wh, energy_left_wh=e.energy_left_wh,
                   end_soc=e.end_soc)
