"""The generated references of the documentation (``docs/hooks/reference.py``): every key of every
YAML schema has a description, and the generated pages hold every key and every command, with the
unit and bounds the schema states (oracles: the pydantic models' own fields and the typer app's
own command list, read directly)."""

from __future__ import annotations

import datetime
import importlib.util
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def reference():
    spec = importlib.util.spec_from_file_location("docs_reference",
                                                  ROOT / "docs" / "hooks" / "reference.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # as mkdocs loads a hook (its dataclasses need it)
    spec.loader.exec_module(module)
    return module


def test_every_schema_key_has_a_description(reference):
    missing = [f"{schema.__name__}.{name} ({folder}: {path})"
               for folder, top in reference.top_level_schemas()
               for path, schema, name, field in reference.walk(top)
               if not (field.description or "").strip()]
    assert not missing, "keys without a description (Field(description=...)):\n" + "\n".join(
        missing)


def test_the_walk_reaches_every_nested_schema(reference):
    from pydantic import BaseModel

    for _, top in reference.top_level_schemas():
        walked = {schema for _, schema, _, _ in reference.walk(top)}
        # an independent walk: pydantic's own JSON schema lists every model it contains
        defs = top.model_json_schema(mode="validation").get("$defs", {})
        named = {m.__name__ for m in walked} | {top.__name__}
        assert set(defs) <= named, f"{top.__name__}: not walked: {set(defs) - named}"
        assert all(issubclass(m, BaseModel) for m in walked)


def test_yaml_page_lists_every_key_with_unit_and_bounds(reference):
    page = reference.yaml_reference()
    for _, top in reference.top_level_schemas():
        for name in top.model_fields:
            assert f"| `{name}` |" in page, f"{top.__name__}.{name} missing from the page"
    from casadrone.config.airframe import AirframeConfig

    alpha = AirframeConfig.model_fields["alpha_deg"]
    gt = next(m.gt for m in alpha.metadata if hasattr(m, "gt"))
    lt = next(m.lt for m in alpha.metadata if hasattr(m, "lt"))
    row = next(line for line in page.splitlines() if line.startswith("| `alpha_deg` |"))
    assert f"> {gt:g}" in row and f"< {lt:g}" in row and "| deg |" in row


@pytest.mark.parametrize(("key", "unit"), [("lambda_a_mm", "mm"), ("ixx_kgm2", "kg·m²"),
                                           ("gravity_mps2", "m/s²"), ("time_constant_s", "s"),
                                           ("kappa_m", "m"), ("name", "")])
def test_unit_from_the_key_suffix(reference, key, unit):
    assert reference.unit_of(key) == unit


def test_cli_page_lists_every_command_and_option(reference):
    import typer

    from casadrone.cli import app

    group = typer.main.get_command(app)
    page = reference.cli_reference()
    for name, command in group.commands.items():
        assert f"## `casadrone {name}`" in page
        for param in command.params:
            for opt in getattr(param, "opts", []):
                if opt.startswith("-"):
                    assert f"`{opt}`" in page, f"{name} {opt} missing"


def _machine():
    """benchmarks/machine.py, loaded by path (benchmarks/ is not an installed package)."""
    spec = importlib.util.spec_from_file_location("bench_machine",
                                                  ROOT / "benchmarks" / "machine.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


RESULT_FILES = sorted((ROOT / "benchmarks").glob("RESULTS-*.md"))


def test_every_result_file_opens_with_a_dated_summary(reference):
    """Each ``benchmarks/RESULTS-*.md`` opens with ``## Summary (YYYY-MM-DD)`` under its title
    (read here with a plain look at the first lines, independently of the hook's parser) and
    the hook reads at least one row of what, figure and command from it."""
    assert len(RESULT_FILES) >= 21
    for path in RESULT_FILES:
        lines = path.read_text(encoding="utf-8").splitlines()
        assert lines[0].startswith("# ") and lines[1] == "", path.name
        match = re.fullmatch(r"## Summary \((\d{4})-(\d{2})-(\d{2})\)", lines[2])
        assert match, f"{path.name}: line 3 is {lines[2]!r}"
        datetime.date(*map(int, match.groups()))  # a real date
        summary = reference.opening_summary("\n".join(lines), path.name)
        assert summary.rows and summary.date == "-".join(match.groups())
        assert summary.title == lines[0][2:]


GOOD = "# T\n\n## Summary (2026-12-01)\n\n| what | figure | command |\n|---|---|---|\n" \
       "| a | 1 s | `cmd` |\n\n## Details\n\nbody\n"


@pytest.mark.parametrize(("text", "words"), [
    ("# T\n\nbody\n\n## Summary (2026-12-01)\n\n| what | figure | command |\n|---|---|---|\n"
     "| a | 1 s | `cmd` |\n", "not followed by"),  # the summary last, as before
    (GOOD.replace(" (2026-12-01)", ""), "not followed by"),  # undated
    (GOOD.replace("2026-12-01", "2026-13-01"), "not a date"),
    (GOOD.replace("| what | figure | command |\n|---|---|---|\n| a | 1 s | `cmd` |\n", "prose\n"),
     "no table"),
    (GOOD.replace("| a | 1 s | `cmd` |\n", ""), "no row"),
    (GOOD.replace("| a | 1 s | `cmd` |", "| a | 1 s |"), "three cells"),
    (GOOD.replace("`cmd`", "cmd"), "three cells"),
    (GOOD.replace("|---|---|---|\n", ""), "no rule"),
    (GOOD.replace("# T\n", "T\n"), "title"),
])
def test_a_result_file_without_its_opening_summary_is_refused(reference, text, words):
    with pytest.raises(ValueError, match=words) as err:
        reference.opening_summary(text, "benchmarks/RESULTS-x.md")
    assert str(err.value).startswith("benchmarks/RESULTS-x.md: ")


def test_the_summary_the_benchmarks_write_is_the_one_the_page_reads(reference):
    """benchmarks/machine.py's ``with_summary`` (what the benchmark scripts call) puts the
    summary where the hook reads it, with the given date, keeping the body after it."""
    machine = _machine()
    rows = [("trim, one core", "3.4 ms", "`python benchmarks/bench_design.py`"),
            ("lap, a pipe escaped", "2 \\| 3", "`x`")]
    text = machine.with_summary("# Design\n\nbody line\n\n## Tables\n\nrow\n", rows,
                                "2026-12-05")
    summary = reference.opening_summary(text, "RESULTS-design.md")
    assert (summary.name, summary.title, summary.date) == ("design", "Design", "2026-12-05")
    assert summary.rows == tuple(f"| {a} | {b} | {c} |" for a, b, c in rows)
    assert text.endswith("body line\n\n## Tables\n\nrow\n")
    today = reference.opening_summary(machine.with_summary("# D\n", rows[:1]), "x").date
    assert today == datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d")


def test_performance_page_gathers_every_summary_in_order_and_links_each_file(reference,
                                                                             tmp_path):
    """The page is every file's opening summary, in the chain's order (a file the order does not
    name comes after, by name), each linked to its own page; a file without its summary fails."""
    (tmp_path / "RESULTS-zzz.md").write_text(GOOD.replace("# T", "# later").replace("`cmd`", "`z`"))
    (tmp_path / "RESULTS-design.md").write_text(GOOD.replace("# T", "# design")
                                                .replace("| what", "prose d\n\n| what"))
    (tmp_path / "RESULTS-lap.md").write_text(GOOD.replace("# T", "# lap").replace("1 s", "2 s"))
    page = reference.benchmark_summary(tmp_path)
    headings = [ln for ln in page.splitlines() if ln.startswith("### ")]
    assert headings == ["### [design](performance/design.md)", "### [lap](performance/lap.md)",
                        "### [later](performance/zzz.md)"]
    assert "prose d" in page and "| a | 2 s | `cmd` |" in page and "| a | 1 s | `z` |" in page
    assert "body" not in page  # the details stay on each file's own page
    (tmp_path / "RESULTS-bad.md").write_text("# bad\n\nno summary\n")
    with pytest.raises(ValueError, match="RESULTS-bad.md"):
        reference.benchmark_summary(tmp_path)


def test_performance_page_is_the_summaries_not_the_files(reference):
    """docs/performance.md holds the marker, not a table of figures; the generated page is a
    small part of the result files (it was all of them: 225 000 px), and each file's own page
    holds the whole file and links back."""
    page = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    assert "<!-- generated: benchmark-summary -->" in page
    assert "| what | figure | command |" not in page
    summary = reference.benchmark_summary()
    whole = sum(len(p.read_text(encoding="utf-8")) for p in RESULT_FILES)
    assert len(summary) < whole / 5
    for path in RESULT_FILES:
        assert f"(performance/{path.stem.removeprefix('RESULTS-')}.md)" in summary
    own = reference.results_page(RESULT_FILES[0])
    assert "](../performance.md)" in own
    assert own.count("\n") >= RESULT_FILES[0].read_text(encoding="utf-8").count("\n")


def test_examples_gallery_shows_and_runs_every_example(reference):
    """Every ``examples/*.py`` has its section with its docstring and whole source; each is run
    at build (a markdown-exec block) except those :data:`EXAMPLES_NOT_RUN` names, which say why."""
    page = reference.examples_gallery()
    files = sorted((ROOT / "examples").glob("*.py"))
    assert len(files) >= 5
    for path in files:
        assert f"## `examples/{path.name}`" in page
        source = path.read_text(encoding="utf-8")
        assert source.splitlines()[-1].strip() in page
    runs = re.findall(r'```python exec="on" result="text"\n(.*?)```', page, re.DOTALL)
    assert len(runs) == len(files) - len(reference.EXAMPLES_NOT_RUN)
    assert all("CASADRONE_EXAMPLE_SMALL" in run for run in runs)
    ran = {name for name in (p.name for p in files) if any(repr(name) in run for run in runs)}
    assert ran == {p.name for p in files} - set(reference.EXAMPLES_NOT_RUN)
    for reason in reference.EXAMPLES_NOT_RUN.values():
        assert reason in page
    nav = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    assert "examples.md" in nav
    assert "<!-- generated: examples -->" in (ROOT / "docs" / "examples.md").read_text()
