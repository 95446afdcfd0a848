"""Analysis of a limit-lap solution: bang-bang fraction, re-simulation with SUNDIALS, and the
lap time's sensitivities to the decision variables (envelope theorem, no re-solve)."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import casadi as ca
import numpy as np

from casadrone.airframe import Airframe, build_airframe, decision_keys, with_theta
from casadrone.config.airframe import AirframeConfig
from casadrone.config.io import ConfigError
from casadrone.limit.attitude import quaternion_f
from casadrone.limit.gates import TARGET_SIZE, target_miss  # noqa: F401 (re-exported)
from casadrone.limit.lagless import is_lagless, lagless_f
from casadrone.model import NU, n_params, propeller_outputs, quadrotor_model
from casadrone.propulsion import airframe_values, propulsion_model


def bang_bang_fraction(u: np.ndarray, tol: float) -> float:
    """Share of ESC commands within ``tol`` of 0 or 1 (over intervals and rotors)."""
    u = np.asarray(u, float)
    return float(np.mean((u <= tol) | (u >= 1 - tol))) if u.size else float("nan")


@lru_cache(maxsize=4)
def scaled_cvodes(rtol: float = 1e-10, atol: float = 1e-10, attitude: str = "euler",
                  propulsion: str = "paper", lagless: bool = False) -> ca.Function:
    """CVODES on ẋ = h f(x, u, p) over [0, 1]: one interval of length h with a held command
    (the same explicit f and SUNDIALS integrator as the closed loop's reference, time-scaled so
    that one Function serves every interval length); ``attitude`` picks the Euler model or the
    quaternion model (:mod:`casadrone.limit.attitude`); ``lagless`` the thrust-lag-off model
    (:mod:`casadrone.limit.lagless`)."""
    if attitude == "quaternion":
        f, rotor = quaternion_f(propulsion), slice(13, 17)
    else:
        f, rotor = quadrotor_model(propulsion).f, slice(12, 16)
    if lagless:
        f = lagless_f(f, rotor)
    x = ca.SX.sym("x", f.size1_in(0))
    NP = n_params(propulsion)
    uph = ca.SX.sym("uph", NU + NP + 1)
    u, p, h = uph[:NU], uph[NU:NU + NP], uph[NU + NP]
    dae = {"x": x, "p": uph, "ode": h * f(x, u, p)}
    tag = "_lagless" if lagless else ""
    return ca.integrator(f"limit_resim_{attitude}_{propulsion}{tag}", "cvodes", dae, 0.0, 1.0,
                         {"abstol": atol, "reltol": rtol})


def fly(airframe: Airframe, lap, first: int = 0, last: int | None = None) -> np.ndarray:
    """Node states first…last (``last`` None: the lap's end) when the lap's commands of those
    intervals are integrated by CVODES from the lap's own node ``first``; NaN from where
    CVODES fails."""
    step = scaled_cvodes(attitude=getattr(lap, "attitude", "euler"),
                         propulsion=airframe.propulsion, lagless=_lagless(airframe))
    last = len(lap.u) if last is None else last
    h = np.diff(lap.t)
    X = np.full((last - first + 1, lap.x.shape[1]), np.nan)
    X[0] = lap.x[first]
    for j, i in enumerate(range(first, last)):
        try:
            X[j + 1] = np.array(step(x0=X[j], p=np.concatenate(
                [lap.u[i], airframe.p, [h[i]]]))["xf"]).ravel()
        except RuntimeError:
            break
    return X


def resimulate(airframe: Airframe, lap) -> np.ndarray:
    """Node states of the lap's commands integrated by CVODES from its start state."""
    return fly(airframe, lap)


def resimulation_miss(airframe: Airframe, lap, targets: np.ndarray, kinds,
                      legs: bool = False) -> float:
    """Largest miss (m) of a ball or gate when the optimal commands are flown open loop: over
    the whole lap from its start state, or (``legs``) each leg from the lap's own node at the
    leg's start (LimitLapOptions.resimulation)."""
    N = lap.layout.intervals
    if legs:
        ends = [fly(airframe, lap, k * N, (k + 1) * N)[-1] for k in range(len(kinds))]
    else:
        X = resimulate(airframe, lap)
        ends = [X[(k + 1) * N] for k in range(len(kinds))]
    misses = [target_miss(end[0:3], targets[TARGET_SIZE * k:TARGET_SIZE * (k + 1)], kind)
              for k, (end, kind) in enumerate(zip(ends, kinds, strict=True))]
    out = max(misses)
    return out if np.isfinite(out) else float("inf")


def _lagless(airframe: Airframe) -> bool:
    return is_lagless(airframe)


def theta_sensitivities(
    cfg: AirframeConfig,
    dT_dp: np.ndarray,
    dT_dx0: np.ndarray,
    start: Callable[[Airframe], np.ndarray],
    keys: tuple[str, ...] | None = None,
    rel_step: float = 1e-5,
) -> dict[str, float]:
    """dT/dθ (s per unit of each key): the NLP's dT/dp and dT/dx_start chained with dp/dθ and
    dx_start/dθ, differentiated through the same config → airframe build as the evaluation
    (so a mass model that derives mass and inertia from θ is included). Central differences of
    that cheap map (no re-solve); one-sided where a side leaves the valid configs (a bound).

    ``keys`` default to the airframe's decision variables
    (:func:`casadrone.airframe.decision_keys`): the seven of paper Table 1 with ``mass_model:
    free``, the four geometry keys with ``components``, whose mass and inertia are derived from
    the geometry and the parts (not keys of the config, so not variables: their effect is inside
    each geometry key's dT/dθ). A key the config does not give (a derived one) raises ValueError
    naming it."""
    keys = decision_keys(cfg) if keys is None else keys
    derived = [k for k in keys if getattr(cfg, k, None) is None]
    if derived:
        raise ValueError(f"{', '.join(derived)}: not given by airframe {cfg.name} (derived "
                         f"from its parts); its decision variables are "
                         f"{', '.join(decision_keys(cfg))}")

    def params(key: str, value: float) -> np.ndarray | None:
        try:
            frame = build_airframe(with_theta(cfg, {key: value}))
        except ConfigError:
            return None
        return np.concatenate([frame.p, start(frame)])

    grad = np.concatenate([dT_dp, dT_dx0])
    out: dict[str, float] = {}
    for key in keys:
        v = float(getattr(cfg, key))
        h = rel_step * max(abs(v), 1e-9)
        hi, lo, mid = params(key, v + h), params(key, v - h), params(key, v)
        if hi is not None and lo is not None:
            d = (hi - lo) / (2 * h)
        elif hi is not None:
            d = (hi - mid) / h
        elif lo is not None:
            d = (mid - lo) / h
        else:
            d = np.zeros_like(grad)
        out[key] = float(grad @ d)
    return out


def thrust_ratios(airframe, J):
    """CT(J)/CT(0) of advance ratios ``J`` (array): 1 with ``paper``; with ``propeller`` the
    shipped quadratic at J, or at max(J, 0) with positive inflow (:func:`lap_propulsion`)."""
    J = np.asarray(J, float)
    if propulsion_model(airframe.propulsion).thrust_is_state:
        return np.ones_like(J)
    q = airframe_values(airframe)
    if q["inflow_positive"] > 0.5:
        J = np.maximum(J, 0.0)
    return (q["ct0"] + q["ct1"] * J + q["ct2"] * J**2) / q["ct0"]


def lap_propulsion(airframe, x, u) -> dict[str, Any]:
    """What the propulsion did over a flight with Euler states ``x`` (M+1, 16) and commands
    ``u`` (M, 4) held from each state: per node (the first M) the airspeed (m/s), each rotor's
    thrust (N) and advance ratio, and the summary ``top_speed_m_s`` and
    ``thrust_at_top_speed_n`` (the four rotors; over all M + 1 nodes, the finish too),
    ``max_advance_ratio`` (NaN with ``paper``, which has no rotor speed),
    ``data_advance_ratio`` (the largest J of the propeller's data, NaN without one),
    ``beyond_data_share`` (the share of rotor-nodes with J above it) and ``min_thrust_ratio``.

    ``min_thrust_ratio`` is the lowest, over every node and every turning rotor, of its thrust
    to the thrust it would give at the same rotor speed without inflow, T(ω, v_a)/T(ω, 0) =
    CT(J)/CT(0) (1 with ``paper``; NaN if no rotor turns). It measures what the inflow costs,
    whatever the command: the issue's first definition, the thrust at full command over the
    static thrust at the same rotor state, is this ratio on the full-command nodes only, and
    near a stopped rotor it had no meaning (J → ∞, the extrapolated CT negative). Inside the
    data (the limit lap's rows) it is bounded below by CT(J_max)/CT(0), 0.34 for the shipped
    propeller. With ``inflow: positive`` J is taken as max(J, 0): the smoothed max(v_a, 0) dips
    to −ε/2 (−0.1 m/s) at zero inflow, which at a nearly stopped rotor would give J → −∞ and a
    ratio without meaning; the model's choice there is the static coefficient, a ratio of 1. A
    stopped rotor (ω = 0, ratio 0/0) is left out."""
    x, u = np.asarray(x, float).reshape(-1, 16), np.asarray(u, float).reshape(-1, 4)
    n = min(len(u), len(x))
    # The top speed counts every node, the last too (a lap's M + 1 nodes, one more than its
    # commands): a lap that finishes on a straight (end: free) is fastest there, and without
    # it the reported top speed was the node before (49.6 against 50.5 m/s, SY250 on a 30 m
    # straight). The last node's thrust is evaluated under the command held into it.
    m = n + 1 if 0 < n < len(x) else n
    x, u = x[:m], np.vstack([u[:n], u[n - 1:n]])[:m] if n else u[:0]
    speed_all = np.linalg.norm(x[:, 3:6], axis=1)
    if n == 0:  # a failed lap: nothing flown
        thrust_all, J_all = np.zeros((0, 4)), np.zeros((0, 4))
    elif propulsion_model(airframe.propulsion).thrust_is_state:
        thrust_all, J_all = x[:, 12:16].copy(), np.full((m, 4), np.nan)
    else:
        out = propeller_outputs().map(m)(x.T, u.T, np.repeat(airframe.p[:, None], m, axis=1))
        thrust_all, J_all = np.asarray(out[0]).T, np.asarray(out[2]).T
    top = int(np.argmax(speed_all)) if n else 0
    # per node and the ratios: the nodes with a command of their own (the figure pairs them)
    speed, thrust, J = speed_all[:n], thrust_all[:n], J_all[:n]
    turning = x[:n, 12:16] > 0
    ratio = thrust_ratios(airframe, J[turning])
    j_data = getattr(airframe, "max_advance_ratio", None)
    return {
        "speed_m_s": speed, "thrust_n": thrust, "advance_ratio": J,
        "top_speed_m_s": float(speed_all[top]) if n else math.nan,
        "thrust_at_top_speed_n": [float(t) for t in thrust_all[top]] if n else [],
        "max_advance_ratio": float(np.nanmax(J)) if n and np.isfinite(J).any() else math.nan,
        "data_advance_ratio": math.nan if j_data is None else float(j_data),
        "beyond_data_share": float(np.mean(J > j_data)) if n and j_data is not None
        else math.nan,
        "min_thrust_ratio": float(ratio.min()) if ratio.size else math.nan,
    }
