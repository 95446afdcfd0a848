"""Write ``example-5in.csv`` beside this script: a synthetic thrust-stand log, the shipped example
of ``casadrone fit-propulsion example-5in --diameter-in 5``.

Synthetic, not measured: a stated propulsion system run through a step test as a Tyto /
RCbenchmark stand logs it (PWM ESC signal in µs, thrust in kgf, torque in N·m, rotor speed in
rpm, 200 Hz), with Gaussian sensor noise from a fixed seed. The physics, written here from the
sources and not from :mod:`casadrone.thruststand` (whose fit the log exercises):

- propeller, static coefficients (UIUC definitions, n in rev/s; Brandt & Selig 2011):
  ``T = C_T0 ρ n² D⁴``, shaft torque ``Q_p = C_P0 ρ n² D⁵ / 2π``;
- Drela's first-order DC motor (MIT 16.50 notes, 2007): ``V_m = ω / K_v + I_m R``, torque
  ``(I_m − I_0) / K_v``;
- a lossless ESC (buck converter) of duty d = (signal − 1000 µs) / 1000 µs:
  ``V_m = d V_bus``, ``I_bus = d I_m``;
- a battery of open-circuit voltage V_oc behind R_int: ``V_bus = V_oc − R_int I_bus``;
- the rotor ``J_r ω̇ = (I_m − I_0) / K_v − Q_p(ω)``, integrated through each ESC step by
  scipy's ``solve_ivp``.

The stand logs the stator's reaction torque (negative: the sign of its mounting) and thrust and
torque as the load cells read them, tared at rest. Run ``python make_example.py`` to write the
file again; the same numpy and scipy give the same bytes.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

#: The generating parameters (SI but K_V in rpm/V): a 5-inch propeller on a 2400 KV motor and a
#: 4S pack, a racing quadrotor's propulsion.
PARAMETERS: dict[str, float] = {
    "diameter_m": 0.127, "air_density_kg_m3": 1.225, "ct0": 0.12, "cp0": 0.06,
    "kv_rpm_per_v": 2400.0, "resistance_ohm": 0.08, "no_load_current_a": 1.2,
    "open_circuit_voltage_v": 16.8, "internal_resistance_ohm": 0.03,
    "rotor_inertia_kgm2": 8e-6,
}
#: Standard deviation of each sensor's noise (thrust N, torque N·m, voltage V, current A, speed
#: rad/s): a few tenths of a percent of full scale, as a stand's load cells and power sensor.
NOISE = {"thrust": 0.02, "torque": 5e-4, "voltage": 5e-3, "current": 0.05, "speed": 2.0}
SEED = 2024
RATE_HZ = 200.0
HOLD_S = 0.6
#: The ESC signal held for HOLD_S each (µs): rest, 100 µs steps to full throttle, rest.
SIGNALS_US = (1000, *range(1200, 2001, 100), 1000)
HEADER = ["Time (s)", "ESC signal (µs)", "Torque (N·m)", "Thrust (kgf)", "Voltage (V)",
          "Current (A)", "Motor Optical Speed (RPM)"]
G0 = 9.80665  # kgf → N (standard gravity)
FILE = Path(__file__).with_name("example-5in.csv")


def motor_current(duty: float, w: np.ndarray) -> np.ndarray:
    """I_m (A) at rotor speed w (rad/s): V_m = d (V_oc − R_int d I_m) = ω/K_v + I_m R."""
    p = PARAMETERS
    kv = p["kv_rpm_per_v"] * 2 * math.pi / 60
    return (duty * p["open_circuit_voltage_v"] - w / kv) / (
        p["resistance_ohm"] + p["internal_resistance_ohm"] * duty**2)


def propeller_torque(w: np.ndarray) -> np.ndarray:
    """Q_p (N·m) at rotor speed w (rad/s)."""
    p = PARAMETERS
    return p["cp0"] * p["air_density_kg_m3"] * (w / (2 * math.pi)) ** 2 * p["diameter_m"] ** 5 \
        / (2 * math.pi)


def motor_torque(duty: float, w: np.ndarray) -> np.ndarray:
    """Shaft torque of the motor (N·m); none unpowered (the ESC off: duty 0)."""
    if duty <= 0:
        return np.zeros_like(w)
    kv = PARAMETERS["kv_rpm_per_v"] * 2 * math.pi / 60
    return (motor_current(duty, w) - PARAMETERS["no_load_current_a"]) / kv


def rotor_speed(duty: float, w_start: float, t: np.ndarray) -> np.ndarray:
    """ω(t) (rad/s) from ``w_start`` at the duty held, at the times t (s) after the step."""
    from scipy.integrate import solve_ivp

    def rhs(_t: float, w: np.ndarray) -> list[float]:
        net = motor_torque(duty, w) - propeller_torque(w)
        return [float(net[0]) / PARAMETERS["rotor_inertia_kgm2"]]

    sol = solve_ivp(rhs, (0.0, float(t[-1])), [w_start], t_eval=t, method="LSODA", rtol=1e-10,
                    atol=1e-8)
    return np.maximum(sol.y[0], 0.0)


def samples() -> np.ndarray:
    """Rows (time, signal, torque, thrust kgf, voltage, current, speed rpm) of the step test."""
    p = PARAMETERS
    rng = np.random.default_rng(SEED)
    per = int(round(HOLD_S * RATE_HZ))
    t = np.arange(1, per + 1) / RATE_HZ
    w_end, blocks = 0.0, []
    for k, signal in enumerate(SIGNALS_US):
        duty = (signal - 1000) / 1000
        w = rotor_speed(duty, w_end, t)
        w_end = float(w[-1])
        i_bus = duty * motor_current(duty, w) if duty > 0 else np.zeros(per)
        n = w / (2 * math.pi)
        thrust = p["ct0"] * p["air_density_kg_m3"] * n**2 * p["diameter_m"] ** 4
        blocks.append(np.column_stack([
            k * HOLD_S + t, np.full(per, float(signal)),
            -(motor_torque(duty, w) + rng.normal(0, NOISE["torque"], per)),
            (thrust + rng.normal(0, NOISE["thrust"], per)) / G0,
            p["open_circuit_voltage_v"] - p["internal_resistance_ohm"] * i_bus
            + rng.normal(0, NOISE["voltage"], per),
            i_bus + rng.normal(0, NOISE["current"], per),
            # an optical sensor counts blade passes: nothing at rest
            np.where(w > 0, w + rng.normal(0, NOISE["speed"], per), 0.0) * 60 / (2 * math.pi),
        ]))
    return np.vstack(blocks)


def comment() -> list[str]:
    """The file's header comment: what it is and from what."""
    p, n = PARAMETERS, NOISE
    return [
        "# SYNTHETIC thrust-stand log, not a measurement: casadrone's fit-propulsion example,",
        "# written by make_example.py beside it (Drela's DC motor behind a lossless ESC and a",
        "# battery, driving a rotor against a static propeller; step test at 200 Hz). From:",
        f"# propeller D {p['diameter_m']} m, C_T0 {p['ct0']}, C_P0 {p['cp0']} (rho "
        f"{p['air_density_kg_m3']} kg/m3); motor KV {p['kv_rpm_per_v']:g} rpm/V,",
        f"# R {p['resistance_ohm']} ohm, I0 {p['no_load_current_a']} A; battery V_oc "
        f"{p['open_circuit_voltage_v']} V, R_int {p['internal_resistance_ohm']} ohm; rotor "
        f"inertia {p['rotor_inertia_kgm2']:g} kg m2;",
        "# ESC duty 0 at 1000 us, 1 at 2000 us. Noise (1 sigma, numpy default_rng seed "
        f"{SEED}): thrust {n['thrust']} N,",
        f"# torque {n['torque']} N m, voltage {n['voltage']} V, current {n['current']} A, "
        f"speed {n['speed']} rad/s (turning).",
    ]


def write(path: Path = FILE) -> Path:
    """Write the example log to ``path``."""
    fmt = ["%.3f", "%d", "%.5f", "%.5f", "%.3f", "%.3f", "%.0f"]
    with path.open("w", newline="", encoding="utf-8") as fh:
        fh.write("\n".join(comment()) + "\n")
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(HEADER)
        writer.writerows([f % v for f, v in zip(fmt, row, strict=True)] for row in samples())
    return path


if __name__ == "__main__":
    print(write())
