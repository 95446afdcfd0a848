"""Grid-continuation rounds of the limit lap (casadrone.limit.lap.grid_rounds): the chosen lap
solved on the coarse and fine grids and brought back. SY250 on the paper track, 24 intervals
per leg, the point-mass start alone: that start stops at 3.8914 s, and the path through 36
intervals leaves it for a lap about 0.3 % faster (measured: 3.8805 s). Oracles: CVODES flies the
chosen lap within the threshold; a primal-dual warm re-solve of it on its own grid stays put (a
converged optimum of this grid's NLP, not a resampled guess); the fine grid's lap is the same
optimum (within CERTAIN_REL), or the result says it is not sure."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from casadrone.config.airframe import load_airframe
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.evaluate import DEFAULT_TRACK
from casadrone.limit.lap import (
    CERTAIN_REL,
    LapSeeds,
    LimitLapOptions,
    check_inputs,
    design_limit_lap,
)

OPTIONS = LimitLapOptions(intervals=24, starts=("point-mass",), sensitivities=False,
                          fallback_reference=None)


@pytest.fixture(scope="module")
def laps():
    frame, track = load_airframe("SY250"), load(TrackConfig, DEFAULT_TRACK)
    plain = design_limit_lap(frame, track, OPTIONS)
    rounds = design_limit_lap(frame, track, replace(OPTIONS, grid_rounds=1))
    return frame, track, plain, rounds


def test_a_round_leaves_the_start_only_for_a_faster_verified_lap(laps):
    """The round's lap is solved and reported beside the start's, and chosen only where it is
    verified and faster. Which optimum each path reaches is the machine's: on the AMD EPYC VMs
    the start stops at 3.8914 s and the round's lap, 3.8805 s, is chosen (faster by far more
    than the solver's tolerance moves a lap, ~1e-6); on an Intel Xeon VM the start stops at
    3.9560 s and the round's lap, 3.9689 s and not verified, is not."""
    _, _, plain, rounds = laps
    assert plain.completed and rounds.completed, (plain.reason, rounds.reason)
    assert plain.start == "point-mass"
    by_name = {s.start: s for s in rounds.starts}
    assert by_name["point-mass"].lap_time_s == pytest.approx(plain.lap_time_s, rel=1e-9)
    round_laps = [s for s in rounds.starts if s.start.startswith("grid-")
                  and "-round-1" in s.start]
    assert round_laps and math.isfinite(round_laps[0].lap_time_s)
    assert rounds.resimulation_miss_m <= OPTIONS.max_miss_m
    if rounds.start == "point-mass":  # the round found no faster verified lap
        assert rounds.lap_time_s == plain.lap_time_s
        assert all(s.lap_time_s >= plain.lap_time_s or not s.resimulation_miss_m
                   <= OPTIONS.max_miss_m for s in round_laps)
    else:
        assert rounds.start in {s.start for s in round_laps}
        assert rounds.lap_time_s < (1 - 1e-4) * plain.lap_time_s


def test_the_chosen_lap_is_an_optimum_of_its_own_grid(laps):
    frame, track, _, rounds = laps
    again = design_limit_lap(frame, track, replace(OPTIONS, starts=(),
                                                   point_mass_reference=False),
                             LapSeeds(warm_starts=(rounds,)))
    assert again.completed and again.start == "warm-1"
    assert again.lap_time_s == pytest.approx(rounds.lap_time_s, rel=1e-6)


def test_the_fine_grid_lap_agrees_or_the_result_says_it_is_not_sure(laps):
    """The same optimum on another grid moves by less than CERTAIN_REL (0.01-0.06 % between 30,
    40 and 60 intervals); which optimum IPOPT reaches on the 36-interval grid, though, differs
    between machines (the same lap, 3.8805 s, on one; 3.8923 s, 0.3 % slower, on another AMD
    VM from the same code: rounding differences of the machine, not traced further). What must
    hold either way: a fine-grid lap that disagrees makes the result say it is not sure, with a
    spread that covers it."""
    _, _, _, rounds = laps
    assert 36 in rounds.grid_laps_s
    fine = rounds.grid_laps_s[36]
    gap = abs(fine - rounds.lap_time_s)
    if gap <= CERTAIN_REL * min(fine, rounds.lap_time_s):
        return  # the same optimum
    assert rounds.certainty == "spread", (fine, rounds.lap_time_s, rounds.certainty)
    assert rounds.spread_s >= gap * (1 - 1e-12)


def test_grid_rounds_out_of_range_are_refused():
    track = load(TrackConfig, DEFAULT_TRACK)
    assert "grid_rounds" in check_inputs(track, replace(OPTIONS, grid_rounds=6))
    assert "grid_rounds" in check_inputs(track, replace(OPTIONS, grid_rounds=-1))
    assert check_inputs(track, replace(OPTIONS, grid_rounds=5)) == ""


def test_the_first_round_starts_from_every_verified_start():
    """Which start's path through the other grids leads to the best optimum is not known in
    advance, so round 1 resamples every distinct verified start, not only the chosen one; the
    chosen lap is the fastest of all of them."""
    frame, track = load_airframe("SY250"), load(TrackConfig, DEFAULT_TRACK)
    lap = design_limit_lap(frame, track, replace(OPTIONS, starts=("point-mass", "closed-loop"),
                                                 grid_rounds=1))
    assert lap.completed, lap.reason
    by_name = {s.start: s for s in lap.starts}
    own = [n for n in ("point-mass", "closed-loop")
           if by_name[n].success and by_name[n].resimulation_miss_m <= OPTIONS.max_miss_m]
    assert len(own) == 2 and abs(by_name[own[0]].lap_time_s - by_name[own[1]].lap_time_s) > 1e-6
    for n in own:  # brought back from the 18- or 36-interval grid (where that lap completed)
        back = {s.start.split("-")[1] for s in lap.starts if s.start.endswith(f"-round-1-{n}")}
        assert back and back <= {"18", "36"}, lap.starts
    assert lap.lap_time_s == min(s.lap_time_s for s in lap.starts
                                 if s.success and s.resimulation_miss_m <= OPTIONS.max_miss_m)
