"""What machine, software and revision a benchmark ran on (shared by every benchmark script)."""

from __future__ import annotations

import datetime
import os
import platform
import subprocess
from pathlib import Path

HERE = Path(__file__).resolve().parent


def cpu_time() -> float:
    """CPU seconds of this process and of its waited-for children: a fatrop solve runs in a
    forked child (casadrone.limit.watchdog), whose CPU time.process_time() does not see."""
    import resource
    import time

    child = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + child.ru_utime + child.ru_stime


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def git_revision() -> str:
    """Short revision, flagged when the package has uncommitted changes (they affect results)."""
    def git(*cmd: str) -> str:
        return subprocess.run(["git", *cmd], capture_output=True, text=True, cwd=HERE,
                              check=True).stdout.strip()

    try:
        dirty = git("status", "--porcelain", "--untracked-files=no", "--", "../casadrone")
        changed = ", ".join(line.split()[-1] for line in dirty.splitlines())
        return git("rev-parse", "--short", "HEAD") + (f" + uncommitted {changed}" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def describe() -> dict[str, str]:
    """Machine, software versions, git revision, date and current load."""
    import casadi
    import numpy
    import scipy

    return {
        "date": datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "uname": " ".join(platform.uname()),
        "cpu": cpu_model(),
        "nproc": str(os.cpu_count()),
        "python": platform.python_version(),
        "versions": f"casadi {casadi.__version__}, numpy {numpy.__version__}, "
                    f"scipy {scipy.__version__}",
        "git": git_revision(),
        "load": "load average " + ", ".join(f"{v:.2f}" for v in os.getloadavg()),
    }


def summary_section(rows: list[tuple[str, str, str]], date: str | None = None) -> str:
    """A result file's opening summary (``## Summary (YYYY-MM-DD)``, dated today in UTC unless
    ``date`` is given): its rows (what, figure, command), which the documentation's Performance
    page gathers when the site is built (``docs/hooks/reference.py``, ``opening_summary``)."""
    date = date or datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d")
    lines = [f"## Summary ({date})", "", "| what | figure | command |", "|---|---|---|"]
    return "\n".join(lines + [f"| {what} | {figure} | {command} |"
                               for what, figure, command in rows]) + "\n"


def with_summary(text: str, rows: list[tuple[str, str, str]], date: str | None = None) -> str:
    """``text`` (a result file, its first line the ``# title``) with its opening summary placed
    right under the title, as every ``RESULTS-*.md`` must open."""
    title, _, rest = text.partition("\n")
    return f"{title}\n\n{summary_section(rows, date)}\n{rest.lstrip(chr(10))}"


def markdown() -> str:
    """The description as a markdown bullet list."""
    return "\n".join(f"- {k}: {v}" for k, v in describe().items())
