"""Certificates of a co-design point: why this frame, and proof that the lap is the frame's own.

At a returned point (θ*, laps):

1. **Lap**: each track's limit lap re-solved with θ fixed at θ*, twice: from the co-design point
   (primal-dual warm start: the co-design optimum must be an optimum of the fixed-frame problem)
   and by :func:`casadrone.limit.lap.design_limit_lap`'s own cold starts (a faster local optimum
   of the fixed frame would show the co-design point is not the frame's best lap). The
   fixed-frame lap, the better of both, must equal the co-design lap within :data:`LAP_RTOL`.
2. **Reduced gradient**: dT/dθ of the fixed-frame optimum by the envelope theorem (its
   multipliers of p and x_start, chained through :mod:`casadrone.massprops`' numbers by
   :func:`casadrone.limit.check.theta_sensitivities`: a path independent of the symbolic frame),
   plus the active feasibility and ε rows times their multipliers. Zero for a variable inside its
   box, the sign of the bound at a bound (≥ 0 at the lower bound: moving in would slow the lap);
   IPOPT's bound multiplier is its negative. These numbers are the "why" of the frame.
3. **Re-simulation**: the fixed-frame lap's commands flown by CVODES pass every target within
   the limit lap's ``max_miss_m``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

import casadi as ca
import numpy as np

from casadrone.airframe import build_airframe
from casadrone.codesign.frame import ROTOR_KEYS
from casadrone.codesign.nlp import epsilon_rows
from casadrone.config.io import ConfigError
from casadrone.limit.check import resimulation_miss, theta_sensitivities
from casadrone.limit.lap import LapSeeds, design_limit_lap, model_states, start_state
from casadrone.limit.nlp import NlpPoint
from casadrone.limit.starts import prepare, trajectory
from casadrone.model import n_params
from casadrone.numtext import fixed

#: Largest relative gap between the co-design lap and the fixed-frame lap (issue: 0.05 %).
LAP_RTOL = 5e-4
#: A reduced-gradient entry counts as zero below this fraction of the largest |dT/ds| over the
#: variables (s per box width), or below GRAD_ATOL; both chosen from the agreement observed
#: between the envelope-theorem gradient and IPOPT's multipliers (see the tests).
GRAD_RTOL = 2e-2
GRAD_ATOL = 1e-4
#: A variable within this fraction of its box from a bound is at that bound (IPOPT's interior
#: point stops ~1e-6 of the box inside a bound: observed 2e-6 on the short test track).
AT_BOUND = 1e-4
#: A row counts as active when its multiplier exceeds this (s per unit of the row); IPOPT leaves
#: ~3e-8 on inactive rows at tol 1e-6 (observed).
ACTIVE = 1e-5


@dataclass(frozen=True)
class TrackCheck:
    label: str
    codesign_lap_s: float
    fixed_warm_lap_s: float
    fixed_cold_lap_s: float
    fixed_lap_s: float
    gap_pct: float
    resimulation_miss_m: float
    passed: bool
    #: the cold fixed-frame solve's decision vector (a restart of the co-design from it)
    cold_w: np.ndarray | None = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class VariableCheck:
    key: str
    value: float
    state: str  # interior | lower | upper
    dT_dtheta: float  # s per unit of the key (combined objective)
    reduced_gradient: float  # s per box width, constraint terms included
    bound_multiplier: float  # IPOPT's, per box width
    passed: bool


@dataclass(frozen=True)
class Certificate:
    tracks: tuple[TrackCheck, ...]
    variables: tuple[VariableCheck, ...]
    active: dict[str, float]  # active feasibility / ε rows and their multipliers
    passed: bool
    reason: str

    def as_dict(self) -> dict[str, Any]:
        def track(t: TrackCheck) -> dict[str, Any]:
            d = {k: v for k, v in asdict(t).items() if k != "cold_w"}
            if math.isnan(t.fixed_cold_lap_s):  # not run (an ε-point's certificate)
                d["fixed_cold_lap_s"] = None
            return d

        return {"tracks": [track(t) for t in self.tracks],
                "variables": [asdict(v) for v in self.variables],
                "active_constraints": dict(self.active), "why": self.why,
                "passed": self.passed, "reason": self.reason}

    @property
    def why(self) -> str:
        """What holds the frame, in one sentence (:func:`why_sentence`)."""
        return why_sentence(self.variables, self.active)

    def summary(self) -> str:
        """The certificate in one line (:func:`summary_of`)."""
        return summary_of(self.as_dict())

    def text(self) -> str:
        """The certificate as lines for the terminal."""
        lines = [f"certificate: {'PASSED' if self.passed else 'FAILED'}"
                 + (f" ({self.reason})" if self.reason else "")]
        for t in self.tracks:
            cold = ("not run" if math.isnan(t.fixed_cold_lap_s)
                    else f"{t.fixed_cold_lap_s:.4f}")
            lines.append(f"  {t.label}: co-design lap {t.codesign_lap_s:.4f} s, θ fixed "
                         f"{t.fixed_lap_s:.4f} s (warm {t.fixed_warm_lap_s:.4f}, cold "
                         f"{cold}), gap {fixed(t.gap_pct, '+.4f')} %, re-simulation "
                         f"miss {t.resimulation_miss_m:.4f} m")
        lines.append(f"  why: {self.why}")
        lines.append("  in numbers (reduced gradient: s per box width; bound multiplier from "
                     "IPOPT):")
        for v in self.variables:
            lines.append(f"    {v.key:<13} {fixed(v.value, '>10.4f')} {v.state:<8} dT/dθ "
                         f"{fixed(v.dT_dtheta, '>+11.4g')}  reduced "
                         f"{fixed(v.reduced_gradient, '>+10.3g')}  multiplier "
                         f"{fixed(v.bound_multiplier, '>+10.3g')}  {'ok' if v.passed else 'NO'}")
        for name, lam in self.active.items():
            lines.append(f"    active: {name} (multiplier {lam:+.4g})")
        return "\n".join(lines)


#: Plain words for a decision variable: (what it is, its symbol, the word for less, for more).
_PLAIN = {"lambda_a_mm": ("the front arms", "λa", "shorter", "longer"),
          "lambda_b_mm": ("the rear arms", "λb", "shorter", "longer"),
          "alpha_deg": ("the front arm angle", "α", "smaller", "larger"),
          "beta_deg": ("the rear arm angle", "β", "smaller", "larger"),
          "ixx_kgm2": ("the roll inertia", "Ixx", "smaller", "larger"),
          "iyy_kgm2": ("the pitch inertia", "Iyy", "smaller", "larger"),
          "izz_kgm2": ("the yaw inertia", "Izz", "smaller", "larger")}
#: Plain names of the propeller-gap rows (``gap A-B``, casadrone.codesign.frame).
_GAPS = {frozenset({"RL", "RR"}): "the rear props' clearance",
         frozenset({"FR", "FL"}): "the front props' clearance",
         frozenset({"FL", "RL"}): "the left props' clearance",
         frozenset({"FR", "RR"}): "the right props' clearance"}


def _value_text(key: str, value: float) -> str:
    """A θ value with its unit: ``100 mm``, ``78.84°``, ``0.00123 kg·m²``."""
    if key.endswith("_mm"):
        return f"{value:.4g} mm"
    if key.endswith("_deg"):
        return f"{value:.2f}°"
    return f"{value:.3g} kg·m²"


def _bound_clauses(variables) -> list[str]:
    """One clause per side and bound value: ``both arms want to be shorter than the 100 mm
    bound`` (a bound whose multiplier is below :data:`ACTIVE` holds nothing: ``rests at``)."""
    groups: dict[tuple[str, bool, str], list[str]] = {}
    for v in variables:
        if v.state == "interior":
            continue
        pushing = abs(v.bound_multiplier) > ACTIVE
        groups.setdefault((v.state, pushing, _value_text(v.key, v.value)), []).append(v.key)
    clauses = []
    for (side, pushing, value), keys in groups.items():
        names = [_PLAIN.get(k, (k, k, "less", "more")) for k in keys]
        arms = {"lambda_a_mm", "lambda_b_mm"} == set(keys)
        subject = "both arms" if arms else " and ".join(n[0] for n in names)
        plural = arms or len(keys) > 1 or subject.endswith("arms")
        if not pushing:
            clauses.append(f"{subject} {'rest' if plural else 'rests'} at the {value} bound")
            continue
        word = names[0][2] if side == "lower" else names[0][3]
        clauses.append(f"{subject} {'want' if plural else 'wants'} to be {word} than the "
                       f"{value} bound")
    return clauses


def _row_clause(name: str, interior: dict[str, float], set_keys: set[str]) -> str:
    """A clause for one active row: what it is and which free variables it sets."""
    if name.startswith("gap "):
        pair = name[4:].split("-")
        what = _GAPS.get(frozenset(pair), f"the {pair[0]}-{pair[1]} props' clearance")
        keys = [k for k in dict.fromkeys(k for r in pair for k in ROTOR_KEYS.get(r, ()))
                if k in interior]
    elif name == "hover":
        what, keys = "the hover limit (the weight four rotors can lift)", []
    elif name.startswith("rigid body "):
        what, keys = f"the possible-body rule {name[11:]}", []
    elif name.startswith("ε "):
        what, keys = f"this front point's limit on {name[2:]}", []
    else:
        what, keys = name, []
    set_keys.update(keys)
    if not keys:
        return f"{what} is active"
    held = " and ".join(f"{_PLAIN.get(k, (k, k))[1]} = {_value_text(k, interior[k])}"
                        for k in keys)
    return f"{what} sets {held}"


def why_sentence(variables, active: dict[str, float]) -> str:
    """What holds a co-design optimum, in one plain sentence, from its active set: the variables
    at a bound (``both arms want to be shorter than the 100 mm bound``: the lap would be faster
    beyond it), each active row and the free variables it sets (a propeller gap depends on the
    keys of its two rotors, :data:`casadrone.codesign.frame.ROTOR_KEYS`: ``the rear props'
    clearance sets β = 78.84°``), and the free variables that no row holds, set by the lap alone
    (``the lap itself sets α = 78.95°``). ``variables``: :class:`VariableCheck` s; ``active``:
    row name → multiplier (:func:`active_constraints`, bounds left out)."""
    interior = {v.key: v.value for v in variables if v.state == "interior"}
    set_keys: set[str] = set()
    clauses = _bound_clauses(variables)
    clauses += [_row_clause(name, interior, set_keys) for name in active
                if not name.endswith(" bound")]
    free = [k for k in interior if k not in set_keys]
    if free:
        clauses.append("the lap itself sets " + " and ".join(
            f"{_PLAIN.get(k, (k, k))[1]} = {_value_text(k, interior[k])}" for k in free))
    return "; ".join(clauses) + "." if clauses else "nothing holds the frame."


def _fixed_warm(prep, point, k: int, cfg):
    """(NlpSolution of track k's limit lap with θ fixed, primal-dual warm-started from the
    co-design point; the prepared fixed-frame problem)."""
    cd = prep.nlp
    frame = build_airframe(cfg)
    pb = prepare(frame, prep.tracks[k], prep.options, prep.options.gate_clearance_m or 0.0)
    w = point.z[cd.offsets[k]:cd.offsets[k + 1]]
    lam_x = point.lam_x[cd.offsets[k]:cd.offsets[k + 1]]
    lam_g = point.lam_g[cd.row_offsets[k]:cd.row_offsets[k + 1]]
    return pb.solve(w, warm=NlpPoint(w, lam_x, lam_g, np.zeros(len(pb.P)))), pb


def _miss(pb, warm) -> float:
    """The CVODES re-simulation miss (m) of a fixed-frame solution (inf when it failed)."""
    if not warm.success:
        return math.inf
    return resimulation_miss(pb.frame, trajectory(pb.full, warm.point.w, pb.layout),
                             pb.targets.vector, pb.targets.kinds,
                             legs=pb.options.resimulation == "legs")


@dataclass(frozen=True)
class LapCheck:
    """The lap part of the certificate alone (every track): the fixed-frame laps from the
    co-design point, their largest gap (%) and re-simulation miss (m)."""

    fixed_lap_s: float  # the combined objective of the fixed-frame laps
    gap_pct: float
    miss_m: float
    passed: bool


def fixed_lap_check(prep, point) -> LapCheck:
    """Each track's limit lap re-solved with θ fixed from ``point`` (warm start only): equal to
    the co-design lap within :data:`LAP_RTOL` and flown by CVODES within ``max_miss_m``."""
    try:
        cfg = prep.config(point.theta)
    except ConfigError:
        return LapCheck(math.nan, math.nan, math.inf, False)
    laps, gaps, misses = [], [], []
    for k, label in enumerate(prep.labels):
        warm, pb = _fixed_warm(prep, point, k, cfg)
        lap = warm.objective if warm.success else math.inf
        laps.append(lap)
        gaps.append(100 * (lap - point.laps_s[label]) / point.laps_s[label])
        misses.append(_miss(pb, warm))
    combined = (sum(w * t for w, t in zip(prep.weights, laps, strict=True))
                if prep.nlp.combine == "sum" else
                max(w * t for w, t in zip(prep.weights, laps, strict=True)))
    gap, miss = max(gaps, key=abs), max(misses)
    return LapCheck(float(combined), float(gap), float(miss),
                    bool(abs(gap) <= 100 * LAP_RTOL and miss <= prep.options.max_miss_m))


def _fixed_laps(prep, point, k: int, cfg):
    """(warm NlpSolution from the co-design point, limit_lap with its own cold starts, the
    prepared fixed-frame problem) for track k with θ fixed."""
    track = prep.tracks[k]
    warm, pb = _fixed_warm(prep, point, k, cfg)
    ref = prep.template_laps[k]
    cold = design_limit_lap(cfg, track, prep.options, LapSeeds(
        warm_starts=(ref,) if ref.solution is not None else ()))
    return warm, cold, pb


def summary_of(c: dict[str, Any], active: bool = True) -> str:
    """A certificate (:meth:`Certificate.as_dict`, as stored beside a front) in one line:
    verdict, the worst track's lap gap and CVODES miss, and the why (each variable's state and
    reduced gradient, s per box width; with ``active``, the active rows' multipliers)."""
    head = "PASSED" if c["passed"] else f"FAILED ({c['reason']})"
    if not c["tracks"]:
        return head
    gap = max((t["gap_pct"] for t in c["tracks"]), key=abs)
    miss = max(t["resimulation_miss_m"] for t in c["tracks"])
    why = ", ".join(f"{v['key']} {v['state']} {v['reduced_gradient']:+.3g}"
                    for v in c["variables"])
    rows = ", ".join(f"{k} {v:+.3g}" for k, v in c["active_constraints"].items()) if active \
        else ""
    return (f"{head}: lap gap {fixed(gap, '+.4f')} %, CVODES miss {miss:.3g} m; why: {why}"
            + (f"; active: {rows}" if rows else ""))


