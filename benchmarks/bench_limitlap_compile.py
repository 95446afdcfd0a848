"""Benchmark: what the limit lap's first compile costs, and what each choice costs per solve.

The limit lap's interval blocks (:func:`casadrone.limit.nlp.interval_blocks`: one shooting
interval's Jacobian and Lagrangian Hessian, three RK4 steps) are generated as C and compiled once
per machine. Two designs, each at three optimisation levels:

- ``whole-step`` (before): CasADi's symbolic Hessian of the whole interval (three RK4 steps
  expanded into one SX graph), as the blocks were built before;
- ``substep-chain`` (after): one RK4 step's Jacobian and Hessian as small functions, chained
  over the steps (:func:`casadrone.limit.nlp.interval_block_functions`).

Per design and flags (``--blocks``): bytes of C, the compiler's CPU, and the CPU of one call of
each block mapped over the paper track's 200 intervals (5 legs of 40; the mean of many calls);
"per solve" is the blocks' CPU in a solve of :data:`SOLVE_ITERATIONS` IPOPT iterations (one
Jacobian and one Hessian call per iteration: 70 and 68 in the fine-grid start's last solve,
benchmarks/RESULTS-limitlap-fastpath.md).

``--first [--checkout DIR]``: ``casadrone limit-lap SY250 --json`` as a user runs it on a new
machine (an empty cache: every block it needs compiled in the call), then again with the cache
filled; the CPU of the process and its children (the compiler), and the lap. ``--checkout``
runs another checkout's code (PYTHONPATH), for the before row.

``--precompile``: ``python -m casadrone.precompile --jobs 1`` into an empty cache (every shipped
block, one at a time): its CPU.

Each measurement appends one JSON line to ``benchmarks/limitlap-compile.jsonl`` (``--log``);
``benchmarks/RESULTS-limitlap-compile.md`` is rewritten from every line of the log
(``--report`` only rewrites it). CPU is the figure to compare: the machine is shared.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from benchmarks.machine import describe, markdown, with_summary  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
FLAGS: dict[str, tuple[str, ...]] = {"O0": ("-O0",), "O1": ("-O1",), "O2-avx2": ("-O2", "-mavx2")}
DESIGNS = ("whole-step", "substep-chain")
INTERVALS = 200  # the paper track: 5 legs of 40
SOLVE_ITERATIONS = 69  # one Jacobian and one Hessian call per iteration (70 and 68 measured)
#: Figures of issue 43 (before this work): the first ``limit-lap SY250`` on an empty cache and
#: ``python -m casadrone.precompile``, for the report's text.
ISSUE_BEFORE = {"first": 256.0, "precompile_min": 14.7}


#: What was measured by hand on the way (each with its command), kept with the report.
NOTES = [
    "## Where a solve's CPU goes (profile)", "",
    "IPOPT's timing statistics (`print_timing_statistics yes`) and CasADi's per-function CPU, "
    "`casadrone limit-lap SY250` from the fine-grid start alone (`LimitLapOptions(starts="
    "('fine-grid',), grid_rounds=0)`, whole-step blocks), the machine at load 10-12:", "",
    "| solve | iterations | CPU (s) | linear solver (MUMPS: factorisation and back-solves) | "
    "Hessian blocks | Jacobian blocks | constraints | rest |",
    "|---|---|---|---|---|---|---|---|",
    "| full model, 40 intervals per leg (the lap's own solve) | 68 | 3.43 | 1.73 (50 %) | "
    "1.02 (30 %) | 0.37 (11 %) | 0.05 | 0.26 |",
    "| full model, 60 per leg (the fine-grid continuation) | 180 | 12.0 | 6.77 (56 %) | "
    "3.46 (29 %) | 1.15 (10 %) | 0.15 | 0.5 |",
    "| point mass, 60 per leg (reference of the fine-grid start; 1 of 3) | 535 | 10.2 | – | "
    "2.38 | 0.80 | 0.18 | – |",
    "| point mass, 40 per leg (the result's reference; 3 solves) | 435, 433, 471 | 5.2, 6.2, "
    "5.5 | 2.96-3.70 (PD system) | 1.1-1.3 | 0.39-0.44 | 0.1 | – |", "",
    "The fine-grid start alone took 62 s CPU: the six point-mass solves (three straight-line "
    "starts on each of 60 and 40 intervals, 430-600 iterations each) are most of it, not the "
    "full-model solves (15.5 s). In a full-model solve MUMPS is half, the compiled blocks 40 %.",
    "",
    "## The designs tried for the blocks", "",
    "- **substep-chain** (`CASADRONE_BLOCKS=substep-chain`): one RK4 step's Jacobian and Hessian "
    "(SX, 11.4 k and 33.8 k instructions against the whole step's 45.7 k and 143 k), chained "
    "over the three steps in generated MX code: 1.07 MB of C instead of 4.38 MB, the same "
    "derivatives to ~1e-16 (tests/unit/test_codegen.py). Compiler CPU of that C by hand "
    "(`gcc FLAGS -shared -fPIC`): -O2 -mavx2 23.2 s, -O1 18.1 s, -O0 2.8 s; the whole step "
    "-O2 -mavx2 198.1 s (1.5 GB of memory).",
    "- **CasADi's own MX derivatives of a step built from calls** (not kept): RK4 in MX calling "
    "one step (SX) 5.37 MB of C; calling the model's f (SX) 1.74 MB, 55.6 s at -O2 -mavx2, "
    "5.7 s at -O0.",
    "- **-O0** (not kept): 2.8 s to compile the chain, but its Hessian block runs ~4x slower "
    "(53 ms against 13 ms per 120 intervals): about +3 s per 68-iteration solve.",
    "- **The first limit lap on an empty cache**, by hand (`CASADRONE_CACHE=<empty dir> "
    "/usr/bin/time casadrone limit-lap SY250 --json`, user + sys): before (whole-step, "
    "e31799a) 260.1 s CPU, of which the compiler 177.1 s for the quadrotor block, lap "
    "3.8914275 s; substep-chain 106.0 s CPU, the compiler 18.2 s for that block, lap "
    "3.8799666 s (the fine-grid start took 115 iterations instead of 68).",
    "- **Why the chain is now the default** (it was opt-in while the fast path's lap "
    "depended on a cold start): the chain's derivatives differ from the whole step's in the "
    "last bits, and IPOPT's path from a cold start follows the last bits (with the chain, "
    "blocks compiled, by hand as above: SY250 3.8800 s against 3.8914 s, HS210 3.8833 s "
    "against 3.8307 s, the gate track 2.1603 s both). The fast path now starts from the "
    "track's shipped lap (casadrone.limit.library), which does not: SY250 3.8795 s and HS210 "
    "3.8312 s from either design. `CASADRONE_BLOCKS=whole-step` keeps every lap as before.",
    "- **The four RK4 stages chained** (the propeller model's blocks, "
    "`casadrone.limit.nlp.rk4_stages`): the right-hand side's Jacobian and Hessian (SX, once) "
    "chained over the four stages of each step in MX, the step's only other nonlinearity the "
    "products h·k_i. C of the blocks, by hand (`/tmp/csrc`: each library's C as precompile "
    "generates it): the propeller limit Jacobian/Hessian library 2.89 MB → 0.20 MB, co-design's "
    "propeller library 3.55 MB → 0.79 MB; every shipped block 44 s of CPU to compile. Per call "
    "of the compiled blocks mapped over 200 intervals (a quiet core, `time.process_time`): "
    "propeller Jacobian 18.3 ms and Hessian 58.6 ms against the whole step's 17.2 and 53.9; "
    "the paper model 9.6 and 32.0 ms against 2.5 and 8.3 (its small right-hand side leaves the "
    "chain's dense 21x21 products dominant), so the paper model keeps the per-step chain "
    "(`STAGE_CHAIN_MIN_INSTRUCTIONS`: 500 SX instructions; the paper model's f has 301, the "
    "propeller's 768).",
    "- **The whole step at -O0 for a first answer** (not built): 7.9 s to compile instead of "
    "157 s (the table above), at +3.1 s of block CPU per 68-iteration solve; without FMA or "
    "reassociation at either level it gives -O2 -mavx2's numbers to the bit (checked by hand: "
    "the SY250 block compiled with `gcc -O0` (9.6 s CPU) and the cached -O2 -mavx2 library, "
    "both mapped over 64 random intervals, Jacobian and Hessian identical), so "
    "a first call on -O0 blocks with -O2 compiled in the background for later processes would "
    "keep every lap. The fast path's first call has four full-model solves (~+12-20 s).",
    "- **The gate track with the chain** (by hand, blocks compiled, `CASADRONE_CACHE=<dir> "
    "/usr/bin/time casadrone limit-lap SY250 --track multigp-cdra-gates --json`): 2.1603 s "
    "from the coarse-grid start, 66.6 s CPU (67.5 s before: RESULTS-limitlap-fastpath.md); "
    "HS210 the same way 3.8833 s in 102.7 s CPU.",
    "- **The point-mass reference with a limited-memory Hessian** (not kept): all three "
    "straight-line starts on 40 intervals hit the 1000-iteration limit (30.0 s CPU) where the "
    "exact Hessian converges in 461-520 iterations (16.2 s CPU for the three, best 3.6967 s).",
    "",
]


def children_cpu() -> float:
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ch.ru_utime + ch.ru_stime


def whole_step_functions(model, substeps: int):
    """The blocks as built before: CasADi's symbolic Jacobian and Hessian of the whole interval
    (``substeps`` RK4 steps in one SX graph), the same inputs and outputs as
    :func:`casadrone.limit.nlp.interval_block_functions`."""
    import casadi as ca

    from casadrone.limit.nlp import rk4_step

    nx, nu = model.nx, model.nu
    z = ca.SX.sym("z", 1 + nu + nx)
    p = ca.SX.sym("p", model.np)
    inv_n = ca.SX.sym("inv_n")
    lam = ca.SX.sym("lam", nx)
    x_next = rk4_step(model, substeps)(z[1 + nu:], z[1:1 + nu], p, z[0] * inv_n)
    H = ca.triu(ca.hessian(ca.dot(lam, x_next), z)[0])
    jac = ca.Function("bench_jac", [z, p, inv_n], [x_next, ca.densify(ca.jacobian(x_next, z))])
    hess = ca.Function("bench_hess", [z, p, inv_n, lam], [ca.vertcat(*H.nonzeros())])
    return jac, hess


def substep_chain_functions(model, substeps: int):
    import casadi as ca

    from casadrone.limit.nlp import chained_block_functions

    jac, hess, _ = chained_block_functions(model, substeps)
    return (ca.Function("bench_jac", jac.mx_in(), jac.call(jac.mx_in())),
            ca.Function("bench_hess", hess.mx_in(), hess.call(hess.mx_in())))


def measure_blocks(design: str, flags_name: str) -> dict:
    """C bytes, compile CPU and per-call CPU of the SY250 paper blocks of ``design``."""
    import casadi as ca
    import numpy as np

    from casadrone.airframe import build_airframe
    from casadrone.codegen import run_compiler
    from casadrone.config.airframe import load_airframe
    from casadrone.limit.nlp import quadrotor_ocp_model

    model = quadrotor_ocp_model("paper")
    build = whole_step_functions if design == "whole-step" else substep_chain_functions
    jac, hess = build(model, 3)
    gen = ca.CodeGenerator("bench_blocks", {"with_header": False})
    gen.add(jac)
    gen.add(hess)
    src = gen.dump()
    with tempfile.TemporaryDirectory() as tmp:
        c_file, so = Path(tmp) / "bench_blocks.c", Path(tmp) / "bench_blocks.so"
        c_file.write_text(src)
        c0 = children_cpu()
        run_compiler([os.environ.get("CC", "gcc"), *FLAGS[flags_name], "-shared", "-fPIC",
                      str(c_file), "-o", str(so), "-lm"])
        compile_cpu = children_cpu() - c0
        cj, ch = (ca.external(n, str(so)) for n in ("bench_jac", "bench_hess"))
        rng = np.random.default_rng(0)
        nx, nu = model.nx, model.nu
        z = np.vstack([np.full(INTERVALS, 3.9 / 5), rng.uniform(0.3, 0.9, (nu, INTERVALS)),
                       rng.normal(0, 1, (nx, INTERVALS))])
        z[1 + nu + 12:] = rng.uniform(1, 5, (4, INTERVALS))  # rotor thrusts (N)
        lam = rng.normal(0, 1, (nx, INTERVALS))
        p = build_airframe(load_airframe("SY250")).p
        per_call = {}
        for name, f, args in (("jac", cj.map(INTERVALS), (z, p, 1 / 40)),
                              ("hess", ch.map(INTERVALS), (z, p, 1 / 40, lam))):
            f(*args)
            n, t = 0, time.process_time()
            while n < 20 or time.process_time() - t < 2.0:
                f(*args)
                n += 1
            per_call[name] = (time.process_time() - t) / n
    return {"kind": "blocks", "design": design, "flags": flags_name, "c_bytes": len(src),
            "compile_cpu_s": compile_cpu, "jac_ms": 1e3 * per_call["jac"],
            "hess_ms": 1e3 * per_call["hess"],
            "per_solve_s": SOLVE_ITERATIONS * (per_call["jac"] + per_call["hess"])}


def run_cli(cmd: list[str], checkout: Path, cache: Path, design: str = "whole-step"
            ) -> tuple[float, float, str]:
    env = dict(os.environ, PYTHONPATH=str(checkout), CASADRONE_CACHE=str(cache),
               CASADRONE_BLOCKS=design)
    c0, w0 = children_cpu(), time.perf_counter()
    out = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env,
                         cwd=checkout)
    if out.returncode:
        raise SystemExit(f"{' '.join(cmd)} failed: {out.stderr.strip().splitlines()[-1:]}")
    return children_cpu() - c0, time.perf_counter() - w0, out.stdout


def git_rev(checkout: Path) -> str:
    return subprocess.run(["git", "-C", str(checkout), "rev-parse", "--short", "HEAD"],
                          capture_output=True, text=True, check=False).stdout.strip()


def measure_first(checkout: Path, design: str) -> list[dict]:
    """``limit-lap SY250`` on an empty cache, then with it filled, with the blocks of ``design``
    (``$CASADRONE_BLOCKS``; a checkout before the chain has only the whole-step blocks)."""
    rows = []
    cmd = ["casadrone", "limit-lap", "SY250", "--json"]
    with tempfile.TemporaryDirectory() as cache:
        for which in ("empty cache", "cache filled"):
            cpu, wall, out = run_cli(cmd, checkout, Path(cache), design)
            lap = json.loads(out)["lap_time_s"]
            rows.append({"kind": "first", "which": which,
                         "checkout": f"{git_rev(checkout)} {design}",
                         "command": " ".join(cmd[:3]), "cpu_s": cpu, "wall_s": wall,
                         "lap_time_s": lap})
    return rows


#: Run in the checkout measured: the bytes of C of every shipped block (as precompile builds it)
SIZES_SNIPPET = """
import json, sys, casadi as ca
from casadrone.precompile import SHIPPED
from casadrone.limit import nlp
from casadrone.limit.lagless import without_lag
import casadrone.codesign.blocks as cb
chain = sys.argv[1] == "substep-chain"
limit_blocks = nlp.chained_block_functions if chain else nlp.interval_block_functions
theta_blocks = cb.chained_theta_block_functions if chain else cb.theta_block_functions
out = {}
for b in SHIPPED:
    maker = {"quadrotor": nlp.quadrotor_ocp_model, "point-mass": nlp.point_mass_ocp_model}
    model = maker[b.model](b.propulsion)
    if b.lagless:
        model = without_lag(model)
    funs = (theta_blocks(model, b.substeps, b.n_dir) if b.kind == "codesign"
            else limit_blocks(model, b.substeps))
    gen = ca.CodeGenerator("sizes", {"with_header": False})
    for f in funs:
        gen.add(f)
    out[b.label] = len(gen.dump())
