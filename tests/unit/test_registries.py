"""Extension points: a new export format, trim solver or integrator is one registry entry and its
implementation; the API and the CLI take it with no other change."""

from __future__ import annotations

import importlib

import numpy as np
import pytest
import typer

from casadrone import export as export_mod
from casadrone.cli import app
from casadrone.trim import TRIM_SOLVERS

#: the modules (``casadrone.simulate`` and ``casadrone.trim`` are also the stage functions)
simulate_mod = importlib.import_module("casadrone.simulate")


@pytest.fixture
def registered(monkeypatch):
    """Add ``name: value`` to a registry for one test."""

    def add(registry: dict, name: str, value) -> None:
        monkeypatch.setitem(registry, name, value)

    return add


def test_a_new_export_format_reaches_the_api_and_the_cli(registered, cli_runner, tmp_path):
    def names(src, _options) -> str:  # a format that lists the rotor labels, one a line
        return "".join(f"{label}\n" for label in ("FR", "FL", "RL", "RR"))

    registered(export_mod.FORMATS, "rotors", export_mod.ExportFormat(".txt", "rotor labels", names))
    result = cli_runner.invoke(app, ["export", "SY250", "--format", "rotors"])
    assert result.exit_code == 0, result.output
    assert result.stdout == "FR\nFL\nRL\nRR\n"
    from casadrone.export.source import source_of

    src = source_of("SY250", None, None)
    assert export_mod.default_name(src, "rotors") == "SY250-rotors.txt"


def test_a_new_trim_solver_reaches_trim_and_the_cli(registered, cli_runner):
    calls = []

    def newton_again(z0, p, op, o):  # the newton solver under another name, counted
        calls.append(1)
        return TRIM_SOLVERS["newton"](z0, p, op, o)

    registered(TRIM_SOLVERS, "newton-again", newton_again)
    from casadrone.airframe import build_airframe
    from casadrone.config.airframe import load_airframe

    trim_module = importlib.import_module("casadrone.trim")
    frame = build_airframe(load_airframe("SY250"))
    mine = trim_module.trim(frame, "hover", solver="newton-again")
    ref = trim_module.trim(frame, "hover", solver="newton")
    assert calls and mine.success and mine.solver == "newton-again"
    assert np.array_equal(mine.x0, ref.x0)  # the same solver: the same point, to the bit
    result = cli_runner.invoke(app, ["trim", "SY250", "--solver", "newton-again", "--json"])
    assert result.exit_code == 0, result.output
    assert '"solver": "newton-again"' in result.stdout


def test_a_new_integrator_is_a_cli_and_problem_choice(registered):
    registered(simulate_mod.INTEGRATORS, "rk4-chunked", simulate_mod.INTEGRATORS["rk4"])
    group = typer.main.get_command(app)
    parent = group.make_context("casadrone", ["simulate"], resilient_parsing=True)
    command = group.get_command(parent, "simulate")
    ctx = command.make_context("simulate", ["SY250", "--integrator", "rk4-chunked"],
                               parent=parent)
    assert ctx.params["integrator"] == "rk4-chunked"
    from casadrone.config.problem import read_problem
    from casadrone.optimise.checks import problem_problems

    problem = read_problem("quick", ["integrator=rk4-chunked"])
    assert not [k for k, _ in problem_problems(problem) if k == "integrator"]
    problem = read_problem("quick", ["integrator=euler"])
    assert [k for k, _ in problem_problems(problem) if k == "integrator"] == ["integrator"]
