"""The generated references of the documentation (``docs/hooks/reference.py``): every key of every
YAML schema has a description, and the generated pages hold every key and every command, with the
unit and bounds the schema states (oracles: the pydantic models' own fields and the typer app's
own command list, read directly)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def reference():
    spec = importlib.util.spec_from_file_location("docs_reference",
                                                  ROOT / "docs" / "hooks" / "reference.py")
    module = importlib.util.module_from_spec(spec)
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


def test_performance_summary_is_gathered_from_the_result_files(reference, tmp_path):
    """The summary table is the rows of the result files' ``## Summary`` sections, in the order
    of benchmarks/collect.py (a file it does not list comes after, by name); a file without one
    adds nothing; each file's section leaves its body on the page (it is in the summary)."""
    rule = "| what | figure | command |\n|---|---|---|\n"
    (tmp_path / "RESULTS-zzz.md").write_text(
        "# later\n\nbody z\n\n## Summary\n\n" + rule + "| z | 3 s | `z` |\n")
    (tmp_path / "RESULTS-design.md").write_text(
        "# design\n\nbody d\n\n## Summary\n\nprose\n\n" + rule + "| d | 1 ms | `d` |\n"
        "| d2 | 2 ms | `d2` |\n\n## Afterwards\n\nkept\n")
    (tmp_path / "RESULTS-lap.md").write_text("# lap\n\nno summary here\n")
    table = reference.benchmark_summary(tmp_path).splitlines()
    assert table[2:] == ["| d | 1 ms | `d` |", "| d2 | 2 ms | `d2` |", "| z | 3 s | `z` |"]
    body, rows = reference._split_summary((tmp_path / "RESULTS-design.md").read_text())
    assert "## Summary" not in body and "1 ms" not in body and "kept" in body
    assert len(rows) == 2


#: The result files that give the performance summary its rows (a re-run benchmark that writes
#: its file afresh must write its summary again: benchmarks/README.md).
SUMMARISED = ("design", "lap", "sensitivity", "evmoga", "limitlap", "trimstudy", "coordinator",
              "replay", "paper-scale")


def test_performance_page_has_no_hand_copied_summary(reference):
    """docs/performance.md holds the marker, not a table of figures; each summarised result
    file gives the summary at least one row, and every row has its three cells."""
    page = (ROOT / "docs" / "performance.md").read_text(encoding="utf-8")
    assert "<!-- generated: benchmark-summary -->" in page
    assert "| what | figure | command |" not in page
    for name in SUMMARISED:
        text = (ROOT / "benchmarks" / f"RESULTS-{name}.md").read_text(encoding="utf-8")
        rows = reference._split_summary(text)[1]
        assert rows, f"benchmarks/RESULTS-{name}.md has no ## Summary rows"
        assert all(row.count(" | ") == 2 for row in rows), rows
