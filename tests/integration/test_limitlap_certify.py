"""The command's two searches on a short track (casadrone.limit.search): ``--certify`` solves a
superset of the fast path's starts with the same deterministic solver, so its lap is never
slower, and its sensitivity table is taken over every distinct verified optimum. Oracles: the
fast path's solves reappear in the certified lap's starts with the same laps (IPOPT with MUMPS
is deterministic); the table counts the distinct verified laps the starts list, and its
uncertainty is the farthest end of its range (at least; more where an optimum lies within
0.1 % of the lap)."""

from __future__ import annotations

import pytest

from casadrone.config.airframe import load_airframe
from casadrone.limit.lap import CERTAIN_REL, LimitLapOptions, design_limit_lap
from casadrone.limit.search import search_options

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def laps():
    from tests.integration.test_limitlap_optimality import TRACK

    cfg = load_airframe("SY250")
    base = LimitLapOptions(intervals=10)
    fast = design_limit_lap(cfg, TRACK, search_options("fast", base, periodic=False))
    certified = design_limit_lap(cfg, TRACK, search_options("certify", base, periodic=False))
    return fast, certified


def test_certify_is_never_slower_than_the_fast_path(laps):
    fast, certified = laps
    assert fast.completed and certified.completed, (fast.reason, certified.reason)
    assert certified.lap_time_s <= fast.lap_time_s + 1e-12
    by_name = {s.start: s for s in certified.starts}
    for s in fast.starts:  # the same solves, the same laps
        assert s.start in by_name
        assert by_name[s.start].lap_time_s == pytest.approx(s.lap_time_s, rel=1e-9, nan_ok=True)
    assert len(certified.starts) > len(fast.starts)


def test_certified_table_spans_every_optimum(laps):
    _, certified = laps
    table = {t.key: t for t in certified.sensitivity_table}
    assert set(table) == set(certified.sensitivities)
    laps_found = {round(s.lap_time_s, 9) for s in certified.starts if s.success
                  and s.resimulation_miss_m <= LimitLapOptions().max_miss_m}
    for key, t in table.items():
        assert t.optima == len(laps_found)
        assert t.s_per_unit == certified.sensitivities[key]
        assert t.low_s_per_unit <= t.s_per_unit <= t.high_s_per_unit
        if t.optima > 1:  # at least the farthest end of the range (more where another
            # optimum is within 0.1 % of the lap: casadrone.limit.sensitivity)
            assert t.uncertainty_s_per_unit >= (1 - 1e-12) * max(
                t.high_s_per_unit - t.s_per_unit, t.s_per_unit - t.low_s_per_unit)
            near = [s.lap_time_s for s in certified.starts if s.success and s.lap_time_s
                    - certified.lap_time_s > 1e-9 * certified.lap_time_s
                    and s.lap_time_s <= (1 + CERTAIN_REL) * certified.lap_time_s]
            if not near:
                assert t.uncertainty_s_per_unit == pytest.approx(
                    max(t.high_s_per_unit - t.s_per_unit, t.s_per_unit - t.low_s_per_unit))
