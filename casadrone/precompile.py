"""Compile the solver blocks of casadrone's models for this machine, several at a time.

The limit lap and co-design compile one shooting interval's derivatives as C the first time a
model is used (:mod:`casadrone.codegen`): 4-140 s of one core each for the quadrotor's models
(the substep-chain blocks, the default, 290 s for all of them; one to four minutes each with
``CASADRONE_BLOCKS=whole-step``), one after the other as a process comes to need them. A fresh
machine that will use them all (a cluster node, a CI runner, the test suite) can compile them
side by side instead, one process per library, the largest first::

    python -m casadrone.precompile [--jobs N]

Each library lands in the same cache, under the same name, as the first use would put it there
(the same functions are called), so later processes find it; a library already there costs a
fingerprint (well under a second). Nothing else is computed.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from multiprocessing import get_context

from casadrone.progress import silence


@dataclass(frozen=True)
class Block:
    """One compiled library: the limit lap's interval blocks and compiled step (``limit``) or
    co-design's θ-blocks (``codesign``, ``n_dir`` design directions) of a model."""

    kind: str  # "limit" or "codesign"
    model: str  # "quadrotor", "point-mass"
    propulsion: str = "paper"
    lagless: bool = False
    substeps: int = 3
    n_dir: int = 4

    @property
    def label(self) -> str:
        extra = "-lagless" if self.lagless else ""
        tail = f" (d{self.n_dir})" if self.kind == "codesign" else ""
        return f"{self.kind} {self.model}{extra} {self.propulsion} rk4x{self.substeps}{tail}"


#: What the shipped problems compile, the largest first (9.8 MB of C in all with the default
#: substep-chain blocks, :data:`casadrone.limit.nlp.BLOCK_DESIGNS`: the limit paper block
#: 14-18 s of CPU at -O2 -mavx2 on the project's AMD VM; with ``CASADRONE_BLOCKS=whole-step``
#: 31 MB: codesign propeller ~4 min, limit propeller ~3.5, codesign paper ~2.5, limit paper
#: ~2.5 (157-198 s measured), the lag-free paper model ~1.5; the point-mass blocks take
#: seconds: benchmarks/RESULTS-limitlap-compile.md).
SHIPPED: tuple[Block, ...] = (
    Block("codesign", "quadrotor", "propeller"),
    Block("limit", "quadrotor", "propeller"),
    Block("codesign", "quadrotor", "paper"),
    Block("limit", "quadrotor", "paper"),
    Block("limit", "quadrotor", "paper", lagless=True),
    Block("limit", "point-mass", "paper"),
    Block("limit", "point-mass", "propeller"),
)


def compile_block(block: Block) -> float:
    """Compile (or find in the cache) ``block``'s library; returns the seconds it took."""
    from casadrone.limit import nlp
    from casadrone.limit.lagless import without_lag

    t0 = time.perf_counter()
    maker = {"quadrotor": nlp.quadrotor_ocp_model, "point-mass": nlp.point_mass_ocp_model}
    model = maker[block.model](block.propulsion)
    if block.lagless:
        model = without_lag(model)
    if block.kind == "codesign":
        from casadrone.codesign.blocks import theta_blocks

        theta_blocks(model, block.substeps, block.n_dir)
    else:
        nlp.step_block(model, block.substeps)
        nlp.interval_blocks(model, block.substeps)
    return time.perf_counter() - t0


def precompile(blocks: tuple[Block, ...] = SHIPPED, jobs: int | None = None,
               report: Callable[[Block, float], None] | None = None, quiet: bool = False
               ) -> list[tuple[Block, float]]:
    """Compile ``blocks`` in ``jobs`` processes (default: the CPUs this process may use), each
    reported to ``report(block, seconds)`` in this process as it ends (the workers' own
    progress cannot reach this process's listener, :mod:`casadrone.progress`). Returns (block,
    seconds) in finishing order. A failing compile (e.g. :class:`casadrone.codegen.NoCompiler`)
    raises here once the compiles already running have ended. Each compile of a quadrotor
    block holds 1.5–3 GB of memory while it runs: ``jobs`` bounds the sum. ``quiet``: the
    workers do not announce their compiles on stderr either."""
    if jobs is None:
        jobs = (len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                else os.cpu_count() or 1)
    done: list[tuple[Block, float]] = []
    # spawn: a child starts clean (no CasADi state, no threads inherited from the parent)
    with ProcessPoolExecutor(max_workers=max(1, min(jobs, len(blocks))),
                             mp_context=get_context("spawn"),
                             initializer=silence if quiet else None) as pool:
        futures = {pool.submit(compile_block, b): b for b in blocks}
        try:
            for fut in as_completed(futures):
                seconds = fut.result()
                done.append((futures[fut], seconds))
                if report is not None:
                    report(futures[fut], seconds)
        except BaseException:
            for fut in futures:  # those not started yet; the running ones end by themselves
                fut.cancel()
            raise
    return done


def ready_lines(total: int, write: Callable[[str], None] | None = None
                ) -> Callable[[Block, float], None]:
    """A ``report`` for :func:`precompile`: the line ``block k/total ready: LABEL (s s wall)``
    given to ``write`` (default: printed on stderr) as each block ends."""
    done = itertools.count(1)

    def ready(block: Block, seconds: float) -> None:
        line = f"block {next(done)}/{total} ready: {block.label} ({seconds:.1f} s wall)"
        if write is not None:
            write(line)
        else:
            print(line, file=sys.stderr, flush=True)

    return ready


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m casadrone.precompile",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=None,
                        help="compiles at a time (default: the CPUs this process may use)")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress lines on stderr (each compile's start, each block "
                        "ready)")
    args = parser.parse_args(argv)
    if args.jobs is not None and args.jobs < 1:
        print("python -m casadrone.precompile: --jobs must be at least 1", file=sys.stderr)
        return 2
    from casadrone.codegen import NoCompiler

    t0 = time.perf_counter()
    try:
        precompile(SHIPPED, jobs=args.jobs,
                   report=None if args.quiet else ready_lines(len(SHIPPED)), quiet=args.quiet)
    except NoCompiler as err:
        print(f"python -m casadrone.precompile: {err.strerror}", file=sys.stderr)
        return 1
    print(f"all {len(SHIPPED)} in {time.perf_counter() - t0:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
