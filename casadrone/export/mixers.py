"""Flight-controller motor mixes from an airframe's allocation matrix: Betaflight ``mmix`` lines and
PX4 control-allocation (``CA_ROTOR*``) parameters.

casadrone's allocation matrix B maps rotor thrusts (N) to [total thrust, Mx, My, Mz] in its body
frame (x forward, y left, z up; rotors FR, FL, RL, RR; ``rotor_spins`` = sign of each rotor's
reaction yaw torque about +z, so -1 is a rotor turning counter-clockwise seen from above). The
columns of B⁻¹ are the thrust changes that give a pure collective thrust, a pure roll, pitch or yaw
moment: that is the mix of an asymmetric frame, without the cross-coupling a symmetric quad-X mix
would give it (a roll command that also yaws, a throttle that also pitches).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from casadrone.airframe import Airframe
from casadrone.config.airframe import MOTOR_NUMBERING, ROTOR_LABELS, ROTOR_NAMES
from casadrone.export.source import ExportSource

#: Betaflight's and PX4's motor numbering as casadrone rotor indices (motor 1 first), from the
#: one table of positions and firmware numbers (:data:`casadrone.config.airframe.MOTOR_NUMBERING`).
BETAFLIGHT_ORDER = MOTOR_NUMBERING["betaflight"].order
PX4_ORDER = MOTOR_NUMBERING["px4"].order
LABELS = ROTOR_NAMES


def spin_word(reaction_sign: float) -> str:
    """Rotor direction seen from above: a rotor turning counter-clockwise (angular velocity +z)
    pushes the body clockwise, a reaction torque about -z (``rotor_spins`` -1)."""
    return "CCW" if reaction_sign < 0 else "CW"


@dataclass(frozen=True)
class MotorMix:
    """Per rotor (casadrone order FR, FL, RL, RR) the throttle, roll, pitch, yaw weights."""

    throttle: np.ndarray
    roll: np.ndarray
    pitch: np.ndarray
    yaw: np.ndarray


def motor_mix(airframe: Airframe) -> MotorMix:
    """The normalised mix of an airframe, in Betaflight's sign conventions.

    Signs (Betaflight's QUADX table): roll +1 on the left motors (a positive roll raises the left
    side), pitch +1 on the rear motors (a positive pitch raises the tail), yaw +1 on the motors
    turning counter-clockwise with ``yaw_motors_reversed = OFF`` (Betaflight negates the yaw PID
    sum unless that setting is on, ``src/main/flight/mixer.c``). In casadrone's frame those are
    +Mx, +My and −Mz: the roll, pitch and negated yaw columns of B⁻¹.

    Normalisation, as Betaflight's built-in mixes are written (``mixer_init.c``): throttle scaled
    to a largest weight of 1 (Betaflight counts the motors of a custom mix up to the first zero
    throttle, so no weight may be 0); roll and pitch by one common factor, largest |weight| 1 (as
    HEX6X: roll ±0.5/±1, pitch ±0.866, so each axis keeps its real authority); yaw to a largest
    |weight| of 1. A symmetric X frame gives exactly QUADX.
    """
    Binv = np.linalg.inv(airframe.allocation_matrix)
    thr, roll, pitch, yaw = Binv[:, 0], Binv[:, 1], Binv[:, 2], -Binv[:, 3]
    if np.any(thr <= 0):
        raise ValueError(f"{airframe.name}: the centre of mass lies outside the rotors' polygon; "
                         "no positive throttle mix holds it level")
    rp = max(np.abs(roll).max(), np.abs(pitch).max())

    def clean(v: np.ndarray) -> np.ndarray:
        v = np.round(v, 12)
        return v + 0.0  # no negative zeros

    return MotorMix(clean(thr / thr.max()), clean(roll / rp), clean(pitch / rp),
                    clean(yaw / np.abs(yaw).max()))


def betaflight(src: ExportSource) -> str:
    """Betaflight CLI lines: ``mixer CUSTOM``, ``mmix reset``, ``mmix N throttle roll pitch yaw``
    (N from 0 = motor 1), ``set yaw_motors_reversed``, ``save``; comments start with ``#``."""
    a = src.airframe
    mix = motor_mix(a)
    spins = a.rotor_spins
    # Betaflight's default (props in): motor 1 rear-right CW, 2 front-right CCW, 3 rear-left CCW,
    # 4 front-left CW. The mirrored set is props out: yaw_motors_reversed = ON, same table.
    props_out = bool(np.all(spins[list(BETAFLIGHT_ORDER)] == [-1, 1, 1, -1]))
    yaw = -mix.yaw if props_out else mix.yaw
    lines = [f"# {h}" for h in src.header_lines("Betaflight custom motor mix")]
    lines += [
        "# Paste into the Betaflight CLI. Motor order (Betaflight numbering, as QUADX):",
        *(f"#   motor {n + 1} (mmix {n}) = {ROTOR_LABELS[i]} {LABELS[i]} rotor, turning "
          f"{spin_word(spins[i])} seen from above, at x={1000 * a.rotor_positions[i, 0]:+.1f} mm "
          f"forward, y={1000 * a.rotor_positions[i, 1]:+.1f} mm left of the centre of mass"
          for n, i in enumerate(BETAFLIGHT_ORDER)),
        "#   " + ("props out: yaw_motors_reversed = ON (every rotor turns opposite to "
                  "Betaflight's default)" if props_out else
                  "props in (Betaflight's default directions): yaw_motors_reversed = OFF"),
        "# Columns: throttle roll pitch yaw, from the inverse allocation matrix (pure thrust,",
        "# roll, pitch, yaw per column); throttle max 1, roll and pitch one common scale",
        "# (max |w| 1), yaw max |w| 1. Signs as Betaflight's QUADX: roll + left, pitch + rear,",
        "# yaw + CCW.",
        "mixer CUSTOM",
        "mmix reset",
    ]
    for n, i in enumerate(BETAFLIGHT_ORDER):
        lines.append(f"mmix {n} {mix.throttle[i]:.6f} {mix.roll[i]:.6f} {mix.pitch[i]:.6f} "
                     f"{yaw[i]:.6f}")
    lines += [f"set yaw_motors_reversed = {'ON' if props_out else 'OFF'}", "save"]
    return "\n".join(lines) + "\n"


