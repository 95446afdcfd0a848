"""Assemble benchmarks/RESULTS.md from the per-benchmark result files.

Each benchmark writes its own ``RESULTS-<name>.md`` (machine, date, command, tables); this script
puts them into one file in the order of the chain. Run after the benchmarks:
``python benchmarks/collect.py``.
"""

from pathlib import Path

HERE = Path(__file__).resolve().parent
ORDER = [
    ("design", "Trim, linearisation and LQR-I per candidate (issue: foundation)",
     "python benchmarks/bench_design.py"),
    ("lap", "One complete evaluation and the closed-loop lap; rotorpy comparison",
     "python benchmarks/bench_lap.py"),
    ("sensitivity", "Geometry must matter: index sensitivity around SY250",
     "python benchmarks/sensitivity.py"),
    ("geometry", "What geometry changes, and why: spreads and rank correlations over random frames",
     "python benchmarks/geometry_effects.py --runs BEFORE AFTER"),
    ("optimise", "Optimisation throughput and ev-MOGA vs NSGA-II on paper-run1",
     "python benchmarks/bench_optimise.py"),
    ("backends", "Process backend: a paper-run1 generation, pickling and IPC, 16-worker projection",
     "python benchmarks/bench_backends.py"),
    ("evmoga", "ev-MOGA and NSGA-II on ZDT1, ZDT2, DTLZ2 (known fronts)",
     "python benchmarks/bench_evmoga_zdt.py"),
    ("limitlap", "The limit lap: solve time, verification, warm starts, grid refinement",
     "casadrone limit-lap SY250 --json; pytest -m slow tests/integration/test_limitlap_slow.py"),
    ("limitlap-frames", "The limit lap over 50 random Table 1 frames: success, spread, ranks",
     "python benchmarks/bench_limitlap.py --n 50 --intervals 40"),
    ("limitlap-solvers", "The limit-lap NLP: IPOPT and fatrop side by side on random frames",
     "python benchmarks/bench_limitlap_solvers.py --n 10 (complete); --n 50 (stopped at 31 "
     "frames); --profile SY250"),
    ("propulsion", "The paper and propeller propulsion models side by side (issue 17)",
     "python benchmarks/bench_propulsion.py; casadrone limit-lap SY250-propeller --json"),
    ("trimstudy", "Trim solvers from many starts across the envelope (issue 23)",
     "python benchmarks/bench_trimstudy.py"),
    ("trimstudy-propeller", "Trim solvers with the propeller model (issue 23)",
     "python benchmarks/bench_trimstudy.py --propeller SY250-propeller --starts 10"),
    ("identity", "ev-MOGA's vectorised archive against the sequential one (issue 10)",
     "python benchmarks/check_evmoga_identity.py"),
    ("coordinator", "ev-MOGA's coordinator alone against archive size (issue 10)",
     "python benchmarks/bench_coordinator.py"),
    ("advance", "ev-MOGA's advance step (archive + P update) per paper-scale generation",
     "python benchmarks/bench_advance.py"),
    ("replay", "The coordinator alone: paper-scale runs replayed from their history (issue 10)",
     "python benchmarks/bench_replay.py --run runs/paper-scale/paper-run1 --out NEW_DIR"),
    ("paper-scale", "Paper-scale runs measured: paper-run1 and paper-run2 (issue 10)",
     "python benchmarks/bench_paper_scale.py --run-root runs/paper-scale --workers 2"),
]


def main() -> None:
    parts = ["# casadrone benchmark results", "",
             "Collected by `python benchmarks/collect.py` from the files each benchmark writes. "
             "Each section names its machine, date, revision and command. The machine has 2 cores "
             "shared with nothing else unless the load average says otherwise.", ""]
    for name, title, command in ORDER:
        path = HERE / f"RESULTS-{name}.md"
        parts.append(f"## {title}")
        parts.append("")
        parts.append(f"Reproduce: `{command}` (raw file: `benchmarks/{path.name}`)")
        parts.append("")
        if path.exists():
            body = path.read_text().strip().splitlines()
            # demote the file's own headings by two levels
            parts += [("##" + ln) if ln.startswith("#") else ln for ln in body]
        else:
            parts.append("_not run yet_")
        parts.append("")
    (HERE / "RESULTS.md").write_text("\n".join(parts) + "\n")
    print(f"wrote {HERE / 'RESULTS.md'}")


if __name__ == "__main__":
    main()
