"""Co-design's progress events (:mod:`casadrone.progress`): the template laps, each start with
its objective, iterations and CPU, the certificate, each point of a front. The limit laps solved
inside those steps run :func:`~casadrone.progress.nested`, so a listener showing depth 0 sees
co-design's own steps only."""

from __future__ import annotations

import math
from collections.abc import Sequence

from casadrone.progress import active, emit


def _theta(theta: dict[str, float]) -> str:
    return ", ".join(f"{k} {v:.2f}" for k, v in theta.items())


def preparing(name: str, tracks: int, variables: int) -> None:
    """Before the template's laps and the co-design NLP are built (a first use compiles)."""
    emit("stage", f"{name}: preparing {tracks} track(s), {variables} design variables: the "
         "template's limit lap and the co-design NLP")


def template_laps(labels: Sequence[str], laps: Sequence) -> None:
    """The template's limit lap on each track (the start of every frame's lap)."""
    for label, lap in zip(labels, laps, strict=True):
        got = f"{lap.lap_time_s:.4f} s" if lap.completed else f"failed ({lap.reason})"
        emit("stage", f"template lap on {label}: {got}", lap_s=lap.lap_time_s)


def start_begun(label: str, k: int, n: int, theta: dict[str, float]) -> None:
    """Start ``k`` of ``n`` begins: its frame's limit laps, then the co-design solve."""
    if active():
        emit("start", f"start {k}/{n} {label}: θ = ({_theta(theta)}): the frame's limit lap, "
             "then the co-design solve")


def start_done(report) -> None:
    """A start ended (a :class:`~casadrone.codesign.driver.StartReport`)."""
    got = (f"objective {report.objective:.4f} s" if report.success and
           math.isfinite(report.objective) else "no optimum")
    emit("start", f"start {report.label}: {got} ({report.status}), {report.iterations} "
         f"iterations, {report.cpu_s:.1f} s CPU", objective_s=report.objective,
         iterations=report.iterations, cpu_s=report.cpu_s)


def certifying(what: str, objective_s: float) -> None:
    """The certificate of a point begins (the fixed-frame laps, the reduced gradient)."""
    emit("stage", f"certificate of {what} ({objective_s:.4f} s): limit laps with the frame "
         "fixed, reduced gradient, re-simulation")


def certified(cert, cpu_s: float) -> None:
    """A certificate was issued (:class:`~casadrone.codesign.certificate.Certificate`)."""
    emit("stage", f"certificate: {cert.summary()} ({cpu_s:.1f} s CPU)",
         passed=float(cert.passed), cpu_s=cpu_s)


def front_point(k: int, n: int, fp, measure: str) -> None:
    """Point ``k`` of at most ``n`` of a design front converged (a FrontPoint)."""
    eps = "" if math.isinf(fp.epsilon) else f"ε = {fp.epsilon:.5g}: "
    emit("step", f"front point {k}/{n}: {eps}lap {fp.point.objective:.4f} s, {measure} "
         f"{fp.measure:.5g}, {fp.point.iterations} iterations, {fp.point.cpu_s:.1f} s CPU",
         lap_s=fp.point.objective, iterations=fp.point.iterations, cpu_s=fp.point.cpu_s)


def front_stopped(why: str) -> None:
    """The continuation stopped before its last point."""
    emit("step", f"front stopped at {why}")
