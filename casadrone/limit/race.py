"""A race: the track's laps (``laps``) flown from its start at the limit, with the pack's state
of charge integrated through the re-simulated flight (:mod:`casadrone.limit.energy`); refused as
infeasible, naming the pack, when the pack runs out or a current limit breaks.

The race is one limit lap over all its laps (:func:`casadrone.limit.lap.limit_lap` flies the
track's ``laps`` as one flight: the laps are optimised together, not each greedily), with the
pack's open-circuit voltage held at the value of the race's *end* state of charge:

- why the end: the open-circuit voltage falls with the charge, so the end's is the lowest of the
  flight. At a lower voltage the same flight needs the same motor currents (they follow from
  the torques) and more pack current (the same power at a lower voltage), and every rotor speed
  the lap reaches stays reachable at a higher one: the flight solved at the end's voltage can be
  flown by the pack at every moment of the race, and its charge drawn is an over-estimate. The
  lap is a conservative one (an upper bound on the race time of this model);
- how: the race is solved at the start's voltage, re-simulated for its charge, then solved
  again at the voltage of the end state of charge found, until the end state of charge moves by
  less than :data:`SOC_TOL` (a 5-inch race uses a few % of a pack per lap: one or two passes),
  at most :data:`MAX_PASSES` solves, each warm-started from the previous one.

Without an OCV curve the voltage is constant and one pass is the answer. Why not a state of
charge in the NLP: it would make the voltage a state (a new model, new compiled blocks, and a
changed result for every existing frame), while the charge a race uses moves the voltage by
little within the race.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from casadrone.airframe import Airframe, build_airframe
from casadrone.config.airframe import AirframeConfig
from casadrone.config.track import TrackConfig
from casadrone.limit.energy import RaceEnergy, flight_energy, race_energy
from casadrone.limit.lap import design_limit_lap
from casadrone.limit.result import LapSeeds, LimitLap, LimitLapOptions, seeds_alone
from casadrone.pool import Pool
from casadrone.propulsion.electric import Pack, pack_of
from casadrone.results import AsDict

#: The end state of charge is settled when a pass moves it by less than this (a 4S LiPo's
#: open-circuit voltage changes by ~0.06 V per 0.01 of charge mid-curve, 0.4 % of 15 V).
SOC_TOL = 0.01
#: Most solves of one race (the first at the start's voltage).
MAX_PASSES = 3
#: How far (relative) a re-simulated sample's current may exceed its limit: none (the limit
#: lap's rows sit casadrone.limit.nlp.CURRENT_MARGIN below the limits for the re-simulation's
#: excess between and at its nodes).
CURRENT_TOL = 0.0


@dataclass(frozen=True)
class Pass(AsDict):
    """One solve of a race: the state of charge whose voltage it flew, that voltage, the race
    time and the state of charge its re-simulation ends at."""

    soc_flown: float
    open_circuit_voltage_v: float
    race_time_s: float
    end_soc: float


@dataclass(frozen=True)
class Race(AsDict):
    """The race's limit lap and what it leaves of the pack (None without ``capacity_ah``)."""

    lap: LimitLap
    energy: RaceEnergy | None = None
    passes: tuple[Pass, ...] = ()

    _omit = ("lap",)
    _properties = ("feasible", "reason")

    @property
    def feasible(self) -> bool:
        return self.lap.completed and (self.energy is None or self.energy.feasible)

    @property
    def reason(self) -> str:
        """Why the race cannot be flown ("" when it can)."""
        if not self.lap.completed:
            return self.lap.reason
        return "" if self.energy is None else self.energy.reason


def with_open_circuit_voltage(cfg: AirframeConfig, volts: float) -> AirframeConfig:
    """``cfg`` with its pack's open-circuit voltage ``volts`` (V), everything else the same."""
    section = cfg.propulsion
    assert section.battery is not None
    battery = section.battery.model_copy(update={"open_circuit_voltage_v": volts})
    return cfg.model_copy(update={"propulsion": section.model_copy(update={"battery": battery})})


