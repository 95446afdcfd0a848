"""Physically impossible propulsion sections are refused (casadrone.config.propulsion): exit 2
and one line ``FILE: key: message`` from the CLI, a validation error naming the key from the API;
real racing quads (and every shipped airframe) still load. The oracles are written out here from
momentum theory, the rotor's geometry and the DC motor's equations, not taken from the code."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from pydantic import ValidationError

from casadrone.config import load_airframe, resolve_config
from casadrone.config.io import ConfigError
from casadrone.config.propulsion import MotorConfig, PropellerConfig

RHO, D, MASS = 1.225, 0.127, 0.320  # SY250-propeller's air, propeller and mass
CT0, CP0 = 0.20939, 0.13199  # its static coefficients
KV_RAD = 2300 * 2 * math.pi / 60  # its motor's K_V (rad/s per V)
R_MOTOR = 0.075  # its winding resistance (Ω)


def _frame(tmp_path: Path, **changes) -> Path:
    """SY250-propeller written to tmp_path with dotted keys changed (a value None deletes)."""
    data = yaml.safe_load(resolve_config("SY250-propeller", "airframes").read_text("utf-8"))
    for dotted, value in changes.items():
        node = data
        *parents, last = dotted.split("__")
        for part in parents:
            node = node[part]
        if value is None:
            node.pop(last, None)
        else:
            node[last] = value
    path = tmp_path / "frame.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _refused_line(cli_runner, path: Path, key: str) -> str:
    """The one stderr line of ``casadrone trim path`` (exit 2), which names the file and key."""
    from casadrone.cli import app

    result = cli_runner.invoke(app, ["trim", str(path)])
    assert result.exit_code == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"{path}: {key}: "), lines[0]
    return lines[0]


def _loads(path: Path):
    return load_airframe(path)


def _ideal_fm(T: float, P: float, diameter: float = D, rho: float = RHO) -> float:
    """Figure of merit from momentum theory in SI units: T^{3/2}/√(2ρA) over the shaft power."""
    return T**1.5 / math.sqrt(2 * rho * math.pi * diameter**2 / 4) / P


# ---------------------------------------------------------------------------------------------
# 1. Momentum theory: figure of merit, positive power over the advance-ratio range
# ---------------------------------------------------------------------------------------------


def _fm_of_coefficients(ct0: float, cp0: float, n: float = 300.0) -> float:
    return _ideal_fm(ct0 * RHO * n**2 * D**4, cp0 * RHO * n**3 * D**5)


def test_shipped_propeller_has_a_possible_figure_of_merit():
    from casadrone.propulsion.data import figure_of_merit

    fm = _fm_of_coefficients(CT0, CP0)
    assert 0.5 < fm < 0.7  # a real 5-inch propeller (hand: 0.577)
    assert figure_of_merit(CT0, CP0) == pytest.approx(fm, rel=1e-12)


def test_figure_of_merit_above_one_is_refused(tmp_path, cli_runner):
    fm = _fm_of_coefficients(CT0, 0.001)
    assert fm == pytest.approx(76.4, abs=0.1)  # hand: √(2/π) 0.20939^1.5 / 0.001 = 76.45
    line = _refused_line(cli_runner, _frame(tmp_path, propulsion__propeller__cp_coefficients=[
        0.001]), "propulsion.propeller.cp_coefficients")
    assert f"{fm:.3g}" in line and "momentum" in line


def test_thrust_coefficient_beyond_momentum_theory_is_refused(tmp_path, cli_runner):
    # the pair is refused on the power that is too small for the thrust; the line names both
    line = _refused_line(cli_runner, _frame(tmp_path, propulsion__propeller__ct_coefficients=[
        1e6]), "propulsion.propeller.cp_coefficients")
    assert "ct_coefficients" in line and f"{_fm_of_coefficients(1e6, CP0):.3g}" in line


def test_figure_of_merit_bound_is_at_one():
    fm_one_cp = math.sqrt(2 / math.pi) * CT0**1.5  # the C_P0 of FM = 1, by hand
    assert _fm_of_coefficients(CT0, fm_one_cp) == pytest.approx(1.0, rel=1e-12)
    PropellerConfig(diameter_m=D, ct_coefficients=(CT0,), cp_coefficients=(fm_one_cp * 1.001,))
    with pytest.raises(ValidationError, match="cp_coefficients"):
        PropellerConfig(diameter_m=D, ct_coefficients=(CT0,),
                        cp_coefficients=(fm_one_cp * 0.999,))


def test_negative_shaft_power_within_the_data_is_refused(tmp_path, cli_runner):
    # CP = 0.13 − 5 J is zero at J = 0.026, inside the shipped data's J ≤ 0.854, where CT > 0
    line = _refused_line(cli_runner, _frame(tmp_path, propulsion__propeller__cp_coefficients=[
        0.13, -5.0]), "propulsion.propeller.cp_coefficients")
    assert "J = 0.026" in line


def test_power_below_the_ideal_climb_power_is_refused():
    """C_P = C_P0 − 0.15 J stays positive to J = 0.88, beyond the data (J ≤ 0.854), but falls
    below the actuator disc's climb power C_T (J/2 + √(J²/4 + 2 C_T/π)) inside it: refused; the
    shipped C_P stays at least 1.3 times above it (hand, 7 points)."""
    ct = [CT0, -0.10647, -0.18471]
    cp_shipped = [CP0, 0.0012666, -0.16208]
    cp_low = [CP0, -0.15, 0.0]
    j_max = 0.854119

    def ratio(cp, J):
        c = ct[0] + ct[1] * J + ct[2] * J**2
        return (cp[0] + cp[1] * J + cp[2] * J**2) / (c * (J / 2 + math.sqrt(J**2 / 4
                                                                          + 2 * c / math.pi)))

    assert cp_low[0] + cp_low[1] * j_max > 0
    assert min(ratio(cp_shipped, 0.8 * k / 6) for k in range(7)) > 1.3
    assert min(ratio(cp_low, 0.8 * k / 6) for k in range(7)) < 1 < ratio(cp_low, 0.0)
    with pytest.raises(ValidationError, match="cp_coefficients") as info:
        PropellerConfig(diameter_m=D, ct_coefficients=tuple(ct), cp_coefficients=tuple(cp_low),
                        data="uiuc-da4022-5x3.75-3blade")
    assert "climb" in str(info.value)


def test_without_a_range_power_must_stay_positive_while_there_is_thrust():
    ct = (CT0, -0.095082, -0.20608)  # zero thrust at J = 0.80
    with pytest.raises(ValidationError, match="cp_coefficients"):
        PropellerConfig(diameter_m=D, ct_coefficients=ct, cp_coefficients=(0.13, -5.0),
                        data="a stand's fit, no wind tunnel")
    # a static fit (what fit-propulsion writes without a shape) is a possible propeller
    PropellerConfig(diameter_m=D, ct_coefficients=(0.115,), cp_coefficients=(0.058,),
                    data="stand.csv (casadrone fit-propulsion): static coefficients only")


def test_linear_inflow_figure_of_merit_above_one_is_refused(tmp_path, cli_runner):
    k_eta, k_m = 1.7e-6, 1e-9
    w = 2000.0  # rad/s: T = k_η ω², P = Q ω = k_m ω³
    fm = _ideal_fm(k_eta * w**2, k_m * w**3)
    assert fm > 1
    path = _frame(tmp_path, propulsion__propeller__ct_coefficients=None,
                  propulsion__propeller__cp_coefficients=None,
                  propulsion__propeller__linear_inflow={"k_eta_n_s2": k_eta, "k_m_n_m_s2": k_m})
    line = _refused_line(cli_runner, path, "propulsion.propeller.linear_inflow.k_m_n_m_s2")
    assert f"{fm:.3g}" in line
    # the literature's values (tests/unit/test_propulsion.py) are a possible rotor: FM 0.48;
    # without k_z its thrust would hold up in climb, so no dataset's advance ratios (data: the
    # shipped propeller's, up to J 0.62) are claimed for it here (the climb check: audit tests)
    assert _ideal_fm(k_eta * w**2, 2.6e-8 * w**3) < 1
    path = _frame(tmp_path, propulsion__propeller__ct_coefficients=None,
                  propulsion__propeller__cp_coefficients=None,
                  propulsion__propeller__data=None,
                  propulsion__propeller__linear_inflow={"k_eta_n_s2": k_eta,
                                                        "k_m_n_m_s2": 2.6e-8})
    assert _loads(path).propulsion.propeller.linear_inflow.k_m_n_m_s2 == 2.6e-8


# ---------------------------------------------------------------------------------------------
# 2-4. Rotor inertia, winding resistance, first-order time constant
# ---------------------------------------------------------------------------------------------


def test_rotor_inertia_above_a_quarter_of_the_vehicle_at_the_tips_is_refused(tmp_path,
                                                                            cli_runner):
    ceiling = (MASS / 4) * (D / 2) ** 2  # a quarter of the vehicle, all at the tip radius
    line = _refused_line(cli_runner, _frame(tmp_path, propulsion__propeller__rotor_inertia_kgm2=1),
                         "propulsion.propeller.rotor_inertia_kgm2")
    assert f"{ceiling:.3g}" in line
    _loads(_frame(tmp_path, propulsion__propeller__rotor_inertia_kgm2=0.99 * ceiling))
    with pytest.raises(ConfigError, match="rotor_inertia_kgm2"):
        _loads(_frame(tmp_path, propulsion__propeller__rotor_inertia_kgm2=1.01 * ceiling))


def test_rotor_inertia_faster_than_the_esc_is_refused(tmp_path, cli_runner):
    floor = 10 / 128e3 / (R_MOTOR * KV_RAD**2)  # τ_m = J R K_V² ≥ ten 128 kHz PWM periods
    line = _refused_line(cli_runner, _frame(tmp_path,
                                            propulsion__propeller__rotor_inertia_kgm2=1e-30),
                         "propulsion.propeller.rotor_inertia_kgm2")
    assert f"{floor:.3g}" in line
    _loads(_frame(tmp_path, propulsion__propeller__rotor_inertia_kgm2=1.01 * floor))
    # the shipped rotor is 350 times above it (τ_m = 28 ms)
    assert 6.4e-6 * R_MOTOR * KV_RAD**2 == pytest.approx(0.0278, rel=1e-2)


def test_winding_resistance_below_its_leads_is_refused(tmp_path, cli_runner):
    leads = 2 * 0.03 * 1.68e-8 / 3.31e-6  # two 3 cm leads of 12 AWG copper (Ω)
    assert leads == pytest.approx(3.0e-4, rel=0.02)
    _refused_line(cli_runner, _frame(tmp_path, propulsion__motor__resistance_ohm=1e-9),
                  "propulsion.motor.resistance_ohm")
    MotorConfig(kv_rpm_per_v=2300, resistance_ohm=3e-4)
    with pytest.raises(ValidationError, match="resistance_ohm"):
        MotorConfig(kv_rpm_per_v=2300, resistance_ohm=2.9e-4)


def test_first_order_time_constant_faster_than_the_esc_is_refused(tmp_path, cli_runner):
    _refused_line(cli_runner, _frame(tmp_path, propulsion__motor__kind="first-order",
                                     propulsion__motor__time_constant_s=1e-12),
                  "propulsion.motor.time_constant_s")
    MotorConfig(kv_rpm_per_v=2300, kind="first-order", time_constant_s=10 / 128e3)
    with pytest.raises(ValidationError, match="time_constant_s"):
        MotorConfig(kv_rpm_per_v=2300, kind="first-order", time_constant_s=7e-5)


# ---------------------------------------------------------------------------------------------
# 5. Supersonic tips
# ---------------------------------------------------------------------------------------------


def test_supersonic_tips_are_refused(tmp_path, cli_runner):
    line = _refused_line(cli_runner, _frame(tmp_path,
                                            propulsion__battery__open_circuit_voltage_v=999),
                         "propulsion.battery.open_circuit_voltage_v")
    assert "343" in line


def test_tip_speed_bound_at_the_speed_of_sound():
    """First-order motor: the steady full-command speed is K_V V_oc, so the tips reach 343 m/s at
    V_oc = 343 / (K_V D/2) = 22.4 V (hand): just below loads, just above is refused."""
    v_sonic = 343.0 / (KV_RAD * D / 2)
    assert v_sonic == pytest.approx(22.43, abs=0.01)
    base = ["propulsion.motor.kind=first-order"]
    load_airframe("SY250-propeller", [*base, f"propulsion.battery.open_circuit_voltage_v="
                                      f"{0.99 * v_sonic}"])
    with pytest.raises(ConfigError, match="open_circuit_voltage_v"):
        load_airframe("SY250-propeller", [*base, f"propulsion.battery.open_circuit_voltage_v="
                                          f"{1.01 * v_sonic}"])


def test_a_6s_racing_setup_whose_no_load_tips_are_supersonic_loads():
    """A 6S 5.1-inch racer with 2522 KV motors (top-level racing builds run such): its no-load
    speed K_V V_oc would put the tips at 428 m/s, but loaded by the propeller at full command
    the DC motor turns it far slower, subsonic; it is not refused."""
    kv, voc, d = 2522, 25.2, 0.1295
    assert kv * 2 * math.pi / 60 * voc * d / 2 > 343
    load_airframe("SY250-propeller", [
        f"propulsion.motor.kv_rpm_per_v={kv}", "propulsion.motor.resistance_ohm=0.04",
        f"propulsion.battery.open_circuit_voltage_v={voc}",
        f"propulsion.propeller.diameter_m={d}", f"prop_diameter_mm={1000 * d}"])


# ---------------------------------------------------------------------------------------------
# 6-10. Diameters, dataset names, masses, unused sections, strict switches
# ---------------------------------------------------------------------------------------------


def test_two_diameters_of_one_propeller_must_agree(tmp_path, cli_runner):
    _refused_line(cli_runner, _frame(tmp_path, propulsion__propeller__diameter_m=0.3),
                  "propulsion.propeller.diameter_m")
    _loads(_frame(tmp_path, propulsion__propeller__diameter_m=0.128))  # 0.8 % apart
    with pytest.raises(ConfigError, match="diameter_m"):
        _loads(_frame(tmp_path, propulsion__propeller__diameter_m=0.1295))  # 2 % apart


def test_unknown_dataset_name_is_refused(tmp_path, cli_runner):
    path = _frame(tmp_path, propulsion__propeller__data="no-such-dataset")
    line = _refused_line(cli_runner, path, "propulsion.propeller.data")
    assert "uiuc-da4022-5x3.75-3blade" in line  # the known names
    # a description (blanks) is provenance, not a name
    cfg = _loads(_frame(tmp_path, propulsion__propeller__data="UIUC DA4022, refitted by hand"))
    assert cfg.propulsion.propeller.data.startswith("UIUC")


@pytest.mark.parametrize(("key", "value", "named"), [
    ("propulsion__motor__mass_kg", 5, "propulsion.motor.mass_kg"),
    ("propulsion__battery__mass_kg", 50, "propulsion.battery.mass_kg"),
    # 4 × 0.06 + 0.08 = 0.32 kg: the parts alone weigh the whole
    ("propulsion__motor__mass_kg", 0.06, "mass_kg"),
])
def test_parts_heavier_than_the_whole_are_refused(tmp_path, cli_runner, key, value, named):
    _refused_line(cli_runner, _frame(tmp_path, **{key: value}), named)


def test_sections_the_paper_model_does_not_use_are_refused(tmp_path, cli_runner):
    line = _refused_line(cli_runner, _frame(tmp_path, propulsion__model="paper"),
                         "propulsion.model")
    assert "propeller, motor, battery" in line
    assert load_airframe("SY250").propulsion.model == "paper"  # no sections: fine


@pytest.mark.parametrize("value", ["no", 0, 0.0, "false", 1])
def test_switches_are_true_or_false_only(tmp_path, cli_runner, value):
    _refused_line(cli_runner, _frame(tmp_path, propulsion__propeller__axial_inflow=value),
                  "propulsion.propeller.axial_inflow")


def test_switch_false_loads(tmp_path):
    assert _loads(_frame(tmp_path, propulsion__propeller__axial_inflow=False)
                  ).propulsion.propeller.axial_inflow is False


# ---------------------------------------------------------------------------------------------
# Every shipped airframe still loads
# ---------------------------------------------------------------------------------------------


def test_every_shipped_airframe_loads():
    from casadrone.config.io import CONFIG_DIR

    files = sorted((CONFIG_DIR / "airframes").glob("*.yaml"))
    assert len(files) >= 12
    for f in files:
        load_airframe(f)
