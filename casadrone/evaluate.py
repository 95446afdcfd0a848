"""θ → Evaluation: the whole chain for one candidate, with every failure captured.

airframe → hover trim → exact linearisation → LQR-I → closed-loop lap → indices. A candidate that
fails at any stage (invalid geometry, no trim, unstable design, lap not completed) comes back as a
failed :class:`Evaluation` with its stage and reason; nothing in here raises for a bad candidate.
The symbolic model, trim solvers and compiled lap are built once per process and reused.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from casadrone.airframe import Airframe, build_airframe, decision_keys, with_theta
from casadrone.config.airframe import AirframeConfig, load_airframe
from casadrone.config.controller import ControllerConfig, load_controller
from casadrone.config.io import ConfigError, load
from casadrone.config.track import DEFAULT_TRACK, TrackConfig
from casadrone.control import design_for
from casadrone.indices import compute_indices, interval_table, limit_indices
from casadrone.limit.lap import limit_lap
from casadrone.results import Record
from casadrone.simulate import SimOptions, Trajectory, simulate
from casadrone.trim import trim

if TYPE_CHECKING:
    from casadrone.limit.lap import LimitLapOptions


@dataclass(frozen=True)
class EvaluationSetup:
    """Everything shared by the candidates of one study (control invariance,
    docs/concepts/chain.md)."""

    template: AirframeConfig
    controller: ControllerConfig
    track: TrackConfig
    integrator: str = "rk4"
    trim_solver: str = "newton"
    sim_options: SimOptions = SimOptions()
    limit: LimitLapOptions | None = None  # also compute the limit lap (J3_limit)
    limit_references: tuple[dict[str, float], ...] = ()  # θ of the per-study warm starts

    @cached_property
    def reference_airframe(self) -> Airframe | None:
        """The airframe whose gain is frozen (frozen-* gain policies), else None."""
        ref = self.controller.reference_airframe
        return build_airframe(load_airframe(ref)) if ref is not None else None

    @cached_property
    def limit_warm_starts(self) -> tuple:
        """The limit laps of ``limit_references``, solved once per process: every worker holds
        the same ones (same inputs, deterministic IPOPT), so warm-starting a candidate from them
        gives the same result on every backend and in any evaluation order."""
        if self.limit is None:  # no limit lap in this study: nothing to warm-start
            return ()
        laps = []
        for theta in self.limit_references:
            try:
                cfg = with_theta(self.template, theta)
            except ConfigError:  # a reference outside the valid geometries is skipped
                continue
            laps.append(limit_lap(cfg, self.track, self.limit))
        return tuple(lap for lap in laps if lap.completed)

    @cached_property
    def template_data(self) -> dict:
        """``template.model_dump()``, once per study (each candidate overrides its θ in it)."""
        return self.template.model_dump()


def default_setup(
    airframe: str | Path = "SY250",
    controller: str | Path | None = None,
    track: str | Path | None = None,
    integrator: str = "rk4",
) -> EvaluationSetup:
    """A setup from config files: ``airframe`` (reference name or path) is the template whose
    mass, drag and propulsion every evaluated θ flies with (defaults: paper track, default
    controller)."""
    return EvaluationSetup(
        template=load_airframe(airframe),
        controller=load_controller(controller),
        track=load(TrackConfig, track or DEFAULT_TRACK),
        integrator=integrator,
    )


@dataclass(frozen=True)
class Evaluation(Record):
    """A :class:`Record` with what only this process has: the per-interval table and, on
    request, the trajectory flown."""

    _omit = ("trajectory",)

    intervals: tuple = ()
    trajectory: Trajectory | None = None

    def record(self) -> Record:
        """The record the optimiser stores (no intervals, no trajectory)."""
        return Record(**{f.name: getattr(self, f.name) for f in fields(Record)})


def _failed(theta, stage, reason, start) -> Evaluation:
    return Evaluation(theta=dict(theta), status="failed", stage=stage, reason=reason,
                      wall_time_s=time.perf_counter() - start)


class Theta(dict):
    """θ read from a named airframe config by :func:`theta_of`: a plain dict of config keys that
    remembers the airframe, so :func:`evaluate` refuses to fly it on another airframe's template
    by accident."""

    def __init__(self, values: Mapping[str, float], airframe: str):
        super().__init__(values)
        self.airframe = airframe


def evaluate(
    theta: Mapping[str, float],
    setup: EvaluationSetup,
    index_names: Sequence[str] | None = None,
    keep_trajectory: bool = False,
) -> Evaluation:
    """Evaluate one candidate ``theta`` (config keys, e.g. ``{"alpha_deg": 80, …}``).

    θ replaces only the decision variables of ``setup.template`` (λa, λb, α, β, Ixx, Iyy, Izz, or
    whichever keys it holds); everything else flown (mass, drag areas, κ, propulsion, prop size,
    rotor spins) is the template's. To fly a reference airframe, use its own setup:
    ``evaluate(theta_of(cfg), default_setup("HS210"))``.

    Raises:
        ValueError: ``theta`` came from :func:`theta_of` of an airframe other than the template
            (it would fly that airframe's geometry with the template's mass and drag); pass
            ``dict(theta)`` to mean exactly that.
    """
    source = getattr(theta, "airframe", None)
    if source is not None and source != setup.template.name:
        raise ValueError(
            f"theta_of({source}) on a setup whose template is {setup.template.name}: this would "
            f"fly {source}'s geometry with {setup.template.name}'s mass, drag and propulsion; use "
            f"default_setup({source!r}) (or replace(setup, template=...)), or pass dict(theta) "
            "to mean it")
    start = time.perf_counter()
    theta = {k: float(v) for k, v in theta.items()}
    try:
        cfg = with_theta(setup.template, theta, base=setup.template_data)
        airframe = build_airframe(cfg)
    except ConfigError as exc:
        return _failed(theta, "geometry", "; ".join(exc.lines), start)
    tp = trim(airframe, "hover", 0.0, solver=setup.trim_solver)
    if not tp.success:
        return _failed(theta, "trim", tp.message, start)
    if np.any(tp.u0 > 1.0):
        return _failed(theta, "trim", f"hover needs ESC commands above 1 ({tp.u0.max():.2f}): "
                       "too heavy for its thrust", start)
    design = design_for(airframe, setup.controller, setup.reference_airframe, tp,
                        certificate=False)
    if not design.stable:
        return _failed(theta, "control", "LQR-I closed loop unstable", start)
    traj = simulate(airframe, design, setup.track, setup.integrator, setup.sim_options)
    if not traj.completed:
        ev = _failed(theta, "lap", traj.reason, start)
        return replace(ev, trajectory=traj) if keep_trajectory else ev
    indices = compute_indices(traj, index_names)
    if setup.limit is not None:
        lap = evaluate_limit(cfg, setup, traj)  # the candidate's config, validated once
        if not lap.completed:
            return _failed(theta, "limit", lap.reason, start)
        indices.update(limit_indices(lap, index_names))
    return Evaluation(
        theta=theta, status="completed", stage="", reason="",
        indices=indices, intervals=tuple(interval_table(traj)),
        wall_time_s=time.perf_counter() - start, trajectory=traj if keep_trajectory else None,
    )


def evaluate_limit(cfg: AirframeConfig, setup: EvaluationSetup, traj: Trajectory | None = None):
    """The limit lap of a candidate under ``setup.limit``: the best of the primal-dual warm
    starts from the per-study references (:attr:`EvaluationSetup.limit_warm_starts`, the same in
    every worker, so the result does not depend on the backend or the evaluation order); from
    its closed-loop lap when no reference solved or every warm start failed, then from
    ``fallback_reference`` (only in that cold call: the references were tried already)."""
    assert setup.limit is not None
    cold = replace(setup.limit, guess_trajectory=traj, starts=("closed-loop", "point-mass"),
                   warm_starts=(), sensitivities=False)
    warm = setup.limit_warm_starts
    if not warm:
        return limit_lap(cfg, setup.track, cold)
    first = limit_lap(cfg, setup.track, replace(cold, starts=(), warm_starts=warm,
                                                fallback_reference=None, refinements=0))
    if first.completed:
        return first
    lap = limit_lap(cfg, setup.track, cold)  # every warm start failed: the cold starts decide
    if not lap.completed:
        lap = replace(lap, reason=f"warm starts: {first.reason}; cold starts: {lap.reason}")
    return lap


def theta_of(cfg: AirframeConfig) -> Theta:
    """The decision variables of an airframe config (Table 1 keys; the four geometry keys with
    ``mass_model: components``), tagged with its name (see :class:`Theta`)."""
    return Theta({k: float(getattr(cfg, k)) for k in decision_keys(cfg)}, cfg.name)

