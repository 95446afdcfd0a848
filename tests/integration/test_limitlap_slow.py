"""Limit lap on the 16-state model (slow: each solve takes seconds to minutes on a loaded
2-core machine). Oracles: the point-mass relaxation, the closed-loop lap, CVODES, finite
differences of re-solves, physical monotonicity and mirror symmetry."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.io import load
from casadrone.config.track import TrackConfig
from casadrone.evaluate import DEFAULT_TRACK, default_setup, evaluate, theta_of
from casadrone.limit.lap import LapSeeds, LimitLapOptions, design_limit_lap

pytestmark = pytest.mark.slow
TRACK = load(TrackConfig, DEFAULT_TRACK)
REFERENCES = ("SY250", "SY220", "HS200", "HS210", "NSY200")
FAST = LimitLapOptions(sensitivities=False)


@pytest.fixture(scope="module")
def laps():
    return {name: design_limit_lap(load_airframe(name), TRACK, FAST) for name in REFERENCES}


#: Laps an independent re-implementation of the same problem found on this grid (issue 19):
#: casadrone's own NLP started there converges to them and passes its re-simulation check.
INDEPENDENT_BEST_S = {"SY250": 3.8951, "HS210": 3.8497}


@pytest.mark.parametrize("name", sorted(INDEPENDENT_BEST_S))
def test_default_starts_reach_the_independent_solvers_optimum(laps, name):
    """The default starts (with the fine-grid continuation) reach, within 0.1 %, the best lap an
    independent solver found (measured: SY250 3.8800 s, HS210 3.8405 s, both below it)."""
    assert laps[name].completed, laps[name].reason
    assert laps[name].lap_time_s <= INDEPENDENT_BEST_S[name] * (1 + 1e-3)


@pytest.mark.parametrize("name", REFERENCES)
def test_reference_lap_faster_than_the_closed_loop(laps, name):
    lap = laps[name]
    assert lap.completed, lap.reason
    J3 = evaluate(theta_of(load_airframe(name)), default_setup(name)).indices["J3"]
    assert lap.lap_time_s <= J3
    assert np.isfinite(lap.point_mass_reference_s)  # reported; not a bound (lap.py)
    assert lap.resimulation_miss_m <= 0.05


@pytest.mark.parametrize("name", REFERENCES)
def test_grid_refinement_changes_the_lap_little(laps, name):
    """Twice the intervals change the lap by < 0.1 %. The fine lap starts from the coarse
    optimum resampled onto the fine grid; the coarse grid is then solved again from the fine
    optimum, so both grids are compared on the same local optimum. (Measured: from the coarse
    multi-start optimum alone the fine lap was 0.22 % (HS200) and 0.25 % (NSY200) faster, but the
    coarse grid started from the fine optimum came within 0.04-0.05 % of it: a neighbouring local
    optimum, not discretisation error.)"""
    coarse = laps[name]
    cfg = load_airframe(name)
    assert coarse.layout is not None  # the grid the default solved it on (40 per leg)
    fine = design_limit_lap(cfg, TRACK, replace(FAST, intervals=2 * coarse.layout.intervals,
                                                point_mass_reference=False, starts=()),
                            LapSeeds(warm_starts=(coarse,)))
    assert fine.completed, fine.reason
    assert fine.start == "resampled-1"
    back = design_limit_lap(cfg, TRACK, replace(FAST, point_mass_reference=False, starts=()),
                            LapSeeds(warm_starts=(fine,)))
    best = min([coarse.lap_time_s] + ([back.lap_time_s] if back.completed else []))
    assert abs(fine.lap_time_s - best) <= 1e-3 * best


def test_slower_lag_and_weaker_thrust_never_faster(laps):
    base = laps["SY250"]
    for override in (["thrust.time_constant_s=0.09"], ["thrust.gain_n=8.0"]):
        cfg = load_airframe("SY250", override)
        lap = design_limit_lap(cfg, TRACK, FAST, LapSeeds(warm_starts=(base,)))
        assert lap.completed, lap.reason
        assert lap.lap_time_s >= base.lap_time_s - 1e-4, override


def _reflect_state(X: np.ndarray) -> np.ndarray:
    """States reflected in the world x–z plane, body frame kept right-handed (body y flipped):
    y, v, p, r, φ, ψ change sign; rotors FR↔FL and RL↔RR swap places."""
    out = X[..., [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 12, 15, 14]].copy()
    out[..., [1, 4, 6, 8, 9, 11]] *= -1
    return out


def _reflect_lap(lap):
    """The lap's primal-dual point reflected (decision vector and multipliers alike: every
    constraint row maps to its mirror, so the multipliers permute and change sign with it)."""
    from casadrone.limit.lap import LimitLap
    from casadrone.limit.nlp import NlpPoint

    M, nx = len(lap.u), 16
    per = 1 + 4 + nx

    def vec(v):  # decision-vector layout: [S, U, X] per interval, then the last X
        blocks = v[:M * per].reshape(M, per).copy()
        blocks[:, 1:5] = blocks[:, [2, 1, 4, 3]]
        blocks[:, 5:] = _reflect_state(blocks[:, 5:])
        return np.concatenate([blocks.ravel(), _reflect_state(v[M * per:])])

    def rows(v):  # constraint layout: 16 dynamics rows per interval, ties, start, balls
        out = v.copy()
        out[:M * nx] = _reflect_state(v[:M * nx].reshape(M, nx)).ravel()
        n0 = M * nx + (M - len(lap.leg_times_s))
        out[n0:n0 + nx] = _reflect_state(v[n0:n0 + nx])
        return out

    sol = lap.solution
    point = NlpPoint(vec(sol.w), vec(sol.lam_x), rows(sol.lam_g), sol.lam_p)
    return LimitLap(status="completed", reason="", layout=lap.layout, solution=point)


def test_mirror_track_same_lap_on_mirror_image_frame(laps):
    """Reflecting the world in the x–z plane maps the track to its mirror image and SY250 to
    itself (its spin pattern is its own mirror image: the prop at FR's image, FL, turns the
    other way, as FL does). So the reflected optimum is an optimum of the mirrored problem:
    started from it (primal and dual), the solver stays there, with the same lap. A model or
    transcription that is not mirror-symmetric (a sign of a rate, a rotor's torque) fails."""
    base = laps["SY250"]
    mirror = TRACK.model_copy(update={"waypoints_m": [(x, -y, z) for x, y, z in
                                                      TRACK.waypoints_m]})
    lap = design_limit_lap(load_airframe("SY250"), mirror,
                           replace(FAST, starts=(), point_mass_reference=False),
                           LapSeeds(warm_starts=(_reflect_lap(base),)))
    assert lap.completed, lap.reason
    assert lap.iterations <= 20
    np.testing.assert_allclose(lap.lap_time_s, base.lap_time_s, rtol=1e-6)
    # the flight path is the reflected one to a centimetre (rates and thrusts on saturated arcs
    # are determined only to the solver's tolerance: up to 0.06 in rad/s or N)
    np.testing.assert_allclose(lap.x[:, 0:3], _reflect_state(base.x)[:, 0:3], atol=0.01)


def test_sensitivities_match_finite_differences_on_asymmetric_frame():
    cfg = load_airframe("HS210")
    lap = design_limit_lap(cfg, TRACK, LimitLapOptions())
    assert lap.completed, lap.reason
    for key, step in (("lambda_a_mm", 2.0), ("ixx_kgm2", 1e-4)):
        v = getattr(cfg, key)
        T = [design_limit_lap(load_airframe("HS210", [f"{key}={v + s}"]), TRACK,
                              replace(FAST, starts=(), point_mass_reference=False,
                                      resimulate=False), LapSeeds(warm_starts=(lap,))).lap_time_s
             for s in (-step, step)]
        fd = (T[1] - T[0]) / (2 * step)
        assert lap.sensitivities[key] == pytest.approx(fd, rel=0.05, abs=1e-6), key


def test_unreachable_gate_is_a_failed_result():
    trk = load(TrackConfig, "configs/tracks/multigp-cdra-gates.yaml", ["time_limit_s=0.1"])
    lap = design_limit_lap(load_airframe("SY250"), trk, FAST)
    assert lap.status == "failed" and lap.reason


#: The keys of ``limit-lap --json`` that users and the documentation rely on.
LIMIT_KEYS = ("status", "reason", "lap_time_s", "point_mass_reference_s", "split_times_s",
              "lap_times_s", "certainty", "spread_s", "start", "attitude", "bang_bang_fraction",
              "resimulation_miss_m", "sensitivities", "iterations", "wall_time_s", "start_state")


def test_cli_json_keys(cli_runner):
    from casadrone.cli import app
    from casadrone.cli.limit import PROPULSION_KEYS

    r = cli_runner.invoke(app, ["limit-lap", "SY250", "--json"])
    assert r.exit_code == 0, r.output
    out = json.loads(r.stdout)
    assert set(LIMIT_KEYS) | set(PROPULSION_KEYS) <= set(out)
    assert out["status"] == "completed"
    assert set(out["sensitivities"]) >= {"lambda_a_mm", "alpha_deg"}


def test_optimisation_same_front_serial_and_processes(tmp_path):
    """Same seed ⇒ same evaluations on both backends: every candidate warm-starts only from the
    per-study references, which each worker solves identically."""
    from casadrone.optimise.checks import load_problem
    from casadrone.optimise.runner import run

    for backend in ("serial", "processes"):
        problem = load_problem("limit-lap", ["algorithm.population=4", "algorithm.generations=1",
                                             "algorithm.settings.n_ind_ga=2",
                                             f"backend.name={backend}", "backend.workers=2"])
        run(problem, tmp_path / backend, quiet=True)
    a, b = ((tmp_path / k / "pareto.csv").read_text() for k in ("serial", "processes"))
    assert a == b and "J3_limit" in a.splitlines()[0]


def test_decide_report_compare_on_a_limit_lap_run(tmp_path, cli_runner):
    """The three commands that follow a run work on one that optimises J3_limit; the report
    shows the limit lap of the chosen candidates."""
    from casadrone.cli import app

    run_dir = tmp_path / "run"
    r = cli_runner.invoke(app, ["run", "limit-lap", "--out", str(run_dir), "--quiet",
                                "algorithm.population=4", "algorithm.generations=1",
                                "algorithm.settings.n_ind_ga=2", "backend.name=serial"])
    assert r.exit_code == 0, r.output
    r = cli_runner.invoke(app, ["decide", str(run_dir)])
    assert r.exit_code == 0 and "J3_limit=" in r.stdout, r.output
    r = cli_runner.invoke(app, ["report", str(run_dir)])
    assert r.exit_code == 0, r.output
    html = (run_dir / "report.html").read_text()
    assert "limit lap beside its closed-loop lap" in html
    r = cli_runner.invoke(app, ["compare", str(run_dir)])
    assert r.exit_code == 0 and "simulated" in r.stdout, r.output


def test_a_start_that_misses_on_resimulation_is_never_chosen(laps):
    """The same converged warm start is chosen under the default threshold and refused under
    one below its re-simulation miss: the check, not the solver, decides."""
    base = laps["SY250"]
    opts, seeds = replace(FAST, starts=(), point_mass_reference=False), LapSeeds(
        warm_starts=(base,))
    lap = design_limit_lap(load_airframe("SY250"), TRACK, opts, seeds)
    assert lap.completed and 0 < lap.resimulation_miss_m <= opts.max_miss_m
    # this start alone: no grid refinement, and no fallback start from SY250's own lap (another
    # optimum, which can pass the stricter check)
    strict = design_limit_lap(load_airframe("SY250"), TRACK,
                              replace(opts, max_miss_m=0.5 * lap.resimulation_miss_m, refinements=0,
                                      fallback_reference=None), seeds)
    assert strict.status == "failed" and "re-simulation" in strict.reason


def test_gate_track_lap_passes_every_gate_opening():
    trk = load(TrackConfig, "configs/tracks/multigp-cdra-gates.yaml")
    lap = design_limit_lap(load_airframe("SY250"), trk, FAST)
    assert lap.completed, lap.reason
    assert lap.resimulation_miss_m <= 0.05
    assert len(lap.split_times_s) == len(trk.gates)


def test_a_frame_whose_own_starts_fail_is_started_from_sy250():
    """The fallback: a frame none of whose own starts converges is started from SY250's verified
    optimum. The frame's own start is made to fail on purpose (its closed-loop guess with every
    state NaN: IPOPT stops at once), so the test does not hang on which random frame happens to
    defeat the solver (frame 14 of 50 random Table 1 frames did at 40 intervals, measured, until
    the starts change). The rescued lap is judged by independent oracles: it is faster than the
    frame's closed-loop lap, and its commands flown by CVODES pass every target. Without the
    fallback the same start fails."""
    from casadrone.airframe import build_airframe
    from casadrone.limit.lap import closed_loop_lap

    cfg = load_airframe("HS210")
    flown = closed_loop_lap(build_airframe(cfg), TRACK)
    broken = replace(flown, x=np.full_like(flown.x, np.nan))
    opts, seeds = replace(FAST, starts=("closed-loop",)), LapSeeds(guess_trajectory=broken)
    without = design_limit_lap(cfg, TRACK, replace(opts, fallback_reference=None,
                                                   point_mass_reference=False), seeds)
    assert not without.completed and "no start converged" in without.reason
    lap = design_limit_lap(cfg, TRACK, opts, seeds)
    assert lap.completed, lap.reason
    assert lap.starts[-1].start == "reference-SY250" == lap.start
    assert not any(s.success for s in lap.starts[:-1])
    J3 = evaluate(theta_of(cfg), default_setup("HS210")).indices["J3"]
    assert lap.lap_time_s <= J3
    assert lap.resimulation_miss_m <= FAST.max_miss_m


QUAT = replace(FAST, attitude="quaternion", tilt_limit="cone")


def test_quaternion_and_euler_laps_agree_where_euler_is_regular():
    """SY250 on the paper track with the total tilt within 60° (a cone: the Euler angles stay
    regular): the Euler model's optimum, converted to quaternions, is an optimum of the
    quaternion model too, of the same time up to the RK4 discretisation of two state
    representations; both pass the re-simulation check of their own model."""
    euler = design_limit_lap(load_airframe("SY250"), TRACK, replace(FAST, tilt_limit="cone",
                                                                     max_tilt_deg=60.0))
    assert euler.completed, euler.reason
    assert np.degrees(np.abs(euler.x[:, 10]).max()) < 60.0 + 1e-3
    quat = design_limit_lap(load_airframe("SY250"), TRACK, replace(
        QUAT, max_tilt_deg=60.0, starts=()), LapSeeds(warm_starts=(euler,)))
    assert quat.completed, quat.reason
    assert quat.attitude == "quaternion" and quat.x.shape[1] == 17
    # observed: 6.041060 s against 6.041119 s (1e-5 relative)
    assert abs(quat.lap_time_s - euler.lap_time_s) <= 1e-4 * euler.lap_time_s
    np.testing.assert_allclose(quat.x_euler[:, 0:3], euler.x[:, 0:3], atol=0.05)
    # both drift alike open loop over the 6 s lap (observed 0.141 and 0.139 m)
    assert max(quat.resimulation_miss_m, euler.resimulation_miss_m) <= FAST.max_miss_m
    assert abs(quat.resimulation_miss_m - euler.resimulation_miss_m) <= 0.02


def test_split_s_is_flown_and_resimulated_within_5_cm():
    """The UZH track's split-S (gate 4 straight above gate 5, flown in opposite directions):
    the quaternion model with no tilt limit flies it, inverted between the two gates (body z
    pointing down), and its commands flown by CVODES pass every gate within 5 cm."""
    trk = load(TrackConfig, "configs/tracks/uzh-split-s.yaml")
    lap = design_limit_lap(load_airframe("SY250"), trk, replace(QUAT, tilt_limit="none"))
    assert lap.completed, lap.reason
    assert lap.resimulation_miss_m <= 0.05
    n = lap.layout.intervals
    between = lap.x[3 * n:4 * n + 1]  # from gate 4 to gate 5
    q = between[:, 9:13] / np.linalg.norm(between[:, 9:13], axis=1, keepdims=True)
    up_z = q[:, 0] ** 2 + q[:, 3] ** 2 - q[:, 1] ** 2 - q[:, 2] ** 2
    assert up_z.min() < 0.0
    assert lap.x[:, 2].min() >= -1e-6  # the floor


def test_two_periodic_laps_take_twice_one_periodic_lap():
    """The issue's acceptance: a closed circuit (the paper rectangle at 20 m, no climb, its
    start on its finish) flown from a flying start. With ``end: periodic`` the flying start is
    the lap's own optimal periodic state (x(T) = x(0), the start state optimised, the lap
    boundary anywhere in the finish ball, as every lap boundary inside a multi-lap flight).

    - two periodic laps are never slower than twice one (the one-lap orbit flown twice is a
      feasible two-lap orbit on the same grid: tolerance 0.1 % for local optima);
    - nor much faster: a two-lap orbit is two laps between lap-boundary states s and e, each at
      least the optimal lap from its start to its end, and the best s → s lap is 1 T1; that
      s → e → s beats it is not excluded by a theorem (a period-doubled orbit), so this is
      the measured property the issue asks for, |T2 − 2 T1| ≤ 0.5 % of 2 T1;
    - an independent integrator closes the orbit: the one-lap commands flown by CVODES from
      the optimised start state end where they began (position within 25 cm, velocity within
      0.25 m/s: the open-loop drift over a lap of a 20-interval grid, observed 82 mm and
      0.025 m/s; 19 mm and 0.011 m/s on another local optimum).

    20 intervals per leg and two starts keep it to a minute; the two-lap orbit repeats the
    one-lap grid, so both are on the same discretisation."""
    from casadrone.limit.check import resimulate

    frame = load_airframe("SY250")
    base = ["climb_to_m=null", "start_position_m=[0, 0, 20]", "end=periodic"]
    opts = replace(FAST, intervals=20, starts=("closed-loop", "point-mass"))
    one = design_limit_lap(frame, load(TrackConfig, DEFAULT_TRACK, base), opts)
    assert one.completed, one.reason
    two = design_limit_lap(frame, load(TrackConfig, DEFAULT_TRACK, [*base, "laps=2"]), opts)
    assert two.completed, two.reason
    assert len(two.lap_times_s) == 2
    np.testing.assert_allclose(two.lap_times_s.sum(), two.lap_time_s, rtol=1e-12)
    assert two.lap_time_s <= 2 * one.lap_time_s * (1 + 1e-3)
    assert abs(two.lap_time_s - 2 * one.lap_time_s) <= 5e-3 * 2 * one.lap_time_s
    np.testing.assert_allclose(one.x[-1], one.x[0], atol=1e-6)  # the periodic rows
    np.testing.assert_allclose(one.start_state, one.x_euler[0])
    flown = resimulate(build_airframe(frame), one)
    assert np.linalg.norm(flown[-1, 0:3] - one.x[0, 0:3]) <= 0.25
    assert np.linalg.norm(flown[-1, 3:6] - one.x[0, 3:6]) <= 0.25


def test_periodic_quaternion_and_euler_laps_agree_where_euler_is_regular():
    """The two attitude models' periodic rows (Euler: each angle back to itself up to full
    turns; quaternion: q(T) parallel to q(0), |q(0)| = 1) pose the same periodic lap where the
    Euler model is regular (tilt cone 60°, closed rectangle at 20 m, 20 intervals per leg): the
    quaternion lap started from the Euler optimum converges to it (observed 3.1e-5 relative, the
    two RK4 discretisations), with a unit start quaternion, and passes the re-simulation
    check."""
    frame = load_airframe("SY250")
    trk = load(TrackConfig, DEFAULT_TRACK, ["climb_to_m=null", "start_position_m=[0, 0, 20]",
                                            "end=periodic", "max_tilt_deg=60"])
    opts = replace(FAST, intervals=20, starts=("closed-loop",), tilt_limit="cone")
    euler = design_limit_lap(frame, trk, opts)
    assert euler.completed, euler.reason
    quat = design_limit_lap(frame, trk, replace(opts, attitude="quaternion", starts=()),
                            LapSeeds(warm_starts=(euler,)))
    assert quat.completed, quat.reason
    np.testing.assert_allclose(quat.lap_time_s, euler.lap_time_s, rtol=3e-4)
    np.testing.assert_allclose(np.linalg.norm(quat.x[0, 9:13]), 1.0, atol=1e-8)
