"""The shipped laps (casadrone.limit.library) and the fast path that starts from them.

Oracles: the track files the laps name (their settings' hash, loaded here), the laps' own
arithmetic (leg times sum to the lap and end the node times), the NLP's unpacking of the stored
decision vector, and a re-solve: the reference frame started from its own shipped lap must
converge back to it (a model changed since the lap was written fails here: a stale library)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from casadrone.config.airframe import load_airframe
from casadrone.config.io import load, resolve_config
from casadrone.config.track import TrackConfig
from casadrone.limit.lap import LimitLapOptions, design_limit_lap
from casadrone.limit.library import LIBRARY_DIR, read, shipped_laps, track_key, usable, write
from casadrone.limit.result import LimitLap
from casadrone.limit.search import search_options

FILES = sorted(LIBRARY_DIR.glob("*.npz"))


def test_the_package_ships_laps_for_the_paper_and_gate_tracks():
    names = {p.name for p in FILES}
    assert {"paper-rectangle--SY250.npz", "multigp-cdra-gates--SY250.npz"} <= names


@pytest.mark.parametrize("path", FILES, ids=[p.stem for p in FILES])
def test_each_shipped_lap_names_its_track_and_adds_up(path):
    s = read(path)
    track_name, airframe = path.stem.split("--")
    assert (s.meta["track"], s.name) == (track_name, airframe)
    track = load(TrackConfig, resolve_config(track_name, "tracks"))
    assert s.track_sha256 == track_key(track)  # the shipped track file as it is today
    assert s.propulsion == load_airframe(airframe).propulsion.model
    lap = s.lap
    assert lap.lap_time_s == pytest.approx(lap.leg_times_s.sum(), rel=1e-12)
    assert lap.t[-1] == pytest.approx(lap.lap_time_s, rel=1e-12)
    assert len(lap.leg_times_s) == lap.layout.n_legs
    assert lap.x.shape[0] == lap.layout.n_legs * lap.layout.intervals + 1 == len(lap.t)
    assert s.meta["command"].startswith("python -m casadrone.limit.ship " + airframe)


def test_an_edited_track_or_another_kind_finds_no_shipped_lap():
    track = load(TrackConfig, resolve_config("paper-rectangle", "tracks"))
    assert [s.name for s in shipped_laps(track, "paper")][:1] == ["SY250"]
    assert shipped_laps(track, "lagless-test-kind") == ()
    edited = track.model_copy(update={"max_tilt_deg": track.max_tilt_deg - 1.0})
    assert track_key(edited) != track_key(track)
    assert shipped_laps(edited, "paper") == ()


def test_usable_says_warm_resampled_or_not():
    s = read(LIBRARY_DIR / "paper-rectangle--SY250.npz")
    lay = s.lap.layout
    assert usable(s, lay, "euler") == "warm"
    assert usable(s, replace(lay, intervals=25), "euler") == "resampled"
    assert usable(s, lay, "quaternion") == "resampled"
    assert usable(s, replace(lay, kinds=lay.kinds[:-1]), "euler") is None
    assert usable(s, replace(lay, method="collocation"), "euler") is None


def test_write_and_read_give_the_same_lap_and_refuse_a_failed_one(tmp_path):
    s = read(LIBRARY_DIR / "paper-rectangle--SY250.npz")
    track = load(TrackConfig, resolve_config("paper-rectangle", "tracks"))
    out = write(tmp_path / "x--SY250.npz", s.lap, "SY250", track, "x", "by hand")
    again = read(out)
    for a in ("t", "x", "u", "leg_times_s"):
        np.testing.assert_array_equal(getattr(again.lap, a), getattr(s.lap, a))
    np.testing.assert_array_equal(again.lap.solution.lam_g, s.lap.solution.lam_g)
    assert again.lap.layout == s.lap.layout and again.meta["command"] == "by hand"
    with pytest.raises(ValueError, match="only a completed lap"):
        write(tmp_path / "y.npz", LimitLap(status="failed", reason="no"), "SY250", track, "x",
              "by hand")
    bad = tmp_path / "bad.npz"
    np.savez(bad, meta=np.array(json.dumps({})))
    with pytest.raises(ValueError, match="bad.npz: not a shipped lap"):
        read(bad)


def test_the_reference_frame_converges_back_to_its_shipped_lap():
    """SY250 from its own shipped lap: the same lap within the solver's tolerance, in a few
    iterations; and the fast path's start is the library's."""
    s = read(LIBRARY_DIR / "paper-rectangle--SY250.npz")
    track = load(TrackConfig, resolve_config("paper-rectangle", "tracks"))
    options = replace(search_options("fast", LimitLapOptions(), periodic=False),
                      sensitivities=False)
    lap = design_limit_lap(load_airframe("SY250"), track, options)
    assert lap.completed, lap.reason
    assert lap.start == "library-SY250"
    assert lap.lap_time_s == pytest.approx(s.lap.lap_time_s, rel=1e-6)
    assert lap.iterations < 30
    assert [x.start for x in lap.starts] == ["library-SY250"]  # the cold starts were not needed
    # the reported point-mass reference is a relaxation's optimum reached from the lap: below it
    assert lap.point_mass_reference_s < lap.lap_time_s


def test_no_shipped_lap_runs_the_fallback_starts(monkeypatch):
    """Where no lap is shipped the library start says so and the fast path's cold starts run
    (here replaced by a start that records it was asked)."""
    from casadrone.limit import starts

    asked = []

    def recorded(pb, lap_of):
        asked.append(pb.options.starts)
        return None

    monkeypatch.setattr(starts, "shipped_laps", lambda track, kind: ())
    monkeypatch.setitem(starts.COLD_STARTS, "coarse-grid", recorded)
    monkeypatch.setitem(starts.COLD_STARTS, "fine-grid", recorded)
    track = load(TrackConfig, resolve_config("paper-rectangle", "tracks"))
    options = replace(search_options("fast", LimitLapOptions(), periodic=False),
                      sensitivities=False, fallback_reference=None, refinements=0)
    lap = design_limit_lap(load_airframe("SY250"), track, options)
    assert not lap.completed
    assert asked == [("coarse-grid", "fine-grid")] * 2
    by = {s.start: s for s in lap.starts}
    assert by["library"].return_status.startswith("not run: no lap of this track")
    assert set(by) == {"library", "coarse-grid", "fine-grid"}
