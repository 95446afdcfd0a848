"""Refusals found by an audit of the propulsion features: each bad input gives exit 2 and one
line naming the file and the key, column or row; a valid input that was refused now loads.

- ``ESC signal (ms)``, ``(s)``, ``(ns)`` were read as µs (the mojibake rule took any short unit
  ending in "s"); ``ms`` is now converted, the others refused.
- A UTF-8 log with one byte that is not UTF-8 was read whole as Latin-1, its "N·m" mangled and
  the log refused for an unknown unit.
- Blank lines above the header were taken for the header ("column missing: time").
- fit-propulsion wrote a section the airframe schema refuses (a static figure of merit above 1).
- The linear-inflow form skipped the climbing actuator disc's check over its stated range, which
  the same propeller given as CT/CP coefficients gets.
- ``inflow: positive`` beside ``linear_inflow`` (always signed) and ``inflow_smoothing_m_s`` with
  signed inflow were silently ignored.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from casadrone.cli import app
from casadrone.config import load_airframe, resolve_config
from casadrone.thruststand import read_log
from tests.unit.test_thruststand import D, write_log

RHO, D_SY250 = 1.225, 0.127
CT0, CP0 = 0.20894, 0.13214  # SY250-propeller's static coefficients
#: Those coefficients in the linear-inflow form (T = k_η ω², Q = k_m ω², ω in rad/s): T = C_T ρ
#: n² D⁴ with n = ω/2π gives k_η = C_T ρ D⁴/(4π²); Q = C_P ρ n² D⁵/(2π) gives k_m = C_P ρ D⁵/(8π³).
K_ETA = CT0 * RHO * D_SY250**4 / (4 * math.pi**2)
K_M = CP0 * RHO * D_SY250**5 / (8 * math.pi**3)


@pytest.fixture(scope="module")
def log_file(tmp_path_factory) -> Path:
    return write_log(tmp_path_factory.mktemp("stand") / "stand.csv")


def _fit(cli_runner, path: Path, *args: str):
    return cli_runner.invoke(app, ["fit-propulsion", str(path), "--diameter-m", str(D), *args])


def _refused(result, *needles: str) -> str:
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def _with_column(log_file: Path, path: Path, column: int, change, header=("", "")) -> Path:
    """The log with every data cell of ``column`` passed through ``change`` (and ``header[0]``
    replaced by ``header[1]`` in the header line), written to ``path``."""
    text = log_file.read_text(encoding="utf-8").splitlines()
    rows = [text[0].replace(*header) if header[0] else text[0]]
    for line in text[1:]:
        cells = line.split(",")
        cells[column] = change(cells[column])
        rows.append(",".join(cells))
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


def _with_header(log_file: Path, tmp_path: Path, old: str, new: str) -> Path:
    text = log_file.read_text(encoding="utf-8")
    path = tmp_path / "log.csv"
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    return path


# --- the ESC signal's unit --------------------------------------------------------------------


@pytest.mark.parametrize("unit", ["s", "ns", "xs"])
def test_an_esc_unit_that_is_not_microseconds_is_refused(tmp_path, log_file, cli_runner, unit):
    path = _with_header(log_file, tmp_path, "ESC signal (µs)", f"ESC signal ({unit})")
    _refused(_fit(cli_runner, path), "log.csv", f"'ESC signal ({unit})'", f"unit '{unit}'")


def test_an_esc_signal_in_milliseconds_is_converted(tmp_path, log_file):
    path = _with_column(log_file, tmp_path / "ms.csv", 1, lambda c: f"{int(c) / 1000:.3f}",
                        ("(µs)", "(ms)"))
    assert read_log(path).esc_us.max() == pytest.approx(2000.0)
    assert read_log(path).esc_us == pytest.approx(read_log(log_file).esc_us)


# UTF-8 read as Latin-1, cp1252 read as cp949, the Greek mu
@pytest.mark.parametrize("mojibake", ["Âµs", "탎", "μs"])
def test_the_mangled_micro_sign_is_still_microseconds(tmp_path, log_file, mojibake):
    path = _with_header(log_file, tmp_path, "(µs)", f"({mojibake})")
    assert read_log(path).esc_us == pytest.approx(read_log(log_file).esc_us)


# --- encoding and blank lines -----------------------------------------------------------------


def test_one_stray_latin1_byte_does_not_mangle_the_units(tmp_path, log_file):
    path = tmp_path / "stray.csv"
    path.write_bytes(log_file.read_bytes() + "# operator: Ren\xe9\n".encode("latin-1"))
    assert read_log(path).torque_nm == pytest.approx(read_log(log_file).torque_nm)


def test_a_windows_export_in_cp1252_reads_its_units(tmp_path, log_file):
    path = tmp_path / "cp1252.csv"
    path.write_bytes(log_file.read_text(encoding="utf-8").encode("cp1252"))
    assert read_log(path).thrust_n == pytest.approx(read_log(log_file).thrust_n, nan_ok=True)


def test_blank_lines_above_the_header_are_skipped(tmp_path, log_file):
    path = tmp_path / "blank.csv"
    path.write_bytes(b"\n\r\n,,\n" + log_file.read_bytes())
    assert read_log(path).time_s == pytest.approx(read_log(log_file).time_s)


# --- the fitted section must load -------------------------------------------------------------


def test_a_fit_above_the_ideal_rotor_is_refused_and_writes_nothing(tmp_path, log_file,
                                                                   cli_runner):
    """A torque column reading 0.4x (a mis-scaled load cell) gives a C_P0 inside PHYSICAL's
    0.005-0.4 but a static figure of merit √(2/π) C_T0^1.5/C_P0 above 1: momentum theory's ideal
    rotor beaten. The generator's propeller has C_T0 0.115, C_P0 0.058: FM 0.54 read right,
    0.54/0.4 = 1.35 read low."""
    assert math.sqrt(2 / math.pi) * 0.115**1.5 / (0.4 * 0.058) > 1
    path = _with_column(log_file, tmp_path / "low.csv", 2, lambda c: f"{float(c) * 0.4:.6f}")
    out = tmp_path / "section.yaml"
    line = _refused(_fit(cli_runner, path, "--out", str(out)), "low.csv",
                    "propulsion.propeller.cp_coefficients", "figure of merit")
    assert "1.3" in line and not out.exists()


def test_a_good_fit_still_writes_a_section_that_loads(tmp_path, log_file, cli_runner):
    out = tmp_path / "section.yaml"
    result = _fit(cli_runner, log_file, "--out", str(out))
    assert result.exit_code == 0, result.stderr
    frame = yaml.safe_load(resolve_config("SY250-propeller", "airframes").read_text("utf-8"))
    frame["propulsion"] = yaml.safe_load(out.read_text(encoding="utf-8"))["propulsion"]
    frame["prop_diameter_mm"] = D * 1000
    path = tmp_path / "frame.yaml"
    path.write_text(yaml.safe_dump(frame), encoding="utf-8")
    assert load_airframe(path).propulsion.model == "propeller"


# --- the linear-inflow form -------------------------------------------------------------------


def _linear_frame(tmp_path: Path, **propeller) -> Path:
    data = yaml.safe_load(resolve_config("SY250-propeller", "airframes").read_text("utf-8"))
    prop = data["propulsion"]["propeller"]
    for key in ("ct_coefficients", "cp_coefficients", "data"):
        prop.pop(key)
    prop["linear_inflow"] = {"k_eta_n_s2": K_ETA, "k_m_n_m_s2": K_M}
    prop.update(propeller)
    path = tmp_path / "frame.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _trim_refused(cli_runner, path: Path, key: str) -> str:
    result = cli_runner.invoke(app, ["trim", str(path)])
    line = _refused(result)
    assert line.startswith(f"{path}: {key}: "), line
    return line


def test_linear_inflow_breaking_momentum_theory_in_climb_is_refused(tmp_path, cli_runner):
    """k_z = 0: the thrust holds in climb at a constant C_P. At J = 0.5 the actuator disc needs
    C_P ≥ C_T (J/2 + √(J²/4 + 2C_T/π)) (Leishman §2.9: P = T (V + v_i)), here written out."""
    J = 0.5
    ideal = CT0 * (J / 2 + math.sqrt(J * J / 4 + 2 * CT0 / math.pi))
    assert ideal > CP0  # 0.148 > 0.132: the rotor would beat the ideal one
    path = _linear_frame(tmp_path, max_advance_ratio=J)
    line = _trim_refused(cli_runner, path, "propulsion.propeller.linear_inflow.k_m_n_m_s2")
    assert "climb" in line
    # the same rotor given as CT/CP coefficients was refused already, naming its own key
    assert load_airframe(_linear_frame(tmp_path, max_advance_ratio=0.3)) is not None
    # the range the limit lap flies may also come from the dataset the section names (its
    # largest J, 0.854 here, advance_ratio_limit): the same rotor is refused by that range too
    line = _trim_refused(cli_runner, _linear_frame(tmp_path, data="uiuc-da4022-5x3.75-3blade"),
                         "propulsion.propeller.linear_inflow.k_m_n_m_s2")
    assert "climb" in line


@pytest.mark.parametrize("propeller, key", [
    ({"inflow": "positive"}, "propulsion.propeller.inflow"),
    ({"inflow_smoothing_m_s": 0.5}, "propulsion.propeller.inflow_smoothing_m_s"),
])
def test_an_inflow_key_linear_inflow_ignores_is_refused(tmp_path, cli_runner, propeller, key):
    _trim_refused(cli_runner, _linear_frame(tmp_path, **propeller), key)


def test_smoothing_with_signed_inflow_is_refused_and_the_defaults_still_load(tmp_path,
                                                                             cli_runner):
    data = yaml.safe_load(resolve_config("SY250-propeller", "airframes").read_text("utf-8"))
    data["propulsion"]["propeller"].update(inflow="signed", inflow_smoothing_m_s=0.5)
    path = tmp_path / "signed.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    _trim_refused(cli_runner, path, "propulsion.propeller.inflow_smoothing_m_s")
    # written and used: positive inflow with its smoothing; the linear form with signed inflow
    data["propulsion"]["propeller"]["inflow"] = "positive"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    assert load_airframe(path).propulsion.propeller.inflow_smoothing_m_s == 0.5
    assert load_airframe(_linear_frame(tmp_path, inflow="signed")) is not None


def test_a_linear_inflow_frame_survives_the_optimiser_round_trip(tmp_path):
    """Each candidate of a study is rebuilt from ``model_dump()``: the unwritten inflow keys must
    not come back as written ones and be refused."""
    from casadrone.config.airframe import AirframeConfig

    cfg = load_airframe(_linear_frame(tmp_path))
    again = AirframeConfig.model_validate(cfg.model_dump())
    assert again.propulsion == cfg.propulsion


def test_a_shaped_section_keeps_to_the_shape_data_range(tmp_path, log_file, cli_runner):
    """--shape borrows CT(J), CP(J) of a shipped dataset, which hold to its largest fitted J
    only; without max_advance_ratio the limit lap had no bound and flew the extrapolation (the
    negative-thrust air brake of docs/concepts/propulsion.md, "Beyond the data")."""
    from casadrone.propulsion.data import SHIPPED_PROPELLER, data_advance_ratio

    out = tmp_path / "shaped.yaml"
    result = _fit(cli_runner, log_file, "--shape", SHIPPED_PROPELLER, "--out", str(out))
    assert result.exit_code == 0, result.stderr
    prop = yaml.safe_load(out.read_text(encoding="utf-8"))["propulsion"]["propeller"]
    assert prop["max_advance_ratio"] == pytest.approx(data_advance_ratio(SHIPPED_PROPELLER),
                                                      rel=1e-5)
    assert len(prop["ct_coefficients"]) == 3


def test_a_lag_written_beside_the_dc_motor_is_refused_and_first_order_uses_it(tmp_path,
                                                                              cli_runner):
    """The DC motor's rotor lag follows from J_r R K_V²: a ``time_constant_s`` beside ``kind: dc``
    was read by nothing. The same key with ``kind: first-order`` is the model's τ_m, seen in the
    linearisation as the rotor mode's eigenvalue −1/τ_m at hover with the inflow and the rotor
    drag at rest (τ_m ω̇ = K_V δ V_oc − ω is linear in ω)."""
    import numpy as np

    from casadrone.airframe import build_airframe
    from casadrone.linearise import linearise
    from casadrone.trim import trim

    data = yaml.safe_load(resolve_config("SY250-propeller", "airframes").read_text("utf-8"))
    data["propulsion"]["motor"]["time_constant_s"] = 0.02
    path = tmp_path / "dc.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    _trim_refused(cli_runner, path, "propulsion.motor.time_constant_s")
    data["propulsion"]["motor"]["kind"] = "first-order"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    cfg = load_airframe(path)
    from casadrone.config.airframe import AirframeConfig

    assert AirframeConfig.model_validate(cfg.model_dump()).propulsion == cfg.propulsion
    frame = build_airframe(cfg)
    lin = linearise(frame, trim(frame, "hover", solver="newton"))
    rotor = slice(12, 16)
    np.testing.assert_allclose(np.diag(lin.A[rotor, rotor]), -1 / 0.02, rtol=1e-9)


@pytest.mark.parametrize("sep, encoding, hint", [
    (";", "utf-8", "separated by semicolons"), ("\t", "utf-8", "separated by tabs"),
    (",", "utf-16", "UTF-16")])
def test_a_log_in_another_dialect_says_so(tmp_path, log_file, cli_runner, sep, encoding, hint):
    """Semicolon or tab exports, and UTF-16 files, read as one header cell: the refusal said only
    "column missing: time", which reads as a misnamed column."""
    text = log_file.read_text(encoding="utf-8").replace(",", sep)
    path = tmp_path / "dialect.csv"
    path.write_text(text, encoding=encoding)
    _refused(_fit(cli_runner, path), "dialect.csv", "column missing", hint)
