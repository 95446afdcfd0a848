"""The pack's energy and the current limits of the ``propeller`` kind: a LiPo pack's state of
charge, its open-circuit voltage from it, and the largest currents its pack and motors may
carry.

The pack is an open-circuit voltage behind an internal resistance (the ``propeller`` model's
battery, :mod:`casadrone.propulsion.propeller`), with the open-circuit voltage a function of
the state of charge s (0 empty, 1 full):

- V_oc(s) = cells · OCV(s), OCV the cell's open-circuit voltage, a smooth interpolation of a
  table (:func:`ocv_cell`);
- the pack current through the ideal-chopper ESC, I_bat = Σ δ_i I_i (each motor's current I_i
  at its command δ_i; :func:`pack_current`), the terminal voltage V = V_oc − R_b I_bat;
- ds/dt = −I_bat / (3600 C), C the capacity (Ah; :func:`soc_rate`): coulomb counting, the
  charge drawn is the capacity's share;
- the energy a pack holds between two states of charge is cells · 3600 C ∫ OCV(s) ds (J;
  :meth:`Pack.energy_j`); what it gives at its terminals is that less ∫ R_b I² dt.

Limits: I_bat ≤ c_rating · C (the maker's continuous C rating), and each motor's I_i ≤ its
``max_current_a``.

The functions take numbers, numpy arrays and CasADi symbols alike (the square root is the power
½, which all three define). Sources: coulomb counting and the OCV–R model are the
"Rint" equivalent circuit (He, Xiong, Fan, "Evaluation of lithium-ion battery equivalent circuit
models for state of charge estimation by an experimental approach", Energies 4(4), 582–598,
2011, section 2.1); the ideal-chopper ESC conserves power, δ V I_motor = V I_bat.

This module sits on the propulsion floor: it imports no schema (its :func:`pack_of` reads any
object with the :class:`casadrone.config.propulsion.BatteryConfig` attributes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

#: The smoothing width of the OCV interpolation's corners, as a share of the table's smallest
#: soc spacing: each corner of the piecewise-linear table is rounded over about this width, and
#: the curve passes a table point within ε |Δslope| / 2 (0.01 V per cell on a 20-point LiPo table
#: whose steepest corner changes slope by 4 V per unit soc over a spacing of 0.05).
SMOOTHING_SHARE = 0.1
#: Seconds per hour: a capacity in Ah is 3600 C coulombs.
S_PER_H = 3600.0
#: Points of the trapezoid rule for the pack's energy over a range of charge (the smoothed
#: curve is piecewise nearly linear: 2000 intervals put the rule's error below 1e-6 relative).
ENERGY_POINTS = 2001


def _root(x):
    """√x for numbers, numpy arrays and CasADi symbols."""
    return x ** 0.5


def _ramp(x, eps: float):
    """max(x, 0) smoothed over ε: ½(x + √(x² + ε²)), smooth, increasing, within ε/2 of it."""
    return 0.5 * (x + _root(x * x + eps * eps))


def ocv_cell(soc, curve: Sequence[tuple[float, float]]):
    """The cell's open-circuit voltage (V) at state of charge ``soc`` (0–1): the table ``curve``
    ((soc, cell V) pairs, soc and V increasing) interpolated piecewise-linearly with each corner
    rounded (:func:`_ramp` over ε = :data:`SMOOTHING_SHARE` × the smallest spacing) and extended
    linearly beyond its ends. Written as v₀ + m₀ (s − s₀) + Σ_k (m_k − m_{k−1}) ramp(s − s_k),
    whose slope is a convex combination of the table's slopes: increasing wherever the table is.
    """
    s = [float(p[0]) for p in curve]
    v = [float(p[1]) for p in curve]
    slopes = [(v[k + 1] - v[k]) / (s[k + 1] - s[k]) for k in range(len(s) - 1)]
    eps = SMOOTHING_SHARE * min(b - a for a, b in zip(s, s[1:], strict=False))
    out = v[0] + slopes[0] * (soc - s[0])
    for k in range(1, len(slopes)):
        out = out + (slopes[k] - slopes[k - 1]) * _ramp(soc - s[k], eps)
    return out


def pack_current(u, motor_currents):
    """The pack current (A) through the ideal-chopper ESC, Σ δ_i I_i: each ESC draws its duty
    cycle δ_i of its motor's current I_i (A) from the pack (power δ_i V I_i = V (δ_i I_i))."""
    return sum(u[i] * motor_currents[i] for i in range(4))


