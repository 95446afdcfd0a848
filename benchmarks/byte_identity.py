"""Every shipped command's output, recorded from one checkout and compared with another's.

A refactoring that must not change behaviour (issue 45: "every shipped command's output and a
paper run's ``pareto.csv`` stay byte-identical") is shown by running the same commands on the
code before and after and comparing what they print and write, byte for byte, after removing the
fields that measure the machine (CPU and wall times, dates, the casadrone version and revision
stamped into files).

    python benchmarks/byte_identity.py record --checkout OLD --out /tmp/bi/before
    python benchmarks/byte_identity.py record --checkout NEW --out /tmp/bi/after
    python benchmarks/byte_identity.py compare /tmp/bi/before /tmp/bi/after

``record`` runs each command of :data:`COMMANDS` in a fresh process with ``PYTHONPATH`` set to
the checkout; ``compare`` prints a Markdown table (command, files, identical or the first
differing line) and exits 1 when any output differs. ``--only NAME`` records some commands.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

#: name → argv after ``python -m casadrone`` ({out}: the command's own output folder). The cheap
#: commands of every stage, the paper run's front, the limit lap and the co-design.
COMMANDS: dict[str, list[str]] = {
    "validate": ["validate", "SY250", "SY250-propeller", "paper-rectangle",
                 "multigp-cdra-gates"],
    "trim": ["trim", "SY250", "--condition", "forward", "--speed", "10", "--json"],
    "trim-propeller": ["trim", "SY250-propeller", "--condition", "forward", "--speed", "10",
                       "--json"],
    "linearise": ["linearise", "SY250", "--json"],
    "lqr": ["lqr", "SY250", "--json"],
    "massprops": ["massprops", "SY250-components", "lambda_a_mm=140", "--json"],
    "simulate": ["simulate", "SY250", "--json"],
    "export-betaflight": ["export", "SY250", "--format", "betaflight"],
    "export-px4": ["export", "SY250", "--format", "px4"],
    "export-urdf": ["export", "SY250", "--format", "urdf"],
    "fit-propulsion": ["fit-propulsion", "example-5in", "--diameter-in", "5", "--json"],
    "run-quick": ["run", "quick", "--out", "{out}/run"],
    "limit-lap": ["limit-lap", "SY250", "--json"],
    "codesign-paper": ["codesign", "codesign-paper", "--json", "--out", "{out}/codesign"],
}

#: JSON keys and text patterns that measure the machine or stamp the code, not the answer.
VOLATILE_KEYS = re.compile(r"(cpu|wall|time_s$|_s_cpu|seconds|date|created|version|revision|"
                           r"git|host|elapsed|timings?$)", re.I)
VOLATILE_TEXT = re.compile(r"(\d+(\.\d+)? ?s (CPU|wall)|CPU [\d.]+ ?s|wall [\d.]+ ?s|"
                           r"casadrone \d[\w.+-]*|20\d\d-\d\d-\d\d[T ][\d:.]+\S*)")
#: The checkout's own path in printed file names (each run names its own copy of a shipped file).
CHECKOUT = re.compile(r"/\S*?/casadrone/(?=data/)")
#: Binary files: the run's resumable state (a pickle of live objects, whose classes may move
#: without the run's answer changing) is not an output; the history database is compared by
#: its rows.
SKIPPED = re.compile(r"checkpoint(\.prev)?\.pkl$")


def content(path: Path) -> str:
    """What is compared of a file: its rows for an SQLite database, else its text."""
    if path.suffix == ".sqlite":
        import sqlite3

        with sqlite3.connect(path) as db:
            return "\n".join(db.iterdump())
    return path.read_text(encoding="utf-8", errors="replace")


def scrub(value: object) -> object:
    """``value`` (parsed JSON) without the keys that measure the machine."""
    if isinstance(value, dict):
        return {k: scrub(v) for k, v in value.items() if not VOLATILE_KEYS.search(k)}
    if isinstance(value, list):
        return [scrub(v) for v in value]
    return value


def normalise(text: str) -> str:
    """A command's output with its volatile fields removed: parsed and re-dumped when it is
    JSON, else line by line with times, dates, versions and the checkout's path masked."""
    text = CHECKOUT.sub("<checkout>/casadrone/", text)
    try:
        return json.dumps(scrub(json.loads(text)), indent=1, sort_keys=True)
    except ValueError:
        return VOLATILE_TEXT.sub("<volatile>", text)


