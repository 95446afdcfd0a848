"""``casadrone fit-propulsion`` refuses bad input with exit code 2 and one stderr line naming the
file and the option, column or row, and never writes over what the user owns: the log, a run
directory's files, a dangling link, existing figures; a refused command writes nothing (the files
on disk are compared byte for byte before and after)."""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import tracemalloc
from pathlib import Path

import pytest

from casadrone.cli import app
from casadrone.thruststand import LogError, fit_propulsion, read_log
from tests.conftest import installed_script
from tests.unit.test_thruststand import D, write_log

BASE = ["--diameter-m", str(D)]


@pytest.fixture(scope="module")
def log_file(tmp_path_factory) -> Path:
    return write_log(tmp_path_factory.mktemp("stand") / "stand.csv")


def _run(cli_runner, *args: str | Path):
    return cli_runner.invoke(app, ["fit-propulsion", *map(str, args)])


def _refused(result, *needles: str) -> str:
    """The one stderr line of a refused command (exit 2), holding every needle."""
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])
    return lines[0]


def _snapshot(folder: Path) -> dict[str, bytes | str]:
    """Every entry under ``folder``: a file's bytes, a link's target, a folder's mark."""
    out: dict[str, bytes | str] = {}
    for path in sorted(folder.rglob("*")):
        key = str(path.relative_to(folder))
        if path.is_symlink():
            out[key] = "-> " + os.readlink(path)
        elif path.is_dir():
            out[key] = "dir"
        else:
            out[key] = path.read_bytes()
    return out


def _copy(log_file: Path, folder: Path, name: str = "good.csv") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_bytes(log_file.read_bytes())
    return path


def _rows(path: Path) -> list[list[str]]:
    with path.open(encoding="utf-8", newline="") as fh:
        return list(csv.reader(fh))


def _write(path: Path, rows: list[list[str]]) -> Path:
    with path.open("w", newline="", encoding="utf-8") as fh:
        csv.writer(fh).writerows(rows)
    return path


# --- 1-5: destinations ---------------------------------------------------------------------------


@pytest.mark.parametrize("spelling", ["same", "other spelling", "symlink"])
def test_out_naming_the_log_is_refused_even_with_force(tmp_path, log_file, cli_runner, spelling):
    log = _copy(log_file, tmp_path / "d")
    out = {"same": log, "other spelling": tmp_path / "d" / ".." / "d" / "good.csv",
           "symlink": tmp_path / "link.yaml"}[spelling]
    if spelling == "symlink":
        out.symlink_to(log)
    before = _snapshot(tmp_path)
    _refused(_run(cli_runner, log, *BASE, "--out", out, "--force"), "--out", "input log")
    assert _snapshot(tmp_path) == before


def test_out_inside_a_run_directory_is_refused_even_with_force(tmp_path, log_file, cli_runner):
    log = _copy(log_file, tmp_path)
    run = tmp_path / "run1"
    run.mkdir()
    (run / "manifest.json").write_text('{"status": "done"}\n')
    (run / "config.yaml").write_text("problem: p\n")
    before = _snapshot(tmp_path)
    for target in ("config.yaml", "new.yaml"):
        _refused(_run(cli_runner, log, *BASE, "--out", run / target, "--force"),
                 "--out", "run directory")
    # the figures of --plot are files too: none inside a run directory either
    _refused(_run(cli_runner, log, *BASE, "--plot", run / "figs", "--force"),
             "--plot", "run directory")
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("force", [[], ["--force"]])
def test_a_dangling_symlink_as_out_is_left_alone(tmp_path, log_file, cli_runner, force):
    log = _copy(log_file, tmp_path)
    link = tmp_path / "section.yaml"
    link.symlink_to(tmp_path / "elsewhere" / "target.yaml")
    before = _snapshot(tmp_path)
    _refused(_run(cli_runner, log, *BASE, "--out", link, *force), "--out", "section.yaml",
             "dangling")
    assert _snapshot(tmp_path) == before and link.is_symlink()