print(json.dumps(out))
"""


def measure_sizes(checkout: Path, design: str) -> dict:
    """Bytes of C of every shipped block's derivatives in ``checkout`` and ``design`` (nothing
    compiled; a checkout before the chain has only ``whole-step``)."""
    env = dict(os.environ, PYTHONPATH=str(checkout))
    out = subprocess.run([sys.executable, "-c", SIZES_SNIPPET, design], capture_output=True,
                         text=True, check=True, env=env, cwd=checkout)
    return {"kind": "sizes", "checkout": f"{git_rev(checkout)} {design}",
            "bytes": json.loads(out.stdout)}


def measure_precompile(checkout: Path, design: str) -> dict:
    """Every shipped block compiled into an empty cache, one job, with ``design``'s blocks."""
    with tempfile.TemporaryDirectory() as cache:
        cpu, wall, _ = run_cli([sys.executable, "-m", "casadrone.precompile", "--jobs", "1",
                                "-q"], checkout, Path(cache), design)
    return {"kind": "precompile", "checkout": f"{git_rev(checkout)} {design}", "cpu_s": cpu,
            "wall_s": wall}


def report(log: Path, out: Path) -> None:
    rows = [json.loads(line) for line in log.read_text().splitlines() if line.strip()]
    last: dict[tuple, dict] = {}
    for r in rows:
        key = (r["kind"], r.get("design"), r.get("flags"), r.get("which"), r.get("checkout"))
        last[key] = r
    blocks = [r for r in last.values() if r["kind"] == "blocks"]
    blocks.sort(key=lambda r: (DESIGNS.index(r["design"]), list(FLAGS).index(r["flags"])))
    firsts = [r for r in last.values() if r["kind"] == "first"]
    pre = [r for r in last.values() if r["kind"] == "precompile"]
    sizes = [r for r in last.values() if r["kind"] == "sizes"]
    dates = sorted({r["date"][:10] for r in rows})
    lines = ["# Limit lap: what the first compile costs", "",
             f"## What was measured ({', '.join(dates)})", "",
             "The SY250 paper-track interval blocks (Jacobian and Hessian of one shooting "
             "interval of three RK4 steps) in the two designs and at three optimisation levels "
             f"(`python benchmarks/bench_limitlap_compile.py --blocks`); per call: the block "
             f"mapped over {INTERVALS} intervals; per solve: {SOLVE_ITERATIONS} calls of each "
             "(a 68-iteration solve). The first `casadrone limit-lap SY250` on an empty cache "
             "and then on a filled one (`--first`, before: `--first --checkout` of the revision "
             "before), CPU of the process and its children (the compiler). The machine's 2 "
             "cores were shared with other jobs (load average 10-13), which inflates CPU "
             "times too (cache and memory contention): compare rows measured together.", "",
             "Machine (at the report; each row's date and load are in "
             "`benchmarks/limitlap-compile.jsonl`):", "", markdown(), "",
             "## The blocks: C, compile and per-solve CPU", "",
             "| design | flags | C (bytes) | compile CPU (s) | Jacobian per call (ms) | "
             "Hessian per call (ms) | blocks per solve (s CPU) |",
             "|---|---|---|---|---|---|---|"]
    for r in blocks:
        lines.append(f"| {r['design']} | {r['flags']} | {r['c_bytes']:,} | "
                     f"{r['compile_cpu_s']:.1f} | {r['jac_ms']:.2f} | {r['hess_ms']:.2f} | "
                     f"{r['per_solve_s']:.2f} |")
    lines += ["", "## The first limit lap", "",
              "| revision | cache | command | lap (s) | CPU (s) | wall (s) |",
              "|---|---|---|---|---|---|"]
    for r in firsts:
        lines.append(f"| {r['checkout']} | {r['which']} | `{r['command']}` | "
                     f"{r['lap_time_s']:.7f} | {r['cpu_s']:.1f} | {r['wall_s']:.0f} |")
    if pre:
        lines += ["", "## Every shipped block", "", "| revision | command | CPU (s) | wall (s) |",
                  "|---|---|---|---|"]
        lines += [f"| {r['checkout']} | `python -m casadrone.precompile --jobs 1` | "
                  f"{r['cpu_s']:.1f} | {r['wall_s']:.0f} |" for r in pre]
    if sizes:
        labels = list(dict.fromkeys(k for r in sizes for k in r["bytes"]))
        lines += ["", "## Every shipped block: bytes of C (`--sizes`, nothing compiled)", "",
                  "| block | " + " | ".join(f"rev {r['checkout']}" for r in sizes) + " |",
                  "|---|" + "---|" * len(sizes)]
        lines += [f"| {k} | " + " | ".join(f"{r['bytes'].get(k, 0):,}" for r in sizes) + " |"
                  for k in labels]
        lines.append("| all | " + " | ".join(f"{sum(r['bytes'].values()):,}" for r in sizes)
                     + " |")
    lines += ["", *NOTES]
    summary = []
    chain = {r["flags"]: r for r in blocks if r["design"] == "substep-chain"}
    whole = {r["flags"]: r for r in blocks if r["design"] == "whole-step"}
    if "O2-avx2" in chain and "O2-avx2" in whole:
        a, b = whole["O2-avx2"], chain["O2-avx2"]
        summary.append(("SY250 interval blocks at -O2 -mavx2: C, compile CPU, blocks' CPU per "
                        "68-iteration solve, whole-step → substep-chain",
                        f"{a['c_bytes'] / 1e6:.1f} → {b['c_bytes'] / 1e6:.1f} MB; "
                        f"{a['compile_cpu_s']:.0f} → {b['compile_cpu_s']:.0f} s; "
                        f"{a['per_solve_s']:.2f} → {b['per_solve_s']:.2f} s",
                        "`python benchmarks/bench_limitlap_compile.py --blocks`"))
    if sizes:
        summary.append(("C of every shipped block's derivatives (`python -m casadrone.precompile` "
                        "compiles them), by revision and design",
                        "; ".join(f"rev {r['checkout']}: {sum(r['bytes'].values()) / 1e6:.1f} MB"
                                  for r in sizes),
                        "`python benchmarks/bench_limitlap_compile.py --sizes [--checkout DIR]`"))
    for r in pre:
        summary.append((f"every shipped block compiled into an empty cache, one job, rev "
                        f"{r['checkout']} (target 3 CPU-minutes; {ISSUE_BEFORE['precompile_min']}"
                        " before)", f"{r['cpu_s']:.1f} s CPU",
                        "`python benchmarks/bench_limitlap_compile.py --precompile --designs "
                        f"{r['checkout'].split()[-1] if ' ' in r['checkout'] else 'whole-step'}`"))
    for r in firsts:
        summary.append((f"first `casadrone limit-lap SY250` ({r['which']}), rev {r['checkout']}",
                        f"{r['lap_time_s']:.7f} s lap in {r['cpu_s']:.1f} s CPU",
                        "`python benchmarks/bench_limitlap_compile.py --first --designs "
                        f"{r['checkout'].split()[-1]}` (`--checkout DIR`: another revision)"))
    text = "\n".join(lines).rstrip("\n") + "\n"
    out.write_text(with_summary(text, summary, dates[-1] if dates else None), encoding="utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", action="store_true", help="C, compile and per-call CPU")
    ap.add_argument("--designs", nargs="+", default=list(DESIGNS), choices=DESIGNS)
    ap.add_argument("--flags", nargs="+", default=list(FLAGS), choices=list(FLAGS))
    ap.add_argument("--first", action="store_true", help="limit-lap SY250 on an empty cache")
    ap.add_argument("--precompile", action="store_true", help="every shipped block, one job")
    ap.add_argument("--sizes", action="store_true", help="C bytes of every shipped block")
    ap.add_argument("--checkout", type=Path, default=ROOT, help="the code to run (--first)")
    ap.add_argument("--log", type=Path, default=HERE / "limitlap-compile.jsonl")
    ap.add_argument("--out", type=Path, default=HERE / "RESULTS-limitlap-compile.md")
    ap.add_argument("--report", action="store_true", help="only rewrite --out from --log")
    args = ap.parse_args(argv)
    found: list[dict] = []
    stamp = {k: describe()[k] for k in ("date", "git", "load")}
    if not args.report:
        if args.blocks:
            found += [measure_blocks(d, f) for d in args.designs for f in args.flags]
        if args.first:
            for d in args.designs:
                found += measure_first(args.checkout.resolve(), d)
        if args.sizes:
            found += [measure_sizes(args.checkout.resolve(), d) for d in args.designs]
        if args.precompile:
            found += [measure_precompile(args.checkout.resolve(), d) for d in args.designs]
    with args.log.open("a", encoding="utf-8") as log:
        for row in found:
            log.write(json.dumps(row | stamp) + "\n")
            print(json.dumps(row), flush=True)
    if args.log.exists():
        report(args.log, args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
