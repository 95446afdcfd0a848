"""Every propulsion model of the registry, the worked example's third model included
(examples/plugins/thrust_curve.py, docs/architecture.md#new-propulsion-model), against the same
oracles: the symbolic model itself (its rotor rows vanish and its thrust is the asked one at the
hover states the entry gives), the weight a hover trim must carry, and the registry's refusals.
"""

from __future__ import annotations

import math
import runpy
from pathlib import Path

import numpy as np
import pytest

from casadrone.airframe import build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.io import ConfigError
from casadrone.drag import DRAG_PARAM_NAMES
from casadrone.model import NP, NX, THR, param_names, quadrotor_model, rotor_thrusts, state_names
from casadrone.propulsion import (
    PROPULSION_MODELS,
    hover_rotors,
    max_static_thrust,
    propulsion_model,
    register_propulsion_model,
    rotor_state_bounds,
)
from casadrone.trim import trim

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "plugins" / "thrust_curve.py"

#: An airframe of each model: the shipped reference where there is one, else SY250 with the
#: model named (a model that reads no section needs nothing more).
SHIPPED = {"paper": "SY250", "propeller": "SY250-propeller"}
MODELS = sorted({*PROPULSION_MODELS, "thrust-curve"})  # the built-ins and the example


@pytest.fixture(autouse=True, scope="module")
def _example_registered():
    """The example's model, registered by running the plugin, and unregistered after these
    tests (as the other registries' examples are, tests/unit/test_registries.py)."""
    saved = dict(PROPULSION_MODELS)
    runpy.run_path(str(EXAMPLE))
    yield
    PROPULSION_MODELS.clear()
    PROPULSION_MODELS.update(saved)


def frame_of(name: str):
    if name in SHIPPED:
        return build_airframe(load_airframe(SHIPPED[name]))
    return build_airframe(load_airframe("SY250", [f"propulsion.model={name}"]))


def test_the_example_is_registered_beside_the_built_ins():
    assert {"paper", "propeller", "thrust-curve"} <= set(PROPULSION_MODELS)


@pytest.mark.parametrize("name", MODELS)
def test_parameter_layout_and_state_names_are_the_models(name):
    model, frame = PROPULSION_MODELS[name], frame_of(name)
    assert frame.propulsion == name
    drag = DRAG_PARAM_NAMES if model.drag_forms else ()  # the body-drag switch after them
    assert len(frame.p) == NP + len(model.param_names) + len(drag) == len(param_names(name))
    assert param_names(name)[NP:] == model.param_names + drag
    assert state_names(name)[12:] == model.rotor_states.names
    assert quadrotor_model(name).state_names == state_names(name)


def _rest_residual(frame, rotors, commands) -> np.ndarray:
    """F(0, x, u, p) at rest (level, no velocity or rates) with the given rotor states."""
    x = np.zeros(NX)
    x[THR] = rotors
    res = quadrotor_model(frame.propulsion).F(np.zeros(NX), x, commands, frame.p)
    return np.asarray(res, float).ravel()


@pytest.mark.parametrize("name", MODELS)
def test_hover_states_hold_the_asked_thrusts_in_the_symbolic_model(name):
    """The entry's hover states and commands are a rest point of the model's own rotor dynamics,
    and the model's thrust there is the asked one (unequal thrusts: each rotor its own)."""
    frame = frame_of(name)
    asked = np.array([0.2, 0.35, 0.5, 0.65]) * max_static_thrust(frame)
    rotors, commands = hover_rotors(frame, asked)
    assert all(0 < c < 1 for c in commands)
    res = _rest_residual(frame, rotors, commands)
    np.testing.assert_allclose(res[12:16], 0.0, atol=1e-9)  # N, or N·m (propeller)
    thrust = np.asarray(rotor_thrusts(np.zeros(3), np.zeros(3), rotors, frame.p, name),
                        float).ravel()
    np.testing.assert_allclose(thrust, asked, rtol=1e-10)


@pytest.mark.parametrize("name", MODELS)
def test_the_largest_static_thrust_is_full_command(name):
    frame = frame_of(name)
    full = max_static_thrust(frame)
    rotors, commands = hover_rotors(frame, np.full(4, full))
    np.testing.assert_allclose(commands, 1.0, rtol=1e-9)
    lo, hi = rotor_state_bounds(frame)
    assert lo <= min(rotors) and max(rotors) <= hi


@pytest.mark.parametrize("name", MODELS)
def test_hover_trim_carries_the_weight(name):
    """Oracle: at hover the four thrusts sum to m g (and the trim's own check passes)."""
    frame = frame_of(name)
    tp = trim(frame, "hover", solver="newton")
    assert tp.success, tp.message
    np.testing.assert_allclose(tp.thrusts.sum(), frame.mass * frame.gravity, rtol=1e-9)


