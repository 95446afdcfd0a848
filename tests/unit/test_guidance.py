"""Line-of-sight guidance on hand-computed cases."""

import math

import casadi as ca
import numpy as np
import pytest

from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.guidance import GuidanceLayout, guidance, segment_headings, track_vector
from casadrone.simulate import split_times

TRACK = "configs/tracks/paper-rectangle.yaml"


@pytest.fixture(scope="module")
def track():
    return load(TrackConfig, TRACK)


@pytest.fixture(scope="module")
def guide(track):
    layout = GuidanceLayout(len(track.route))
    pos, seg = ca.SX.sym("pos", 3), ca.SX.sym("seg")
    g = ca.SX.sym("g", layout.size)
    out = guidance(pos, seg, g, layout)
    fun = ca.Function("guide", [pos, seg, g], list(out))
    gv = track_vector(track)

    def call(p, s):
        p_ref, v_ref, psi_ref, seg_next = fun(p, s, gv)
        return (np.array(p_ref).ravel(), np.array(v_ref).ravel(), float(psi_ref), float(seg_next))

    return call


def test_route_of_paper_track(track):
    # start on the ground, climb point above it, then the four corners of 50 m x 2.5 m at 20 m
    np.testing.assert_allclose(
        track.route,
        [[0, 0, 0], [0, 0, 20], [50, 0, 20], [50, 2.5, 20], [0, 2.5, 20], [0, 0, 20]],
    )
    assert track.first_timed_segment == 1


def test_headings_left_hand_and_climb_takes_next(track):
    h = segment_headings(track.route, 0.0)
    # climb (vertical) points the nose like the first straight (east); then east, north, west, south
    np.testing.assert_allclose(h, [0, 0, math.pi / 2, math.pi, 3 * math.pi / 2], atol=1e-12)


def test_look_ahead_and_cross_track_on_straight(guide, track):
    # on segment 1 (0,0,20)->(50,0,20) at (10, 2, 20): projection s = 10, look-ahead 3 m ahead
    p_ref, v_ref, psi_ref, seg = guide([10.0, 2.0, 20.0], 1)
    assert seg == 1
    np.testing.assert_allclose(p_ref, [10, 0, 20], atol=1e-12)  # closest point: cross-track only
    los = np.array([13.0, 0.0, 20.0]) - [10.0, 2.0, 20.0]
    # 40 m to the corner: sqrt(4² + 2·6·40) = 22.3 > 15, so the reference speed is V = 15 m/s
    np.testing.assert_allclose(v_ref, 15.0 * los / np.linalg.norm(los), atol=1e-12)
    assert psi_ref == pytest.approx(0.0)


def test_speed_profile_brakes_before_waypoint(guide):
    # 2 m before WP1 on the centre line: v = sqrt(V_c² + 2 a d) = sqrt(16 + 24) m/s towards WP1
    _, v_ref, _, seg = guide([48.0, 0.0, 20.0], 1)
    assert seg == 1
    np.testing.assert_allclose(v_ref, [math.sqrt(16 + 2 * 6 * 2), 0, 0], atol=1e-12)


def test_switch_inside_acceptance_radius(guide):
    # 0.5 m from WP1 (radius 1 m): switch to the curve leg heading north
    p_ref, v_ref, psi_ref, seg = guide([49.6, 0.3, 20.0], 1)
    assert seg == 2
    assert psi_ref == pytest.approx(math.pi / 2)
    np.testing.assert_allclose(p_ref, [50.0, 0.3, 20.0], atol=1e-12)


def test_switch_when_past_segment_end(guide):
    # 3 m past WP1 and 3 m off to the side: outside the radius but s > L, so it switches
    _, _, _, seg = guide([53.0, -3.0, 20.0], 1)
    assert seg == 2


def test_no_switch_before_end_outside_radius(guide):
    _, _, _, seg = guide([45.0, -3.0, 20.0], 1)
    assert seg == 1


def test_done_holds_last_waypoint(guide):
    p_ref, v_ref, _, seg = guide([0.3, 0.2, 20.0], 4)  # inside radius of WP4 on the last leg
    assert seg == 5
    np.testing.assert_allclose(p_ref, [0, 0, 20])
    np.testing.assert_allclose(v_ref, 0.0)


def test_split_time_interpolated_inside_sample(track):
    # flying along the first straight at 10 m/s; WP1's acceptance sphere (1 m) is entered at x = 49
    Ts = 0.01
    t = np.arange(0, 0.5, Ts)
    x = np.zeros((len(t), 16))
    x[:, 0] = 45.0 + 10.0 * t + 0.003  # offset so that x = 49 falls inside a sample
    x[:, 2] = 20.0
    seg = np.where(x[:, 0] >= 49.0, 2, 1)
    splits = split_times(t, x, seg, track.route, track)
    assert splits[0] == pytest.approx((49.0 - 45.003) / 10.0, abs=1e-9)
    assert np.isnan(splits[1:]).all()


def test_climb_is_capped_and_brakes_to_rest_at_the_top(guide, track):
    # halfway up the climb: the climb speed cap (5 m/s), straight up
    _, v_ref, psi_ref, seg = guide([0.0, 0.0, 10.0], 0)
    assert seg == 0
    np.testing.assert_allclose(v_ref, [0, 0, track.climb_speed_mps], atol=1e-12)
    assert psi_ref == pytest.approx(0.0)  # nose already points down the first straight
    # 1.5 m below the top: braking to rest, v = sqrt(0 + 2 a d) = sqrt(2·6·1.5) = 4.24 m/s
    _, v_ref, _, _ = guide([0.0, 0.0, 18.5], 0)
    np.testing.assert_allclose(v_ref, [0, 0, math.sqrt(2 * 6 * 1.5)], atol=1e-12)