def test_existing_figures_are_kept_unless_forced(tmp_path, log_file, cli_runner):
    log = _copy(log_file, tmp_path)
    plots = tmp_path / "myplots"
    plots.mkdir()
    (plots / "propulsion-fit-steady.png").write_bytes(b"my own picture")
    before = _snapshot(tmp_path)
    _refused(_run(cli_runner, log, *BASE, "--plot", plots, "--out", tmp_path / "p.yaml"),
             "--plot", "propulsion-fit-steady.png", "--force")
    assert _snapshot(tmp_path) == before  # neither the figures nor --out written
    r = _run(cli_runner, log, *BASE, "--plot", plots, "--force")
    assert r.exit_code == 0, r.stderr
    assert (plots / "propulsion-fit-steady.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_its_own_figures_are_replaced_without_force(tmp_path, log_file, cli_runner):
    """As every --plot: a figure casadrone wrote (its mark read back by PIL) is replaced, a
    picture of the user's (written by PIL) is not, and then nothing is written."""
    from PIL import Image

    log = _copy(log_file, tmp_path)
    plots = tmp_path / "plots"
    assert _run(cli_runner, log, *BASE, "--plot", plots).exit_code == 0
    figures = sorted(plots.iterdir())
    assert len(figures) == 4
    with Image.open(plots / "propulsion-fit-steps.png") as im:
        assert im.info["Software"].startswith("casadrone ")
    for path in figures:
        os.utime(path, ns=(10**18, 10**18))
    again = _run(cli_runner, log, *BASE, "--plot", plots)
    assert again.exit_code == 0, again.stderr
    assert sorted(plots.iterdir()) == figures
    assert all(p.stat().st_mtime_ns > 10**18 for p in figures)
    Image.new("RGB", (3, 2)).save(plots / "propulsion-fit-steps.png")
    before = _snapshot(tmp_path)
    line = _refused(_run(cli_runner, log, *BASE, "--plot", plots, "--out", tmp_path / "p.yaml"),
                    "--plot", "propulsion-fit-steps.png", "not a casadrone figure", "--force")
    assert _snapshot(tmp_path) == before, line


def test_out_that_is_also_a_figure_is_refused(tmp_path, log_file, cli_runner):
    log = _copy(log_file, tmp_path)
    before = _snapshot(tmp_path)
    _refused(_run(cli_runner, log, *BASE, "--plot", tmp_path / "f", "--out",
                  tmp_path / "f" / "propulsion-fit-steps.svg"), "--out", "--plot")
    assert _snapshot(tmp_path) == before


@pytest.mark.parametrize("where", ["dangling folder link", "/proc"])
def test_nothing_is_written_when_one_destination_cannot_be(tmp_path, log_file, cli_runner,
                                                           where):
    log = _copy(log_file, tmp_path)
    if where == "/proc":
        if not Path("/proc/self").is_dir():
            pytest.skip("no /proc here")
        plots = Path("/proc/casadrone-plots")
    else:
        plots = tmp_path / "plots"
        plots.symlink_to(tmp_path / "gone")
    before = _snapshot(tmp_path)
    _refused(_run(cli_runner, log, *BASE, "--out", tmp_path / "partial.yaml", "--plot", plots),
             "--plot", str(plots))
    assert _snapshot(tmp_path) == before and not (tmp_path / "partial.yaml").exists()


def test_an_out_folder_that_cannot_be_made_is_named_not_a_temporary_file(tmp_path, log_file,
                                                                          cli_runner):
    log = _copy(log_file, tmp_path)
    (tmp_path / "nodir").symlink_to(tmp_path / "gone")
    before = _snapshot(tmp_path)
    line = _refused(_run(cli_runner, log, *BASE, "--out", tmp_path / "nodir" / "sub" / "x.yaml"),
                    "--out", str(tmp_path / "nodir" / "sub" / "x.yaml"))
    assert ".tmp" not in line and _snapshot(tmp_path) == before
    # a missing folder is made, as export's --out does
    r = _run(cli_runner, log, *BASE, "--out", tmp_path / "new" / "sub" / "x.yaml")
    assert r.exit_code == 0 and (tmp_path / "new" / "sub" / "x.yaml").is_file(), r.stderr


def test_an_out_folder_is_said_to_be_one(tmp_path, log_file, cli_runner):
    log = _copy(log_file, tmp_path)
    (tmp_path / "adir.csv").mkdir()
    before = _snapshot(tmp_path)
    line = _refused(_run(cli_runner, log, *BASE, "--out", tmp_path / "adir.csv", "--force"),
                    "--out", "adir.csv", "folder")
    assert "give --force" not in line and _snapshot(tmp_path) == before


# --- 6, 8, 9: the log's contents -----------------------------------------------------------------


def test_a_cell_over_the_csv_field_limit_is_refused_naming_the_row(tmp_path, log_file,
                                                                    cli_runner):
    rows = _rows(log_file)
    rows[100][3] = "1" * 140_000
    _refused(_run(cli_runner, _write(tmp_path / "long.csv", rows), *BASE), "long.csv", "row 101")


def test_an_unclosed_quote_is_refused_naming_its_row(tmp_path, log_file, cli_runner):
    lines = log_file.read_text(encoding="utf-8").splitlines()
    lines[50] = lines[50].replace(",", ',"', 1)  # file row 51 opens a quote never closed
    big = tmp_path / "quote.csv"
    big.write_text("\n".join(lines) + "\n", encoding="utf-8")
    _refused(_run(cli_runner, big, *BASE), "quote.csv", "row 51")
    small = tmp_path / "quote_small.csv"  # the rest of the file fits in one cell
    small.write_text("\n".join(lines[:400]) + "\n", encoding="utf-8")
    line = _refused(_run(cli_runner, small, *BASE), "quote_small.csv", "row 51", "quote")
    assert len(line) < 400  # the swallowed cell is not printed whole


def test_a_huge_cell_gives_one_line_and_no_warning(tmp_path, log_file):
    """Run as the user runs it (a process of its own: pytest would catch the warnings)."""
    rows = _rows(log_file)
    rows[3500][3] = "1e300"  # in a powered plateau's settled half: it reaches the fit
    path = _write(tmp_path / "e300.csv", rows)
    r = subprocess.run([str(installed_script("casadrone")), "fit-propulsion", str(path), *BASE],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path,
                       env={**os.environ, "PYTHONWARNINGS": "default"})
    assert r.returncode == 2, r.stderr
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and "e300.csv" in lines[0] and "row 3501" in lines[0], r.stderr
    assert "Thrust (kgf)" in lines[0]


@pytest.mark.parametrize("extra", ["Thrust (kgf)", "Thrust (N)", "ESC signal"])
def test_two_columns_of_one_quantity_are_refused(tmp_path, log_file, cli_runner, extra):
    rows = _rows(log_file)
    source = 1 if extra.startswith("ESC") else 3
    rows = [r + [r[source]] for r in rows]
    rows[0][-1] = extra
    _refused(_run(cli_runner, _write(tmp_path / "dup.csv", rows), *BASE), "dup.csv",
             f"'{rows[0][source]}'", f"'{extra}'")


def test_a_log_is_read_in_a_few_times_its_size(tmp_path):
    """Peak memory (tracemalloc: Python objects and numpy buffers) of reading a ~6 MB log stays
    under 3x the file; with the size cap that is well under 1 GB. Reading it whole into lists of
    strings, as before, took ~16x."""
    path = tmp_path / "big.csv"
    with path.open("w", encoding="utf-8") as fh:
        fh.write("Time (s),ESC signal (µs),Torque (N·m),Thrust (kgf),Voltage (V),Current (A),"
                 "Motor Optical Speed (RPM)\n")
        fh.writelines(f"{i / 1000:.3f},{1000 + 50 * (i // 600 % 20)},-0.0123,0.4567,16.2,"
                      f"{i % 97 / 10:.1f},{20000 + i % 300}\n" for i in range(150_000))
    size = path.stat().st_size
    tracemalloc.start()
    try:
        log = read_log(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(log.time_s) == 150_000
    from casadrone.thruststand import MAX_LOG_BYTES

    assert peak < 3 * size and 3 * MAX_LOG_BYTES < 2**30 // 4, (peak, size)


def test_a_log_over_the_cap_is_refused_unread(tmp_path, cli_runner):
    from casadrone.thruststand import MAX_LOG_BYTES

    path = tmp_path / "huge.csv"
    with path.open("wb") as fh:
        fh.truncate(MAX_LOG_BYTES + 1)  # sparse: no disk used
    _refused(_run(cli_runner, path, *BASE), "huge.csv", "larger than")


def test_more_steady_points_than_any_test_are_refused(log_file, monkeypatch):
    import casadrone.thruststand as ts

    monkeypatch.setattr(ts, "MAX_STEADY_POINTS", 10)
    with pytest.raises(LogError, match="stand.csv: .* steady points"):
        fit_propulsion(read_log(log_file), D)


# --- 7, 11: options and the log's kind ------------------------------------------------------------


@pytest.mark.parametrize("option, value", [
    ("--esc-max-us", "inf"), ("--esc-min-us", "nan"), ("--esc-max-us", "1e9"),
    ("--air-density", "inf"), ("--air-density", "nan"), ("--diameter-m", "nan"),
    ("--diameter-in", "inf"), ("--motor-poles", "3"),
])
def test_an_option_out_of_range_is_refused_naming_it(tmp_path, log_file, cli_runner, option,
                                                     value):
    out = tmp_path / "p.yaml"
    args = [option, value] if option.startswith("--diameter") else [*BASE, option, value]
    _refused(_run(cli_runner, log_file, *args, "--out", out), option)
    assert not out.exists()


@pytest.mark.parametrize("kind, needle", [("folder", "is a directory"),
                                          ("fifo", "not a regular file"),
                                          ("/dev/zero", "not a regular file")])
def test_a_log_that_is_not_a_file_is_said_to_be_so(tmp_path, cli_runner, kind, needle):
    if kind == "folder":
        path = tmp_path / "logs"
        path.mkdir()
    elif kind == "fifo":
        if not hasattr(os, "mkfifo"):
            pytest.skip("no FIFOs here")
        path = tmp_path / "pipe.csv"
        os.mkfifo(path)
    else:
        path = Path(kind)
        if not path.exists():
            pytest.skip("no /dev/zero here")
    line = _refused(_run(cli_runner, path, *BASE), path.name, needle)
    assert "not found" not in line


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX links")
def test_the_log_is_untouched_by_a_forced_run_elsewhere(tmp_path, log_file, cli_runner):
    """The control: the same command with a fresh --out writes it and leaves the log alone."""
    log = _copy(log_file, tmp_path)
    before = log.read_bytes()
    r = _run(cli_runner, log, *BASE, "--out", tmp_path / "p.yaml", "--force")
    assert r.exit_code == 0 and (tmp_path / "p.yaml").read_text().startswith("# propulsion")
    assert log.read_bytes() == before
