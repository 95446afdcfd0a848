"""The CLI's help: every command ends its --help with examples that its own parser accepts, flags
show and parse as flags, and the choices of registry options are the registries' names."""

from __future__ import annotations

import re
import shlex
import textwrap

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


# --- the help as read at 80 columns ------------------------------------------------------------

#: The terminal width the help is read at (a terminal's default).
COLUMNS = 80
#: What ends a sentence or a clause a line may end on.
TERMINAL = ".:;!?"


def help_at(cli_runner, args: list[str], columns: int = COLUMNS) -> str:
    result = cli_runner.invoke(app, [*args, "--help"], env={"COLUMNS": str(columns)})
    assert result.exit_code == 0, result.output
    return result.stdout


def _last_chunk_start(inner: str) -> int:
    """Where the last text of a panel row starts after a gap of two or more spaces (its help
    column when the row has help text; 0 when the row is one chunk)."""
    starts = [m.end() for m in re.finditer(r" {2,}(?=\S)", inner)]
    return starts[-1] if starts else 0


def paragraphs(text: str) -> list[tuple[list[str], int]]:
    """The paragraphs of a rendered help and the width each was wrapped to (a lower bound):
    the text outside the panels (split at blank lines; the terminal's width less rich's one
    column each side) and, in each panel (options, arguments, commands), each row's help column
    (its width bounded by the widest line seen in that column). A panel row's ``[default: …]``
    or ``[required]`` line is a separate item, not part of the paragraph."""
    out: list[tuple[list[str], int]] = []
    lines = text.splitlines()
    i = 0
    current: list[str] = []
    while i < len(lines):
        line = lines[i].rstrip()
        if line.startswith("╭"):
            if current:
                out.append((current, COLUMNS - 2))
                current = []
            j = i + 1
            while not lines[j].startswith("╰"):
                j += 1
            out += _panel_paragraphs([row.rstrip()[1:-1] for row in lines[i + 1:j]])
            i = j + 1
            continue
        if line.strip():
            current.append(line.strip())
        elif current:
            out.append((current, COLUMNS - 2))
            current = []
        i += 1
    if current:
        out.append((current, COLUMNS - 2))
    return out


def _panel_paragraphs(rows: list[str]) -> list[tuple[list[str], int]]:
    column = max(_last_chunk_start(r) for r in rows)
    cells = [(r[:column].strip() == "", r[column:].strip()) for r in rows]
    width = max(len(c) for _, c in cells)
    out: list[list[str]] = []
    for continued, cell in cells:
        if continued and out and cell and not cell.startswith("["):
            out[-1].append(cell)
        elif cell:
            out.append([cell])
    return [(p, width) for p in out]


def broken_lines(text: str) -> list[str]:
    """Lines broken mid-sentence: a line of a paragraph that ends without terminal punctuation
    although the next line's first word would have fitted on it. A wrapper that fills lines
    (rich's, textwrap's) never breaks there, so such a break is a line break written into the
    help text, which the terminal shows at another width as a short line mid-sentence."""
    found = []
    for lines, width in paragraphs(text):
        for this, following in zip(lines, lines[1:], strict=False):
            word = following.split()[0]
            if this[-1] not in TERMINAL and len(this) + 1 + len(word) <= width:
                found.append(f"{this!r} / {following!r}")
    return found


def test_the_broken_line_check_finds_a_written_break_and_passes_a_filled_paragraph():
    # an independent wrapper (textwrap fills lines greedily, as rich does) gives no finding;
    # the same text with a line break written mid-sentence gives one
    words = ("Prints the lap time, the point-mass reference (attitude dynamics removed; the best "
             "of a few local optima of that relaxation, not a bound), split and lap times.")
    filled = textwrap.fill(words, COLUMNS - 2)
    assert broken_lines(filled) == []
    broken = words.replace("best of a few ", "best of a few\n", 1)
    assert broken_lines(textwrap.fill(broken, COLUMNS - 2, replace_whitespace=False)) != []


HELPS = [[], *[[c] for c in COMMANDS]]


@pytest.mark.parametrize("args", HELPS, ids=lambda a: a[0] if a else "casadrone")
def test_help_reads_at_80_columns(cli_runner, args):
    text = help_at(cli_runner, args)
    assert broken_lines(text) == []
    # rich crops a word too long for its column with "…" (a default path was cut so)
    assert "…" not in text
    assert max(len(line.rstrip()) for line in text.splitlines()) <= COLUMNS


@pytest.mark.parametrize("command", COMMANDS)
def test_one_examples_block_each_example_on_one_line(cli_runner, command):
    lines = [line.strip() for line in help_at(cli_runner, [command]).splitlines()]
    assert lines.count("Examples:") == 1
    for example in EXAMPLES[command]:
        assert example in lines, f"{example!r} is not one whole line at {COLUMNS} columns"


def test_the_top_level_help_names_every_command(cli_runner):
    # the description (above the panels) names each command, not only the commands panel
    text = help_at(cli_runner, [])
    description = " ".join(text.split("╭")[0].split()[1:])
    missing = [c for c in COMMANDS if not re.search(rf"(?<![\w-]){re.escape(c)}(?![\w-])",
                                                     description)]
    assert missing == []


def test_the_defaults_shown_are_the_shipped_defaults():
    # the names --help shows for --track and --controller resolve to the files the commands use
    # without the option
    from casadrone.cli.common import DEFAULT_CONTROLLER_NAME, DEFAULT_TRACK_NAME
    from casadrone.config.controller import load_controller
    from casadrone.config.io import load, resolve_config
    from casadrone.config.track import DEFAULT_TRACK, TrackConfig

    assert resolve_config(DEFAULT_TRACK_NAME, "tracks") == DEFAULT_TRACK
    assert load(TrackConfig, DEFAULT_TRACK).name == DEFAULT_TRACK_NAME
    assert load_controller(None) == load_controller(DEFAULT_CONTROLLER_NAME)


#: Solver internals and benchmark figures that belong in the docs, not in an option's help.
INTERNALS = ("CVODES", "ε", "reduced gradient", "ETDRK4", "Riccati", "benchmarks/", "0.69x")


@pytest.mark.parametrize("args", HELPS, ids=lambda a: a[0] if a else "casadrone")
def test_help_speaks_plainly(cli_runner, args):
    text = " ".join(help_at(cli_runner, args, columns=200).split())
    assert [w for w in INTERNALS if w in text] == []