def theta_gradient(prep, cfg, track, dT_dP: np.ndarray) -> np.ndarray:
    """dT/dθ (s per unit of each key) from dT/dP of one track's fixed-frame optimum (P = [p,
    x_start, targets] in the frame's propulsion layout), chained through the numeric airframe
    build by :func:`casadrone.limit.check.theta_sensitivities` (envelope theorem)."""
    nx = prep.nlp.parts[0].nlp.model.nx
    attitude = prep.options.attitude
    n_p = n_params(cfg.propulsion.model)
    sens = theta_sensitivities(cfg, dT_dP[:n_p], dT_dP[n_p:n_p + nx],
                               lambda f: model_states(attitude, start_state(
                                   f, track, prep.options))[0], keys=prep.keys)
    return np.array([sens[k] for k in prep.keys])


def frame_terms(prep, point) -> np.ndarray:
    """The θ-only rows' part of the reduced gradient (s per box width): the feasibility rows'
    and the mass and span ε rows' Jacobians in s times their multipliers at ``point``. The
    effort row is not θ-only: it reaches θ through the lap (its multipliers are in dT/dP)."""
    cd = prep.nlp
    lam_feas, _, lam_eps = _row_multipliers(cd, point.lam_g)
    _, s = cd.split(point.z)
    rows = _frame_jacobians(cd, s)
    out = rows["feas"].T @ lam_feas
    for m, lam in lam_eps.items():
        if m in rows:
            out = out + rows[m].T @ lam
    return out


