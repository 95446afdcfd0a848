"""Random frames inside paper Table 1 for the limit-lap benchmarks, and which is nearest which.

The benchmarks draw frames with :func:`casadrone.airframe.random_thetas` and warm-start each from
its nearest other frame, by distance in Table 1's ranges scaled to the unit cube (every key
counts alike, whatever its unit).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from casadrone.airframe import TABLE1_BOUNDS, build_airframe, with_theta


def unit_positions(thetas: list[dict[str, float]]) -> np.ndarray:
    """Each θ (a row) in Table 1's ranges scaled to [0, 1] per key (the keys of ``thetas[0]``)."""
    keys = list(thetas[0])
    lo = np.array([TABLE1_BOUNDS[k][0] for k in keys])
    hi = np.array([TABLE1_BOUNDS[k][1] for k in keys])
    return (np.array([[t[k] for k in keys] for t in thetas]) - lo) / (hi - lo)


def nearest(i: int, candidates: Iterable[int], unit: np.ndarray) -> list[int]:
    """``candidates`` other than ``i``, nearest to frame ``i`` first (:func:`unit_positions`)."""
    return sorted((j for j in candidates if j != i),
                  key=lambda j: float(np.linalg.norm(unit[i] - unit[j])))


def frame_problem(template, theta: dict[str, float], name: str, track, options):
    """(frame, prepared limit-lap problem) of ``template`` at ``theta`` on ``track``, with the
    frame's own clearance (:func:`casadrone.limit.lap.frame_clearance_m`)."""
    from casadrone.limit import lap as limit
    from casadrone.limit.starts import prepare

    cfg = with_theta(template, theta, name=name)
    frame = build_airframe(cfg)
    return frame, prepare(frame, track, options,
                          limit.frame_clearance_m(frame, cfg.prop_diameter_mm / 1000))


#: Draws of a move's signs (:func:`moved_problem`) before a frame whose every move is
#: impossible is left out
MOVE_DRAWS = 20


def moved_theta(theta: dict[str, float], r: float, rng: np.random.Generator) -> dict[str, float]:
    """``theta`` with every key moved by ± r of its Table 1 range (random sign), kept inside."""
    return {k: float(np.clip(v + r * (TABLE1_BOUNDS[k][1] - TABLE1_BOUNDS[k][0])
                             * rng.choice([-1, 1]), *TABLE1_BOUNDS[k])) for k, v in theta.items()}


def moved_problem(template, theta: dict[str, float], r: float, rng: np.random.Generator,
                  name: str, track, options):
    """:func:`frame_problem` of ``theta`` moved by ``r`` (:func:`moved_theta`). A move that
    makes an impossible frame (e.g. rotors that overlap) is drawn again with other signs, up to
    :data:`MOVE_DRAWS` times; None: every draw was impossible, the frame is left out. A move
    that is possible at the first draw uses the random stream as the plain move does."""
    from casadrone.config.io import ConfigError

    for _ in range(MOVE_DRAWS):
        try:
            return frame_problem(template, moved_theta(theta, r, rng), name, track, options)
        except ConfigError:
            continue
    return None


def cold_frames(n: int, seed: int, template_name: str = "SY250") -> tuple[np.ndarray, list, list]:
    """``n`` random Table 1 frames of ``template_name`` on the paper track at the default grid:
    their unit-cube positions, prepared problems and cold IPOPT solutions from the point-mass
    start (each reported on stderr)."""
    import sys

    from casadrone.airframe import random_thetas
    from casadrone.config.airframe import load_airframe
    from casadrone.config.io import load
    from casadrone.config.track import TrackConfig
    from casadrone.evaluate import DEFAULT_TRACK
    from casadrone.limit import lap as limit
    from casadrone.limit.nlp import solve

    template = load_airframe(template_name)
    track = load(TrackConfig, DEFAULT_TRACK)
    options = limit.LimitLapOptions(intervals=limit.DEFAULT_INTERVALS["paper"])
    thetas, _ = random_thetas(template, n, seed)
    problems, cold = [], []
    for i, theta in enumerate(thetas):
        _, pb = frame_problem(template, theta, f"frame{i}", track, options)
        problems.append(pb)
        cold.append(solve(pb.full, pb.lifted, pb.P, *pb.box, lbg=pb.rows[0], ubg=pb.rows[1]))
        print(f"cold {i}: {cold[-1].return_status} {cold[-1].objective:.5f} "
              f"{cold[-1].iterations} it", file=sys.stderr, flush=True)
    return unit_positions(thetas), problems, cold
