"""The pack's energy and current limits (casadrone.propulsion.electric, casadrone.limit.energy):
the OCV interpolation against a published curve, a hover's charge against the closed-form
current, the two energy balances of a re-simulated flight, a race the pack cannot fly refused
naming the pack, the current rows of the limit lap, and bad pack values refused."""

from __future__ import annotations

import math
from dataclasses import replace
from types import SimpleNamespace

import casadi as ca
import numpy as np
import pytest
from typer.testing import CliRunner

from casadrone.airframe import build_airframe
from casadrone.cli import app
from casadrone.config.airframe import load_airframe
from casadrone.limit.check import fly
from casadrone.limit.energy import flight_energy, race_energy
from casadrone.limit.nlp import CURRENT_MARGIN, Layout, current_rows, quadrotor_ocp_model
from casadrone.model import named
from casadrone.propulsion import hover_rotors
from casadrone.propulsion.electric import SMOOTHING_SHARE, Pack, ocv_cell, soc_of_voltage


#: Chen and Rincón-Mora, "Accurate electrical battery model capable of predicting runtime and
#: I-V performance", IEEE Trans. Energy Conversion 21(2), 504-511, 2006, eq. (1): the open-circuit
#: voltage (V) of a TCL PL-383562 polymer Li-ion cell against its state of charge.
def chen_ocv(s):
    return (-1.031 * np.exp(-35 * s) + 3.685 + 0.2156 * s - 0.1178 * s**2 + 0.3201 * s**3)


SOC = (0.0, 0.01, 0.02, 0.03, 0.05, 0.075, 0.1, 0.15, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9,
       1.0)
CURVE = tuple((s, float(chen_ocv(s))) for s in SOC)


@pytest.fixture(scope="module")
def frame():
    return build_airframe(load_airframe("SY250-propeller", []))


def hover(frame, seconds: float, intervals: int = 10):
    """(t, x0, u) of a hover held ``seconds``."""
    w, d = hover_rotors(frame, frame.hover_thrusts())
    x0 = np.zeros(16)
    x0[12:16] = w
    return np.linspace(0, seconds, intervals + 1), x0, np.tile(d, (intervals, 1))


def test_ocv_passes_the_published_curve_and_rises_numbers_and_casadi_alike():
    s = np.array(SOC)
    # at the table's points within the rounding of the corners: ε |Δm_k| / 2 of its own corner,
    # plus at most ε²/(4 d) ≤ ε/40 |Δm_j| of every other corner j (d ≥ 10 ε away), ε one tenth
    # of the smallest spacing; 5 mV here, at the steepest corners near empty
    m = np.diff([v for _, v in CURVE]) / np.diff(s)
    eps = SMOOTHING_SHARE * np.diff(s).min()
    dm = np.abs(np.diff(m))
    own = np.r_[0.0, eps * dm / 2, 0.0]
    bound = own + eps / 40 * dm.sum() + 1e-12
    assert bound.max() < 5.5e-3
    assert np.all(np.abs(ocv_cell(s, CURVE) - chen_ocv(s)) <= bound)
    # between them within linear interpolation's error h² max|V''| / 8 of each interval (the
    # table is linear between its points, the curve is not) plus the rounding's bound
    mid = 0.5 * (s[1:] + s[:-1])
    h = np.diff(s)
    def curvature(a, b):  # |V''| of eq. (1) over [a, b], largest
        z = np.linspace(a, b, 50)
        return np.abs(-1.031 * 35**2 * np.exp(-35 * z) - 0.2356 + 1.9206 * z).max()

    lin = h**2 * np.array([curvature(a, b) for a, b in zip(s[:-1], s[1:], strict=True)]) / 8
    assert np.all(np.abs(ocv_cell(mid, CURVE) - chen_ocv(mid)) <= lin + bound.max())
    fine = np.linspace(0, 1, 5001)
    assert np.all(np.diff(ocv_cell(fine, CURVE)) > 0)
    x = ca.SX.sym("s")
    f = ca.Function("ocv", [x], [ocv_cell(x, CURVE)])
    np.testing.assert_allclose(np.asarray(f(mid)).ravel(), ocv_cell(mid, CURVE), rtol=1e-14)


def test_soc_of_voltage_inverts_the_curve_and_energy_of_a_linear_curve():
    pack = Pack(capacity_ah=0.65, resistance_ohm=0.04, open_circuit_voltage_v=4 * 3.9,
                cells=4, ocv_curve=CURVE)
    s0 = pack.start_soc
    assert 4 * ocv_cell(s0, CURVE) == pytest.approx(15.6, abs=1e-9)
    assert 0.7 < s0 < 0.8  # 3.9 V lies between the curve's 3.888 V (0.7) and 3.946 V (0.8)
    # a linear cell curve 3 V + 1.2 V s: energy from s = 1 to 0.5 is 3600 C cells ∫ (3 + 1.2 s) ds
    lin = Pack(capacity_ah=2.0, resistance_ohm=0.0, open_circuit_voltage_v=8.4, cells=2,
               ocv_curve=((0.0, 3.0), (1.0, 4.2)))
    exact = 3600 * 2.0 * 2 * (3.0 * 0.5 + 0.6 * (1.0 - 0.25))
    assert lin.energy_j(1.0, 0.5) == pytest.approx(exact, rel=1e-9)
    assert soc_of_voltage(lin, 2 * 3.6) == pytest.approx(0.5, abs=1e-9)