def certify(prep, point) -> Certificate:
    """The certificate of ``point`` (a :class:`casadrone.codesign.driver.CodesignPoint`)."""
    cd = prep.nlp
    try:
        cfg = prep.config(point.theta, name=f"{prep.template.name}-codesign")
    except ConfigError as exc:
        return Certificate((), (), {}, False, f"the frame is not a valid airframe: {exc}")
    checks, grads = [], []
    for k, label in enumerate(prep.labels):
        warm, cold, pb = _fixed_laps(prep, point, k, cfg)
        laps = [warm.objective if warm.success else math.inf,
                cold.lap_time_s if cold.completed else math.inf]
        fixed = min(laps)
        ref = point.laps_s[label]
        gap = 100 * (fixed - ref) / ref
        miss = _miss(pb, warm)
        ok = abs(gap) <= 100 * LAP_RTOL and miss <= prep.options.max_miss_m
        cold_w = cold.solution.w if cold.completed and cold.solution is not None else None
        checks.append(TrackCheck(label, ref, laps[0], laps[1], fixed, gap, miss, ok, cold_w))
        grads.append(theta_gradient(prep, cfg, prep.tracks[k], -warm.point.lam_p)
                     if warm.success else np.full(len(prep.keys), np.nan))
    _, mu, _ = _row_multipliers(cd, point.lam_g)
    weights = np.array(prep.weights) * mu
    g_theta = sum(w * g for w, g in zip(weights, grads, strict=True))
    # the effort row's θ-terms are not here: the certificate is issued at the unconstrained
    # point, where no ε row is posed (ε-points: casadrone.codesign.frontcert)
    reduced = g_theta * (prep.upper - prep.lower) + frame_terms(prep, point)
    return verdict(prep, point, tuple(checks), g_theta, reduced)