def race(cfg: AirframeConfig, track: TrackConfig,
         options: LimitLapOptions = LimitLapOptions(), frame: Airframe | None = None,
         pool: Pool | None = None, seeds: LapSeeds = LapSeeds(),
         soc: float | None = None) -> Race:
    """The race of ``track.laps`` laps (module docstring); without a pack capacity, the limit
    lap alone (of ``frame``, where ``cfg`` is built already); each lap's independent solves on
    ``pool`` where given. With ``seeds`` (a neighbouring race), the first pass starts from them
    alone and each later one from the pass before alone (:func:`seeded_lap`); without, each
    pass solves its starts, the later ones with the pass before beside them. ``soc``: the
    state of charge whose open-circuit voltage the first pass flies (a neighbouring race's
    end, where it is known: one pass instead of two where the race ends within
    :data:`SOC_TOL` of it, the same test as every later pass's); the pack's start where None
    or where the pack has no OCV curve."""
    pack = pack_of(cfg.propulsion.battery)
    if pack is None:
        return Race(seeded_lap(cfg, track, options, seeds, frame, pool))
    passes: list[Pass] = []
    lap, account = None, None
    guess = soc is not None and pack.ocv_curve is not None and math.isfinite(soc)
    # the first pass: at the guess, else the section's own voltage
    soc = min(max(soc, 0.0), pack.start_soc) if guess and soc is not None else pack.start_soc
    volts = float(pack.ocv(soc)) if guess else pack.open_circuit_voltage_v
    for _ in range(MAX_PASSES):
        flown = with_open_circuit_voltage(cfg, volts)
        if lap is None:
            lap = seeded_lap(flown, track, options, seeds, None, pool)
        elif seeds.warm_starts:  # seeded: each later pass from the one before alone
            lap = seeded_lap(flown, track, options, LapSeeds(warm_starts=(lap,)), None, pool)
        else:
            lap = design_limit_lap(flown, track, options, LapSeeds(warm_starts=(lap,)),
                                   pool=pool)
        if not lap.completed:
            return Race(lap, None, tuple(passes))
        account = account_of(flown, lap, pack)
        passes.append(Pass(soc, volts, lap.lap_time_s, account.end_soc))
        if not account.feasible or pack.ocv_curve is None \
                or abs(account.end_soc - soc) < SOC_TOL:
            break
        soc = account.end_soc
        volts = float(pack.ocv(soc))
    assert lap is not None
    return Race(lap, account, tuple(passes))


def seeded_lap(cfg: AirframeConfig, track: TrackConfig, options: LimitLapOptions,
               seeds: LapSeeds, frame: Airframe | None, pool: Pool | None) -> LimitLap:
    """The limit lap from ``seeds``' warm starts alone where there are any, and from
    ``options.starts`` where there are none or they give no verified lap (a pass warm-started
    from the one before, or a race from a neighbour's, is one solve instead of the starts')."""
    if seeds.warm_starts:
        lap = design_limit_lap(cfg, track, seeds_alone(options), seeds, frame=frame,
                               pool=pool)
        if lap.completed:
            return lap
    return design_limit_lap(cfg, track, options, frame=frame, pool=pool)


def account_of(cfg: AirframeConfig, lap: LimitLap, pack: Pack) -> RaceEnergy:
    """The pack's account of a completed lap flown by ``cfg`` (its re-simulation from the lap's
    start state, :func:`casadrone.limit.energy.flight_energy`); the state of charge starts at
    the pack's own start (``pack``), whatever voltage the lap was flown at."""
    frame = build_airframe(cfg)
    energy = flight_energy(frame, lap.t, lap.x[0], lap.u, lap.attitude)
    return race_energy(energy, pack, lap.lap_times_s, frame.max_motor_current_a, CURRENT_TOL)


def race_text(race_: Race) -> list[str]:
    """The pack's lines of the command's text summary (none without a pack capacity)."""
    e = race_.energy
    if e is None:
        return []
    verdict = "flies it" if e.feasible else f"INFEASIBLE: {e.reason}"
    flown = race_.passes[-1] if race_.passes else None
    volts = f"; flown at {flown.open_circuit_voltage_v:.2f} V open-circuit (state of charge " \
        f"{flown.soc_flown:.3f})" if flown else ""
    margin = ", ".join(f"{name} {peak:.1f} A (margin {m:.1f} A)" if math.isfinite(m) else
                       f"{name} {peak:.1f} A (no limit)"
                       for name, peak, m in (("pack", e.peak_pack_current_a,
                                              e.pack_current_margin_a),
                                             ("motor", e.peak_motor_current_a,
                                              e.motor_current_margin_a)))
    return [f"  race of {e.laps} lap(s) on the {e.pack}: {verdict}{volts}",
            f"  energy used {e.energy_used_wh:.2f} Wh ({e.capacity_used_pct:.1f} % of the "
            f"capacity), left {e.energy_left_wh:.2f} Wh; state of charge {e.start_soc:.3f} -> "
            f"{e.end_soc:.3f}; peak currents: {margin}",
            f"  energy check: pack ∫V·I dt against the rotors' loads and losses, "
            f"{100 * e.energy_balance_error:.2g} % apart"]
