"""The CLI's help: every command ends its --help with examples that its own parser accepts, flags
show and parse as flags, and the choices of registry options are the registries' names."""

from __future__ import annotations

import shlex

import pytest
import typer

from casadrone.cli import app
from casadrone.cli.common import command_name
from casadrone.cli.examples import EXAMPLES

GROUP = typer.main.get_command(app)
COMMANDS = [command_name(c) for c in app.registered_commands]


def context(line: str):
    """Parse a ``casadrone ...`` command line with the command's own parser (nothing runs)."""
    words = shlex.split(line)
    assert words[0] == "casadrone"
    parent = GROUP.make_context("casadrone", words[1:2], resilient_parsing=True)
    command = GROUP.get_command(parent, words[1])
    assert command is not None, f"no command {words[1]!r}"
    return command.make_context(words[1], words[2:], parent=parent)


def test_every_command_has_examples_and_only_commands_have_them():
    assert set(COMMANDS) == set(EXAMPLES)
    assert all(1 <= len(EXAMPLES[c]) <= 2 for c in COMMANDS)


@pytest.mark.parametrize("command", COMMANDS)
def test_help_ends_with_the_examples(cli_runner, command):
    result = cli_runner.invoke(app, [command, "--help"], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    tail = [line.strip() for line in result.stdout.splitlines() if line.strip()]
    n = len(EXAMPLES[command])
    assert tail[-n - 1:] == ["Examples:", *EXAMPLES[command]]


@pytest.mark.parametrize("line", [e for c in COMMANDS for e in EXAMPLES[c]])
def test_every_example_parses(line):
    # the command's parser (and the registry options' checks) accept it: an example that names a
    # removed option, a bad choice or a missing argument fails here
    ctx = context(line)
    assert ctx.command.name == shlex.split(line)[1]


def test_an_example_with_a_bad_option_would_fail():
    with pytest.raises(Exception, match="--no-such-option"):
        context("casadrone simulate SY250 --no-such-option")
    with pytest.raises(Exception, match="unknown integrator 'euler'"):
        context("casadrone simulate SY250 --integrator euler")


def test_flags_show_and_parse_as_flags(cli_runner):
    result = cli_runner.invoke(app, ["simulate", "--help"], env={"COLUMNS": "200"})
    json_line = next(line for line in result.stdout.splitlines() if "--json" in line)
    assert "<bool>" not in json_line and "print one JSON object" in json_line
    assert context("casadrone validate SY250 --json").params["as_json"] is True
    assert context("casadrone validate SY250").params["as_json"] is False


def test_registry_options_take_the_registries_names():
    from casadrone.export import FORMATS
    from casadrone.simulate import INTEGRATORS
    from casadrone.trim import TRIM_SOLVERS

    for name in INTEGRATORS:
        assert context(f"casadrone simulate SY250 --integrator {name}").params["integrator"] == name
    for name in TRIM_SOLVERS:
        assert context(f"casadrone trim SY250 --solver {name}").params["solver"] == name
    for name in FORMATS:
        assert context(f"casadrone export SY250 --format {name}").params["fmt"] == name