def verdict(prep, point, checks: tuple[TrackCheck, ...], g_theta: np.ndarray,
            reduced: np.ndarray) -> Certificate:
    """The certificate from the track checks and the reduced gradient (s per box width, the
    frame's and ε rows' terms included): each variable's state (interior, at a bound), its check
    (zero inside the box, the bound's sign at a bound), the active rows, and what failed."""
    cd = prep.nlp
    _, s = cd.split(point.z)
    active = {k: v for k, v in active_constraints(prep, point).items() if "bound" not in k}
    lam_s = point.lam_x[cd.offsets[-1]:cd.offsets[-1] + len(prep.keys)]
    width = prep.upper - prep.lower
    scale = max(float(np.max(np.abs(g_theta * width))), 1e-12)
    tol = max(GRAD_RTOL * scale, GRAD_ATOL)
    variables = []
    for i, key in enumerate(prep.keys):
        state = "lower" if s[i] <= AT_BOUND else "upper" if s[i] >= 1 - AT_BOUND else "interior"
        r = float(reduced[i])
        ok = (abs(r) <= tol if state == "interior" else r >= -tol if state == "lower"
              else r <= tol)
        variables.append(VariableCheck(key, point.theta[key], state, float(g_theta[i]), r,
                                       float(lam_s[i]), bool(ok and np.isfinite(r))))
    failed = [f"{t.label}: lap gap {t.gap_pct:+.3f} %, miss {t.resimulation_miss_m:.3g} m"
              for t in checks if not t.passed]
    failed += [f"{v.key}: reduced gradient {v.reduced_gradient:+.3g} s ({v.state})"
               for v in variables if not v.passed]
    return Certificate(checks, tuple(variables), active, not failed, "; ".join(failed))


