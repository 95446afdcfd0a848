"""What is known to be wrong before any work is bad input, said in one line that tells what to do
(issue 20, points 3, 5, 7 and 8): a gate no limit lap can pass, sizes beyond their documented
ceilings, parts placed off the airframe, an empty front, a full disk mid-run, a problem given
for an airframe, ``gates: []`` and ``validate FILE key=value``."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from casadrone.cli import app
from casadrone.config.io import DATA_DIR, ConfigError
from casadrone.optimise.checks import load_problem

TRACKS = DATA_DIR / "configs" / "tracks"
PROBLEMS = DATA_DIR / "problems"


def cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def one_line_exit_2(result) -> str:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.splitlines()
    assert len(lines) >= 1
    return lines[0]


@pytest.fixture
def narrow_track(tmp_path) -> Path:
    """The MultiGP track with its first gate 0.2 m wide: less than twice the limit lap's 0.15 m
    clearance, so no limit lap can pass it (the clearance is a property of every lap)."""
    text = (TRACKS / "multigp-cdra-gates.yaml").read_text()
    first = "width_m: 1.524, height_m: 1.524}      # 1\n"
    assert first in text
    path = tmp_path / "narrow.yaml"
    path.write_text(text.replace(first, "width_m: 0.2, height_m: 0.2}      # 1\n", 1))
    return path


# --------------------------------------------------------------------------------------------
# 3. a problem that cannot produce a front: exit 2 at validate and at run
# --------------------------------------------------------------------------------------------


def narrow_problem(tmp_path: Path, track: Path) -> Path:
    text = (PROBLEMS / "limit-lap.yaml").read_text()
    lines = [f"track: {track}" if line.startswith("track:") else line
             for line in text.splitlines()]
    assert f"track: {track}" in lines and "J3_limit" in text
    path = tmp_path / "narrow-problem.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_gate_no_limit_lap_can_pass_fails_validate_and_run(tmp_path, narrow_track):
    problem = narrow_problem(tmp_path, narrow_track)
    for args in (["validate", problem], ["run", problem, "--out", tmp_path / "out"]):
        line = one_line_exit_2(cli(*args))
        assert line.startswith(f"{problem}: track: gate 1: opening 0.2 x 0.2 m is not wider "
                               "than twice the clearance")
        assert "J3_limit" in line
    assert not (tmp_path / "out").exists()


def test_the_same_track_without_a_limit_index_is_accepted(tmp_path, narrow_track):
    problem = narrow_problem(tmp_path, narrow_track)
    text = problem.read_text().replace("J3_limit", "J3")
    problem.write_text(text)
    load_problem(problem)  # the closed loop flies through gate centres: no clearance needed


def test_limit_lap_on_an_impassable_gate_is_bad_input(narrow_track):
    line = one_line_exit_2(cli("limit-lap", "SY250", "--track", narrow_track))
    assert line.startswith(f"{narrow_track}: gate 1: opening 0.2 x 0.2 m")


# --------------------------------------------------------------------------------------------
# 5. size options have ceilings
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("args", [
    ["limit-lap", "SY250", "--intervals", "10000000"],
    ["limit-lap", "SY250", "--intervals", "401"],
    ["validate", "quick", "algorithm.population=10000000"],
    ["validate", "quick", "algorithm.generations=1000000000"],
    ["validate", "quick", "algorithm.settings.n_ind_ga=100000000"],
    ["validate", "quick", "algorithm.settings.n_div=100000000"],
])
def test_sizes_beyond_their_ceilings_exit_2(args):
    result = cli(*args)
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert any(c in result.stderr for c in ("400", "10000", "100000"))


def test_the_limit_lap_refuses_too_many_intervals_through_the_api_too():
    from casadrone.config.io import load
    from casadrone.config.track import TrackConfig
    from casadrone.limit.lap import MAX_INTERVALS, LimitLapOptions, check_inputs

    track = load(TrackConfig, TRACKS / "paper-rectangle.yaml")
    assert check_inputs(track, LimitLapOptions(intervals=MAX_INTERVALS)) == ""
    assert "intervals must be 2…400" in check_inputs(track, LimitLapOptions(intervals=10**7))


def test_the_ceilings_admit_the_papers_budget():
    for name in ("paper-run1", "paper-run2"):  # 850 individuals, 350 generations, 200 divisions
        load_problem(name)


# --------------------------------------------------------------------------------------------
# 7. parts have physical ceilings
# --------------------------------------------------------------------------------------------


@pytest.mark.parametrize("override", [
    "components.battery_position_mm=[1000000, 0, 0]",  # a battery 1 km from the hub
    "components.body_size_mm=[90, 45, 1e8]",
    "components.battery_mass_kg=5000",
])
def test_parts_off_the_airframe_are_refused(override):
    key = override.partition("=")[0]
    line = one_line_exit_2(cli("massprops", "SY250-components", override))
    assert key in line and "less than or equal" in line


def test_parts_within_the_ceilings_still_compute():
    result = cli("massprops", "SY250-components", "components.battery_position_mm=[40, 0, 45]",
                 "--json")
    assert result.exit_code == 0, result.output


# --------------------------------------------------------------------------------------------
# 8. messages that say what to do
# --------------------------------------------------------------------------------------------


def test_a_problem_given_for_an_airframe_is_named_as_one():
    problem = PROBLEMS / "quick.yaml"
    result = cli("massprops", problem)
    assert result.stderr.splitlines() == [f"{problem}: this is a problem, not an airframe; give "
                                          "an airframe here (a YAML file or a shipped name)"]
    assert result.exit_code == 2


def test_empty_gates_are_named(tmp_path):
    path = tmp_path / "tracks" / "empty.yaml"
    path.parent.mkdir()
    path.write_text("name: empty\ngates: []\nstraight: []\n")
    result = cli("validate", path)
    assert result.exit_code == 2
    assert f"{path}: gates: give at least one gate" in result.stderr
    assert "required key missing" not in result.stderr


def test_validate_takes_overrides_as_the_readme_shows():
    result = cli("validate", "SY250", "izz_kgm2=0.0045")
    assert result.exit_code == 2
    assert "izz_kgm2: Ixx + Iyy ≥ Izz violated" in result.stderr
    assert "file not found" not in result.stderr
    assert cli("validate", "SY250", "izz_kgm2=0.0036").exit_code == 0


def test_default_variables_on_a_components_airframe_name_the_default(tmp_path):
    path = tmp_path / "comp.yaml"
    path.write_text("name: comp\nairframe: SY250-components\nobjectives:\n  - {index: J1}\n")
    with pytest.raises(ConfigError) as err:
        load_problem(path)
    (line,) = err.value.lines
    assert line.startswith(f"{path}: variables: not given, so the default (paper Table 1)")
    assert "variables.4" not in line


def test_an_empty_front_is_said_plainly(tmp_path):
    from tests.unit.test_cli import make_run_dir  # a finished run directory, written directly

    run = make_run_dir(tmp_path / "run")
    header = (run / "pareto.csv").read_text().splitlines()[0]
    (run / "pareto.csv").write_text(header + "\n")
    for args in (["export", run, "--candidate", "0"], ["export", run, "--candidate", "A"],
                 ["decide", run]):
        line = one_line_exit_2(cli(*args))
        assert "the Pareto front is empty" in line and "0..-1" not in line


def test_a_full_disk_mid_run_names_the_file_the_cause_and_resume(tmp_path, monkeypatch):
    from casadrone.rundir import store as store_mod

    real = store_mod.RunStore.write_checkpoint

    def full(self, data):
        if (self.path / "history.sqlite").exists() and self.generations():
            raise OSError(28, "No space left on device", str(self.path / ".checkpoint.pkl.tmp"))
        return real(self, data)

    monkeypatch.setattr(store_mod.RunStore, "write_checkpoint", full)
    out = tmp_path / "run"
    line = one_line_exit_2(cli("run", "quick", "algorithm.population=12",
                               "algorithm.generations=2", "algorithm.settings.n_ind_ga=6",
                               "--backend", "serial", "--quiet", "--out", out))
    assert line.startswith(f"{out / '.checkpoint.pkl.tmp'}: No space left on device")
    assert "the disk is full" in line and line.endswith(f"casadrone resume {out}")
    monkeypatch.undo()
    resumed = cli("resume", out, "--quiet")  # and it does continue
    assert resumed.exit_code == 0, resumed.output
    assert (out / "pareto.csv").is_file()
