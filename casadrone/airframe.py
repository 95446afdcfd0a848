"""Airframe: geometry θ and physical data → rotor layout, allocation, model parameter vector.

Frames (docs/concepts/conventions.md): body x forward (nose), y left, z up; rotors FR, FL, RL, RR.
The paper draws the nose on body +y (x to the right): :func:`from_paper_frame` converts at this
boundary.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cache, cached_property
from typing import Literal

import numpy as np

from casadrone.config.airframe import TABLE1_BOUNDS, AirframeConfig
from casadrone.config.io import ConfigError, field_adapter, format_errors
from casadrone.drag import DEFAULT_DRAG, drag_params
from casadrone.massprops import mass_properties, rotor_positions_mm
from casadrone.propulsion import advance_ratio_limit, propulsion_model
from casadrone.propulsion.base import PaperParams
from casadrone.propulsion.electric import current_limits

#: Names and order of the decision vector θ (paper Table 1) and their config keys.
THETA_NAMES = ("lambda_a", "lambda_b", "alpha", "beta", "Ixx", "Iyy", "Izz")
THETA_KEYS = (
    "lambda_a_mm",
    "lambda_b_mm",
    "alpha_deg",
    "beta_deg",
    "ixx_kgm2",
    "iyy_kgm2",
    "izz_kgm2",
)
#: The decision variables of ``mass_model: components``: the geometry alone (mass and inertia
#: follow from the parts).
GEOMETRY_KEYS = THETA_KEYS[:4]

#: Order of the model parameter vector p (see :mod:`casadrone.model`): the fields of its typed
#: record, :class:`casadrone.propulsion.base.PaperParams`, declared there with their units.
PARAM_NAMES: tuple[str, ...] = tuple(PaperParams.__annotations__)

Family = Literal["SY", "HS", "NSY"]


def family(alpha_deg: float, beta_deg: float, tol_deg: float = 1e-6) -> Family:
    """SY: α = β = 90°; HS: exactly one of them at 90°; NSY: neither at 90° (paper §1.1.1)."""
    a90 = abs(alpha_deg - 90.0) <= tol_deg
    b90 = abs(beta_deg - 90.0) <= tol_deg
    if a90 and b90:
        return "SY"
    if a90 or b90:
        return "HS"
    return "NSY"


def from_paper_frame(r_paper: np.ndarray) -> np.ndarray:
    """Paper body frame (x right, y nose, z up) → casadrone body frame (x nose, y left, z up)."""
    r = np.asarray(r_paper, dtype=float)
    return np.stack([r[..., 1], -r[..., 0], r[..., 2]], axis=-1)


@dataclass(frozen=True)
class Airframe:
    """A physical airframe in SI units; ``p`` is the model parameter vector (PARAM_NAMES order)."""

    name: str
    family: Family
    theta: np.ndarray  # λa (m), λb (m), α (rad), β (rad), Ixx, Iyy, Izz (kg·m²)
    mass: float  # kg
    inertia: np.ndarray  # 3×3 (kg·m²)
    rotor_positions: np.ndarray  # 4×3 (m), body frame, rotors FR, FL, RL, RR
    rotor_spins: np.ndarray  # 4, sign of reaction yaw torque about +z
    kappa: float  # m
    drag_area: np.ndarray  # 3 (m²)
    thrust_gain: float  # K (N per unit command)
    thrust_time_constant: float  # τ (s)
    battery_voltage: float  # V
    air_density: float  # kg/m³
    gravity: float  # m/s²
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))  # hub → CoM (m), body axes
    #: propulsion kind (:mod:`casadrone.propulsion`) and its parameters appended to p
    propulsion: str = "paper"
    propulsion_params: tuple[float, ...] = ()
    #: largest advance ratio of the propeller's data, which the limit lap keeps every rotor
    #: within (:func:`casadrone.propulsion.advance_ratio_limit`); None: no bound (``paper``)
    max_advance_ratio: float | None = None
    #: the pack's c_rating × capacity_ah and the motor's max_current_a (A), which the limit lap
    #: keeps every node within (:func:`casadrone.propulsion.electric.current_limits`); None: none
    max_pack_current_a: float | None = None
    max_motor_current_a: float | None = None
    #: body-drag form (:mod:`casadrone.drag`); its switch follows the propulsion parameters in p
    #: when the propulsion model has ``drag_forms``
    drag_model: str = DEFAULT_DRAG

    @cached_property
    def p(self) -> np.ndarray:
        """Model parameter vector, ordered as :data:`PARAM_NAMES` followed, for a ``propeller``
        airframe, by :data:`casadrone.propulsion.PROPELLER_PARAM_NAMES` and the body-drag switch
        :data:`casadrone.drag.DRAG_PARAM_NAMES` (:func:`casadrone.model.param_names`; computed
        once, read-only)."""
        J = self.inertia
        p = np.concatenate(
            [
                [self.mass, J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]],
                self.rotor_positions.ravel(),
                self.rotor_spins,
                [self.kappa],
                self.drag_area,
                [self.air_density, self.thrust_gain, self.thrust_time_constant, self.gravity],
                self.propulsion_params,
                drag_params(self.drag_model)
                if getattr(propulsion_model(self.propulsion), "drag_forms", False) else (),
            ]
        ).astype(float)
        p.flags.writeable = False
        return p

    @property
    def allocation_matrix(self) -> np.ndarray:
        """4×4 map from rotor thrusts (N) to [total thrust (N), Mx, My, Mz (N·m)]."""
        r, s = self.rotor_positions, self.rotor_spins
        return np.vstack([np.ones(4), r[:, 1], -r[:, 0], s * self.kappa])

    @property
    def diagonal_mm(self) -> float:
        """Motor-to-motor diagonal λ = λa + λb (mm), the size class."""
        return 1000.0 * float(self.theta[0] + self.theta[1])

    def hover_thrusts(self) -> np.ndarray:
        """Rotor thrusts (N) that hold the airframe still: Σ T = m g, zero net moment."""
        rhs = np.array([self.mass * self.gravity, 0.0, 0.0, 0.0])
        return np.linalg.solve(self.allocation_matrix, rhs)


def build_airframe(cfg: AirframeConfig) -> Airframe:
    """Build the SI :class:`Airframe` of a validated config (the schema has already checked the
    geometry and that the inertia tensor is a possible rigid body).

    Mass, centre of mass and inertia come from :func:`casadrone.massprops.mass_properties` (given,
    or computed from the parts); the rotor positions are referred to the centre of mass
    (r_i − c), which is where the model's moments are taken.
    """
    mp = mass_properties(cfg)
    limits = current_limits(cfg.propulsion)
    r = np.array(rotor_positions_mm(cfg.lambda_a_mm, cfg.lambda_b_mm, cfg.alpha_deg, cfg.beta_deg))
    J = mp.inertia_kgm2
    theta = np.array(
        [
            cfg.lambda_a_mm / 1000,
            cfg.lambda_b_mm / 1000,
            np.radians(cfg.alpha_deg),
            np.radians(cfg.beta_deg),
            J[0, 0],
            J[1, 1],
            J[2, 2],
        ]
    )
    return Airframe(
        name=cfg.name,
        family=family(cfg.alpha_deg, cfg.beta_deg),
        theta=theta,
        mass=mp.mass_kg,
        inertia=J,
        rotor_positions=r / 1000.0 - mp.com_m,
        rotor_spins=np.array(cfg.rotor_spins, dtype=float),
        kappa=cfg.kappa_m,
        drag_area=np.array(cfg.drag_area_m2, dtype=float),
        thrust_gain=cfg.thrust.gain_n,
        thrust_time_constant=cfg.thrust.time_constant_s,
        battery_voltage=cfg.battery_voltage_v,
        air_density=cfg.air_density_kgm3,
        gravity=cfg.gravity_mps2,
        com=mp.com_m,
        propulsion=cfg.propulsion.model,
        propulsion_params=tuple(propulsion_model(cfg.propulsion.model).pack(
            cfg.propulsion, cfg.air_density_kgm3)),
        max_advance_ratio=advance_ratio_limit(cfg.propulsion),
        max_pack_current_a=limits[0],
        max_motor_current_a=limits[1],
        drag_model=cfg.drag_model,
    )


def decision_keys(cfg: AirframeConfig) -> tuple[str, ...]:
    """The decision variables of an airframe's mass model: the seven of paper Table 1
    (``free``), or the four geometry keys (``components``: mass and inertia follow from them)."""
    return GEOMETRY_KEYS if cfg.mass_model == "components" else THETA_KEYS


def with_theta(cfg: AirframeConfig, theta: dict[str, float], name: str | None = None,
               base: dict | None = None):
    """A copy of ``cfg`` with decision variables replaced (keys as in the config, e.g.
    ``alpha_deg``), validated like a file: invalid geometry raises ConfigError. ``base``:
    ``cfg.model_dump()`` if the caller already has it (an optimiser keeps it per study)."""
    from pydantic import ValidationError

    fast = _replace_valid(cfg, theta, name)
    if fast is not None:
        return fast
    data = dict(base) if base is not None else cfg.model_dump()
    data.update(theta)
    if name is not None:
        data["name"] = name
    try:
        return AirframeConfig.model_validate(data)
    except ValidationError as exc:
        raise ConfigError(format_errors(exc, name or cfg.name, AirframeConfig)) from None


@cache
def _field_validator(key: str):
    """The strict validator of one airframe field (built once per key)."""
    return field_adapter(AirframeConfig, key)


def _replace_valid(cfg: AirframeConfig, theta: dict[str, float],
                   name: str | None) -> AirframeConfig | None:
    """The per-candidate fast path of :func:`with_theta`: ``cfg`` is valid already, so only the
    replaced fields (each as strictly as the schema) and the cross-field checks need running;
    that is the whole schema's verdict (a model validator checks nothing else) at a fraction of
    a full re-validation (~0.5 ms of every evaluation). None when something is invalid: the
    full validation then words the error."""
    update = {}
    for key, value in theta.items():
        if key not in AirframeConfig.model_fields or key == "name":
            return None
        try:
            update[key] = _field_validator(key).validate_python(value)
        except ValueError:
            return None
    if name is not None:
        update["name"] = name
    new = cfg.model_copy(update=update)
    return None if AirframeConfig.problems(dict(new)) else new


def random_thetas(
    template: AirframeConfig, n: int, seed: int = 0, bounds: dict | None = None
) -> tuple[list[dict[str, float]], int]:
    """``n`` decision vectors drawn uniformly inside ``bounds`` (default: paper Table 1, for the
    template's decision variables) that are valid on ``template`` (rotors that overlap, and
    inertias no rigid body has, are redrawn), and the rejected count."""
    rng = np.random.default_rng(seed)
    if bounds is None:
        bounds = {k: TABLE1_BOUNDS[k] for k in decision_keys(template)}
    out: list[dict[str, float]] = []
    rejected = 0
    while len(out) < n:
        theta = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in bounds.items()}
        try:
            with_theta(template, theta)
        except ConfigError:
            rejected += 1
            continue
        out.append(theta)
    return out, rejected
