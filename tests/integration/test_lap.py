"""Closed-loop lap: integrator agreement, physical consistency, failures as results."""

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.controller import load_controller
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.control import design_for
from casadrone.simulate import chunk_function, simulate, step_function

REFERENCES = ["SY250", "SY220", "HS200", "HS210", "NSY200"]
TRACK = "configs/tracks/paper-rectangle.yaml"


@pytest.fixture(scope="module")
def track():
    return load(TrackConfig, TRACK)


@pytest.fixture(scope="module")
def ctrl():
    return load_controller()


def fly(name, track, ctrl, integrator="rk4", overrides=None):
    a = build_airframe(load_airframe(name, overrides))
    return a, simulate(a, design_for(a, ctrl), track, integrator)


@pytest.mark.parametrize("name", REFERENCES)
def test_fast_and_reference_integrators_agree(name, track, ctrl):
    """rk4 (compiled, fixed step) vs CVODES and IDAS (adaptive, rtol 1e-8): every index and
    split time agrees to about 10x the observed agreement (the issue's acceptance, 1 % and
    0.5 %, was ~10⁴ times looser than what holds, so it could not see an integrator error).
    Observed, five references, both integrators: indices within 9.0e-7 relative (J4, J5), the
    lap time J3 within 2.3e-8, split times within 3.1e-8."""
    from casadrone.indices import compute_indices

    runs = {i: fly(name, track, ctrl, i)[1] for i in ("rk4", "cvodes", "idas")}
    for integ, tr in runs.items():
        assert tr.completed, f"{name} {integ}: {tr.reason}"
    ref = compute_indices(runs["rk4"])
    for integ in ("cvodes", "idas"):
        other = compute_indices(runs[integ])
        for key, value in ref.items():
            assert other[key] == pytest.approx(value, rel=1e-5), f"{name} {integ} {key}"
        np.testing.assert_allclose(runs[integ].split_times, runs["rk4"].split_times, rtol=3e-7)


def test_compiled_chunk_equals_casadi_virtual_machine(track, ctrl):
    """The generated-and-compiled C lap equals the same Function evaluated by CasADi's VM."""
    from casadrone.guidance import track_vector
    from casadrone.simulate import initial_state

    a = build_airframe(load_airframe("HS210"))
    d = design_for(a, ctrl)
    n = len(track.route)
    compiled = chunk_function(d.sample_time_s, 2, n, 250)
    vm = step_function(d.sample_time_s, 2, n).mapaccum("vm", 250, 2)
    x, c = initial_state(a, d, track)
    args = (x, c, a.p, d.x0, d.u0, d.K, track_vector(track))
    for out_c, out_v in zip(compiled(*args), vm(*args), strict=True):
        np.testing.assert_allclose(np.array(out_c), np.array(out_v), rtol=1e-10, atol=1e-10)


def test_logged_acceleration_is_newtons_law(track, ctrl):
    """m a = R (Σ T e_z + drag) + m g, recomputed in numpy from the logged states."""
    a, tr = fly("NSY200", track, ctrl)
    x = tr.x
    phi, th, psi = x[:, 9], x[:, 10], x[:, 11]
    c, s = np.cos, np.sin
    # body z axis and full rotation written out independently of casadrone.model
    R = np.empty((len(x), 3, 3))
    R[:, 0] = np.stack([c(psi) * c(th), c(psi) * s(th) * s(phi) - s(psi) * c(phi),
                        c(psi) * s(th) * c(phi) + s(psi) * s(phi)], axis=1)
    R[:, 1] = np.stack([s(psi) * c(th), s(psi) * s(th) * s(phi) + c(psi) * c(phi),
                        s(psi) * s(th) * c(phi) - c(psi) * s(phi)], axis=1)
    R[:, 2] = np.stack([-s(th), c(th) * s(phi), c(th) * c(phi)], axis=1)
    v = x[:, 3:6]
    drag = -0.5 * a.air_density * a.drag_area * np.abs(v) * v
    force_body = drag.copy()
    force_body[:, 2] += x[:, 12:16].sum(axis=1)
    acc = np.einsum("nij,nj->ni", R, force_body) / a.mass - [0, 0, a.gravity]
    np.testing.assert_allclose(tr.acceleration, acc, atol=1e-9)


def test_sy250_flight_is_physically_sensible(track, ctrl):
    a, tr = fly("SY250", track, ctrl)
    assert tr.completed
    # 105 m of legs + 20 m climb at up to 15 m/s, braking to 4 m/s at four corners: 10-25 s
    assert 10.0 < tr.lap_time < 25.0
    assert np.all(np.diff(tr.split_times) > 0)
    # never faster than the reference speed plus a tracking overshoot
    assert tr.speed.max() < 1.2 * track.speed_mps
    assert np.degrees(np.abs(tr.x[:, 9:11]).max()) < 75.0
    # thrust stays within the actuator range [0, K]
    assert tr.thrust.min() >= -1e-9 and tr.thrust.max() <= a.thrust_gain + 1e-9
    assert tr.u.min() >= 0.0 and tr.u.max() <= 1.0
    # it ends inside the acceptance radius of the last waypoint
    assert np.linalg.norm(tr.x[-1, :3] - track.waypoints_m[-1]) <= track.acceptance_radius_m