def appended_rows(cd) -> tuple[slice, slice | None, dict[str, slice]]:
    """Where the rows appended to the tracks' own lie in g: the feasibility rows, the epigraph
    rows of ``combine: worst`` (None for ``sum``), and each ε measure's rows."""
    row = cd.row_offsets[-1]
    feas = slice(row, row + cd.n_feas)
    row += cd.n_feas
    epigraph = None
    if cd.combine == "worst":
        epigraph = slice(row, row + len(cd.parts))
        row += len(cd.parts)
    eps = {}
    for m in cd.epsilon:
        eps[m] = slice(row, row + epsilon_rows(m))
        row += epsilon_rows(m)
    return feas, epigraph, eps


def _row_multipliers(cd, lam_g: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                      dict[str, np.ndarray]]:
    """IPOPT's multipliers of the rows appended to the tracks' own: (feasibility rows, the
    epigraph rows of ``combine: worst`` (ones for ``sum``), each ε measure's rows)."""
    feas, epigraph, eps = appended_rows(cd)
    mu = lam_g[epigraph] if epigraph is not None else np.ones(len(cd.parts))
    return lam_g[feas], mu, {m: lam_g[rows] for m, rows in eps.items()}


def active_constraints(prep, point) -> dict[str, float]:
    """What holds a co-design point: the frame's feasibility rows, the ε rows and the θ bounds
    whose multiplier exceeds :data:`ACTIVE` (name → IPOPT's multiplier: s of lap per unit of the
    row, per box width for a bound; negative at a lower bound)."""
    cd = prep.nlp
    lam_feas, _, lam_eps = _row_multipliers(cd, point.lam_g)
    active = {n: float(lam) for n, lam in zip(cd.frame.row_names, lam_feas, strict=True)
              if abs(lam) > ACTIVE}
    for m, lam in lam_eps.items():
        for j, value in enumerate(lam):
            if abs(value) > ACTIVE:
                active[f"ε {m}{'' if len(lam) == 1 else f' diagonal {j + 1}'}"] = float(value)
    _, s = cd.split(point.z)
    lam_s = point.lam_x[cd.offsets[-1]:cd.offsets[-1] + len(prep.keys)]
    for key, si, lam in zip(prep.keys, s, lam_s, strict=True):
        side = "lower" if si <= AT_BOUND else "upper" if si >= 1 - AT_BOUND else ""
        if side and abs(lam) > ACTIVE:
            active[f"{key} at its {side} bound"] = float(lam)
    return active


def _frame_jacobians(cd, s: np.ndarray) -> dict[str, np.ndarray]:
    """∂(feasibility rows, mass, diagonals)/∂s of the symbolic frame at s."""
    sym = ca.MX.sym("s", len(s))
    _, _, feas, mass, diag = cd.frame.function(sym)
    J = ca.Function("frame_jac", [sym], [ca.jacobian(feas, sym), ca.jacobian(mass, sym),
                                         ca.jacobian(diag, sym)])
    f, m, d = (np.array(v, float) for v in J(s))
    return {"feas": f, "mass_kg": m, "span_m": d}
