"""LQR-I: discrete LQR with integral action on x, y, z and yaw, its stability certificate and the
robustness ensemble of paper Appendix B.

The augmented state is [δx (16), ξ (4)] with ξ[k+1] = ξ[k] + Ts·(x, y, z, ψ)[k] − references; the
control law is δ = u0 − K [δx; ξ]. The design is discrete (zero-order hold at Ts), so stability
means every closed-loop eigenvalue inside the unit circle, and the Lyapunov certificate is the
discrete counterpart of Appendix B's A_clᵀP + P A_cl = −I: A_clᵀ P A_cl − P = −I with P ≻ 0.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from casadrone.airframe import Airframe
from casadrone.config.controller import ControllerConfig
from casadrone.linearise import LinearModel, linearise
from casadrone.model import IDX, NX, STATE_NAMES, THR
from casadrone.propulsion import hover_rotors, propulsion_model
from casadrone.results import AsDict

INTEGRATED = ("x", "y", "z", "psi")
AUG_STATE_NAMES = STATE_NAMES + tuple(f"int_{n}" for n in INTEGRATED)


@dataclass(frozen=True)
class HoverPoint:
    """Analytic hover equilibrium: Σ T = m g with zero net moment (allocation matrix solve)."""

    x0: np.ndarray
    u0: np.ndarray


def hover_point(airframe: Airframe) -> HoverPoint:
    """Hover trim from the allocation matrix (exact for rotors in the CoM plane)."""
    rotors, u0 = hover_rotors(airframe, airframe.hover_thrusts())
    x0 = np.zeros(NX)
    x0[12:16] = rotors
    return HoverPoint(x0=x0, u0=np.asarray(u0))


def discretise(A: np.ndarray, B: np.ndarray, Ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Zero-order-hold discretisation at period Ts (s)."""
    n, m = B.shape
    M = np.zeros((n + m, n + m))
    M[:n, :n], M[:n, n:] = A, B
    Md = sla.expm(M * Ts)
    return Md[:n, :n], Md[:n, n:]


