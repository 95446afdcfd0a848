"""The limit lap's settings, declared once (casadrone.config.limitlap.LimitLapConfig): every key
is in ``casadrone limit-lap --help`` and in the YAML reference (a problem file's ``limit_lap:``),
an option and its ``key=value`` give the same options, and a bad value is refused naming the key
before any solve. The oracles are the schema's own fields (enumerated, never listed here), the
help and reference pages as a user reads them, and the options the command hands the limit lap
(recorded by a stand-in for the solve)."""

from __future__ import annotations

import importlib.util
import re
import sys
from pathlib import Path

import pytest

from casadrone.config.limitlap import LimitLapConfig, choices

ROOT = Path(__file__).resolve().parents[2]
KEYS = list(LimitLapConfig.model_fields)
#: the option of each key (typer's rule: the key, dashed); ``search`` is the ``--certify`` flag
#: and ``starts`` (a list) is a key=value argument only
OPTIONS = {k: f"--{k.replace('_', '-')}" for k in KEYS if k not in ("search", "starts")}


def _help(cli_runner) -> str:
    from casadrone.cli import app

    r = cli_runner.invoke(app, ["limit-lap", "--help"], env={"COLUMNS": "400"})
    assert r.exit_code == 0, r.output
    return " ".join(r.stdout.replace("│", " ").split())


def test_every_key_is_in_the_commands_help(cli_runner):
    text = _help(cli_runner)
    listed = re.search(r"settings: ([\w, ]+) \(each also an option", text)
    assert listed is not None, text
    assert listed.group(1).split(", ") == KEYS
    for key, option in OPTIONS.items():
        # the option is there, with the schema's description as its help
        description = " ".join(str(LimitLapConfig.model_fields[key].description).split())
        assert re.search(rf"{option}\b", text), option
        assert description in text, key
    assert "--certify" in text and "search=certify" in text


def test_every_key_is_in_the_yaml_reference():
    spec = importlib.util.spec_from_file_location("docs_reference_lap",
                                                  ROOT / "docs" / "hooks" / "reference.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    page = module.yaml_reference()
    for key in KEYS:
        assert f"| `limit_lap.{key}` |" in page, key


def test_the_keys_are_not_the_airframes():
    # a key=value argument of limit-lap goes to the limit lap or to the airframe by its key
    from casadrone.config.airframe import AirframeConfig

    assert set(KEYS).isdisjoint(AirframeConfig.model_fields)


def test_the_limit_laps_types_are_the_schemas():
    """One declaration: the limit lap's and the problem file's choices are the schema's."""
    from casadrone.config import limitlap
    from casadrone.config.codesign import LapStart
    from casadrone.config.problem import ProblemConfig
    from casadrone.limit import result

    for name in ("Start", "Attitude", "TiltLimit", "Resimulation", "Solver", "RotorStep"):
        assert getattr(result, name) is getattr(limitlap, name), name
    assert LapStart is limitlap.Start
    assert ProblemConfig.model_fields["limit_lap"].annotation is LimitLapConfig


def test_defaults_are_the_fast_path():
    """The settings' defaults give the options the command flew before its settings were a
    schema (typed in: the fast path's shipped laps, the two grid-continuation starts where those
    give no lap, no rounds, IPOPT, RK4 with
    3 steps, Euler angles, the axes tilt limit, the whole lap re-simulated)."""
    from casadrone.limit.result import LimitLapOptions
    from casadrone.limit.search import lap_options

    o = lap_options(LimitLapConfig(), periodic=False)
    assert (o.starts, o.grid_rounds, o.solver) == (("library",), 0, "ipopt")
    assert o.fallback_starts == ("coarse-grid", "fine-grid")
    assert (o.intervals, o.substeps, o.rotor_step) == (None, 3, "rk4")
    assert (o.attitude, o.tilt_limit, o.resimulation) == ("euler", "axes", "lap")
    library = LimitLapOptions()
    assert (library.substeps, library.rotor_step, library.attitude, library.tilt_limit,
            library.resimulation) == (3, "rk4", "euler", "axes", "lap")
    certify = lap_options(LimitLapConfig(search="certify", starts=("fine-grid",)), False)
    assert certify.starts == ("fine-grid",) and certify.grid_rounds == 3
    assert certify.fallback_starts == ()  # the starts a user names are the only ones


@pytest.fixture
def recorded(monkeypatch):
    """The options ``casadrone limit-lap`` hands the solve (which is not run)."""
    import casadrone.limit.race as race_module
    from casadrone.limit.result import LimitLap

    seen = []

    def fake(cfg, track, options, seeds=None, frame=None, pool=None):
        seen.append(options)
        return LimitLap(status="failed", reason="not solved: the options were recorded")

    monkeypatch.setattr(race_module, "design_limit_lap", fake)
    return seen


#: a value of each key other than its default, as the option and as key=value take it
OTHER = {"intervals": "30", "attitude": "quaternion", "tilt": "cone", "solver": "fatrop",
         "grid_rounds": "2", "rotor_step": "exponential", "substeps": "4",
         "resimulation": "legs"}


def test_options_and_keys_give_the_same_options(cli_runner, recorded):
    from casadrone.cli import app

    assert set(OTHER) == set(OPTIONS)
    as_options = [w for k, v in OTHER.items() for w in (OPTIONS[k], v)] + ["--certify"]
    as_keys = [f"{k}={v}" for k, v in OTHER.items()] + ["search=certify"]
    for args in (as_options, as_keys):
        r = cli_runner.invoke(app, ["limit-lap", "SY250", "--json", *args])
        assert r.exit_code == 0, r.output
    by_option, by_key = recorded
    assert by_option == by_key
    assert (by_key.intervals, by_key.attitude, by_key.tilt_limit, by_key.solver,
            by_key.grid_rounds, by_key.rotor_step, by_key.substeps, by_key.resimulation) == (
        30, "quaternion", "cone", "fatrop", 2, "exponential", 4, "legs")
    assert len(by_key.starts) == 5  # certify: the cold starts but one, the library


@pytest.mark.parametrize("key", [k for k in KEYS if choices(k) or k == "starts"])
def test_a_bad_value_is_refused_naming_the_key(cli_runner, recorded, key):
    from casadrone.cli import app

    value = "[no-such-start]" if key == "starts" else "no-such-choice"
    r = cli_runner.invoke(app, ["limit-lap", "SY250", f"{key}={value}", "--json"])
    assert r.exit_code == 2 and "Traceback" not in r.output and recorded == []
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"limit-lap: {key}"), lines
    if key in OPTIONS:  # and as an option, naming the option
        r = cli_runner.invoke(app, ["limit-lap", "SY250", OPTIONS[key], value, "--json"])
        assert r.exit_code == 2 and OPTIONS[key] in r.stderr and recorded == []


