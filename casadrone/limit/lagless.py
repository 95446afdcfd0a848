"""The thrust-lag-off idealisation of the limit lap: each rotor's thrust is K·δ at once.

Published time-optimal planners often fly an idealised vehicle whose thrusts are the controls
(no motor lag; e.g. Foehn et al., "Time-optimal planning for quadrotor waypoint flight", Sci.
Robotics 2021, whose model commands the rotor thrusts directly). casadrone's paper model lags
each thrust by τ (τ Ṫ + T = K δ, paper Table 6); an airframe with ``thrust.time_constant_s: 0``
asks for the lag-free limit: T = K δ, held over each interval like the command.

The lagged model's explicit form divides by τ, so τ = 0 is a different model *form*, not a
parameter value of the same graph: :func:`lagless_f` evaluates the lagged dynamics with the rotor
states replaced by K δ, and freezes the rotor states (Ṫ = 0; the lap reports T = K δ instead,
:func:`lagless_thrust_states`). The default (lagged) model and its compiled blocks are unchanged;
the lag-free model is a graph of its own, built and compiled the first time a lag-free airframe
asks for it. Only the paper propulsion model has τ; the propeller model's lag is its motor's.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from casadrone.model import PARAM_NAMES
from casadrone.propulsion import propulsion_model

#: Index of the thrust gain K in p (paper layout, the propeller's starts with it).
K_INDEX = PARAM_NAMES.index("K")


def lagless_f(f: ca.Function, rotor: slice) -> ca.Function:
    """``f(x, u, p) -> ẋ`` without thrust lag: the lagged ``f`` evaluated with the rotor states
    ``x[rotor]`` replaced by K·u, and the rotor states' derivatives zero (τ = 0 makes the
    lagged rotor rows 0/0; they are not evaluated)."""
    x = ca.SX.sym("x", f.size1_in(0))
    u = ca.SX.sym("u", f.size1_in(1))
    p = ca.SX.sym("p", f.size1_in(2))
    xs = ca.vertcat(x[:rotor.start], p[K_INDEX] * u, x[rotor.stop:])
    xdot = f(xs, u, p)
    n = f.size1_in(0)
    rows = [xdot[i] if not rotor.start <= i < rotor.stop else ca.SX(0) for i in range(n)]
    return ca.Function(f"{f.name()}_lagless", [x, u, p], [ca.vertcat(*rows)],
                       ["x", "u", "p"], ["xdot"])


def lagless_thrust_states(x: np.ndarray, u: np.ndarray, rotor: slice | None, gain_n: float
                          ) -> np.ndarray:
    """Node states ``x`` (M + 1 rows) with the rotor states set to the thrusts the lag-free
    model flies: K·δ of the command held from each node (the last node repeats the last)."""
    out = np.array(x, float)
    u = np.asarray(u, float)
    if len(u) and rotor is not None:
        out[:, rotor] = gain_n * np.vstack([u, u[-1:]])
    return out


#: The lag the closed-loop start of a lag-free airframe is flown with (s): the paper's Table 6
#: τ. The closed loop (LQR-I design, simulation) needs the lagged model; its lap is only a start
#: of the lag-free NLP, which then removes the lag.
GUESS_LAG_S = 0.060538


def is_lagless(airframe) -> bool:
    """Whether ``airframe`` asks for the thrust-lag-off idealisation (paper model, τ = 0)."""
    return (propulsion_model(airframe.propulsion).lagless
            and airframe.thrust_time_constant == 0)


def without_lag(model):
    """The :class:`casadrone.limit.nlp.OcpModel` ``model`` with the lag-free dynamics
    (:func:`lagless_f`), under its own name (so its own NLP and compiled blocks)."""
    from dataclasses import replace

    if model.rotor is None:  # the point mass has no rotor states: nothing lags
        return model
    return replace(model, name=f"{model.name}-lagless", f=lagless_f(model.f, model.rotor))


def with_guess_lag(airframe):
    """``airframe`` with the lag its closed-loop start is flown with (itself when it lags)."""
    from dataclasses import replace

    return replace(airframe, thrust_time_constant=GUESS_LAG_S) if is_lagless(airframe) \
        else airframe
