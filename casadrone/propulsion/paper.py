"""The paper's thrust model (``propulsion.model: paper``, the default): Table 6's T = K δ lagged
by τ, independent of airspeed, rotor speed and battery state, with the yaw reaction κ T of each
rotor. The rotor states are the thrusts T_i (N), the parameters the paper's own (K, τ, κ of
:data:`casadrone.airframe.PARAM_NAMES`): the model appends none. Every result of the paper
problems is computed with it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from casadrone.propulsion.base import RotorStates, register_propulsion_model


class PaperThrust:
    """The paper's first-order thrust lag (:class:`casadrone.propulsion.base.PropulsionModel`)."""

    name = "paper"
    description = "paper (Table 6 thrust model)"
    sections: tuple[str, ...] = ()
    no_sections = "its thrust is the airframe's thrust section"
    param_names: tuple[str, ...] = ()
    rotor_states = RotorStates(("T1", "T2", "T3", "T4"), "rotor thrusts", "N")
    thrust_is_state = True
    command_linear = True
    trim_unknowns = 6
    default_intervals = 40
    rotor_scale: float | None = None  # thrusts of a few newtons: the NLP's own units
    lagless = True
    suffix = ""
    warm_ipopt: Mapping[str, float] = {}
    drag_forms = False  # the paper's per-axis drag only: p, and every result, as they were

    def pack(self, section: Any, rho: float) -> list[float]:
        return []

    def section_problems(self, section: Any, **_: Any) -> list[tuple[str, str]]:
        return []

    def full_static_thrust(self, section: Any, rho: float) -> float | None:
        return None

    def advance_ratio_limit(self, section: Any) -> float | None:
        return None

    def terms(self, vel, omega, rotor, rotor_dot, u, q, r, s):
        """Σ T_i along body z; thrust moments r_i × T_i e_z and yaw reactions s_i κ T_i e_z;
        τ Ṫ_i + T_i − K δ_i (the arithmetic in the order of the paper model's residual, so
        results stay bit-equal)."""
        import casadi as ca

        kappa, K, tau = q["kappa"], q["K"], q["tau"]
        T = rotor
        ez = ca.DM([0, 0, 1])
        force = ca.sum1(T) * ez
        torque = sum(
            (ca.cross(r[i], T[i] * ez) + s[i] * kappa * T[i] * ez for i in range(4)),
            ca.DM.zeros(3),
        )
        return force, torque, tau * rotor_dot + T - K * u

    def thrusts(self, vel, omega, rotor, q, r, s):
        return rotor

    def steady_rotors(self, delta, q):
        return q["K"] * delta

    def static_rotors(self, thrust, q):
        return thrust

    def currents(self, rotor, u, q):
        """None: the thrust model has no current."""
        return None

    def decay_rate(self, q):
        """1/τ of the thrust lag."""
        return 1 / q["tau"]

    def max_static_thrust(self, airframe) -> float:
        return float(airframe.thrust_gain)

    def rotor_thrust_bound(self, airframe) -> float:
        """K: each lagged thrust stays below K."""
        return float(airframe.thrust_gain)

    def rotor_state_bounds(self, airframe) -> tuple[float, float]:
        return 0.0, float(airframe.thrust_gain)

    def hover_rotors(self, airframe, thrusts) -> tuple[list[float], list[float]]:
        return list(thrusts), list(thrusts / airframe.thrust_gain)

    def static_thrusts(self, airframe, rotor_states):
        import numpy as np

        return np.asarray(rotor_states, float)


PAPER = register_propulsion_model(PaperThrust())
