"""Nothing the user owns is overwritten, nothing edited is silently mixed in (issue 20, points 1,
2 and 11).

An export never replaces an existing file without ``--force`` and never writes inside a run
directory (whose files are the run's state); a run refuses to continue, decide, export or report
once a file it depends on differs from the one it was created with, naming that file; exported
files carry no absolute path of the machine that wrote them.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from casadrone.cli import app
from casadrone.config.problem import BackendConfig
from casadrone.optimise.checks import load_problem
from casadrone.optimise.runner import resume, run
from casadrone.rundir.store import InputsChanged, RunStore

QUICK = "problems/quick.yaml"
TINY = ["algorithm.population=12", "algorithm.generations=2", "algorithm.settings.n_ind_ga=6"]
SERIAL = BackendConfig(name="serial")


def cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def stopped(tmp_path_factory) -> Path:
    """A run stopped after its first generation (as if killed), resumable."""
    out = tmp_path_factory.mktemp("owned") / "stopped"
    run(load_problem(QUICK, TINY), out, SERIAL, quiet=True, stop_after=1)
    return out


@pytest.fixture(scope="module")
def finished(tmp_path_factory, stopped) -> Path:
    out = tmp_path_factory.mktemp("owned") / "finished"
    shutil.copytree(stopped, out)
    resume(out, SERIAL, quiet=True)
    return out


# --------------------------------------------------------------------------------------------
# 1. export --out: no overwrite without --force, never inside a run directory, atomic
# --------------------------------------------------------------------------------------------


def test_export_refuses_an_existing_file_and_replaces_it_with_force(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("my notes\n")
    refused = cli("export", "SY250", "--out", notes)
    assert refused.exit_code == 2 and "exists" in refused.stderr and "--force" in refused.stderr
    assert notes.read_text() == "my notes\n"
    forced = cli("export", "SY250", "--out", notes, "--force")
    assert forced.exit_code == 0, forced.output
    assert notes.read_text().startswith("# Betaflight custom motor mix")
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]  # no temporary file left


@pytest.mark.parametrize("target", ["pareto.csv", "inputs/airframe.yaml", "checkpoint.pkl",
                                    "history.sqlite", "A-betaflight.txt", "plots/new.txt"])
def test_export_never_writes_inside_a_run_directory(finished, target):
    path = finished / target
    before = path.read_bytes() if path.exists() else None
    for extra in ([], ["--force"]):
        result = cli("export", "SY250", "--out", path, *extra)
        assert result.exit_code == 2, result.output
        assert "inside the run directory" in result.stderr
    assert (path.read_bytes() if path.exists() else None) == before
    RunStore(finished).check_inputs()  # the run is intact


def test_report_out_refuses_an_existing_file_before_any_work(tmp_path, finished):
    notes = tmp_path / "notes.html"
    notes.write_text("my notes\n")
    refused = cli("report", finished, "--out", notes)
    assert refused.exit_code == 2 and "exists" in refused.stderr and "--force" in refused.stderr
    assert notes.read_text() == "my notes\n"
    assert not (finished / "plots").exists() and not (finished / "report.html").exists()


def test_export_under_a_regular_file_says_so(tmp_path):
    (tmp_path / "file").write_text("x")
    result = cli("export", "SY250", "--out", tmp_path / "file" / "mix.txt")
    assert result.exit_code == 2
    assert f"{tmp_path / 'file'} is a file, not a folder" in result.stderr
    assert "File exists" not in result.stderr


def test_a_full_disk_at_export_names_the_file_and_leaves_nothing(tmp_path, monkeypatch):
    import os

    def full(fd):  # a full disk surfaces at the latest when the data is forced out
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    target = tmp_path / "mix.txt"
    result = cli("export", "SY250", "--out", target)
    monkeypatch.undo()
    assert result.exit_code == 2
    assert result.stderr.startswith(f"{target}: No space left on device")
    assert "free some space" in result.stderr
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------------------
# 2. inputs hashed at creation: an edited one is named, never mixed in
# --------------------------------------------------------------------------------------------

EDITS = {
    "inputs/airframe.yaml": ("mass_kg: 0.32", "mass_kg: 0.40"),
    "inputs/track.yaml": ("paper-rectangle", "paper-rectangle-edited"),
    "inputs/controller.yaml": ("\n", "\n# tuned\n"),
    "inputs/reference_airframe.yaml": ("mass_kg: 0.32", "mass_kg: 0.30"),
    "config.yaml": ("integrator: rk4", "integrator: cvodes"),
}


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, f"{old!r} not in {path}"
    path.write_text(text.replace(old, new, 1))


@pytest.mark.parametrize("name", sorted(EDITS))
def test_resume_after_editing_an_input_is_refused_naming_it(tmp_path, stopped, name):
    out = tmp_path / "run"
    shutil.copytree(stopped, out)
    edit(out / name, *EDITS[name])
    with pytest.raises(InputsChanged, match=f"{out / name}: changed since the run was created"):
        resume(out, SERIAL, quiet=True)
    result = cli("resume", out, "--quiet")
    assert result.exit_code == 2
    assert f"casadrone run {out / 'config.yaml'} --out NEW_DIR" in result.stderr
    assert "pareto.csv" not in {p.name for p in out.iterdir()}  # nothing was run


def test_resume_after_editing_a_plugin_is_refused_naming_it(tmp_path):
    """A plugin is code the run depends on: its source is hashed at creation like an input."""
    import hashlib
    import json

    plugin = tmp_path / "my_plugin.py"
    plugin.write_text("SCALE = 1.0\n")
    out = tmp_path / "run"
    run(load_problem(QUICK, [*TINY, f"plugins=[{plugin}]"]), out, SERIAL, quiet=True,
        stop_after=1)
    recorded = json.loads((out / "manifest.json").read_text())["plugin_hashes"]
    assert recorded == {str(plugin.resolve()): hashlib.sha256(plugin.read_bytes()).hexdigest()}
    RunStore(out).check_inputs()  # unchanged: accepted
    plugin.write_text("SCALE = 2.0\n")
    with pytest.raises(InputsChanged, match=f"{plugin.resolve()}: changed since the run"):
        resume(out, SERIAL, quiet=True)
    assert "pareto.csv" not in {p.name for p in out.iterdir()}  # nothing was run


def test_the_suggested_new_run_reads_the_edited_inputs(tmp_path, stopped):
    out = tmp_path / "run"
    shutil.copytree(stopped, out)
    edit(out / "inputs" / "airframe.yaml", *EDITS["inputs/airframe.yaml"])
    problem = load_problem(out / "config.yaml")  # what 'casadrone run DIR/config.yaml' loads
    airframe = Path(problem.airframe)
    assert not airframe.is_absolute() or airframe.resolve() == (out / "inputs" /
                                                                 "airframe.yaml").resolve()


@pytest.mark.parametrize(("command", "name", "change"), [
    (["decide"], "config.yaml", ("sense: max", "sense: min")),
    (["export", "--candidate", "A"], "inputs/airframe.yaml", EDITS["inputs/airframe.yaml"]),
    (["report"], "inputs/track.yaml", EDITS["inputs/track.yaml"]),
    (["compare"], "inputs/controller.yaml", EDITS["inputs/controller.yaml"]),
])
def test_reading_a_finished_run_with_an_edited_input_is_refused(tmp_path, finished, command,
                                                                name, change):
    out = tmp_path / "run"
    shutil.copytree(finished, out)
    if command[0] == "decide":  # the unedited copy reads (the others take long to run whole)
        assert cli(command[0], out, *command[1:]).exit_code == 0
    edit(out / name, *change)
    result = cli(command[0], out, *command[1:])
    assert result.exit_code == 2, result.output
    assert result.stderr.startswith(f"{out / name}: changed since the run was created")
    assert "Traceback" not in result.output


def test_a_missing_input_is_named(tmp_path, stopped):
    out = tmp_path / "run"
    shutil.copytree(stopped, out)
    (out / "inputs" / "track.yaml").unlink()
    result = cli("resume", out)
    assert result.exit_code == 2 and "inputs/track.yaml" in result.stderr


def test_the_manifest_hashes_every_file_the_run_reads(stopped):
    import hashlib
    import json

    recorded = json.loads((stopped / "manifest.json").read_text())["input_hashes"]
    on_disk = {p.relative_to(stopped).as_posix() for p in (stopped / "inputs").iterdir()}
    assert set(recorded) == on_disk | {"config.yaml"}
    for name, digest in recorded.items():  # an independent SHA-256 of each file
        assert hashlib.sha256((stopped / name).read_bytes()).hexdigest() == digest


# --------------------------------------------------------------------------------------------
# 11. no machine paths in exported files
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("fmt", ["betaflight", "px4", "urdf", "svg", "dxf"])
def test_exports_carry_no_absolute_path(tmp_path, finished, fmt):
    import casadrone

    install = str(Path(casadrone.__file__).resolve().parent.parent)
    for source in (["SY250"], [finished, "--candidate", "B"]):
        result = cli("export", *source, "--format", fmt, "--out", tmp_path / f"x.{fmt}")
        assert result.exit_code == 0, result.output
        text = (tmp_path / f"x.{fmt}").read_text()
        (tmp_path / f"x.{fmt}").unlink()
        assert install not in text and str(finished.parent) not in text
        assert "/tmp/" not in text and "/home/" not in text and "/root/" not in text
