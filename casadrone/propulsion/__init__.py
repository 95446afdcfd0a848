"""Propulsion models: what drives the rotors, one registry (:data:`PROPULSION_MODELS`) of one
module each.

* ``paper`` (default, :mod:`casadrone.propulsion.paper`): the paper's Table 6 thrust model,
  T = K δ lagged by τ; the rotor states are the thrusts (N). Every result of the paper problems
  is computed with it, unchanged.
* ``propeller`` (:mod:`casadrone.propulsion.propeller`): propeller coefficients CT(J), CP(J) at
  each rotor's own axial inflow, rotor drag, a DC or first-order motor and a sagging battery;
  the rotor states are the rotor speeds (rad/s).

An airframe names its model in ``propulsion.model``; the schema's choices, the parameter vector,
the symbolic model and every stage's questions (the largest thrust, the rotor-state bounds, the
hover states) go through the entry (:class:`casadrone.propulsion.base.PropulsionModel`), so a
new model is one module that registers one (docs/architecture.md#new-propulsion-model). The
static physics and shipped data the schema checks are :mod:`casadrone.propulsion.data`.

The package sits below the configuration: it imports no schema and CasADi only inside the
symbolic functions. The functions below take any object with the
:class:`casadrone.airframe.Airframe` attributes and ask the airframe's model.
"""

from __future__ import annotations

from typing import Any

from casadrone.propulsion.base import (
    DEFAULT_MODEL,
    PROPULSION_MODELS,
    PropulsionModel,
    RotorStates,
    appended_names,
    model_of_length,
    propulsion_model,
    register_propulsion_model,
)
from casadrone.propulsion.data import (
    SHIPPED_PROPELLER,
    data_advance_ratio,
    fit_points,
    propeller_data,
    shipped_datasets,
)
from casadrone.propulsion.paper import PAPER
from casadrone.propulsion.propeller import (
    PROPELLER,
    PROPELLER_PARAM_NAMES,
    advance_margins,
    airframe_values,
    axial_inflow,
    box_thrust_bound,
    fit_coefficients,
    full_static_thrust,
    hover_commands,
    motor_currents,
    propeller_params,
    propeller_terms,
    rotor_loads,
    speed_for_thrust,
    static_speed,
    static_thrust,
    thrust_bound,
)

__all__ = [
    "DEFAULT_MODEL", "PAPER", "PROPELLER", "PROPELLER_PARAM_NAMES", "PROPULSION_MODELS",
    "SHIPPED_PROPELLER", "PropulsionModel", "RotorStates", "advance_margins",
    "advance_ratio_limit", "airframe_problems", "airframe_values", "axial_inflow",
    "box_thrust_bound", "data_advance_ratio", "equal_rotor_guess", "fit_coefficients",
    "fit_points", "full_static_thrust", "hover_commands", "hover_rotors", "max_static_thrust",
    "appended_names", "model_of_length", "motor_currents", "propeller_data", "propeller_params",
    "propeller_terms",
    "propulsion_model", "register_propulsion_model", "rotor_loads", "rotor_state_bounds",
    "rotor_thrust_bound", "shipped_datasets", "speed_for_thrust", "static_speed",
    "static_thrust", "static_thrusts", "thrust_bound",
]  # fmt: skip


def max_static_thrust(airframe) -> float:
    """Thrust (N) of one rotor at full command and zero airspeed (all four at full command):
    K with ``paper``; the steady DC-motor/propeller balance with the battery's sag with
    ``propeller``."""
    return propulsion_model(airframe.propulsion).max_static_thrust(airframe)


def rotor_thrust_bound(airframe) -> float:
    """The point mass's bound (N) of one rotor's share of the total thrust: K with ``paper``
    (each lagged thrust stays below K); :func:`thrust_bound` with ``propeller`` (inf with signed
    inflow)."""
    return propulsion_model(airframe.propulsion).rotor_thrust_bound(airframe)


def rotor_state_bounds(airframe) -> tuple[float, float]:
    """Bounds of the four rotor states in the limit lap: thrust in [0, K] (``paper``), rotor
    speed in [0, K_V V_oc] (``propeller``)."""
    return propulsion_model(airframe.propulsion).rotor_state_bounds(airframe)


def hover_rotors(airframe, thrusts) -> tuple[list[float], list[float]]:
    """(rotor states, ESC commands) holding each rotor at ``thrusts`` (N) at zero airspeed:
    (T, T/K) with ``paper``; (ω, δ) of :func:`hover_commands` with ``propeller``."""
    return propulsion_model(airframe.propulsion).hover_rotors(airframe, thrusts)


def static_thrusts(airframe, rotor_states):
    """Thrust (N) of rotor states (any shape) at zero inflow: the states themselves with
    ``paper``, ρ c₀ D⁴ n² of the rotor speeds with ``propeller``."""
    return propulsion_model(airframe.propulsion).static_thrusts(airframe, rotor_states)


def equal_rotor_guess(airframe, thrust_per_rotor):
    """(rotor states (N, 4), commands (N, 4)) of N nodes whose four rotors each give
    ``thrust_per_rotor`` (N,) at rest (:func:`hover_rotors` per node): a guess for a trajectory
    from a point-mass solution."""
    import numpy as np

    t = np.asarray(thrust_per_rotor, float).ravel()
    rows = [hover_rotors(airframe, np.full(4, ti)) for ti in t]
    return (np.array([r[0] for r in rows], float).reshape(-1, 4),
            np.array([r[1] for r in rows], float).reshape(-1, 4))


def advance_ratio_limit(section) -> float | None:
    """The largest advance ratio the limit lap may fly with a ``propulsion:`` section
    (dimensionless), None for none (:func:`casadrone.propulsion.propeller.advance_ratio_limit`)."""
    return propulsion_model(section.model).advance_ratio_limit(section)


def airframe_problems(section, **context: Any) -> list[tuple[str, str]]:
    """Problems of a valid ``propulsion:`` section against the rest of its airframe, as (airframe
    key, message), keywords ``mass_kg``, ``rho``, ``prop_diameter_mm``, ``mass_key``
    (:func:`casadrone.propulsion.propeller.airframe_problems`)."""
    return propulsion_model(section.model).section_problems(section, **context)
