"""A third propulsion model, registered when this module is imported: the paper's thrust lag with
a curved command-to-thrust map (docs/architecture.md#new-propulsion-model).

PX4's thrust model (its parameter ``THR_MDL_FAC``, f; PX4 user guide, "Thrust Curve") maps the
ESC command δ ∈ [0, 1] to the steady thrust through

    T_ss(δ) = K ((1 − f) δ + f δ²),

linear for f = 0 (the paper's T = K δ), quadratic for f = 1 (thrust ∝ ω², ω ∝ δ). The thrust lags
T_ss by the airframe's τ as in the paper: τ Ṫ + T − T_ss(δ) = 0. The rotor states stay the
thrusts (N), bounded by [0, K] (T_ss(1) = K); the yaw reaction is κ T. The model appends one
parameter to p, f (:data:`FACTOR`, the same for every airframe here; a model that reads it from
YAML would add a section to :mod:`casadrone.config.propulsion`).

An airframe flies it with ``propulsion: {model: thrust-curve}`` once this module is imported
(``plugins:`` of a problem, or an import before the YAML is read).
"""

from __future__ import annotations

import math

from casadrone.propulsion import PROPULSION_MODELS, register_propulsion_model
from casadrone.propulsion.paper import PaperThrust

#: f of T_ss(δ) = K ((1 − f) δ + f δ²): halfway between linear and quadratic (illustrative; PX4
#: identifies it per vehicle from a thrust-stand run).
FACTOR = 0.5


class ThrustCurve(PaperThrust):
    """The paper's first-order thrust lag toward K ((1 − f) δ + f δ²): the paper model's force,
    torque, bounds and hover thrust, its own steady thrust and hover commands."""

    name = "thrust-curve"
    description = "thrust-curve (paper lag, PX4 thrust curve)"
    no_sections = "its thrust is the airframe's thrust section"
    param_names: tuple[str, ...] = ("thr_mdl_fac",)
    command_linear = False  # T = K δ does not hold: no frozen-wrench gains, no T/K guesses
    lagless = False
    suffix = "-thrust-curve"

    def pack(self, section, rho: float) -> list[float]:
        return [FACTOR]

    def terms(self, vel, omega, rotor, rotor_dot, u, q, r, s):
        force, torque, _ = super().terms(vel, omega, rotor, rotor_dot, u, q, r, s)
        return force, torque, q["tau"] * rotor_dot + rotor - self.steady_rotors(u, q)

    def steady_rotors(self, delta, q):
        f = q["thr_mdl_fac"]
        return q["K"] * ((1 - f) * delta + f * delta * delta)

    def hover_rotors(self, airframe, thrusts) -> tuple[list[float], list[float]]:
        """(T, δ) with δ the root in [0, 1] of f δ² + (1 − f) δ − T/K = 0."""
        f = airframe.propulsion_params[0]
        commands = [t / airframe.thrust_gain if f == 0 else
                    (-(1 - f) + math.sqrt((1 - f) ** 2 + 4 * f * t / airframe.thrust_gain))
                    / (2 * f) for t in thrusts]
        return [float(t) for t in thrusts], commands


THRUST_CURVE = ThrustCurve()
if THRUST_CURVE.name not in PROPULSION_MODELS:
    register_propulsion_model(THRUST_CURVE)