def to_frd(r: np.ndarray) -> np.ndarray:
    """casadrone body frame (x forward, y left, z up) → PX4's FRD (x forward, y right, z down):
    a rotation of 180° about x."""
    r = np.asarray(r, dtype=float)
    return r * np.array([1.0, -1.0, -1.0])


#: MAVLink parameter types (MAV_PARAM_TYPE) of the parameters written: CA_AIRFRAME and
#: CA_ROTOR_COUNT are INT32 enums, the geometry REAL32 (PX4's control_allocator module.yaml).
MAV_PARAM_INT32, MAV_PARAM_REAL32 = 6, 9


def px4_parameters(src: ExportSource) -> list[tuple[str, float, int]]:
    """(name, value, MAV_PARAM_TYPE) of PX4's dynamic control allocation: CA_AIRFRAME 0
    (multirotor), CA_ROTOR_COUNT, CA_ROTORn_PX/PY/PZ (m, FRD, relative to the centre of mass) and
    CA_ROTORn_KM (torque per thrust, m; positive for a rotor turning counter-clockwise seen from
    above, PX4's parameter reference)."""
    a = src.airframe
    out: list[tuple[str, float, int]] = [("CA_AIRFRAME", 0, MAV_PARAM_INT32),
                                         ("CA_ROTOR_COUNT", 4, MAV_PARAM_INT32)]
    frd = to_frd(a.rotor_positions)
    for n, i in enumerate(PX4_ORDER):
        km = -a.rotor_spins[i] * a.kappa
        out += [(f"CA_ROTOR{n}_PX", frd[i, 0] + 0.0, MAV_PARAM_REAL32),
                (f"CA_ROTOR{n}_PY", frd[i, 1] + 0.0, MAV_PARAM_REAL32),
                (f"CA_ROTOR{n}_PZ", frd[i, 2] + 0.0, MAV_PARAM_REAL32),
                (f"CA_ROTOR{n}_KM", km + 0.0, MAV_PARAM_REAL32)]
    return out


