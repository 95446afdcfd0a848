"""fit-propulsion against logs generated here from a known motor, propeller and battery.

The generator below is written from the physics, not from :mod:`casadrone.thruststand`: for each
ESC duty it solves the steady torque balance of Drela's first-order DC motor behind a lossless ESC
and a battery with internal resistance (a root of one scalar equation, scipy's brentq), lets the
rotor speed follow each step with a first-order lag, derives thrust, torque, bus current and
voltage from it, adds sensor noise and writes the CSV as a Tyto/RCbenchmark stand does (units in
the header). The fit must recover every coefficient within 2 % (the issue's acceptance).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.optimize import brentq

from casadrone.thruststand import LogError, fit_propulsion, read_log

TRUE = dict(ct0=0.115, cp0=0.058, kv_rpm_per_v=1950.0, resistance_ohm=0.065,
            no_load_current_a=1.3, open_circuit_voltage_v=16.4, internal_resistance_ohm=0.022,
            time_constant_s=0.035)
D, RHO = 0.1295, 1.225  # a 5.1-inch propeller at sea level


def steady_speed(duty: float) -> float:
    """Rotor speed (rad/s) where motor torque equals propeller torque at this duty."""
    kv = TRUE["kv_rpm_per_v"] * 2 * math.pi / 60
    R, i0, v0, rb = (TRUE[k] for k in ("resistance_ohm", "no_load_current_a",
                                       "open_circuit_voltage_v", "internal_resistance_ohm"))

    def imbalance(w):
        im = (duty * v0 - w / kv) / (R + rb * duty**2)  # V_bus = V0 - rb * duty * I_m
        q_prop = TRUE["cp0"] * RHO * (w / (2 * math.pi)) ** 2 * D**5 / (2 * math.pi)
        return (im - i0) / kv - q_prop

    return brentq(imbalance, 1.0, duty * v0 * kv)


def sensors(duty: float, w: np.ndarray) -> dict[str, np.ndarray]:
    kv = TRUE["kv_rpm_per_v"] * 2 * math.pi / 60
    R, v0, rb = TRUE["resistance_ohm"], TRUE["open_circuit_voltage_v"], \
        TRUE["internal_resistance_ohm"]
    n = w / (2 * math.pi)
    im = (duty * v0 - w / kv) / (R + rb * duty**2)
    ib = duty * im
    return {"thrust": TRUE["ct0"] * RHO * n**2 * D**4,
            "torque": TRUE["cp0"] * RHO * n**2 * D**5 / (2 * math.pi),
            "current": ib, "voltage": v0 - rb * ib}


def write_log(path: Path, seed: int = 0, rate_hz: float = 1000.0, hold_s: float = 1.5,
              header: list[str] | None = None) -> Path:
    rng = np.random.default_rng(seed)
    steps_us = [1000, 1150, 1300, 1450, 1600, 1750, 1900, 2000, 1700, 1400, 1100, 1000]
    per = int(hold_s * rate_hz)
    blocks, w_end = [], 0.0
    for k, esc in enumerate(steps_us):
        duty = (esc - 1000) / 1000
        target = steady_speed(duty) if duty > 0 else 0.0
        t = (k * per + np.arange(1, per + 1)) / rate_hz
        w = target + (w_end - target) * np.exp(-(np.arange(1, per + 1) / rate_hz)
                                               / TRUE["time_constant_s"])
        w_end = float(w[-1])
        if duty > 0:
            s = sensors(duty, w)
        else:
            zero = np.zeros(per)
            s = {"thrust": zero, "torque": zero, "current": zero,
                 "voltage": zero + TRUE["open_circuit_voltage_v"]}
        blocks.append(np.column_stack([
            t, np.full(per, esc),
            -(s["torque"] + rng.normal(0, 0.0008, per)),  # stands log the reaction torque
            (s["thrust"] + rng.normal(0, 0.03, per)) / 9.80665,  # kgf
            s["voltage"] + rng.normal(0, 0.01, per),
            s["current"] + rng.normal(0, 0.08, per),
            (w + rng.normal(0, 3.0, per)) * 60 / (2 * math.pi),
        ]))
    fmt = ["%.4f", "%d", "%.5f", "%.5f", "%.4f", "%.4f", "%.1f"]
    rows = [[f % v for f, v in zip(fmt, r, strict=True)] for r in np.vstack(blocks)]
    header = header or ["Time (s)", "ESC signal (µs)", "Torque (N·m)", "Thrust (kgf)",
                        "Voltage (V)", "Current (A)", "Motor Optical Speed (RPM)"]
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        writer.writerows(rows)
    return path


@pytest.fixture(scope="module")
def log_file(tmp_path_factory) -> Path:
    return write_log(tmp_path_factory.mktemp("stand") / "stand.csv")


@pytest.mark.parametrize("seed", [0, 1])
def test_every_coefficient_is_recovered_within_two_percent(tmp_path, seed):
    fit = fit_propulsion(read_log(write_log(tmp_path / "log.csv", seed=seed)), D, RHO)
    got = dict(ct0=fit.ct0, cp0=fit.cp0, kv_rpm_per_v=fit.kv_rpm_per_v,
               resistance_ohm=fit.resistance_ohm, no_load_current_a=fit.no_load_current_a,
               open_circuit_voltage_v=fit.open_circuit_voltage_v,
               internal_resistance_ohm=fit.internal_resistance_ohm,
               time_constant_s=fit.time_constant_s)
    for key, true in TRUE.items():
        assert got[key] == pytest.approx(true, rel=0.02), key


def test_units_are_read_from_the_header(tmp_path):
    """The same test logged in N, N·mm and electrical rpm (14 poles) fits the same."""
    a = fit_propulsion(read_log(write_log(tmp_path / "a.csv")), D, RHO)
    path = write_log(tmp_path / "b.csv")
    rows = list(csv.reader(path.open(encoding="utf-8")))
    rows[0] = ["Time (ms)", "ESC signal (us)", "Torque (N·mm)", "Thrust (N)", "Voltage (V)",
               "Current (A)", "Motor Electrical Speed (RPM)"]
    for r in rows[1:]:
        r[0] = f"{float(r[0]) * 1e3:.1f}"
        r[2] = f"{float(r[2]) * 1e3:.4f}"
        r[3] = f"{float(r[3]) * 9.80665:.6f}"
        r[6] = f"{float(r[6]) * 7:.1f}"
    with path.open("w", newline="", encoding="utf-8") as fh:
        csv.writer(fh).writerows(rows)
    b = fit_propulsion(read_log(path, motor_poles=14), D, RHO)
    for key in ("ct0", "cp0", "kv_rpm_per_v", "internal_resistance_ohm"):
        assert getattr(b, key) == pytest.approx(getattr(a, key), rel=1e-3), key


@pytest.mark.parametrize("edit, needle", [
    (lambda rows: [r[:4] + r[5:] for r in rows], "column missing: voltage"),
    (lambda rows: [[c.replace("Thrust (kgf)", "Thrust (stone)") for c in r] for r in rows],
     "'Thrust (stone)'"),
    (lambda rows: rows[:40] + [rows[40][:3] + ["heavy"] + rows[40][4:]] + rows[41:], "row 41"),
    (lambda rows: rows[:30] + [rows[29]] + rows[30:], "row 31, column 'Time'"),
    (lambda rows: rows[:1] + rows[1:1500], "powered steady points"),
])
def test_a_malformed_log_is_refused_naming_the_column_or_row(tmp_path, log_file, edit, needle):
    rows = list(csv.reader(log_file.open(encoding="utf-8")))
    path = tmp_path / "bad.csv"
    with path.open("w", newline="", encoding="utf-8") as fh:
        csv.writer(fh).writerows(edit(rows))
    with pytest.raises(LogError, match=None) as info:
        fit_propulsion(read_log(path), D, RHO)
    assert needle in str(info.value) and "bad.csv" in str(info.value)


def test_cli_writes_the_section_and_never_overwrites(tmp_path, log_file, cli_runner):
    from casadrone.cli import app

    def _cli(*args):
        return cli_runner.invoke(app, list(args))

    out = tmp_path / "prop.yaml"
    r = _cli("fit-propulsion", str(log_file), "--diameter-m", str(D), "--out", str(out), "--json",
             "--plot", str(tmp_path / "plots"))
    assert r.exit_code == 0, r.stderr
    import matplotlib.image

    for png in (p for p in json.loads(r.stdout)["figures"] if p.endswith(".png")):
        assert matplotlib.image.imread(png).shape[0] > 100  # a picture, read back by a consumer
    report = json.loads(r.stdout)
    section = yaml.safe_load(out.read_text(encoding="utf-8"))["propulsion"]
    assert section == report["propulsion"]
    assert section["motor"]["kv_rpm_per_v"] == pytest.approx(TRUE["kv_rpm_per_v"], rel=0.02)
    assert {q["quantity"] for q in report["residuals"]} >= {"thrust", "torque", "bus voltage"}
    before = out.read_bytes()
    again = _cli("fit-propulsion", str(log_file), "--diameter-m", "0.2", "--out", str(out))
    assert again.exit_code == 2 and "exists" in again.stderr and "--force" in again.stderr
    assert out.read_bytes() == before
    bad = _cli("fit-propulsion", str(tmp_path / "missing.csv"), "--diameter-in", "5")
    assert bad.exit_code == 2 and "missing.csv" in bad.stderr and "Traceback" not in bad.stderr
