"""The cold part of ``bench_limitlap.py``'s table rebuilt from its per-frame log lines, for a run
stopped before its end (the benchmark writes its results file only when every frame and every
warm solve is done).

Each line ``i: completed LAP s (reference REF) CPU s CPU ...`` is frame i of
``random_thetas(template, n, seed)``, the same draws as the run; the frames' features are
recomputed (``bench_limitlap.features``) and ranked against the laps (Spearman). Run:
``python benchmarks/summarise_limitlap_log.py LOG --n 12 --seed 0 --template SY250-propeller``.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.bench_limitlap import features  # noqa: E402
from casadrone.airframe import build_airframe, random_thetas, with_theta  # noqa: E402
from casadrone.config.airframe import load_airframe  # noqa: E402

LINE = re.compile(r"^(\d+): (\w+) (\S+) s \(reference (\S+)\) (\S+) s CPU")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", type=Path)
    ap.add_argument("--n", type=int, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--template", default="SY250")
    a = ap.parse_args(argv)
    template = load_airframe(a.template)
    thetas, _ = random_thetas(template, a.n, a.seed)
    rows = [m.groups() for m in map(LINE.match, a.log.read_text().splitlines()) if m]
    done = [(int(i), float(lap), float(ref), float(t)) for i, st, lap, ref, t in rows
            if st == "completed"]
    print(f"| frames logged | {len(rows)} of {a.n} |\n| completed | {len(done)} |")
    if not done:
        return 0
    laps = np.array([d[1] for d in done])
    cpu = np.array([d[3] for d in done])
    print(f"| cold CPU per frame (median, max) | {np.median(cpu):.1f} s, {cpu.max():.1f} s |")
    print(f"| limit lap (min, median, max) | {laps.min():.3f}, {np.median(laps):.3f}, "
          f"{laps.max():.3f} s |")
    print(f"| spread (max − min) / median | {100 * np.ptp(laps) / np.median(laps):.1f} % |")
    print(f"| lap / point-mass reference (median) | "
          f"{np.median(laps / np.array([d[2] for d in done])):.3f} |")
    feats = [features(build_airframe(with_theta(template, thetas[d[0]]))) for d in done]
    for name in feats[0]:
        v = np.array([f[name] for f in feats])
        if np.ptp(v) == 0:
            print(f"| {name} | – (constant: {v[0]:g}) | – |")
            continue
        rho, p = spearmanr(v, laps)
        print(f"| {name} | {rho:+.2f} | {p:.2g} |")
    print("\n| frame | lap (s) | " + " | ".join(feats[0]) + " |")
    for d, f in zip(done, feats, strict=True):
        print(f"| {d[0]} | {d[1]:.4f} | " + " | ".join(f"{x:.4g}" for x in f.values()) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
