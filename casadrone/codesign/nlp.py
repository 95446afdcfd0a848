"""The co-design NLP: the limit-lap NLPs of one or more tracks with the airframe's θ appended.

Built around :mod:`casadrone.limit.nlp`, never a copy of it: each track's limit-lap NLP gives its
symbolic decision vector w, parameter P = [p, x_start, targets], objective and constraints
(:attr:`casadrone.limit.nlp.Nlp.problem`); here P is replaced by [p(θ), x_start(θ), targets]
(p(θ) and the hover thrusts of the start state from :mod:`casadrone.codesign.frame`), θ is
appended to the decision vector (normalised to [0, 1] in the problem's box), and the frame's
feasibility rules and any ε-constraints are appended to the constraints. So transcription,
attitude and constraint changes of the limit lap carry over unchanged.

Decision vector: [w_1, …, w_K, s (θ normalised), t (only for ``combine: worst``)].
Objective: Σ_k weight_k T_k (``sum``), or t with weight_k T_k ≤ t for every k (``worst``, the
epigraph form that keeps the NLP smooth).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal, cast

import casadi as ca
import numpy as np

from casadrone.codesign.budget import CpuBudget
from casadrone.codesign.derivatives import codesign_derivatives, uses_blocks
from casadrone.codesign.frame import SymbolicFrame
from casadrone.indices import EFFORT_SMOOTHING_N  # one δ for the index and the NLP
from casadrone.limit.nlp import Nlp, ipopt_options
from casadrone.model import rotor_thrust_function
from casadrone.propulsion import propulsion_model

Combine = Literal["sum", "worst"]
#: Lower bound of the frame's feasibility rows (each scaled to order one): IPOPT meets a row to
#: its tolerance, and a frame on the no-overlap boundary then failed the airframe schema's exact
#: check by 10⁻⁷ deg (SY250-components-propeller on the paper track, β = 78.8399689° where
#: 78.84° is needed). 10⁻⁶ of the row keeps the frame inside, ~10⁻⁵ deg from the boundary.
FEASIBILITY_MARGIN = 1e-6
#: The ε-constrained measures a co-design NLP can hold: the frame's mass and span, and the
#: limit lap's effort (:func:`effort`).
MEASURES = ("mass_kg", "span_m", "effort")


def epsilon_rows(measure: str) -> int:
    """Rows of a measure's ε bound: ``span_m`` bounds both rotor diagonals, the others are one
    row each (:func:`build_codesign_nlp` appends them in :attr:`CodesignNlp.epsilon` order)."""
    return 2 if measure == "span_m" else 1
#: Iterations of one ε-continuation step (:attr:`CodesignNlp.step`). Every converged step of the
#: measured fronts took 27–101 (paper track, `paper`) and 79–170 (`propeller`, 120 intervals per
#: leg) iterations; a step that would need more is one IPOPT has lost (restoration: one step
#: of the paper front on another machine crawled for 1090 s of CPU), and is split in two
#: instead (:func:`casadrone.codesign.front.continued`).
STEP_MAX_ITER = 250
#: ... and its CPU seconds (IPOPT's ``max_cpu_time``), an absolute guard: a lost step's
#: iterations can each take seconds (the 1090 s step above: infeasibility 10³ after
#: restoration, slow factorisations), so the iteration cap alone does not bound it. The budget
#: below decides first; this only bounds a budget gone wrong.
STEP_MAX_CPU_S = 600.0
#: A step's own budget follows the front (:func:`casadrone.codesign.front.step_budget`): this
#: many times the slowest solve so far (the fastest frame's and every converged step's), at
#: least :data:`STEP_MIN_CPU_S`. Why a multiple, not a fixed cap: the lost paper step above,
#: re-run, took 113 iterations of 1.2 s on average (the converged steps' take 0.1 s; a limit of
#: 10 successive restoration iterations did not stop it) to a 120 s cap, while the paper
#: front's converged steps took 2–10 s and its two halves converged in 2 and 7 s; and a fixed
#: 120 s cap stopped the `propeller` front (120 intervals per leg) at its 12th point on a
#: loaded 2-vCPU VM, where its converged steps took 33–109 s (benchmarks/RESULTS-codesign.md).
STEP_CPU_FACTOR = 3.0
STEP_MIN_CPU_S = 15.0


def effort_terms(part: TrackPart, w, p=None):
    """The limit lap's effort ∫ Σ_i T_i^{3/2} dt (N^1.5·s) over the lap, interval by interval,
    from w: each interval's length times its start node's rotor thrusts (a left rectangle rule).

    Why this measure: by momentum theory a rotor making thrust T in still air needs at least the
    ideal induced power T^{3/2} / sqrt(2 ρ A) (Leishman, Principles of Helicopter Aerodynamics,
    2nd ed., eq. 2.17), so the effort is the rotors' ideal energy over the lap times sqrt(2 ρ A),
    a constant of the frame's propellers (not a decision variable). It is what the limit lap
    spends (bang-bang thrust) and what a battery pays for, it is smooth in the NLP's variables,
    and unlike the closed-loop J5 it needs no controller. The thrusts are the rotor states with
    the paper propulsion model; with ``propeller`` (``part.propulsion``) each node's
    T_i = CT(J_i) ρ n_i² D⁴ of its rotor speeds and own axial inflows, the model's thrust
    (:func:`casadrone.model.rotor_thrusts`) on the airframe vector ``p`` (symbolic p(θ) in the
    co-design NLP), as :func:`casadrone.indices.limit_lap_effort` reads a lap."""
    nlp = part.nlp
    L, M, N = nlp.layout.n_legs, nlp.layout.n_intervals, nlp.layout.intervals
    zero_u = np.zeros((M, nlp.model.nu))
    X = np.zeros((M + 1, nlp.model.nx))
    h = w[np.flatnonzero(nlp.pack(np.ones(L), X, zero_u)).tolist()] / N
    if propulsion_model(part.propulsion).thrust_is_state:
        X[:M, nlp.model.rotor] = 1.0
        at_t = np.flatnonzero(nlp.pack(np.zeros(L), X, zero_u))
        T = ca.reshape(w[at_t.tolist()], -1, M)  # rotors × intervals
    else:
        T = _node_thrusts(part, w, p)
    power = ca.sum1((T ** 2 + EFFORT_SMOOTHING_N ** 2) ** 0.75)
    return power.T * h  # one term per interval


def _node_thrusts(part: TrackPart, w, p):
    """The rotor thrusts (N, rotors × intervals) at the start node of every interval, from the
    node states in w (the NLP's units, :attr:`casadrone.limit.nlp.OcpModel.scale`) and p."""
    nlp, model = part.nlp, part.nlp.model
    if p is None or model.velocity is None or model.rates is None or model.rotor is None:
        raise ValueError(f"the effort of {model.name} needs p and the velocity, rates and "
                         "rotor states of its model")
    L, M = nlp.layout.n_legs, nlp.layout.n_intervals
    X = np.zeros((M + 1, model.nx))
    X[:M, :] = 1.0
    at_x = np.flatnonzero(nlp.pack(np.zeros(L), X, np.zeros((M, model.nu))))
    Xs = ca.reshape(w[at_x.tolist()], model.nx, M)  # states × nodes, node-major in w
    if model.scale is not None:  # back to the model's units
        Xs = Xs * ca.repmat(ca.DM(model.scale), 1, M)
    f = rotor_thrust_function(part.propulsion).map(M)
    return f(Xs[model.velocity, :], Xs[model.rates, :], Xs[model.rotor, :], p)


def effort(part: TrackPart, w, p=None):
    """The limit lap's effort ∫ Σ_i T_i^{3/2} dt (N^1.5·s): the sum of :func:`effort_terms`."""
    return ca.sum1(effort_terms(part, w, p))


@dataclass(frozen=True)
class TrackPart:
    """One track's limit-lap NLP and the numbers that pose it (bounds, start, targets)."""

    nlp: Nlp
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray  # the limit lap's row bounds for this track (Nlp.row_bounds)
    ubg: np.ndarray
    x_start: np.ndarray  # in the model's states; its rotor states become the frame's hover thrusts
    targets: np.ndarray
    weight: float = 1.0
    hover_start: bool = True  # the start state's thrusts follow the frame (hover at the start)
    #: the rotor states' upper bound (thrust N, or rotor speed rad/s with ``propeller``): the
    #: bound of the freed start rotor states
    thrust_max: float = np.inf
    first_timed: int = 0  # the leg that ends at the first timed target (split times from there)
    propulsion: str = "paper"  # the frame's propulsion kind: what the rotor states are


@dataclass(frozen=True)
class CodesignNlp:
    """A built co-design NLP: solvers, bounds and where each part lies in the decision vector."""

    parts: tuple[TrackPart, ...]
    frame: SymbolicFrame
    combine: Combine
    epsilon: tuple[str, ...]  # measures constrained ≤ ε (their values are the parameter)
    cold: ca.Function
    warm: ca.Function
    lbg: np.ndarray
    ubg: np.ndarray
    offsets: tuple[int, ...]  # start of each w_k; the last entry is where s starts
    n_feas: int
    row_offsets: tuple[int, ...] = field(default=())  # start of each track's rows; then feas
    n_lift: int = 0  # accumulated-effort variables at the end of z (ε on effort; see build)
    lift: ca.Function | None = None  # z without them → their values (a warm start's)
    #: the symbolic NLP given to ``nlpsol`` ({"x", "p", "f", "g"}) and the derivative functions
    #: given with it (empty: CasADi's AD)
    problem: dict = field(default_factory=dict, compare=False, repr=False)
    derivatives: dict = field(default_factory=dict, compare=False, repr=False)
    #: with ε rows: the warm solver of one continuation step, capped at :data:`STEP_MAX_ITER`
    #: (a front's step that needs more is split, :func:`casadrone.codesign.front.continued`)
    step: ca.Function | None = field(default=None, compare=False, repr=False)
    #: :attr:`step`'s CPU budget, set per solve (:func:`casadrone.codesign.driver.solve_from`)
    budget: CpuBudget | None = field(default=None, compare=False, repr=False)

    @property
    def n_theta(self) -> int:
        return len(self.frame.keys)

    @property
    def nw(self) -> int:
        return self.offsets[-1] + self.n_theta + (self.combine == "worst") + self.n_lift

    def full(self, z: np.ndarray) -> np.ndarray:
        """``z`` with the accumulated-effort variables appended when it lacks them (a point of
        the NLP without the ε row on effort); any other z as it is."""
        z = np.asarray(z, float).ravel()
        if self.lift is None or len(z) == self.nw:
            return z
        return np.concatenate([z, np.asarray(self.lift(z), float).ravel()])

    def split(self, z: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
        """(w_k of each track, s) of a decision vector."""
        z = np.asarray(z, float).ravel()
        ws = [z[self.offsets[k]:self.offsets[k + 1]] for k in range(len(self.parts))]
        return ws, z[self.offsets[-1]:self.offsets[-1] + self.n_theta]

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Decision-vector bounds: each track's, with the start thrusts freed to [0, ∞) where they
        follow the frame (the start equality row holds them), s in [0, 1], t free."""
        lo: list[Any] = []
        hi: list[Any] = []
        for part in self.parts:
            lbx, ubx = part.lbx.copy(), part.ubx.copy()
            if part.hover_start:
                first = start_thrust_index(part.nlp)
                unit = 1.0 if part.nlp.model.scale is None else \
                    np.asarray(part.nlp.model.scale)[part.nlp.model.rotor]  # the NLP's units
                lbx[first], ubx[first] = 0.0, part.thrust_max / unit
            lo.append(lbx)
            hi.append(ubx)
        lo.append(np.zeros(self.n_theta))
        hi.append(np.ones(self.n_theta))
        if self.combine == "worst":
            lo.append([0.0])
            hi.append([np.inf])
        lo.append(np.zeros(self.n_lift))
        hi.append(np.full(self.n_lift, np.inf))
        return np.concatenate(lo), np.concatenate(hi)



def start_thrust_index(nlp: Nlp) -> np.ndarray:
    """Indices in w of the first node's rotor thrusts."""
    X = np.zeros((nlp.layout.n_intervals + 1, nlp.model.nx))
    X[0, nlp.model.rotor] = 1.0
    w = nlp.pack(np.zeros(nlp.layout.n_legs), X,
                 np.zeros((nlp.layout.n_intervals, nlp.model.nu)))
    return np.flatnonzero(w)


def build_codesign_nlp(parts: tuple[TrackPart, ...], frame: SymbolicFrame, combine: Combine,
                       epsilon: tuple[str, ...] = (), tol: float = 1e-6,
                       max_iter: int = 1000, expand: bool = False, compiled: bool = True
                       ) -> CodesignNlp:
    """The co-design NLP of ``parts`` (tracks) with the frame's θ as variables; ``epsilon``
    names the measures bounded above by the parameter (``mass_kg``, ``span_m``, ``effort``);
    ``compiled=False`` leaves the derivatives to CasADi's AD of the composed graph (the oracle of
    tests/unit/test_codesign_derivatives.py, and the co-design before the compiled blocks)."""
    s = ca.MX.sym("s", len(frame.keys))
    p, hover, feas, mass, diagonals = frame.function(s)
    ws, fs, gs, lbg, ubg, offsets, row_offsets = [], [], [], [], [], [0], [0]
    x0s, Ps = [], []
    for k, part in enumerate(parts):
        sym = part.nlp.problem
        # the objective (the leg durations' sum: linear in w) apart from the rows, so that its
        # derivatives never go through the dynamics' graph
        inner_f = ca.Function(f"limit_f_{k}", [sym["x"], sym["p"]], [sym["f"]])
        inner = ca.Function(f"limit_{k}", [sym["x"], sym["p"]], [sym["g"]])
        w = ca.MX.sym(f"w{k}", sym["x"].numel())
        x0: Any = ca.DM(part.x_start)
        if part.hover_start:
            rotor = part.nlp.model.rotor
            assert rotor is not None  # a hover start has rotor states
            x0 = ca.vertcat(x0[:rotor.start], hover, x0[rotor.stop:])
        P = ca.vertcat(p, x0, ca.DM(part.targets))
        f, g = inner_f(w, P), inner(w, P)
        x0s.append(x0)
        Ps.append(P)
        ws.append(w)
        fs.append(part.weight * f)
        gs.append(g)
        lbg.append(part.lbg)
        ubg.append(part.ubg)
        offsets.append(offsets[-1] + w.numel())
        row_offsets.append(row_offsets[-1] + g.numel())
    gs.append(feas)
    lbg.append(np.full(feas.numel(), FEASIBILITY_MARGIN))
    ubg.append(np.full(feas.numel(), np.inf))
    n_feas = feas.numel()
    z = ca.vertcat(*ws, s)
    if combine == "worst":
        t = ca.MX.sym("t")
        z = ca.vertcat(z, t)
        objective = t
        gs.append(ca.vertcat(*fs) - t)
        lbg.append(np.full(len(fs), -np.inf))
        ubg.append(np.zeros(len(fs)))
    else:
        objective = cast(ca.MX, sum(fs))
    eps = ca.MX.sym("eps", len(epsilon))
    measures = {"mass_kg": mass, "span_m": diagonals}
    lift_rows, lift, n_lift = None, None, 0
    if "effort" in epsilon:
        # The effort sums every interval's thrusts and duration: as one row it is a dense row
        # of the constraint Jacobian, which needs a forward colour per nonzero (~1000 on the
        # paper track; benchmarks/bench_codesign_profile.py). Lifted into its running sum
        # E_k = E_{k-1} + q_k (one sparse row per interval, the usual lifting of an integral
        # cost into a state), the ε row holds the last E alone.
        q = ca.vertcat(*(effort_terms(part, w, p) for part, w in zip(parts, ws, strict=True)))
        n_lift = q.numel()
        E = ca.MX.sym("E", n_lift)
        lift_rows = E - ca.vertcat(0, E[:-1]) - q
        lift = ca.Function("effort_lift", [z], [ca.cumsum(q)])
        measures["effort"] = E[-1]
        z = ca.vertcat(z, E)
    for i, name in enumerate(epsilon):
        m = measures[name]
        gs.append(m - eps[i])
        lbg.append(np.full(m.numel(), -np.inf))
        ubg.append(np.zeros(m.numel()))
    if lift_rows is not None:  # after the ε rows: the certificate reads those by position
        gs.append(lift_rows)
        lbg.append(np.zeros(n_lift))
        ubg.append(np.zeros(n_lift))
    problem = {"x": z, "p": eps, "f": objective, "g": ca.vertcat(*gs)}
    tag = f"codesign_{len(parts)}x{combine}_{'_'.join(epsilon) or 'free'}"
    # Exact derivatives from compiled blocks (casadrone.codesign.derivatives) where every track
    # is a shooting NLP with compiled blocks; otherwise (collocation, or expand: true) CasADi
    # differentiates the composed graph (MX, or SX with expand).
    extra: dict[str, Any] = {"expand": True} if expand else {}
    if not expand and compiled and uses_blocks(frame.cfg.propulsion.model, parts):
        extra = codesign_derivatives(parts, ws, s, z, eps, frame.function, x0s, Ps, objective,
                                     ca.vertcat(*gs[len(parts):]), tuple(offsets))
    kind = frame.cfg.propulsion.model  # the warm settings of the limit lap's own kind
    cold = ca.nlpsol(tag, "ipopt", problem, ipopt_options(tol, max_iter, False) | extra)
    warm = ca.nlpsol(tag + "_warm", "ipopt", problem,
                     ipopt_options(tol, max_iter, True, propulsion=kind) | extra)
    step = budget = None
    if epsilon:
        options = ipopt_options(tol, min(max_iter, STEP_MAX_ITER), True, propulsion=kind)
        options["ipopt"] = options["ipopt"] | {"max_cpu_time": STEP_MAX_CPU_S}
        budget = CpuBudget(tag + "_budget", z.numel(), problem["g"].numel(), eps.numel())
        step = ca.nlpsol(tag + "_step", "ipopt", problem,
                         options | extra | {"iteration_callback": budget})
    return CodesignNlp(parts, frame, combine, tuple(epsilon), cold, warm, np.concatenate(lbg),
                       np.concatenate(ubg), tuple(offsets), n_feas, tuple(row_offsets), n_lift,
                       lift, problem, {k: v for k, v in extra.items() if k != "expand"}, step,
                       budget)
