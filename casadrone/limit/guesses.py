"""Initial guesses of the limit-lap NLP: from the frame's closed-loop lap, from another limit lap
(another grid or attitude model), along straight lines, and between the full model and the point
mass. Pure functions of their inputs (docs/concepts/limit-lap.md)."""

from __future__ import annotations

import numpy as np

from casadrone.airframe import Airframe, build_airframe
from casadrone.config.airframe import load_airframe
from casadrone.config.controller import ControllerConfig, load_controller
from casadrone.config.track import TrackConfig
from casadrone.limit.nlp import Nlp
from casadrone.limit.result import LimitLap, euler_states, model_states, node_times
from casadrone.model import NX, rotation_matrix
from casadrone.propulsion import equal_rotor_guess, static_thrusts
from casadrone.trim import trim


def closed_loop_lap(airframe: Airframe, track: TrackConfig,
                    controller: ControllerConfig | None = None):
    """casadrone's closed-loop lap of this frame (a :class:`Trajectory`), or None if the frame
    cannot be trimmed or controlled."""
    from casadrone.control import design_for
    from casadrone.simulate import simulate

    ctrl = controller or load_controller(None)
    tp = trim(airframe, "hover", 0.0, solver="newton")
    if not tp.success or np.any(tp.u0 > 1.0):
        return None
    ref = ctrl.reference_airframe
    reference = None
    if ref is not None:
        reference = build_airframe(load_airframe(ref))
    design = design_for(airframe, ctrl, reference, tp, certificate=False)
    if not design.stable:
        return None
    return simulate(airframe, design, track)


def _sample(t_nodes, t, values, hold: bool):
    if hold:
        idx = np.clip(np.searchsorted(t, t_nodes, side="right") - 1, 0, len(t) - 1)
        return values[idx]
    return np.column_stack([np.interp(t_nodes, t, values[:, i]) for i in range(values.shape[1])])


def guess_from_trajectory(nlp: Nlp, traj, x0: np.ndarray) -> np.ndarray | None:
    """Decision vector sampled from a completed closed-loop lap (leg ends where the guidance
    switched segment); None when the lap did not reach the end (or the NLP has more legs than
    the closed loop flew: a multi-lap course)."""
    L, N = nlp.layout.n_legs, nlp.layout.intervals
    switches = []
    for k in range(L):
        hit = np.flatnonzero(traj.segment > k)
        if not hit.size:
            return None
        switches.append(traj.t[hit[0]])
    ends = np.maximum.accumulate(np.maximum(switches, 1e-2 * np.arange(1, L + 1)))
    T = np.diff(np.concatenate([[0.0], ends]))
    t_nodes = np.concatenate([[0.0]] + [s + np.linspace(0, d, N + 1)[1:] for s, d in
                                        zip(ends - T, T, strict=True)])
    X = model_states(nlp.model.attitude, _sample(t_nodes, traj.t, traj.x, hold=False))
    X[0] = x0
    U = _sample(t_nodes[:-1], traj.t, traj.u, hold=True)
    return nlp.pack(T, X, U)


def guess_from_lap(nlp: Nlp, lap: LimitLap, x0: np.ndarray) -> np.ndarray:
    """Decision vector of a limit lap solved on another grid of the same legs (grid
    refinement) or with the other attitude model: same leg durations, states interpolated at
    the new nodes, commands held."""
    T = lap.leg_times_s
    t_nodes = node_times(T, nlp.layout.intervals)
    x = lap.x
    if lap.attitude != nlp.model.attitude:  # a lap of the other attitude model, converted
        x = model_states(nlp.model.attitude, lap.x_euler)
    X = _sample(t_nodes, lap.t, x, hold=False)
    X[0] = x0
    U = _sample(t_nodes[:-1], lap.t[:-1], lap.u, hold=True)
    return nlp.pack(T, X, U)


def straight_guess(nlp: Nlp, route: np.ndarray, x0: np.ndarray, speed: float = 5.0,
                   weight_n: float = 0.0, hover_command: float | None = None) -> np.ndarray:
    """Constant ``speed`` (m/s) along the route in the start's attitude: the guess when no
    closed loop flies, and the point-mass reference's starts (commands ``hover_command``;
    default the paper model's rotor thrust over K)."""
    L, N = nlp.layout.n_legs, nlp.layout.intervals
    T = np.maximum(np.linalg.norm(np.diff(route, axis=0), axis=1) / speed, 0.1)
    X = np.repeat(x0[None, :], L * N + 1, axis=0)
    for k in range(L):
        s = np.linspace(0, 1, N + 1)[1:, None]
        X[k * N + 1:(k + 1) * N + 1, 0:3] = route[k] + s * (route[k + 1] - route[k])
    rotor = nlp.model.rotor
    if rotor is None:  # the point mass: level, total thrust the weight
        U = np.zeros((L * N, nlp.model.nu))
        U[:, 3] = weight_n
        return nlp.pack(T, X, U)
    U = np.full((L * N, nlp.model.nu), float(np.mean(x0[rotor])) / 9.0519
                if hover_command is None else hover_command)
    return nlp.pack(T, X, np.clip(U, 0, 1))


def point_mass_guess(full: Nlp, pm: Nlp, w_full: np.ndarray, airframe: Airframe | None = None
                     ) -> np.ndarray:
    """The point-mass decision vector of a full-model one: same durations, positions, world
    velocities; attitude and total thrust (of the rotor states at rest) as the controls."""
    T, X, U = full.unpack(w_full)
    X = euler_states(full.model.attitude, X)
    Xp = np.zeros((len(X), 6))
    Xp[:, 0:3] = X[:, 0:3]
    for i, x in enumerate(X):
        Xp[i, 3:6] = np.asarray(rotation_matrix(*x[9:12])).reshape(3, 3) @ x[3:6]
    rotor = X[:-1, 12:16] if airframe is None else static_thrusts(airframe, X[:-1, 12:16])
    Up = np.column_stack([X[:-1, 9:12], rotor.sum(axis=1)])
    return pm.pack(T, Xp, Up)


def lifted_guess(full: Nlp, pm: Nlp, w_pm: np.ndarray, airframe: Airframe, x0: np.ndarray
                 ) -> np.ndarray:
    """A full-model decision vector from a point-mass solution: attitude from its controls,
    body velocity rotated into it, each rotor a quarter of the thrust, no body rates."""
    T, Xp, Up = pm.unpack(w_pm)
    X = np.zeros((len(Xp), NX))
    att = np.vstack([Up, Up[-1:]])
    X[:, 0:3] = Xp[:, 0:3]
    X[:, 9:12] = att[:, 0:3]
    X[:, 12:16], U = equal_rotor_guess(airframe, att[:, 3] / 4)
    for i in range(len(X)):
        R = np.asarray(rotation_matrix(*att[i, 0:3])).reshape(3, 3)
        X[i, 3:6] = R.T @ Xp[i, 3:6]
    X = model_states(full.model.attitude, X)
    X[0] = x0
    U = np.clip(U[:-1], 0, 1)
    return full.pack(T, X, U)