def test_too_heavy_airframe_fails_with_reason(track, ctrl):
    """3 kg on 4 x 9.05 N: hover needs 81 % of full thrust and the racer loses attitude control."""
    _, tr = fly("SY250", track, ctrl, overrides=["mass_kg=3.0"])
    assert tr.status == "failed"
    assert "attitude beyond" in tr.reason
    assert np.isnan(tr.lap_time)


def test_time_out_is_a_failed_result(track, ctrl):
    short = track.model_copy(update={"time_limit_s": 3.0})
    a = build_airframe(load_airframe("SY250"))
    tr = simulate(a, design_for(a, ctrl), short, "rk4")
    assert tr.status == "failed" and tr.reason.startswith("time-out")
    assert tr.t[-1] == pytest.approx(3.0, abs=0.01)


@pytest.mark.parametrize("integrator", ["rk4", "cvodes"])
def test_attitude_limit_fails_same_way_on_both_integrators(integrator, track, ctrl):
    strict = track.model_copy(update={"max_tilt_deg": 20.0})
    a = build_airframe(load_airframe("SY250"))
    tr = simulate(a, design_for(a, ctrl), strict, integrator)
    assert tr.status == "failed" and "attitude beyond 20 deg" in tr.reason


def test_compiled_lap_is_cached_on_disk_between_processes(tmp_path):
    """The first process compiles the lap into $CASADRONE_CACHE; a second one loads that library
    (same file, untouched) instead of compiling again."""
    import os
    import subprocess
    import sys

    code = ("from casadrone.simulate import chunk_function; "
            "f = chunk_function(0.01, 1, 6, 50); print(f.class_name())")
    env = {**os.environ, "CASADRONE_CACHE": str(tmp_path)}
    first = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert first.stdout.strip() == "External", first.stderr
    libs = sorted(tmp_path.glob("*.so"))
    assert len(libs) == 1
    stamp = libs[0].stat().st_mtime_ns
    env["CC"] = "/nonexistent-compiler"  # a second compile would fail and fall back to the VM
    second = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert second.stdout.strip() == "External", second.stderr
    assert sorted(tmp_path.glob("*.so")) == libs and libs[0].stat().st_mtime_ns == stamp


def test_without_a_c_compiler_the_lap_runs_on_casadis_virtual_machine(tmp_path):
    import os
    import subprocess
    import sys

    code = ("from casadrone.simulate import chunk_function; "
            "f = chunk_function(0.01, 1, 6, 50); print(f.class_name())")
    env = {**os.environ, "CASADRONE_CACHE": str(tmp_path), "CC": "/nonexistent-compiler"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() != "External" and not list(tmp_path.glob("*.so"))


@pytest.mark.parametrize(("name", "overrides", "track_update", "ending", "substeps"), [
    ("SY250", None, {}, "completed", 1),
    ("NSY200", None, {}, "completed", 1),
    ("HS210", None, {}, "completed", 2),
    ("SY250", ["mass_kg=3.0"], {}, "attitude beyond", 1),
    ("SY250", None, {"max_tilt_deg": 20.0}, "attitude beyond 20 deg", 1),
    ("HS210", None, {"time_limit_s": 3.37}, "time-out", 1),
])
def test_whole_lap_loop_equals_chunked_loop(name, overrides, track_update, ending, substeps,
                                            track, ctrl, monkeypatch):
    """The compiled whole-lap loop (one C call, checks after every sample) flies exactly, to the
    last bit, the lap of the chunked mapaccum path with the checks in numpy, and ends the same
    way: completed, failed (same reason) or timed out (same number of samples)."""
    import importlib

    sim = importlib.import_module("casadrone.simulate")  # the package exports a function too
    tr = track.model_copy(update=track_update)
    a = build_airframe(load_airframe(name, overrides))
    d = design_for(a, ctrl)
    options = sim.SimOptions(substeps=substeps)
    assert sim.lap_driver(d.sample_time_s, substeps, len(tr.route)) is not None, "no C compiler"
    whole = simulate(a, d, tr, "rk4", options)
    monkeypatch.setattr(sim, "lap_driver", lambda *args: None)
    chunked = simulate(a, d, tr, "rk4", options)
    assert (whole.status, whole.reason) == (chunked.status, chunked.reason)
    assert ending in (whole.status + " " + whole.reason)
    for field in ("t", "x", "u", "acceleration", "p_ref", "v_ref", "segment"):
        np.testing.assert_array_equal(getattr(whole, field), getattr(chunked, field), field)
    np.testing.assert_array_equal(whole.split_times, chunked.split_times)


def test_evaluations_in_threads_equal_serial():
    """A Dask worker may run several threads: evaluations in 4 threads at once (zero-copy trim
    and linearisation buffers per thread, the lap loop's arrays per call) equal serial ones."""
    import threading

    from casadrone.airframe import random_thetas
    from casadrone.evaluate import default_setup, evaluate

    setup = default_setup(controller="frozen-wrench-sy250")
    thetas, _ = random_thetas(setup.template, 12, seed=5)
    serial = [evaluate(th, setup) for th in thetas]
    got: dict[int, object] = {}

    def work(idx):
        for _ in range(3):
            for i in idx:
                got[i] = evaluate(thetas[i], setup)

    threads = [threading.Thread(target=work, args=(range(k, 12, 4),)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i, ev in enumerate(serial):
        assert (got[i].status, got[i].reason, got[i].indices) == (ev.status, ev.reason, ev.indices)
