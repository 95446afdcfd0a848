"""The propulsion-model protocol and its registry, :data:`PROPULSION_MODELS`.

A propulsion model is everything that depends on what drives the rotors: the parameters it
appends to the airframe vector p and how they are packed from the ``propulsion:`` section, its
rotor force, torque and rotor dynamics (symbolic), what its four rotor states are, and the
numeric helpers the other stages ask of it (the largest thrust, the bounds of the rotor states,
the states and commands of hover). Every stage reads the model of an airframe from the registry
by its name (``Airframe.propulsion``, ``propulsion.model`` in YAML); none compares the name.
Adding a model is one module that registers one entry (docs/architecture.md#new-propulsion-model).

This module imports nothing of casadrone but the body-drag forms' names (:mod:`casadrone.drag`):
the schema (:mod:`casadrone.config.propulsion`) takes its choices from the registry, so the
registry sits below it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol, TypedDict

from casadrone.drag import DRAG_PARAM_NAMES
from casadrone.num import Num

#: The model of an airframe whose ``propulsion:`` section names none.
DEFAULT_MODEL = "paper"


class PaperParams(TypedDict):
    """The airframe vector p by name (:func:`casadrone.model.named`), symbolic or numeric: the
    paper's parameters, in the order of p (:data:`casadrone.airframe.PARAM_NAMES` is this list),
    which every propulsion model's p starts with; a model's own follow them (its
    :attr:`PropulsionModel.param_names`)."""

    mass: Num  # kg
    Ixx: Num  # inertia about the body axes at the centre of mass (kg·m²)
    Iyy: Num
    Izz: Num
    Ixy: Num  # products of inertia (kg·m²)
    Ixz: Num
    Iyz: Num
    r1x: Num  # rotor positions from the centre of mass (m, body axes), rotors FR, FL, RL, RR
    r1y: Num
    r1z: Num
    r2x: Num
    r2y: Num
    r2z: Num
    r3x: Num
    r3y: Num
    r3z: Num
    r4x: Num
    r4y: Num
    r4z: Num
    s1: Num  # spin signs: the sign of each rotor's reaction torque about +z
    s2: Num
    s3: Num
    s4: Num
    kappa: Num  # yaw reaction per thrust (m)
    CdA_x: Num  # drag areas along the body axes (m²)
    CdA_y: Num
    CdA_z: Num
    rho: Num  # air density (kg/m³)
    K: Num  # thrust gain (N per unit command)
    tau: Num  # thrust time constant (s)
    g: Num  # gravity (m/s²)


@dataclass(frozen=True)
class RotorStates:
    """What the four rotor states are with one propulsion model: their names, what they are
    (for text) and their unit."""

    names: tuple[str, ...]
    what: str
    unit: str


class PropulsionModel(Protocol):
    """One entry of :data:`PROPULSION_MODELS`.

    ``q`` below is the airframe vector p by name, the paper's names (:class:`PaperParams`) and
    this model's :attr:`param_names` (:func:`casadrone.model.named`); it and the other values of
    the symbolic methods are :data:`casadrone.num.Num` (numbers or CasADi expressions); ``r``
    the four rotor positions from the centre of mass (m), ``s`` the spin signs. ``airframe`` is
    anything with the :class:`casadrone.airframe.Airframe` attributes; ``section`` a
    :class:`casadrone.config.propulsion.PropulsionConfig`.
    """

    #: The name YAML gives in ``propulsion.model`` (the key of the registry).
    name: str
    #: One line for the schema's description and ``--help``.
    description: str
    #: The sub-sections of ``propulsion:`` the model reads (``propeller``, ``motor``,
    #: ``battery``); the schema requires them and refuses the others.
    sections: tuple[str, ...]
    #: Why the model needs none of the sections it does not read (the schema's refusal says so).
    no_sections: str
    #: The names appended to the paper's parameter vector (SI units), in packing order. The
    #: trim tells the model of a vector by its length (:func:`model_of_length`), so no two models
    #: append the same number.
    param_names: tuple[str, ...]
    #: The four rotor states: names, what they are, unit.
    rotor_states: RotorStates
    #: The rotor states are the rotor thrusts (N), bounded by [0, K]: the thrust of a node is its
    #: state, independent of the airspeed and of p.
    thrust_is_state: bool
    #: At rest the thrust is K δ (the command scales linearly to the thrust gain K): the
    #: frozen-wrench gain policy and the guesses that divide a thrust by K hold.
    command_linear: bool
    #: Unknowns of a trim: 6 (φ, θ, δ1…δ4) when :meth:`steady_rotors` gives the rotor states at
    #: rest in closed form, 10 with the four rotor states as unknowns too.
    trim_unknowns: int
    #: Default intervals per leg of the limit lap.
    default_intervals: int
    #: The unit of the rotor states in the limit lap's NLP (their own unit times this), None for
    #: their own unit.
    rotor_scale: float | None
    #: ``thrust.time_constant_s: 0`` (the limit lap's lag-free idealisation) is allowed.
    lagless: bool
    #: Appended to the names of the model's compiled blocks (``quadrotor-propeller``) and of the
    #: shipped reference airframes that fly it (``SY250-propeller``); empty for the default.
    suffix: str
    #: IPOPT settings added to a warm-started limit-lap solve.
    warm_ipopt: Mapping[str, float]
    #: The airframe's ``drag_model`` may choose its body-drag form (:mod:`casadrone.drag`): p
    #: carries :data:`casadrone.drag.DRAG_PARAM_NAMES` after :attr:`param_names`. False (the
    #: paper's model): the per-axis form only, p unchanged.
    drag_forms: bool

    def pack(self, section: Any, rho: float) -> list[float]:
        """The :attr:`param_names` values of an airframe's section at air density ``rho``."""
        ...

    def section_problems(self, section: Any, *, mass_kg: float | None, rho: float | None,
                         prop_diameter_mm: float | None, mass_key: str
                         ) -> list[tuple[str, str]]:
        """(airframe key, message) of a valid section against the rest of its airframe."""
        ...

    def full_static_thrust(self, section: Any, rho: float) -> float | None:
        """Thrust (N) of one rotor at full command and rest, from the section; None where it is
        the airframe's thrust gain K (the airframe's hover check then uses K)."""
        ...

    def advance_ratio_limit(self, section: Any) -> float | None:
        """The largest advance ratio the limit lap may fly, None for none."""
        ...

    def terms(self, vel: Num, omega: Num, rotor: Num, rotor_dot: Num, u: Num, q: PaperParams,
              r: list[Num], s: list[Num]) -> tuple[Num, Num, Num]:
        """(rotor force (3, N, body frame), rotor torque (3, N·m), rotor residual (4, zero along
        a flight)) at body velocity ``vel``, body rates ``omega``, rotor states ``rotor`` and
        their derivative ``rotor_dot``, ESC commands ``u`` (symbolic)."""
        ...

    def thrusts(self, vel: Num, omega: Num, rotor: Num, q: PaperParams, r: list[Num],
                s: list[Num]) -> Num:
        """Each rotor's thrust (N, 4) along its axis, the same expression :meth:`terms` uses."""
        ...

    def steady_rotors(self, delta: Num, q: PaperParams) -> Num | None:
        """The rotor states at rest under commands ``delta`` (symbolic), None when not explicit
        (then they are unknowns of the trim, :attr:`trim_unknowns`)."""
        ...

    def static_rotors(self, thrust: Num, q: PaperParams) -> Num:
        """The rotor states giving ``thrust`` (N) at rest (symbolic or numeric)."""
        ...

    def currents(self, rotor: Num, u: Num, q: PaperParams) -> tuple[Num, Num] | None:
        """(pack current (A), the four motor currents (A)) at rotor states ``rotor`` under
        commands ``u`` (symbolic), what the limit lap's current limits bound
        (:func:`casadrone.limit.nlp.current_rows`); None for a model without currents."""
        ...

    def decay_rate(self, q: PaperParams) -> Num:
        """The rotor states' linear decay rate λ (1/s) that depends on p only: the part −λ x of
        ẋ the exponential step integrates exactly (:func:`casadrone.limit.nlp.etdrk4_step`)."""
        ...

    def max_static_thrust(self, airframe: Any) -> float:
        """Thrust (N) of one rotor at full command and rest (all four at full command)."""
        ...

    def rotor_thrust_bound(self, airframe: Any) -> float:
        """The point mass's bound (N) of one rotor's share of the total thrust (may be inf)."""
        ...

    def rotor_state_bounds(self, airframe: Any) -> tuple[float, float]:
        """Bounds of the four rotor states in the limit lap."""
        ...

    def hover_rotors(self, airframe: Any, thrusts: Any) -> tuple[list[float], list[float]]:
        """(rotor states, ESC commands) holding each rotor at ``thrusts`` (N) at rest."""
        ...

    def static_thrusts(self, airframe: Any, rotor_states: Any) -> Any:
        """Thrust (N) of rotor states (any shape) at zero inflow (numeric)."""
        ...