def augment(Ad: np.ndarray, Bd: np.ndarray, Ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Append the four integrators of (x, y, z, ψ) to a discrete plant."""
    n, m = Bd.shape
    k = len(INTEGRATED)
    Aa, Ba = np.zeros((n + k, n + k)), np.zeros((n + k, m))
    Aa[:n, :n], Ba[:n] = Ad, Bd
    Aa[n + np.arange(k), [IDX[name] for name in INTEGRATED]] = Ts
    Aa[n:, n:] = np.eye(k)
    return Aa, Ba


def weights(ctrl: ControllerConfig) -> tuple[np.ndarray, np.ndarray]:
    """Diagonal Q (20×20) and R (4×4) from the controller config."""
    q = ctrl.q
    diag = [*q.position, *q.velocity, *q.rates, *q.attitude, *q.thrust, *ctrl.q_integral]
    return np.diag(diag), np.diag(ctrl.r)


def solve_dare(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray,
               rtol: float = 1e-14, max_iter: int = 64) -> np.ndarray:
    """Stabilising solution S of the discrete algebraic Riccati equation
    S = AᵀSA − AᵀSB (R + BᵀSB)⁻¹ BᵀSA + Q, by the structure-preserving doubling algorithm
    (Chu, Fan, Lin & Wang 2004: A₀ = A, G₀ = BR⁻¹Bᵀ, H₀ = Q; W = I + GH,
    A⁺ = A W⁻¹A, G⁺ = G + A W⁻¹G Aᵀ, H⁺ = H + Aᵀ H W⁻¹A; H → S quadratically).

    About 15 doublings for the LQR-I plants here, each a 20 × 20 solve and a few products: half
    the time of scipy's QZ-based ``solve_discrete_are``, whose solution it matches to ~1e-12
    (tested against it). Stops when H changes by less than ``rtol`` × max|H|; if it has not
    converged after ``max_iter`` doublings it returns scipy's solution instead.
    """
    n = A.shape[0]
    G = B @ np.linalg.solve(R, B.T)
    H, Ak, eye = np.array(Q, float), np.array(A, float), np.eye(n)
    for _ in range(max_iter):
        V = np.linalg.solve(eye + G @ H, np.hstack([Ak, G]))
        H_next = H + Ak.T @ H @ V[:, :n]
        G = G + Ak @ V[:, n:] @ Ak.T
        Ak = Ak @ V[:, :n]
        if not np.all(np.isfinite(H_next)):
            break
        converged = np.max(np.abs(H_next - H)) <= rtol * np.max(np.abs(H_next))
        H = H_next
        if converged:
            return 0.5 * (H + H.T)
    return sla.solve_discrete_are(A, B, Q, R)


@dataclass(frozen=True)
class LQRIDesign(AsDict):
    """A discrete LQR-I gain and its certificate.

    Attributes:
        K: 4×20 gain on [δx; ξ].
        Ad, Bd: augmented discrete plant (20×20, 20×4) the gain was designed on.
        closed_loop_eigenvalues: eigenvalues of Ad − Bd K (complex, 20).
        stable: all eigenvalues strictly inside the unit circle.
        lyapunov_min_eig: smallest eigenvalue of P solving A_clᵀ P A_cl − P = −I (> 0 ⇒ stable).
        riccati: the DARE solution S (:func:`solve_dare`).
    """

    K: np.ndarray
    Ad: np.ndarray
    Bd: np.ndarray
    sample_time_s: float
    x0: np.ndarray
    u0: np.ndarray
    closed_loop_eigenvalues: np.ndarray
    stable: bool
    lyapunov_min_eig: float
    riccati: np.ndarray
    state_names: tuple[str, ...] = AUG_STATE_NAMES

    _omit = ("Ad", "Bd", "x0", "u0", "riccati")  # the design's inputs and internals
    _properties = ("spectral_radius",)

    @property
    def spectral_radius(self) -> float:
        """Largest |eigenvalue| of the closed loop (< 1: stable)."""
        return float(np.max(np.abs(self.closed_loop_eigenvalues)))


def certify(Acl: np.ndarray, lyapunov: bool = True) -> tuple[np.ndarray, bool, float]:
    """Eigenvalues, stability and (if ``lyapunov``) the Lyapunov certificate of a discrete closed
    loop; without it the certificate is NaN (the optimiser needs only the eigenvalues)."""
    eig = np.linalg.eigvals(Acl)
    stable = bool(np.max(np.abs(eig)) < 1.0)
    if not stable or not lyapunov:
        return eig, stable, float("nan")
    P = sla.solve_discrete_lyapunov(Acl.T, np.eye(Acl.shape[0]))
    return eig, stable, float(np.min(np.linalg.eigvalsh(0.5 * (P + P.T))))


def design_lqri(linear_model: LinearModel, ctrl: ControllerConfig,
                certificate: bool = True) -> LQRIDesign:
    """Discrete LQR-I gain at period ``ctrl.sample_time_s`` for a linear model (``certificate``:
    also solve the Lyapunov equation)."""
    Ts = ctrl.sample_time_s
    Aa, Ba = augment(*discretise(linear_model.A, linear_model.B, Ts), Ts)
    Q, R = weights(ctrl)
    S = solve_dare(Aa, Ba, Q, R)
    K = np.linalg.solve(R + Ba.T @ S @ Ba, Ba.T @ S @ Aa)
    eig, stable, lmin = certify(Aa - Ba @ K, certificate)
    return LQRIDesign(K=K, Ad=Aa, Bd=Ba, sample_time_s=Ts, x0=linear_model.x0,
                      u0=linear_model.u0, closed_loop_eigenvalues=eig, stable=stable,
                      lyapunov_min_eig=lmin, riccati=S,
                      state_names=tuple(linear_model.state_names)
                      + AUG_STATE_NAMES[len(STATE_NAMES):])


def design_for(
    airframe: Airframe,
    ctrl: ControllerConfig,
    reference: Airframe | None = None,
    operating_point=None,
    certificate: bool = True,
) -> LQRIDesign:
    """The gain an airframe flies with under the controller's gain policy.

    ``operating_point`` (anything with ``x0``, ``u0``: a hover TrimPoint) defaults to the analytic
    :func:`hover_point`. ``redesign``: the gain comes from the airframe's own linearisation.
    ``frozen-command``: ``reference``'s gain (the controller's ``reference_airframe``), shared by
    every candidate as is. ``frozen-wrench``: the reference's gain mapped through the candidate's
    own allocation (:func:`frozen_wrench_gain`). In both frozen policies the operating point
    (x0, u0) stays the candidate's own and the closed loop is certified on its own plant.
    """
    op = operating_point if operating_point is not None else hover_point(airframe)
    if ctrl.frozen_gain:
        if reference is None:
            raise ValueError(f"gain_policy '{ctrl.gain_policy}' needs the reference airframe")
        ref = _frozen_gain(reference, ctrl)
        K = ref.K
        if ctrl.gain_policy == "frozen-wrench":
            K = frozen_wrench_gain(ref.K, reference, airframe)
        Aa, Ba = plant(airframe, ctrl.sample_time_s, op)
        eig, stable, lmin = certify(Aa - Ba @ K, certificate)
        return dataclasses.replace(ref, K=K, Ad=Aa, Bd=Ba, x0=np.asarray(op.x0),
                                   u0=np.asarray(op.u0), closed_loop_eigenvalues=eig,
                                   stable=stable, lyapunov_min_eig=lmin)
    return design_lqri(linearise(airframe, op), ctrl, certificate)


_FROZEN: dict[tuple, LQRIDesign] = {}
_FROZEN_BY_ID: dict[tuple[int, int], tuple[Airframe, ControllerConfig, LQRIDesign]] = {}


def _frozen_gain(reference: Airframe, ctrl: ControllerConfig) -> LQRIDesign:
    """The reference airframe's design, computed once per process for a (reference, weights);
    the same two objects (one study's) find it again without rebuilding the key."""
    hit = _FROZEN_BY_ID.get((id(reference), id(ctrl)))
    if hit is not None and hit[0] is reference and hit[1] is ctrl:
        return hit[2]
    key = (reference.name, tuple(reference.p), ctrl.model_copy(update={"gain_policy": "redesign"}))
    if key not in _FROZEN:
        _FROZEN[key] = design_lqri(linearise(reference, hover_point(reference)), ctrl)
    if len(_FROZEN_BY_ID) > 64:
        _FROZEN_BY_ID.clear()
    _FROZEN_BY_ID[(id(reference), id(ctrl))] = (reference, ctrl, _FROZEN[key])  # holds both
    return _FROZEN[key]


def frozen_wrench_gain(K_ref: np.ndarray, reference: Airframe, airframe: Airframe) -> np.ndarray:
    """The reference's gain ``K_ref`` (4×20, commands from [δx; ξ]) frozen in wrench space and
    mixed for ``airframe`` by its own allocation inverse: what a flight controller does when it
    keeps its attitude and position gains and gets a per-frame mixer.

    Derivation. A frame's allocation A (4×4, :attr:`Airframe.allocation_matrix`) maps rotor
    thrusts T to the wrench W = A T = [collective thrust, roll, pitch, yaw torque]. With the thrust
    lag τ Ṫ = K_g δ − T, the wrench obeys τ Ẇ = w_c − W with the commanded wrench w_c = K_g A δ:
    in wrench coordinates every frame has the same actuator (a first-order lag from w_c to W) and
    the same rigid-body input (W), and the allocation has disappeared. The reference law
    δ = u0 − K_ref [δx_s; δT; ξ] (δx_s the 12 rigid-body errors, δT = T − T0 the thrust errors,
    ξ the integrators) is therefore, in wrench space,

        w_c − w_c0 = −K_g,ref A_ref [K_s δx_s + K_T A_ref⁻¹ δW + K_ξ ξ] = −K_w [δx_s; δW; ξ],

    with δW = A_ref δT, K_ref = [K_s | K_T | K_ξ]. That K_w is the frozen gain: from state error
    (the thrust states read as the wrench they produce) to the commanded wrench. A candidate
    measures its own wrench error δW = A δT and turns the commanded wrench into its commands by
    its own inverse, δ − u0 = A⁻¹ (w_c − w_c0) / K_g:

        K = (K_g,ref / K_g) A⁻¹ A_ref [K_s | K_T A_ref⁻¹ A | K_ξ].

    The mapping is exact (no linearisation), so the commanded wrench K_g A (δ − u0) equals the
    reference controller's for the same rigid-body and wrench errors whatever the frame, and on
    the reference itself K = K_ref. Frames with equal mass, inertia, drag and thrust lag thus fly
    the same rigid-body trajectory until a command is clipped to [0, 1] (clipping acts per motor,
    after the mixer, so there the arms matter). Cost per candidate: two 4×4 solves and a 4×20
    product.
    """
    other = [k for k in (airframe.propulsion, reference.propulsion)
             if not propulsion_model(k).command_linear]
    if other:
        raise ValueError("frozen-wrench gain policy: defined for the paper propulsion model only "
                         "(its rotor states are thrusts, K maps command to thrust); use "
                         f"gain_policy redesign with propulsion model {other[0]}")
    A_ref, A = reference.allocation_matrix, airframe.allocation_matrix
    K = np.array(K_ref, float)
    K[:, THR] = K[:, THR] @ np.linalg.solve(A_ref, A)
    return (reference.thrust_gain / airframe.thrust_gain) * np.linalg.solve(A, A_ref @ K)


def plant(airframe: Airframe, Ts: float, operating_point=None) -> tuple[np.ndarray, np.ndarray]:
    """Augmented discrete plant of an airframe about an operating point (default: hover)."""
    lin = linearise(airframe, operating_point or hover_point(airframe))
    return augment(*discretise(lin.A, lin.B, Ts), Ts)


# --------------------------------------------------------------------------------------------
# Robustness ensemble (paper Appendix B)
# --------------------------------------------------------------------------------------------


def perturb(airframe: Airframe, rng: np.random.Generator, dynamics: float, coupling: float):
    """A perturbed airframe: mass, inertia and drag scaled by U(1 ± dynamics) (the inertia by
    :func:`perturb_inertia`, so it stays a possible body); thrust gain, time constant, κ and each
    rotor's arm length by U(1 ± coupling)."""

    def s(spread, size=None):
        return rng.uniform(1 - spread, 1 + spread, size)

    J = perturb_inertia(airframe.inertia, s(dynamics, 3))
    return dataclasses.replace(
        airframe,
        name=f"{airframe.name}-perturbed",
        mass=airframe.mass * s(dynamics),
        inertia=J,
        drag_area=airframe.drag_area * s(dynamics, 3),
        thrust_gain=airframe.thrust_gain * s(coupling),
        thrust_time_constant=airframe.thrust_time_constant * s(coupling),
        kappa=airframe.kappa * s(coupling),
        rotor_positions=airframe.rotor_positions * s(coupling, (4, 1)),
    )


def perturb_inertia(J: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The inertia (kg·m²) of the body ``J`` with its second moments along body axes i, j scaled
    by √(d_i d_j): S = Σ m r rᵀ = ½ tr(J) I − J, S' = S ∘ √(d dᵀ), J' = tr(S') I − S'.

    S' is a congruence of S, so it stays positive semi-definite: J' is again a possible body (its
    principal moments keep the triangle inequalities), which scaling J itself does not ensure.
    Each diagonal moment moves by a factor inside [min d, max d].
    """
    S = 0.5 * np.trace(J) * np.eye(3) - J
    S = S * np.sqrt(np.outer(d, d))
    return np.trace(S) * np.eye(3) - S


@dataclass(frozen=True)
class Ensemble(AsDict):
    """Closed loops of N perturbed plants under one gain."""

    n: int
    eigenvalues: np.ndarray  # n × 20 complex
    stable_each: np.ndarray  # n bool
    plants: tuple[tuple[np.ndarray, np.ndarray], ...]  # (Aa, Ba) per plant

    _omit = ("eigenvalues", "stable_each", "plants")
    _properties = ("stable", "n_stable", "max_spectral_radius")

    @property
    def n_stable(self) -> int:
        """Plants of the ensemble stable under the shared gain."""
        return int(np.sum(self.stable_each))

    @property
    def stable(self) -> bool:
        """Every plant of the ensemble is stable under the shared gain."""
        return bool(np.all(self.stable_each))

    @property
    def max_spectral_radius(self) -> float:
        """Largest |eigenvalue| over the ensemble."""
        return float(np.max(np.abs(self.eigenvalues)))


def robustness_ensemble(
    airframe: Airframe, design: LQRIDesign, ctrl: ControllerConfig, n: int | None = None
) -> Ensemble:
    """Apply ``design.K`` to ``n`` perturbed plants (default from the controller config)."""
    rob = ctrl.robustness
    n = rob.n_plants if n is None else n
    rng = np.random.default_rng(rob.seed)
    eigs, ok, plants = [], [], []
    for _ in range(n):
        pert = perturb(airframe, rng, rob.dynamics_pct / 100, rob.coupling_pct / 100)
        Aa, Ba = plant(pert, design.sample_time_s)
        e = np.linalg.eigvals(Aa - Ba @ design.K)
        eigs.append(e)
        ok.append(np.max(np.abs(e)) < 1.0)
        plants.append((Aa, Ba))
    return Ensemble(n=n, eigenvalues=np.array(eigs), stable_each=np.array(ok), plants=tuple(plants))


def disturbance_response(Aa: np.ndarray, Ba: np.ndarray, K: np.ndarray, dx0: np.ndarray,
                         steps: int) -> np.ndarray:
    """Linear closed-loop response δx[k] (steps × 20) from a deviation ``dx0`` (Fig. B1)."""
    Acl = Aa - Ba @ K
    out = np.empty((steps, Aa.shape[0]))
    x = np.asarray(dx0, float)
    for k in range(steps):
        out[k] = x
        x = Acl @ x
    return out
