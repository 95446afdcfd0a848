"""Benchmark: what a process pays for the limit lap's compiled derivative blocks when the compile
cache already holds them (the interval blocks and co-design's θ blocks), in process time.

    python benchmarks/bench_cache_hit.py paper
    python benchmarks/bench_cache_hit.py propeller

Run it once to fill the cache (the first run compiles, minutes), then in fresh processes.
"""

import argparse
import time

from casadrone.codesign.blocks import theta_blocks
from casadrone.limit import nlp


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("propulsion", choices=["paper", "propeller"])
    parser.add_argument("--substeps", type=int, default=3)
    parser.add_argument("--directions", type=int, default=4, help="θ directions (co-design)")
    args = parser.parse_args()
    model = nlp.quadrotor_ocp_model(args.propulsion)
    t = time.process_time()
    nlp.interval_blocks(model, args.substeps)
    blocks = time.process_time() - t
    t = time.process_time()
    theta_blocks(model, args.substeps, args.directions)
    theta = time.process_time() - t
    print(f"{args.propulsion}: interval_blocks {blocks:.3f} s, theta_blocks {theta:.3f} s")


if __name__ == "__main__":
    main()