#: The propulsion models by name: the schema's ``propulsion.model`` choices, what every stage
#: builds and asks of an airframe's propulsion.
PROPULSION_MODELS: dict[str, PropulsionModel] = {}


def register_propulsion_model(model: PropulsionModel) -> PropulsionModel:
    """Add ``model`` to :data:`PROPULSION_MODELS` (and return it). Refuses a taken name, or a
    parameter layout as long as a registered model's (the trim tells models apart by it)."""
    if model.name in PROPULSION_MODELS:
        raise ValueError(f"propulsion model {model.name!r} is registered already")
    for other in PROPULSION_MODELS.values():
        if len(other.param_names) == len(model.param_names):
            raise ValueError(
                f"propulsion model {model.name!r} appends {len(model.param_names)} parameters, "
                f"as {other.name!r} does: the trim tells models apart by the vector's length")
    PROPULSION_MODELS[model.name] = model
    return model


def propulsion_model(name: str) -> PropulsionModel:
    """The registered model ``name``; ValueError naming the choices otherwise."""
    try:
        return PROPULSION_MODELS[name]
    except KeyError:
        raise ValueError(f"unknown propulsion model '{name}'; choose one of "
                         f"{', '.join(PROPULSION_MODELS)}") from None


def appended_names(model: PropulsionModel) -> tuple[str, ...]:
    """The names ``model`` appends to the paper's parameter vector: its own, then the body-drag
    switch when it declares ``drag_forms``."""
    return model.param_names + (DRAG_PARAM_NAMES if getattr(model, "drag_forms", False) else ())


def model_of_length(n_extra: int) -> str:
    """The name of the model that appends ``n_extra`` parameters to the paper's vector."""
    for name, model in PROPULSION_MODELS.items():
        if len(appended_names(model)) == n_extra:
            return name
    raise ValueError(f"no propulsion model appends {n_extra} parameters to the paper's vector")
