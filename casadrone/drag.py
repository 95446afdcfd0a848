"""Body-drag forms of the airframe: one registry (:data:`DRAG_MODELS`), the airframe's
``drag_model`` key names one. Both act on the body-frame airspeed v (m/s) with the airframe's drag
areas C_d·A_i (``drag_area_m2``, m²) and air density ρ, and agree exactly along a body axis; they
differ in between, which a racing lap (pitched 40-70° into the flow at 20-45 m/s) flies all along.

* ``per-axis`` (default): the paper's −½ ρ C_d·A_i |v_i| v_i on each body axis. Every result of the
  paper problems is computed with it, unchanged (the same expression, the same sparsity).
  In between the axes its force falls: with equal areas, at 45° it is 1/√2 of the on-axis drag
  at the same airspeed and points off the airflow.
* ``isotropic``: −½ ρ C_d·A_i |v| v_i, the parasitic drag of RotorPy (Folk, Paulos, Kumar,
  "RotorPy: A Python-based multirotor simulator with aerodynamics for education and research",
  arXiv:2306.04485, 2023; ``rotorpy/vehicles/multirotor.py``: D = −‖v‖ C_D v with
  C_D = diag(c_Dx, c_Dy, c_Dz) in N/(m/s)², i.e. c_D,i = ½ ρ C_d·A_i here). Each axis's force grows
  with the whole airspeed: an area's normal force falls with the flow's incidence α as sin α
  (per-axis: sin² α, half of it at 45°), nearer flat plates inclined to the flow, whose normal
  force past stall falls no faster than sin α (Hoerner, Fluid-Dynamic Drag, 1965, ch. 3). |v| is
  smoothed as √(|v|² + ε²) − ε (exactly 0 at rest, within ε of |v|, smooth for IPOPT): along an
  axis the force is (1 − ε/|v|) of the per-axis one.

The form enters the parameter vector p as one switch (:data:`DRAG_PARAM_NAMES`) for the propulsion
models that declare ``drag_forms`` (``propeller``); the paper's model has none and keeps the
per-axis form. CasADi is imported only inside the symbolic function.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

#: Width ε (m/s) of the smoothed airspeed √(|v|² + ε²) − ε of the ``isotropic`` form: along a body
#: axis its force is within ε/|v| of the per-axis form's (1 % at 10 m/s, 0.2 % at 45 m/s).
SPEED_SMOOTHING_M_S = 0.1
#: Appended to p after the propulsion model's own names when that model declares ``drag_forms``:
#: 1 for ``isotropic``, 0 for ``per-axis``.
DRAG_PARAM_NAMES = ("drag_isotropic",)


@dataclass(frozen=True)
class DragModel:
    """One body-drag form.

    Attributes:
        name: the ``drag_model`` value in YAML.
        switch: its value of ``drag_isotropic`` in p.
        description: one line for the schema's description.
    """

    name: str
    switch: float
    description: str


#: The body-drag forms, by their YAML name.
DRAG_MODELS: dict[str, DragModel] = {
    "per-axis": DragModel("per-axis", 0.0, "the paper's −½ρ C_d·A_i |v_i| v_i per body axis"),
    "isotropic": DragModel("isotropic", 1.0, "RotorPy's −½ρ C_d·A_i |v| v_i (the whole airspeed "
                           "on each axis's area; casadrone.drag)"),
}
#: The form of an airframe that names none (and the only one of the paper's model).
DEFAULT_DRAG = "per-axis"


def drag_params(name: str) -> tuple[float, ...]:
    """The :data:`DRAG_PARAM_NAMES` values of form ``name``."""
    return (DRAG_MODELS[name].switch,)


def body_drag(vel: Any, rho: Any, cda: Any, q: Any = None) -> Any:
    """Body drag (N, body frame) at body airspeed ``vel`` (m/s, 3) with density ``rho`` (kg/m³)
    and drag areas ``cda`` (m², 3), symbolic. ``q``: p by name; when it holds ``drag_isotropic``
    the form is chosen by it (1 ``isotropic``, 0 ``per-axis``: each exactly, not a blend), else
    the per-axis expression alone, the paper's, operation for operation."""
    import casadi as ca

    per_axis = -0.5 * rho * cda * ca.fabs(vel) * vel
    if q is None or DRAG_PARAM_NAMES[0] not in q:
        return per_axis
    f = q[DRAG_PARAM_NAMES[0]]
    eps = SPEED_SMOOTHING_M_S
    speed = ca.sqrt(ca.dot(vel, vel) + eps**2) - eps
    return (1 - f) * per_axis + f * (-0.5 * rho * cda * speed * vel)


def drag_force(vel: tuple[float, ...], rho: float, cda: tuple[float, ...],
               name: str = DEFAULT_DRAG) -> tuple[float, ...]:
    """:func:`body_drag` in plain floats (N, body frame), form ``name``: the numeric twin the
    tests and tables read."""
    if name == "per-axis":
        return tuple(-0.5 * rho * c * abs(v) * v for c, v in zip(cda, vel, strict=True))
    eps = SPEED_SMOOTHING_M_S
    speed = math.sqrt(sum(v * v for v in vel) + eps**2) - eps
    return tuple(-0.5 * rho * c * speed * v for c, v in zip(cda, vel, strict=True))
