"""Nothing is written to the current working directory: `casadrone simulate` and `casadrone run`
work from a read-only one, with a cold compile cache (the lap's C is generated and compiled in a
private temporary directory, the library moved into the cache atomically)."""

import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-c", "from casadrone.cli import app; app()"]
TINY = ["algorithm.population=8", "algorithm.generations=1", "algorithm.settings.n_ind_ga=4"]


def read_only_dirs(tmp_path: Path) -> list[Path]:
    """A temp dir chmod'ed read-only; as root (who may write there anyway), also /proc, where
    nobody can create a file."""
    ro = tmp_path / "read-only"
    ro.mkdir()
    ro.chmod(stat.S_IRUSR | stat.S_IXUSR | stat.S_IRGRP | stat.S_IXGRP)
    return [ro, Path("/proc")] if os.geteuid() == 0 else [ro]


@pytest.mark.parametrize("command", ["simulate", "run"])
def test_cli_works_from_a_read_only_working_directory(command, tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    try:
        for i, cwd in enumerate(read_only_dirs(tmp_path)):
            env["CASADRONE_CACHE"] = str(tmp_path / f"cache{i}")  # cold: compile from here
            if command == "simulate":
                args = ["simulate", "SY250"]
            else:
                args = ["run", str(ROOT / "problems" / "quick.yaml"), *TINY, "--out",
                        str(tmp_path / f"run{i}"), "--backend", "serial", "--quiet"]
            before = sorted(p.name for p in cwd.iterdir()) if cwd != Path("/proc") else None
            done = subprocess.run([*CLI, *args], cwd=cwd, env=env, capture_output=True,
                                  text=True, timeout=300)
            assert done.returncode == 0, f"{cwd}: {done.stderr[-2000:]}"
            if before is not None:
                assert sorted(p.name for p in cwd.iterdir()) == before
            assert list((tmp_path / f"cache{i}").glob("*.so")), "the lap was compiled"
            assert not list((tmp_path / f"cache{i}").glob("*.tmp")), "no staged file left"
            if command == "run":
                assert (tmp_path / f"run{i}" / "pareto.csv").exists()
            else:
                assert "J3" in done.stdout
    finally:
        (tmp_path / "read-only").chmod(0o755)
