"""The pack's side of a flown lap (``propeller`` kind, DC motor): its commands re-simulated by
CVODES with the currents and energies integrated beside the states, sampled within every
interval; and what that leaves of a pack over a race (:func:`race_energy`).

Two independent energy balances of one flight, both integrated by CVODES as quadratures:

- the pack's: E_pack = ∫ V_bat I_bat dt, the terminal voltage times the pack current
  (:mod:`casadrone.propulsion.electric`);
- the rotors': E_rotor = ∫ Σ Q_i ω_i dt (the propellers' shaft power from their loads, CP(J)
  at each rotor's own inflow) + Σ ½ J_r (ω_i,end² − ω_i,start²) (the rotors' kinetic energy) +
  ∫ Σ R I_i² dt (copper) + ∫ Σ I₀ ω_i / K_V dt (the no-load losses).

The model conserves power (the ideal-chopper ESC δ V I = V I_bat; the DC motor
δ V I = R I² + (ω/K_V) I; its torque (I − I₀)/K_V drives J_r ω̇ + Q), so the two agree to the
integration's accuracy; the issue asks 0.5 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import casadi as ca
import numpy as np

from casadrone.airframe import Airframe
from casadrone.limit.attitude import quaternion_f
from casadrone.model import n_params, named, quadrotor_model, unpack_params
from casadrone.propulsion import propeller_terms, rotor_loads
from casadrone.propulsion.electric import Pack, pack_current
from casadrone.propulsion.propeller import motor_currents
from casadrone.results import AsDict

#: Samples of the re-simulation within each interval (besides its start): the currents are
#: checked against their limits at each.
SAMPLES_PER_INTERVAL = 4
#: CVODES tolerances of the energy re-simulation (as the limit lap's re-simulation check).
RESIM_TOL = 1e-10
#: The quadratures: charge (C), pack energy (J), shaft energy, copper loss, no-load loss (J).
QUADRATURES = ("charge", "pack", "shaft", "copper", "no_load")


@lru_cache(maxsize=4)
def energy_integrator(attitude: str = "euler") -> ca.Function:
    """CVODES on ẋ = h f(x, u, p) over [0, 1] of the ``propeller`` model, with the
    :data:`QUADRATURES` integrated beside it (h times their rates), output at
    :data:`SAMPLES_PER_INTERVAL` evenly spaced points (cumulative from 0)."""
    if attitude == "quaternion":
        f, rotor = quaternion_f("propeller"), slice(13, 17)
    else:
        f, rotor = quadrotor_model("propeller").f, slice(12, 16)
    x = ca.SX.sym("x", f.size1_in(0))
    NP = n_params("propeller")
    uph = ca.SX.sym("uph", 4 + NP + 1)
    u, p, h = uph[:4], uph[4:4 + NP], uph[4 + NP]
    rates = node_rates(x[3:6], x[6:9], x[rotor], u, p)
    grid = [k / SAMPLES_PER_INTERVAL for k in range(1, SAMPLES_PER_INTERVAL + 1)]
    dae = {"x": x, "p": uph, "ode": h * f(x, u, p), "quad": h * rates[0]}
    return ca.integrator(f"energy_resim_{attitude}", "cvodes", dae, 0.0, grid,
                         {"abstol": RESIM_TOL, "reltol": RESIM_TOL})


def node_rates(vel, omega, w, u, p) -> tuple:
    """(rates of the :data:`QUADRATURES` (5), pack current, motor currents (4), pack voltage)
    at body velocity ``vel``, rates ``omega``, rotor speeds ``w`` and commands ``u``."""
    q = named(p)
    _, _, r, s, _ = unpack_params(p)
    V, current = motor_currents(w, u, q)
    i_bat = pack_current(u, current)
    inflows = propeller_terms(vel, omega, w, ca.SX.zeros(4), u, q, r, s)[4]
    shaft = sum(rotor_loads(w[i], inflows[i], q)[1] * w[i] for i in range(4))
    copper = q["motor_R"] * ca.sumsqr(current)
    no_load = q["motor_I0"] * ca.sum1(w) / q["motor_kv"]
    return ca.vertcat(i_bat, V * i_bat, shaft, copper, no_load), i_bat, current, V


@lru_cache(maxsize=4)
def sample_function(attitude: str = "euler") -> ca.Function:
    """``(x, u, p) -> (pack current, motor currents (4), pack voltage)`` at one sample."""
    rotor = slice(13, 17) if attitude == "quaternion" else slice(12, 16)
    nx = 17 if attitude == "quaternion" else 16
    x, u, p = ca.SX.sym("x", nx), ca.SX.sym("u", 4), ca.SX.sym("p", n_params("propeller"))
    _, i_bat, current, V = node_rates(x[3:6], x[6:9], x[rotor], u, p)
    return ca.Function("pack_sample", [x, u, p], [i_bat, current, V])


@dataclass(frozen=True)
class FlightEnergy(AsDict):
    """A flight's pack side: samples (the start of every interval under its command, then
    :data:`SAMPLES_PER_INTERVAL` within it) and the two energy balances (J)."""

    t_s: np.ndarray
    pack_current_a: np.ndarray
    motor_current_a: np.ndarray  # (samples, 4)
    pack_voltage_v: np.ndarray
    charge_c: np.ndarray  # drawn since the start, at each sample (C)
    energy_pack_j: float  # ∫ V_bat I_bat dt
    energy_rotor_j: float  # shaft + rotor kinetic + copper + no-load
    shaft_j: float
    kinetic_j: float
    copper_j: float
    no_load_j: float

    _omit = ("t_s", "pack_current_a", "motor_current_a", "pack_voltage_v", "charge_c")

    @property
    def balance_error(self) -> float:
        """|E_pack − E_rotor| / E_pack."""
        return abs(self.energy_pack_j - self.energy_rotor_j) / abs(self.energy_pack_j)


def flight_energy(airframe: Airframe, t: np.ndarray, x0: np.ndarray, u: np.ndarray,
                  attitude: str = "euler") -> FlightEnergy:
    """The pack side of the commands ``u`` (M, 4) held on the intervals of node times ``t``
    (M + 1) flown from ``x0`` by CVODES (:func:`energy_integrator`; the airframe's p, its
    open-circuit voltage fixed). Raises ValueError for a model without a DC motor's currents."""
    if airframe.propulsion != "propeller" or named(airframe.p)["motor_dc"] < 0.5:
        raise ValueError("the pack's energy needs the propeller kind with motor kind: dc")
    step, sample = energy_integrator(attitude), sample_function(attitude)
    p = np.asarray(airframe.p, float)
    q = named(p)
    rotor = slice(13, 17) if attitude == "quaternion" else slice(12, 16)
    x = np.asarray(x0, float).ravel()
    times, cur, mot, volt, charge = [], [], [], [], []
    total = np.zeros(len(QUADRATURES))
    K = SAMPLES_PER_INTERVAL
    for i, h in enumerate(np.diff(np.asarray(t, float))):
        out = step(x0=x, p=np.concatenate([u[i], p, [h]]))
        X, Q = np.asarray(out["xf"]), np.asarray(out["qf"])
        states = np.column_stack([x, X])
        qs = np.column_stack([np.zeros(len(QUADRATURES)), Q]) + total[:, None]
        for k in range(K + 1):
            i_bat, i_mot, V = sample(states[:, k], u[i], p)
            times.append(t[i] + h * k / K)
            cur.append(float(i_bat))
            mot.append(np.asarray(i_mot, float).ravel())
            volt.append(float(V))
            charge.append(qs[0, k])
        total = qs[:, -1]
        x = X[:, -1]
    w0, w1 = np.asarray(x0, float).ravel()[rotor], x[rotor]
    kinetic = 0.5 * float(q["rotor_J"]) * float(np.sum(w1**2 - w0**2))
    _, pack_j, shaft, copper, no_load = (float(v) for v in total)
    return FlightEnergy(np.array(times), np.array(cur), np.array(mot), np.array(volt),
                        np.array(charge), pack_j, shaft + kinetic + copper + no_load, shaft,
                        kinetic, copper, no_load)