def _px4_notes(src: ExportSource) -> list[str]:
    a = src.airframe
    return [
        "Positions in PX4's body frame FRD (x forward, y right, z down), metres from the centre",
        "of mass: casadrone's (x, y, z) becomes (x, -y, -z). KM = +kappa for a CCW rotor (seen",
        "from above), -kappa for a CW one. CA_ROTORn_AX/AY/AZ stay at PX4's default (0, 0, -1):",
        "thrust up the body; CA_ROTORn_CT stays yours (it depends on the motor and ESC).",
        "Rotor order (PX4 quadrotor-x numbering):",
        *(f"  CA_ROTOR{n} = motor {n + 1} = {ROTOR_LABELS[i]} {LABELS[i]}, "
          f"{spin_word(a.rotor_spins[i])}"
          for n, i in enumerate(PX4_ORDER)),
    ]


def _value(value: float, kind: int) -> str:
    return str(int(value)) if kind == MAV_PARAM_INT32 else f"{value:.6f}"


def px4(src: ExportSource) -> str:
    """QGroundControl's parameter file (``.params``) of :func:`px4_parameters`, with how to apply
    it. QGroundControl's reader (``ParameterManager::readParametersFromStream``) skips lines
    starting with ``#`` and reads every other line as five tab-separated fields: vehicle (system)
    id, component id, name, value, MAV_PARAM_TYPE; it refuses a file whose system id is not the
    vehicle's and skips a parameter whose type differs from the vehicle's. PX4's autopilot is
    system 1, component 1 by default (MAV_SYS_ID, MAV_COMP_ID_AUTOPILOT1)."""
    lines = [f"# {h}" for h in src.header_lines("PX4 control-allocation parameters "
                                                  "(QGroundControl parameter file)")]
    lines += [f"# {n}" for n in _px4_notes(src)]
    lines += [
        "# How to apply: QGroundControl > Vehicle Setup > Parameters > Tools > Load from file...,",
        "# choose this file, confirm, then reboot the vehicle (PX4 reads CA_* at boot). Check the",
        "# motor order and directions in Actuators > Identify & Assign Motors before flying.",
        "# Vehicle-Id 1 is PX4's default MAV_SYS_ID; QGroundControl refuses the file for a vehicle",
        "# with another id: edit the first column to match. For the NSH console instead, use",
        "# 'casadrone export ... --format px4-shell' (param set lines).",
        "#",
        "# Vehicle-Id Component-Id Name Value Type",
    ]
    lines += [f"1\t1\t{name}\t{_value(value, kind)}\t{kind}"
              for name, value, kind in px4_parameters(src)]
    return "\n".join(lines) + "\n"


def px4_shell(src: ExportSource) -> str:
    """The same parameters as ``param set`` lines for PX4's NSH console (MAVLink shell), or an
    ``etc/extras.txt`` on the SD card."""
    lines = [f"# {h}" for h in src.header_lines("PX4 control-allocation parameters "
                                                  "(param set lines)")]
    lines += [f"# {n}" for n in _px4_notes(src)]
    lines += ["# How to apply: paste into QGroundControl's MAVLink Console (Analyze Tools), or",
              "# the NSH console, then 'param save' and reboot. For QGroundControl's Load from",
              "# file, use 'casadrone export ... --format px4' (a .params file)."]
    lines += [f"param set {name} {_value(value, kind)}" for name, value, kind in
              px4_parameters(src)]
    return "\n".join(lines) + "\n"
