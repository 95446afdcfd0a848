"""Benchmark: where a co-design point's lap drifts from CVODES (why a certificate fails on the
re-simulation).

Solves a co-design problem from the template's geometry (``codesign.starts=0``), then flies the
point's commands with CVODES (the certificate's re-simulation, :func:`casadrone.limit.check.
resimulate`) and prints, per track and leg: the leg's duration and interval length, the
position drift of the re-simulated lap from the NLP's nodes at the leg's end and the target's
miss; and the intervals whose one-interval defect is largest (CVODES from the NLP's node
against the NLP's next node, body velocity and rates), with their commands and rotor states.

Run: ``python benchmarks/bench_codesign_miss.py codesign-paper
airframe=configs/airframes/SY250-components-propeller.yaml limit_lap.intervals=80``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))


def main(argv: list[str]) -> int:
    from casadrone.airframe import build_airframe
    from casadrone.codesign.checks import load_codesign_problem
    from casadrone.codesign.driver import initial_vector, prepare, solve_from, start_points
    from casadrone.limit.check import resimulate, scaled_cvodes, target_miss
    from casadrone.limit.gates import TARGET_SIZE
    from casadrone.limit.starts import trajectory

    problem, *overrides = argv
    prep = prepare(load_codesign_problem(problem, ["codesign.starts=0", *overrides]))
    (_, theta), = start_points(prep)
    z0 = initial_vector(prep, theta)
    assert z0 is not None, "the template has no limit lap"
    ok, status, pt = solve_from(prep, z0)
    print(f"{status}: objective {pt.objective:.5f} s, θ = {pt.theta}")
    frame = build_airframe(prep.config(pt.theta))
    ws, _ = prep.nlp.split(pt.z)
    for label, part, w in zip(prep.labels, prep.nlp.parts, ws, strict=True):
        lap = trajectory(part.nlp, w, part.nlp.layout)
        T, _, _ = part.nlp.unpack(w)
        N = part.nlp.layout.intervals
        X = resimulate(frame, lap)
        drift = np.linalg.norm(X[:, :3] - lap.x[:, :3], axis=1)
        print(f"{label}: {N} intervals per leg")
        for k, kind in enumerate(part.nlp.layout.kinds):
            i = (k + 1) * N
            miss = target_miss(X[i, :3], part.targets[TARGET_SIZE * k:TARGET_SIZE * (k + 1)],
                               kind)
            print(f"  leg {k + 1}: {T[k]:.3f} s, intervals of {1e3 * T[k] / N:.1f} ms; drift at "
                  f"its end {drift[i]:.4f} m, target miss {miss:.4f} m")
        step = scaled_cvodes(attitude=lap.attitude, propulsion=frame.propulsion,
                             lagless=False)
        h = np.diff(lap.t)
        defect = np.array([np.linalg.norm(np.array(step(x0=lap.x[i], p=np.concatenate(
            [lap.u[i], frame.p, [h[i]]]))["xf"]).ravel()[3:9] - lap.x[i + 1, 3:9])
            for i in range(len(h))])
        print(f"  one-interval defects (velocity and rates): median {np.median(defect):.2e}, "
              f"sum {defect.sum():.4f}; the largest:")
        for i in np.argsort(defect)[::-1][:5]:
            print(f"    interval {i} (leg {i // N + 1}, t = {lap.t[i]:.3f} s): {defect[i]:.4f}; "
                  f"commands {np.round(lap.u[i], 3)}, rotor states {np.round(lap.x[i, 12:16], 1)}"
                  f" -> {np.round(lap.x[i + 1, 12:16], 1)}")
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
