"""The re-simulation check's two modes (LimitLapOptions.resimulation): "lap" flies the whole
lap's commands open loop from the start state, "legs" each leg's commands from the lap's own
node at the leg's start.

Oracle: the quadrotor's dynamics do not depend on where it is (no term of the model reads the
position), so a lap whose nodes from the second leg on are moved by a constant δ is flown, leg
by leg, to its own moved nodes: the "legs" miss of the moved lap is the miss of the lap's own
end node moved by δ (to within the leg's open-loop drift), while the "lap" miss, flown from the
unmoved start, does not change at all."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.limit.check import fly, resimulation_miss
from casadrone.limit.lap import LimitLapOptions, design_limit_lap, frame_clearance_m, track_targets
from casadrone.targets import TARGET_SIZE, target_miss
from tests.integration.test_limitlap_optimality import TRACK

N = 20
DELTA = np.array([0.0, 0.0, 3.0])  # m, well outside the 1 m balls


@pytest.fixture(scope="module")
def flown():
    cfg = load_airframe("SY250")
    options = LimitLapOptions(intervals=N, starts=("point-mass",), sensitivities=False,
                              point_mass_reference=False, fallback_reference=None,
                              refinements=0)
    lap = design_limit_lap(cfg, TRACK, options)
    assert lap.completed, lap.reason
    frame = build_airframe(cfg)
    targets = track_targets(TRACK, options, frame_clearance_m(frame, cfg.prop_diameter_mm / 1000))
    return frame, lap, targets


def test_legs_fly_each_leg_from_its_own_node(flown):
    frame, lap, targets = flown
    x = lap.x.copy()
    x[N:, 0:3] += DELTA  # the second leg starts (and ends) 3 m higher
    moved = replace(lap, x=x)
    k = len(targets.kinds) - 1  # the last target: the second leg's end
    end_target = targets.vector[TARGET_SIZE * k:TARGET_SIZE * (k + 1)]
    expected = target_miss(x[(k + 1) * N, 0:3], end_target, targets.kinds[k])
    assert expected > 2.0  # the moved end node is far outside its ball
    legs = resimulation_miss(frame, moved, targets.vector, targets.kinds, legs=True)
    assert legs == pytest.approx(expected, abs=0.01)
    whole = resimulation_miss(frame, lap, targets.vector, targets.kinds)
    assert resimulation_miss(frame, moved, targets.vector, targets.kinds) == whole < 0.15


def test_each_leg_of_the_unmoved_lap_lands_on_its_own_end_node(flown):
    """CVODES and the NLP's RK4 steps agree leg by leg: each leg flown from the lap's node at
    its start ends within 1 cm of the NLP's node at its end, and the lap passes both checks."""
    frame, lap, targets = flown
    for k in range(len(targets.kinds)):
        end = fly(frame, lap, k * N, (k + 1) * N)[-1]
        assert np.linalg.norm(end[:3] - lap.x[(k + 1) * N, :3]) < 0.01
    assert resimulation_miss(frame, lap, targets.vector, targets.kinds, legs=True) < 0.15
    assert resimulation_miss(frame, lap, targets.vector, targets.kinds) < 0.15


def test_an_unknown_mode_is_refused():
    lap = design_limit_lap(load_airframe("SY250"), TRACK,
                           LimitLapOptions(intervals=N, resimulation="open"))  # type: ignore[arg-type]
    assert lap.status == "failed" and "resimulation" in lap.reason