def record(checkout: Path, out: Path, only: list[str] | None) -> None:
    """Run :data:`COMMANDS` with ``checkout`` on the path; stdout, exit code and written files
    under ``out/NAME``."""
    env = dict(os.environ, PYTHONPATH=str(checkout.resolve()))
    for name, argv in COMMANDS.items():
        if only and name not in only:
            continue
        folder = out / name
        shutil.rmtree(folder, ignore_errors=True)
        folder.mkdir(parents=True)
        args = [a.replace("{out}", str(folder)) for a in argv]
        start = time.perf_counter()
        proc = subprocess.run([sys.executable, "-m", "casadrone", *args], env=env,
                              capture_output=True, text=True, cwd=folder)
        (folder / "stdout.txt").write_text(proc.stdout, encoding="utf-8")
        (folder / "stderr.log").write_text(proc.stderr, encoding="utf-8")
        (folder / "rc.txt").write_text(f"{proc.returncode}\n", encoding="utf-8")
        print(f"{name}: rc {proc.returncode}, {time.perf_counter() - start:.0f} s",
              file=sys.stderr)


def files(folder: Path) -> dict[str, Path]:
    """Relative path → file under ``folder``, stderr and logs of timings aside."""
    return {str(p.relative_to(folder)): p for p in sorted(folder.rglob("*"))
            if p.is_file() and not re.search(r"(timings|progress|\.log$|\.lock$)", p.name)
            and not SKIPPED.search(p.name)}


def compare(before: Path, after: Path, results: Path | None = None,
            revisions: str = "") -> int:
    """Print the table (and write it to ``results``, opening with its dated summary); 1 when any
    command's output or files differ."""
    lines = ["| command | files compared | outcome |", "|---|---|---|"]
    bad = 0
    for name in COMMANDS:
        a, b = before / name, after / name
        if not a.is_dir() or not b.is_dir():
            continue
        fa, fb = files(a), files(b)
        outcome = "identical"
        if set(fa) != set(fb):
            outcome = f"different files: {sorted(set(fa) ^ set(fb))}"
        else:
            for rel in fa:
                ta, tb = (normalise(content(p)) for p in (fa[rel], fb[rel]))
                if ta != tb:
                    la, lb = ta.splitlines(), tb.splitlines()
                    i = next((i for i, (x, y) in enumerate(zip(la, lb, strict=False))
                              if x != y), min(len(la), len(lb)))
                    was, now = (lines_[i].strip()[:60] if i < len(lines_) else "(end)"
                                for lines_ in (la, lb))
                    outcome = f"{rel} differs at line {i + 1}: `{was}` became `{now}`"
                    break
        bad += outcome != "identical"
        lines.append(f"| `casadrone {' '.join(COMMANDS[name])}` | {len(fa)} | {outcome} |")
    print("\n".join(lines))
    if results is not None:
        write_results(results, lines, bad, revisions)
    return 1 if bad else 0


def write_results(path: Path, table: list[str], bad: int, revisions: str) -> None:
    """``path``: the table under the dated summary every results file opens with."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from machine import markdown, with_summary

    n = len(table) - 2
    figure = (f"{n - bad} of {n} commands identical" + (f", {bad} differ" if bad else "")
              + (f" ({revisions})" if revisions else ""))
    text = "\n".join([
        "# Every shipped command's output, before and after", "",
        "What was measured: each command of `benchmarks/byte_identity.py` run in a fresh process "
        "on two checkouts, stdout and every written file compared byte for byte after removing "
        "what measures the machine (CPU and wall times, dates, the version stamped into files, "
        "the checkout's own path); SQLite files by their rows; the run's pickled resumable "
        "state (`checkpoint.pkl`) is not an output and is not compared. "
        + (f"Revisions: {revisions}." if revisions else ""), "",
        *table, "", "Machine:", "", markdown(), ""])
    path.write_text(with_summary(text, [(
        "every shipped command's output, before and after", figure,
        "`python benchmarks/byte_identity.py record --checkout OLD --out A`, the same with NEW "
        "into B, then `python benchmarks/byte_identity.py compare A B --results FILE`")]),
        encoding="utf-8")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="what", required=True)
    rec = sub.add_parser("record")
    rec.add_argument("--checkout", type=Path, required=True)
    rec.add_argument("--out", type=Path, required=True)
    rec.add_argument("--only", nargs="*")
    cmp = sub.add_parser("compare")
    cmp.add_argument("before", type=Path)
    cmp.add_argument("after", type=Path)
    cmp.add_argument("--results", type=Path, help="also write the table as a results file")
    cmp.add_argument("--revisions", default="", help="what OLD and NEW are, for the file")
    args = parser.parse_args()
    if args.what == "record":
        record(args.checkout, args.out, args.only)
        return 0
    return compare(args.before, args.after, args.results, args.revisions)


if __name__ == "__main__":
    sys.exit(main())