@pytest.mark.parametrize("name", MODELS)
def test_decay_rate_is_at_most_the_rotor_rows_own_damping(name):
    """The exponential step's rate λ(p) is the part of −∂ẋ_rotor/∂x_rotor that depends on p
    only: equal to it where the rotor dynamics are linear (thrust lags), below it where the
    propeller's load adds damping (the full Jacobian, at hover)."""
    import casadi as ca

    frame = frame_of(name)
    model = quadrotor_model(name)
    rotors, commands = hover_rotors(frame, np.full(4, frame.mass * frame.gravity / 4))
    x = np.zeros(NX)
    x[THR] = rotors
    xs = ca.MX.sym("x", NX)
    jac = np.asarray(ca.Function("j", [xs], [ca.jacobian(model.f(xs, commands, frame.p), xs)])(x),
                     float)
    own = -np.diag(jac[12:16, 12:16])
    from casadrone.model import named

    rate = float(propulsion_model(name).decay_rate(named(frame.p, name)))
    assert rate > 0
    if PROPULSION_MODELS[name].thrust_is_state:
        np.testing.assert_allclose(own, rate, rtol=1e-12)
    else:
        assert np.all(rate <= own * (1 + 1e-12))


def test_the_example_follows_px4s_thrust_curve():
    """T_ss(δ) = K ((1 − f) δ + f δ²), f = 0.5: half the full thrust at δ = (√5 − 1)/2 ≈ 0.618
    (f δ² + (1 − f) δ = 1/2 solved by hand), and the model's rest thrust at δ = 0.5 is
    K (0.25 + 0.125) = 0.375 K."""
    frame = frame_of("thrust-curve")
    K = frame.thrust_gain
    _, commands = hover_rotors(frame, np.full(4, K / 2))
    np.testing.assert_allclose(commands, (math.sqrt(5) - 1) / 2, rtol=1e-12)
    res = _rest_residual(frame, np.full(4, 0.375 * K), np.full(4, 0.5))
    np.testing.assert_allclose(res[12:16], 0.0, atol=1e-12)


def test_the_schema_takes_its_choices_from_the_registry():
    with pytest.raises(ConfigError, match="not a propulsion model; known: paper, propeller"):
        load_airframe("SY250", ["propulsion.model=jet"])
    with pytest.raises(ConfigError, match="thrust-curve uses no propeller, motor, battery section"):
        load_airframe("SY250-propeller", ["propulsion.model=thrust-curve"])
    with pytest.raises(ConfigError, match="thrust.time_constant_s"):  # not the lag-free model
        load_airframe("SY250", ["propulsion.model=thrust-curve", "thrust.time_constant_s=0"])


def test_the_registry_refuses_a_taken_name_or_layout_length():
    with pytest.raises(ValueError, match="registered already"):
        register_propulsion_model(PROPULSION_MODELS["paper"])

    class SameLength:
        name = "another"
        param_names = ("a",)  # as long as thrust-curve's

    with pytest.raises(ValueError, match="tells models apart"):
        register_propulsion_model(SameLength())  # type: ignore[arg-type]
    assert "another" not in PROPULSION_MODELS
    with pytest.raises(ValueError, match="unknown propulsion model 'jet'; choose one of paper"):
        propulsion_model("jet")


def test_a_new_model_reaches_the_command_line(cli_runner):
    from casadrone.cli import app

    done = cli_runner.invoke(app, ["trim", "SY250", "propulsion.model=thrust-curve", "--solver",
                                   "newton", "--json"])
    assert done.exit_code == 0, done.output
    assert '"success": true' in done.output


def test_the_typed_parameter_record_names_the_entries_of_p():
    """named(p) reads p through the typed records (PaperParams, PropellerParams): each name gives
    the airframe's own value, read from the Airframe's attributes and the YAML section (the
    oracle), so the records' field order is the vector's packing order."""
    from casadrone.model import named
    from casadrone.propulsion.propeller import PropellerParams

    cfg = load_airframe("SY250-propeller")
    frame = build_airframe(cfg)
    q = named(frame.p, "propeller")
    assert list(q) == list(PropellerParams.__annotations__) == list(param_names("propeller"))
    assert q["mass"] == frame.mass and q["Ixy"] == frame.inertia[0, 1]
    assert q["Izz"] == frame.inertia[2, 2] and q["r2y"] == frame.rotor_positions[1, 1]
    assert q["r4z"] == frame.rotor_positions[3, 2] and q["s3"] == frame.rotor_spins[2]
    assert q["kappa"] == frame.kappa and q["CdA_y"] == frame.drag_area[1]
    assert (q["rho"], q["K"], q["tau"], q["g"]) == (frame.air_density, frame.thrust_gain,
                                                    frame.thrust_time_constant, frame.gravity)
    assert q["prop_D"] == 0.127 and q["ct1"] == -0.10647 and q["cp2"] == -0.16208  # the YAML's
    assert q["drag_isotropic"] == 1.0  # drag_model: isotropic, the racing preset's
    assert q["motor_kv"] == pytest.approx(2300 * 2 * math.pi / 60, rel=1e-15)  # rpm/V → rad/s/V
    assert (q["motor_R"], q["motor_I0"], q["batt_Voc"], q["batt_R"]) == (0.075, 1.4, 16.8, 0.040)
    assert q["rotor_J"] == 6.4e-6 and q["rotor_kd"] == 8.0e-6 and q["motor_dc"] == 1.0