@dataclass(frozen=True)
class RaceEnergy(AsDict):
    """What a flight leaves of a pack: state of charge, energy used and left, peak currents and
    their margins to the limits (inf: no limit), and whether the pack flies it."""

    feasible: bool
    reason: str  # why not ("" when feasible)
    pack: str  # the pack's label (e.g. "4S 650 mAh pack")
    laps: int
    start_soc: float
    end_soc: float  # may be negative: the pack ran out before the end
    energy_used_wh: float  # at the pack's terminals, ∫ V I dt
    energy_left_wh: float  # the open-circuit energy from end_soc to empty (0 when out)
    capacity_used_pct: float  # charge drawn / capacity
    peak_pack_current_a: float
    peak_motor_current_a: float
    pack_current_margin_a: float  # limit − peak
    motor_current_margin_a: float
    energy_balance_error: float  # |E_pack − E_rotor| / E_pack (flight_energy)
    soc_at_lap_end: tuple[float, ...] = ()
    empty_at_s: float = math.nan  # when the state of charge reached 0 (NaN: never)
    empty_in_lap: int = 0  # 1-based lap in which it did (0: never)
    lap_ends_s: tuple[float, ...] = field(default_factory=tuple)


def race_energy(energy: FlightEnergy, pack: Pack, lap_times_s, max_motor_current_a=None,
                current_tol: float = 0.0) -> RaceEnergy:
    """The pack's account of a flight of ``len(lap_times_s)`` laps: the state of charge
    s(t) = s₀ − charge(t)/(3600 C) over the samples; infeasible, naming the pack, where it
    reaches 0 (the lap and time where it does) or where a sample's current exceeds a limit by
    more than ``current_tol`` (relative)."""
    laps = len(lap_times_s)
    ends = np.cumsum(np.asarray(lap_times_s, float))
    s0 = pack.start_soc
    soc = s0 - energy.charge_c / (3600.0 * pack.capacity_ah)
    end_soc = float(soc[-1])
    at_ends = tuple(float(np.interp(e, energy.t_s, soc)) for e in ends)
    peak_pack = float(energy.pack_current_a.max())
    peak_motor = float(energy.motor_current_a.max())
    motor_limit = math.inf if max_motor_current_a is None else float(max_motor_current_a)
    reason, empty_at, empty_lap = "", math.nan, 0
    if np.any(soc <= 0):
        k = int(np.argmax(soc <= 0))
        # linear between the samples around the crossing
        t0, t1, s_a, s_b = energy.t_s[k - 1], energy.t_s[k], soc[k - 1], soc[k]
        empty_at = float(t0 + (t1 - t0) * s_a / (s_a - s_b)) if k > 0 else 0.0
        empty_lap = int(np.searchsorted(ends, empty_at)) + 1
        reason = (f"{pack.label} empty in lap {empty_lap} of {laps} (state of charge 0 at "
                  f"{empty_at:.2f} s; it started at {s0:.3f}): the pack cannot fly this race at "
                  "the limit lap's pace")
    elif peak_pack > pack.max_current_a * (1 + current_tol):
        reason = (f"{pack.label}: current {peak_pack:.1f} A above its limit "
                  f"{pack.max_current_a:.1f} A (c_rating x capacity_ah)")
    elif peak_motor > motor_limit * (1 + current_tol):
        reason = (f"motor current {peak_motor:.1f} A above the motor's max_current_a "
                  f"{motor_limit:.1f} A")
    left = pack.energy_j(end_soc, 0.0) / 3600.0 if end_soc > 0 else 0.0
    return RaceEnergy(
        feasible=not reason, reason=reason, pack=pack.label, laps=laps, start_soc=s0,
        end_soc=end_soc, energy_used_wh=energy.energy_pack_j / 3600.0, energy_left_wh=left,
        capacity_used_pct=100.0 * float(energy.charge_c[-1]) / (3600.0 * pack.capacity_ah),
        peak_pack_current_a=peak_pack, peak_motor_current_a=peak_motor,
        pack_current_margin_a=pack.max_current_a - peak_pack,
        motor_current_margin_a=motor_limit - peak_motor,
        energy_balance_error=energy.balance_error, soc_at_lap_end=at_ends,
        empty_at_s=empty_at, empty_in_lap=empty_lap,
        lap_ends_s=tuple(float(e) for e in ends))