def test_hover_draws_a_constant_current_and_the_charge_falls_linearly(frame):
    """Oracle: at hover each motor carries I_i = I₀ + K_V Q_i with Q_i = CP₀ ρ n² D⁵ / (2π) the
    static shaft torque (n = ω/2π), the pack Σ δ_i I_i; over t seconds the state of charge falls
    by I t / (3600 C)."""
    t, x0, u = hover(frame, 2.0)
    q = {k: float(v) for k, v in named(frame.p).items()}
    n = x0[12:16] / (2 * math.pi)
    torque = q["cp0"] * q["rho"] * n**2 * q["prop_D"] ** 5 / (2 * math.pi)
    current = float(np.dot(u[0], q["motor_I0"] + q["motor_kv"] * torque))
    energy = flight_energy(frame, t, x0, u)
    np.testing.assert_allclose(energy.pack_current_a, current, rtol=1e-9)
    np.testing.assert_allclose(energy.charge_c, current * energy.t_s, rtol=1e-8, atol=1e-12)
    pack = Pack(capacity_ah=0.65, resistance_ohm=0.04, open_circuit_voltage_v=16.8)
    account = race_energy(energy, pack, [1.0, 1.0])
    assert account.feasible
    assert 1.0 - account.end_soc == pytest.approx(current * 2.0 / (3600 * 0.65), rel=1e-8)
    assert account.soc_at_lap_end[0] == pytest.approx(1 - current / (3600 * 0.65), rel=1e-9)


def test_pack_energy_equals_the_rotor_loads_over_a_flight_with_steps(frame):
    """Acceptance: the energy from the pack, ∫ V I dt, equals the rotors' shaft work, kinetic
    energy and the motors' losses within 0.5 %, over commands that step up and down."""
    t, x0, u = hover(frame, 0.5, intervals=20)
    u[4:9] = 0.9
    u[9:13] = [0.05, 0.3, 0.05, 0.3]
    energy = flight_energy(frame, t, x0, u)
    assert abs(energy.energy_pack_j - energy.energy_rotor_j) <= 5e-3 * energy.energy_pack_j
    # every term of the rotors' side is there (the steps spin the rotors up and down)
    assert energy.copper_j > 0.05 * energy.energy_pack_j
    assert energy.no_load_j > 0 and abs(energy.kinetic_j) > 1e-3
    assert energy.pack_current_a.max() > 5 * energy.pack_current_a[0]


def test_a_pack_too_small_for_the_race_is_refused_naming_it(frame):
    """A 4S 5 mAh pack at hover (~2.85 A) holds 18 C: empty after ~6.3 s, in lap 3 of four
    2.5 s laps; the time follows from the constant current."""
    t, x0, u = hover(frame, 10.0, intervals=40)
    energy = flight_energy(frame, t, x0, u)
    pack = Pack(capacity_ah=0.005, resistance_ohm=0.04, open_circuit_voltage_v=16.8, cells=4)
    account = race_energy(energy, pack, [2.5] * 4)
    current = energy.pack_current_a[0]
    assert not account.feasible
    assert account.empty_in_lap == 3
    assert account.empty_at_s == pytest.approx(3600 * 0.005 / current, rel=1e-6)
    assert "4S 5 mAh pack empty in lap 3 of 4" in account.reason
    assert account.energy_left_wh == 0.0


def test_a_current_above_its_limit_is_named(frame):
    t, x0, u = hover(frame, 0.2, intervals=4)
    energy = flight_energy(frame, t, x0, u)
    peak = energy.pack_current_a.max()
    pack = Pack(capacity_ah=1.0, resistance_ohm=0.04, open_circuit_voltage_v=16.8, c_rating=1.0)
    assert not race_energy(energy, replace(pack, c_rating=0.99 * peak), [0.2]).feasible
    ok = race_energy(energy, replace(pack, c_rating=1.01 * peak), [0.2])
    assert ok.feasible and ok.pack_current_margin_a == pytest.approx(0.01 * peak, rel=1e-6)
    motor = energy.motor_current_a.max()
    assert "max_current_a" in race_energy(energy, replace(pack, c_rating=None), [0.2],
                                          0.99 * motor).reason