def soc_rate(current, capacity_ah: float):
    """ds/dt (1/s) of a pack of ``capacity_ah`` (Ah) delivering ``current`` (A): −I/(3600 C)."""
    return -current / (S_PER_H * capacity_ah)


@dataclass(frozen=True)
class Pack:
    """A pack with a capacity: what the energy model needs of a ``battery:`` section.

    ``ocv_curve`` None: the open-circuit voltage stays ``open_circuit_voltage_v`` whatever the
    charge (the constant-voltage pack of the ``propeller`` model), and the start is full. With a
    curve the start's state of charge is the one whose open-circuit voltage is
    ``open_circuit_voltage_v`` (a pack is charged to a voltage, which is what a pilot measures).
    """

    capacity_ah: float
    resistance_ohm: float
    open_circuit_voltage_v: float
    cells: int | None = None
    c_rating: float | None = None
    ocv_curve: tuple[tuple[float, float], ...] | None = None

    @property
    def label(self) -> str:
        """How refusals name the pack: "4S 650 mAh pack" (cells where given)."""
        size = f"{self.capacity_ah * 1000:.0f} mAh"
        return f"{self.cells}S {size} pack" if self.cells else f"{size} pack"

    @property
    def max_current_a(self) -> float:
        """The largest pack current (A), c_rating × capacity; inf without a C rating."""
        return math.inf if self.c_rating is None else self.c_rating * self.capacity_ah

    def ocv(self, soc):
        """The pack's open-circuit voltage (V) at ``soc`` (numbers or CasADi)."""
        if self.ocv_curve is None:
            return self.open_circuit_voltage_v + 0 * soc
        assert self.cells is not None  # the schema requires cells with a curve
        return self.cells * ocv_cell(soc, self.ocv_curve)

    @property
    def start_soc(self) -> float:
        """The state of charge at the start: 1 without a curve, else where
        cells · OCV(s) = open_circuit_voltage_v (bisection; the schema keeps it in [0, 1])."""
        if self.ocv_curve is None:
            return 1.0
        return soc_of_voltage(self, self.open_circuit_voltage_v)

    def energy_j(self, soc_from: float, soc_to: float) -> float:
        """Energy (J) the open-circuit voltage gives from ``soc_from`` down to ``soc_to``:
        3600 C ∫ V_oc(s) ds (trapezoid over :data:`ENERGY_POINTS` points)."""
        import numpy as np

        s = np.linspace(soc_to, soc_from, ENERGY_POINTS)
        v = np.asarray(self.ocv(s), float)
        return float(S_PER_H * self.capacity_ah * np.trapezoid(v, s))


def soc_of_voltage(pack: Pack, volts: float, tol: float = 1e-12) -> float:
    """The state of charge whose open-circuit voltage is ``volts`` (V), by bisection on [0, 1]
    (the curve increases); clipped to the ends outside them."""
    lo, hi = 0.0, 1.0
    if volts <= float(pack.ocv(lo)):
        return lo
    if volts >= float(pack.ocv(hi)):
        return hi
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if float(pack.ocv(mid)) < volts else (lo, mid)
    return 0.5 * (lo + hi)


def pack_of(battery: Any) -> Pack | None:
    """The :class:`Pack` of a ``battery:`` section, None without ``capacity_ah`` (no energy
    model: the pack is the constant open-circuit voltage of before, nothing limited)."""
    if battery is None or getattr(battery, "capacity_ah", None) is None:
        return None
    curve = battery.ocv_curve
    return Pack(capacity_ah=float(battery.capacity_ah),
                resistance_ohm=float(battery.internal_resistance_ohm),
                open_circuit_voltage_v=float(battery.open_circuit_voltage_v),
                cells=battery.cells, c_rating=battery.c_rating,
                ocv_curve=None if curve is None else tuple((float(a), float(b))
                                                           for a, b in curve))


def current_limits(section: Any) -> tuple[float | None, float | None]:
    """(largest pack current, largest motor current) (A) of a ``propulsion:`` section, each None
    where the section gives none (no rows in the limit lap): the pack's c_rating × capacity_ah,
    the motor's max_current_a."""
    pack = pack_of(getattr(section, "battery", None))
    motor = getattr(section, "motor", None)
    pack_a = None if pack is None or pack.c_rating is None else pack.max_current_a
    motor_a = None if motor is None else getattr(motor, "max_current_a", None)
    return pack_a, None if motor_a is None else float(motor_a)
