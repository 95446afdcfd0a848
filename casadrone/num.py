"""``Num``: a value the model's formulas take, a number or a CasADi expression.

The physics of :mod:`casadrone.model` and :mod:`casadrone.propulsion` is written once and
evaluated on floats, NumPy arrays and CasADi's ``SX``, ``MX`` and ``DM`` alike (the same
expression builds the symbolic model and checks a number). ``Num`` names that in a signature:
``rotation_matrix(phi: Num, theta: Num, psi: Num) -> Num``.

For the type checker ``Num`` is ``Any``, and this is the one place that says why: casadi 3.8's
stubs type each operator once per class (``SX + SX -> SX``, ``MX + MX -> MX``, ``DM + DM -> DM``,
through overloads on ``self``), and a union cannot say that a formula gets one kind of expression
at a time (all SX, or all MX, with numbers). Written as ``float | numpy.ndarray | SX | MX | DM``,
``Num`` made mypy report 213 errors (casadi 3.8.2: 99 in model.py, 95 in
propulsion/propeller.py, the rest in their callers), nearly all an SX meeting an MX or a float
asked for ``.T``: combinations no call makes. The alias keeps the intent in the signatures
without those false refusals; it imports nothing, so the propulsion models below the
configuration (which loads no CasADi) can use it.
"""

from __future__ import annotations

from typing import Any, TypeAlias

#: A number or a CasADi expression: float, NumPy array, ``casadi.SX``, ``casadi.MX`` or
#: ``casadi.DM`` (checked as ``Any``: see the module docstring).
Num: TypeAlias = Any

__all__ = ["Num"]