def test_current_rows_are_the_currents_at_both_ends_of_every_interval(frame):
    """The limit lap's rows equal the re-simulation's currents at the nodes (the same model,
    two code paths), and without limits there are none (the NLP unchanged)."""
    model = quadrotor_ocp_model("propeller")
    layout = Layout(("ball",), intervals=3)
    X, U, p = ca.SX.sym("X", 16, 4), ca.SX.sym("U", 4, 3), ca.SX.sym("p", model.np)
    assert current_rows(model, layout, X, U, p) == []
    limited = replace(layout, max_pack_current_a=40.0, max_motor_current_a=30.0)
    (g, lo, hi), = current_rows(model, limited, X, U, p)
    assert g.numel() == 2 * 3 * 5 and np.all(np.isinf(lo))
    np.testing.assert_allclose(hi[:5], np.array([40.0, 30.0, 30.0, 30.0, 30.0])
                               * (1 - CURRENT_MARGIN), rtol=1e-15)
    t, x0, u = hover(frame, 0.03, intervals=3)
    u[1] = 0.6
    energy = flight_energy(frame, t, x0, u)
    nodes = np.array([0, 4, 5, 9, 10, 14])  # samples: interval starts, then each one's end
    f = ca.Function("rows", [X, U, p], [g])
    # the nodes CVODES flies from x0, as the limit lap's re-simulation check does
    Xn = fly(frame, SimpleNamespace(t=t, u=u, x=np.tile(x0, (4, 1)))).T
    rows = np.asarray(f(Xn, u.T, frame.p)).ravel().reshape(2, 3, 5)
    sampled_pack = energy.pack_current_a[nodes].reshape(3, 2)
    np.testing.assert_allclose(rows[0, :, 0], sampled_pack[:, 0], rtol=1e-8)  # starts
    np.testing.assert_allclose(rows[1, :, 0], sampled_pack[:, 1], rtol=1e-8)  # ends
    sampled_motor = energy.motor_current_a[nodes].reshape(3, 2, 4)
    np.testing.assert_allclose(rows[1, :, 1:], sampled_motor[:, 1], rtol=1e-8)


def _cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


@pytest.mark.parametrize(("override", "key", "why"), [
    ("propulsion.battery.capacity_ah=-0.65", "propulsion.battery.capacity_ah", "greater than 0"),
    ("propulsion.battery.c_rating=0", "propulsion.battery.c_rating", "greater than 0"),
    ("propulsion.motor.max_current_a=0", "propulsion.motor.max_current_a", "greater than 0"),
    ("propulsion.battery.ocv_curve=[[0,3.3],[0.5,3.2],[1,4.2]]",
     "propulsion.battery.ocv_curve", "increasing"),
    ("propulsion.battery.ocv_curve=[[0.1,3.3],[1,4.2]]", "propulsion.battery.ocv_curve",
     "rise from 0 to 1"),
])
def test_bad_pack_values_are_refused_in_one_line_naming_file_and_key(override, key, why):
    extra = [] if "capacity_ah" in override else ["propulsion.battery.capacity_ah=0.65",
                                                  "propulsion.battery.cells=4"]
    result = _cli("limit-lap", "SY250-propeller", override, *extra, "--json")
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    line, = result.stderr.splitlines()
    assert "SY250-propeller.yaml" in line and f"{key}:" in line and why in line


def test_a_start_voltage_outside_the_curve_is_refused():
    result = _cli("limit-lap", "SY250-propeller", "propulsion.battery.capacity_ah=0.65",
                  "propulsion.battery.cells=4",
                  f"propulsion.battery.ocv_curve={[list(p) for p in CURVE]}")
    line, = result.stderr.splitlines()
    assert result.exit_code == 2
    assert "propulsion.battery.open_circuit_voltage_v: 16.8 V is outside" in line



def test_a_seeded_lap_solves_its_seeds_alone_then_its_starts_where_they_fail(monkeypatch):
    """A race seeded by a neighbour's (the build's continuation) solves from the seeds alone: no
    cold start, no fallback start or reference; only where that gives no verified lap does it
    solve from the options' starts. Unseeded, it solves from the starts once."""
    from types import SimpleNamespace

    from casadrone.limit import race as race_mod
    from casadrone.limit.result import LapSeeds, LimitLapOptions

    calls: list[tuple] = []
    outcomes: list[bool] = []

    def fake(cfg, track, options, seeds=LapSeeds(), frame=None, pool=None):
        calls.append((options.starts, options.fallback_starts, options.fallback_reference,
                      len(seeds.warm_starts)))
        return SimpleNamespace(completed=outcomes.pop(0))
    monkeypatch.setattr(race_mod, "design_limit_lap", fake)
    options = LimitLapOptions(starts=("library",), fallback_starts=("coarse-grid",))
    seeded = LapSeeds(warm_starts=("neighbour",))  # type: ignore[arg-type]
    for outcome, seeds, want in (
            ([True], seeded, [((), (), None, 1)]),
            ([False, True], seeded, [((), (), None, 1),
                                     (("library",), ("coarse-grid",), "SY250", 0)]),
            ([True], LapSeeds(), [(("library",), ("coarse-grid",), "SY250", 0)])):
        calls.clear()
        outcomes[:] = outcome
        race_mod.seeded_lap(None, None, options, seeds, None, None)
        assert calls == want