def test_a_key_given_twice_or_a_bad_combination_is_refused(cli_runner, recorded):
    from casadrone.cli import app

    r = cli_runner.invoke(app, ["limit-lap", "SY250", "--solver", "ipopt", "solver=fatrop"])
    assert r.exit_code == 2 and r.stderr.startswith("limit-lap: solver: given as an option")
    r = cli_runner.invoke(app, ["limit-lap", "SY250", "attitude=quaternion"])
    assert r.exit_code == 2 and r.stderr.startswith("limit-lap: tilt: axes bounds Euler")
    r = cli_runner.invoke(app, ["limit-lap", "SY250", "substeps=0"])
    assert r.exit_code == 2 and r.stderr.startswith("limit-lap: substeps:")
    assert recorded == []


def test_a_run_written_with_limit_solver_still_loads_and_both_names_are_refused():
    """Every run directory written before the ``limit_lap:`` section stores ``limit_solver`` in
    its config.yaml; ``casadrone resume`` reads that file, so the older name must still load (as
    ``limit_lap.solver``), and given beside the new one it is refused naming both."""
    import yaml
    from pydantic import ValidationError

    import casadrone
    from casadrone.config.problem import ProblemConfig

    data = Path(casadrone.__file__).parent / "data"
    quick = yaml.safe_load((data / "problems" / "quick.yaml").read_text(encoding="utf-8"))
    quick |= {"airframe": str(data / "configs/airframes/SY250.yaml"),
              "track": str(data / "configs/tracks/paper-rectangle.yaml")}
    assert ProblemConfig.model_validate(quick).limit_lap.solver is None
    old = {**quick, "limit_solver": "fatrop"}
    assert ProblemConfig.model_validate(old).limit_lap.solver == "fatrop"
    with pytest.raises(ValidationError, match="limit_solver: give limit_lap.solver alone"):
        ProblemConfig.model_validate({**old, "limit_lap": {"solver": "ipopt"}})
