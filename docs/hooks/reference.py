"""mkdocs hook: the pages written from the code, not by hand.

A page holding one of the markers below gets it replaced, at every build, by text generated from
what the package says now:

- ``<!-- generated: yaml-reference -->``: every key of every YAML schema (pydantic), with its
  type, unit, bounds, default and description, walked from the schemas ``casadrone validate``
  knows, nested sections included;
- ``<!-- generated: cli-reference -->``: every command of the typer app, with its usage, help,
  examples, arguments and options;
- ``<!-- generated: benchmark-summary -->``: the opening summary (what, figure, command; its
  date) of every ``benchmarks/RESULTS-*.md``, each linked to that file's own page: the
  performance page, so its figures are never copied by hand;
- ``<!-- generated: changelog -->``: ``CHANGELOG.md``;
- ``<!-- generated: api-reference -->``: the Python API page (``casadrone._API``);
- ``<!-- generated: examples -->``: the examples gallery, every ``examples/*.py`` with its
  source and what it printed, run at every build.

Each result file also becomes a page of its own (``performance/<name>.md``, :func:`on_files`);
a result file that does not open with its dated summary fails the build.

The same walk over the schemas is what ``tests/unit/test_docs_reference.py`` checks: a key without
a description fails it.
"""

from __future__ import annotations

import ast
import datetime
import html as html_module
import importlib
import inspect
import json
import re
import sys
import types
import typing
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pydantic import BaseModel
from pydantic.fields import FieldInfo

ROOT = Path(__file__).resolve().parents[2]


def _import_from_checkout(name: str) -> types.ModuleType:
    """``name`` imported from the checkout (whatever else is installed), now.

    mkdocs loads a hook with the hook's folder on ``sys.path`` and restores ``sys.path`` after,
    so a path the hook adds does not outlive its loading: what the hook needs from the checkout is
    imported here, at load time (later imports of its submodules follow the package's own
    ``__path__``). Nothing else the hook uses lives outside the installed packages.
    """
    sys.path.insert(0, str(ROOT))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(ROOT))


_import_from_checkout("casadrone")

#: The unit a key's suffix names (the project's rule: units in keys), longest suffix first.
UNIT_SUFFIXES: tuple[tuple[str, str], ...] = (
    ("_rpm_per_v", "rpm/V"), ("_kgm3", "kg/m³"), ("_kgm2", "kg·m²"), ("_kgpm", "kg/m"),
    ("_mps2", "m/s²"), ("_radps", "rad/s"), ("_degps", "deg/s"), ("_mps", "m/s"), ("_ohm", "Ω"),
    ("_deg", "deg"), ("_rad", "rad"), ("_kg", "kg"), ("_mm", "mm"), ("_m2", "m²"), ("_hz", "Hz"),
    ("_pct", "%"), ("_n", "N"), ("_nm", "N·m"), ("_v", "V"), ("_a", "A"), ("_w", "W"),
    ("_s", "s"), ("_m", "m"), ("_g", "g"),
)

#: Where each top-level schema's files live, for the page's headings.
FOLDER_TITLES = {
    "airframes": "Airframes",
    "controllers": "Controllers",
    "tracks": "Tracks",
    "references": "Reference measurements (paper Table 4)",
    "problems": "Problems",
}


# --------------------------------------------------------------------------------------------
# YAML reference
# --------------------------------------------------------------------------------------------


def top_level_schemas() -> list[tuple[str, type[BaseModel]]]:
    """(folder, schema) of every kind of YAML file ``casadrone validate`` knows."""
    for name in ("casadrone.config.validation", "casadrone.validation"):
        try:
            module = importlib.import_module(name)
        except ImportError:
            continue
        if hasattr(module, "SCHEMAS_BY_FOLDER"):
            return [(folder, _schema(entry)) for folder, entry in module.SCHEMAS_BY_FOLDER.items()]
    raise ImportError("no module of casadrone holds SCHEMAS_BY_FOLDER")


def _schema(entry: type[BaseModel] | str) -> type[BaseModel]:
    """A registered schema: the class, or a ``"module:Class"`` string naming it."""
    if isinstance(entry, str):
        module, _, name = entry.partition(":")
        return getattr(importlib.import_module(module), name)
    return entry


def _strip(annotation: Any) -> Any:
    """The annotation without ``Annotated[...]`` metadata."""
    while typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    return annotation


def nested_models(annotation: Any) -> Iterator[tuple[str, type[BaseModel]]]:
    """Schemas inside a field's annotation, with the path step that reaches them (``""`` for the
    field itself, ``"[]"`` for items of a list, ``"{}"`` for values of a mapping)."""
    annotation = _strip(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        yield "", annotation
        return
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin in (list, tuple, set, frozenset) or origin is typing.Sequence:
        for arg in args:
            for step, model in nested_models(arg):
                yield "[]" + step, model
    elif origin is dict or origin is typing.Mapping:
        for step, model in nested_models(args[-1] if args else Any):
            yield "{}" + step, model
    elif origin in (typing.Union, types.UnionType):
        for arg in args:
            yield from nested_models(arg)


def walk(model: type[BaseModel], prefix: str = "",
         seen: tuple[type, ...] = ()) -> Iterator[tuple[str, type[BaseModel], str, FieldInfo]]:
    """Every key of ``model`` and of the schemas nested in it, depth first: (dotted path, the
    schema holding the key, the key, its field)."""
    for name, field in model.model_fields.items():
        path = f"{prefix}{name}"
        yield path, model, name, field
        for step, sub in dict.fromkeys(nested_models(field.annotation)):
            if sub not in seen and sub is not model:
                yield from walk(sub, f"{path}{step}.", (*seen, model))


def unit_of(key: str) -> str:
    """The unit named by the key's suffix (``lambda_a_mm`` → mm), or ``""``."""
    for suffix, unit in UNIT_SUFFIXES:
        if key.endswith(suffix):
            return unit
    return ""


_BOUND_SIGNS = {"gt": ">", "ge": "≥", "lt": "<", "le": "≤"}


def _bounds(metadata: list[Any]) -> list[str]:
    out = []
    for item in metadata:
        if isinstance(item, FieldInfo):
            out += _bounds(item.metadata)
            continue
        for attr, sign in _BOUND_SIGNS.items():
            value = getattr(item, attr, None)
            if value is not None:
                out.append(f"{sign} {value:g}" if isinstance(value, int | float) else
                           f"{sign} {value}")
        for attr, word in (("min_length", "length ≥ {}"), ("max_length", "length ≤ {}")):
            value = getattr(item, attr, None)
            if value is not None:
                out.append(word.format(value))
    return out


def bounds_of(field: FieldInfo) -> str:
    """The field's bounds as text, including those on the items of a tuple or list."""
    own = _bounds(field.metadata)
    inner: list[str] = []
    for arg in typing.get_args(_strip(field.annotation)):
        if typing.get_origin(arg) is typing.Annotated:
            inner = _bounds(list(typing.get_args(arg)[1:]))
            break
    text = ", ".join(own)
    if inner:
        text = ", ".join(filter(None, [text, "each " + ", ".join(inner)]))
    return text


def type_name(annotation: Any) -> str:
    """A short, readable name of a field's type."""
    annotation = _strip(annotation)
    if annotation is type(None):
        return "null"
    if isinstance(annotation, type):
        if issubclass(annotation, BaseModel):
            return "section"
        return {"str": "text", "float": "number", "int": "integer", "bool": "true/false",
                "Path": "path", "PosixPath": "path"}.get(annotation.__name__, annotation.__name__)
    origin, args = typing.get_origin(annotation), typing.get_args(annotation)
    if origin is typing.Literal:
        return " | ".join(f"`{a}`" for a in args)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(dict.fromkeys(type_name(a) for a in args))
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"list of {type_name(args[0])}"
        names = [type_name(a) for a in args]
        return (f"{len(names)} × {names[0]}" if len(set(names)) == 1
                else "(" + ", ".join(names) + ")")
    if origin in (list, set, frozenset) or origin is typing.Sequence:
        return f"list of {type_name(args[0]) if args else 'any'}"
    if origin is dict or origin is typing.Mapping:
        return f"mapping of {type_name(args[-1]) if args else 'any'}"
    return str(annotation).replace("typing.", "")


def field_type(field: FieldInfo) -> str:
    """The field's type; a text key whose choices come from a registry (its JSON schema's
    ``enum``, e.g. a gate's ``shape``) shows those choices."""
    extra = field.json_schema_extra
    if isinstance(extra, dict) and isinstance(extra.get("enum"), list | tuple):
        return " | ".join(f"`{choice}`" for choice in extra["enum"])
    return type_name(field.annotation)


def default_of(field: FieldInfo) -> str:
    """The default as a YAML reader would write it, ``required`` when there is none."""
    if field.is_required():
        return "required"
    value = field.get_default(call_default_factory=True)
    if isinstance(value, BaseModel):
        return "(its defaults)"
    from pydantic_core import to_jsonable_python

    try:
        text = json.dumps(to_jsonable_python(value), ensure_ascii=False)
    except (TypeError, ValueError):
        text = repr(value)
    return f"`{text}`" if len(text) <= 60 else f"`{text[:57]}…`"


def _cell(text: str) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _doc(model: type[BaseModel]) -> str:
    doc = inspect.getdoc(model) or ""
    if doc == inspect.getdoc(BaseModel) or model.__doc__ is None:
        return ""
    return doc


def yaml_reference() -> str:
    """The YAML reference page's body: one section per kind of file, one table row per key."""
    out: list[str] = []
    for folder, schema in top_level_schemas():
        title = FOLDER_TITLES.get(folder, folder.capitalize())
        out += [f"## {title}", "",
                f"Files in `{folder}/` (schema `{schema.__module__}.{schema.__qualname__}`). "
                f"Check any of them with `casadrone validate FILE`.", ""]
        doc = _doc(schema)
        if doc:
            out += [doc, ""]
        out += ["| key | type | unit | bounds | default | description |",
                "|---|---|---|---|---|---|"]
        for path, _, name, field in walk(schema):
            out.append("| " + " | ".join([
                f"`{path}`", _cell(field_type(field)), unit_of(name),
                _cell(bounds_of(field)), _cell(default_of(field)),
                _cell(field.description or "")]) + " |")
        out.append("")
        sections = dict.fromkeys((model, path.rsplit(".", 1)[0]) for path, model, _, _ in
                                 walk(schema) if model is not schema)
        notes = [(model, where) for model, where in sections if _doc(model)]
        if notes:
            out += ["Sections:", ""]
            out += [f"- `{where}` ({model.__qualname__}): {' '.join(_doc(model).split())}"
                    for model, where in notes]
            out.append("")
    return "\n".join(out)


# --------------------------------------------------------------------------------------------
# CLI reference
# --------------------------------------------------------------------------------------------


def _click_app():
    import typer

    from casadrone.cli import app

    return typer.main.get_command(app)


def _param_row(param: Any, ctx: Any) -> str:
    import enum

    kind = type(param).__name__
    if "Argument" in kind:
        name = f"`{(param.metavar or param.name).upper()}`"
    else:
        name = ", ".join(f"`{o}`" for o in (*param.opts, *param.secondary_opts))
    if getattr(param, "is_flag", False):
        ptype = "flag"
    elif hasattr(param, "display_type"):  # typer >= 0.20: its own parameter classes
        ptype = param.display_type(ctx).strip("<>").replace("|", " | ")
        ptype = re.sub(r"^list\[(\w+)\]$", r"\1", ptype)
        ptype = {"str": "text", "Path": "path", "float": "number", "int": "integer",
                 "int range": "integer"}.get(ptype, ptype)
    else:
        ptype = param.type.name
    if getattr(param, "multiple", False) or param.nargs == -1:
        ptype += " (repeatable)"
    value = param.default.value if isinstance(param.default, enum.Enum) else param.default
    if param.required:
        default = "required"
    elif value is None or value == () or value is False or value == []:
        default = ""
    else:
        default = f"`{value}`"
    help_text = getattr(param, "help", "") or ""
    return f"| {name} | {_cell(ptype)} | {_cell(default)} | {_cell(help_text)} |"


def _paragraphs(text: str) -> str:
    """Click's help text as Markdown: ``\\b`` blocks (kept verbatim) become code blocks."""
    text = inspect.cleandoc(text)
    if text.startswith("Examples:"):  # the epilog of casadrone.cli.examples: shell commands
        commands = [line.strip() for line in text.splitlines()[1:] if line.strip()]
        return "Examples:\n\n```bash\n" + "\n".join(commands) + "\n```"
    out = []
    for block in re.split(r"\n\s*\n", text):
        if block.startswith("\b"):
            out.append("```text\n" + block.lstrip("\b").strip("\n") + "\n```")
        else:
            out.append(block)
    return "\n\n".join(out)


def cli_reference() -> str:
    """The CLI reference page's body: one section per command of ``casadrone``."""
    group = _click_app()
    root = group.context_class(group, info_name="casadrone")
    out = [f"`casadrone --help`: {group.help}", ""]
    for name in group.list_commands(root):
        command = group.get_command(root, name)
        if command is None or command.hidden:
            continue
        ctx = command.context_class(command, info_name=name, parent=root)
        usage = " ".join(command.collect_usage_pieces(ctx))
        usage = re.sub(r"[{\[](\w+)[}\]]", lambda m: m.group(0)[0].replace("{", "")
                       + m.group(1).upper() + m.group(0)[-1].replace("}", ""), usage)
        out += [f"## `casadrone {name}`", "", f"```text\ncasadrone {name} {usage}\n```", ""]
        if command.help:
            out += [_paragraphs(command.help), ""]
        params = [p for p in command.params if p.name != "help"]
        if params:
            out += ["| argument or option | type | default | meaning |", "|---|---|---|---|"]
            out += [_param_row(p, ctx) for p in params]
            out.append("")
        if command.epilog:
            out += [_paragraphs(command.epilog), ""]
    return "\n".join(out)


# --------------------------------------------------------------------------------------------
# Benchmarks and changelog
# --------------------------------------------------------------------------------------------


#: The result files in the order of the chain (model and lap, optimiser, trim, propulsion, limit
#: lap, co-design): a ``RESULTS-<name>.md`` not named here comes after them, by name.
RESULTS_ORDER = ("design", "lap", "sensitivity", "geometry", "optimise", "backends", "evmoga",
                 "identity", "coordinator", "advance", "replay", "paper-scale", "trimstudy",
                 "trimstudy-propeller", "propulsion", "limitlap", "limitlap-issue19",
                 "limitlap-frames", "limitlap-frames-propeller", "limitlap-solvers", "codesign")

#: The opening summary's heading: ``## Summary (YYYY-MM-DD)``, the date its figures were recorded.
SUMMARY_HEADING = re.compile(r"## Summary \((\d{4}-\d{2}-\d{2})\)")
SUMMARY_HEADER = "| what | figure | command |"
_RULE = re.compile(r"\|(\s*:?-+:?\s*\|){3}")
_CELL_SPLIT = re.compile(r"(?<!\\)\|")

#: The folder of the generated pages, one per result file (``performance/<name>.md``).
RESULTS_PAGES = "performance"


@dataclass(frozen=True)
class ResultSummary:
    """A result file's opening summary: the file's name (``<name>`` of ``RESULTS-<name>.md``),
    its title, the date of its figures, an optional paragraph and the table rows (what, figure,
    command)."""

    name: str
    title: str
    date: str
    prose: str
    rows: tuple[str, ...]


def result_files(folder: Path) -> list[Path]:
    """Every ``RESULTS-*.md`` of ``folder``: those of :data:`RESULTS_ORDER` in its order, then
    the others by name."""
    def key(path: Path) -> tuple[int, str]:
        name = path.stem.removeprefix("RESULTS-")
        return (RESULTS_ORDER.index(name) if name in RESULTS_ORDER else len(RESULTS_ORDER), name)

    return sorted(folder.glob("RESULTS-*.md"), key=key)


def opening_summary(text: str, source: str) -> ResultSummary:
    """The summary a result file opens with; the file must read::

        # Title

        ## Summary (YYYY-MM-DD)

        An optional paragraph: what was measured.

        | what | figure | command |
        |---|---|---|
        | ... | ... | `the command` |

    and goes on with its sections. Raises ValueError naming ``source`` and what is missing."""
    lines = text.splitlines()
    if not lines or not lines[0].startswith("# "):
        raise ValueError(f"{source}: the first line is not its '# title'")
    at = next((i for i in range(1, len(lines)) if lines[i].strip()), len(lines))
    match = SUMMARY_HEADING.fullmatch(lines[at].strip()) if at < len(lines) else None
    if match is None:
        raise ValueError(f"{source}: the title is not followed by '## Summary (YYYY-MM-DD)'")
    try:
        datetime.date.fromisoformat(match.group(1))
    except ValueError:
        raise ValueError(f"{source}: {match.group(1)} is not a date") from None
    end = next((i for i in range(at + 1, len(lines)) if lines[i].startswith("#")), len(lines))
    section = lines[at + 1:end]
    if SUMMARY_HEADER not in section:
        raise ValueError(f"{source}: its summary has no table '{SUMMARY_HEADER}'")
    head = section.index(SUMMARY_HEADER)
    if head + 1 >= len(section) or not _RULE.fullmatch(section[head + 1].strip()):
        raise ValueError(f"{source}: its summary table has no rule under its header")
    rows: list[str] = []
    for line in section[head + 2:]:
        if not line.startswith("|"):
            break
        cells = _CELL_SPLIT.split(line.strip())[1:-1]
        if len(cells) != 3 or not all(c.strip() for c in cells) or "`" not in cells[2]:
            raise ValueError(f"{source}: summary row {line!r}: not three cells with the command "
                             "in backticks")
        rows.append(line.strip())
    if not rows:
        raise ValueError(f"{source}: its summary table has no row")
    prose = " ".join(" ".join(section[:head]).split())
    return ResultSummary(Path(source).stem.removeprefix("RESULTS-"), lines[0][2:].strip(),
                         match.group(1), prose, tuple(rows))


def _summary(path: Path) -> ResultSummary:
    return opening_summary(path.read_text(encoding="utf-8"), f"benchmarks/{path.name}")


def benchmark_summary(folder: Path = ROOT / "benchmarks") -> str:
    """The performance page's body: every result file's opening summary, in the order of
    :func:`result_files`, each linked to the page of the whole file."""
    out = []
    for summary in map(_summary, result_files(folder)):
        page = f"{RESULTS_PAGES}/{summary.name}.md"
        out += [f"### [{summary.title}]({page})", "",
                f"Recorded {summary.date}; the whole file: [`benchmarks/RESULTS-{summary.name}.md`]"
                f"({page}).", ""]
        if summary.prose:
            out += [summary.prose, ""]
        out += [SUMMARY_HEADER, "|---|---|---|", *summary.rows, ""]
    return "\n".join(out)


def results_page(path: Path) -> str:
    """The page of one result file: the file as recorded, with where it lives and a way back."""
    _summary(path)  # a file without its opening summary fails the build
    title, _, rest = path.read_text(encoding="utf-8").partition("\n")
    return "\n".join([title, "", f"Recorded in `benchmarks/{path.name}`; the summaries of every "
                       f"result file: [Performance](../performance.md).", rest])


#: Examples shown but not run when the site is built, and why.
EXAMPLES_NOT_RUN = {
    "dask_cluster.py": "it starts a Dask cluster of two worker processes; `tests/integration/"
                       "test_examples.py` runs it among the slow tests",
}

_RUN_EXAMPLE = """import os, subprocess, sys
root = {root!r}
env = {{**os.environ, "CASADRONE_EXAMPLE_SMALL": "1",
       "PYTHONPATH": os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))}}
done = subprocess.run([sys.executable, os.path.join(root, "examples", {name!r})], cwd=root,
                      env=env, capture_output=True, text=True, timeout=600)
if done.returncode:
    raise RuntimeError("examples/{name} failed: " + done.stderr[-2000:])
print(done.stdout.rstrip())
"""


def examples_gallery(folder: Path = ROOT / "examples") -> str:
    """The examples page's body: each ``examples/*.py`` with its docstring, its source and, run
    when the site is built (markdown-exec, ``CASADRONE_EXAMPLE_SMALL=1``: tiny budgets), what it
    printed; an example that fails fails the build."""
    out = []
    for path in sorted(folder.glob("*.py")):
        source = path.read_text(encoding="utf-8")
        doc = ast.get_docstring(ast.parse(source)) or ""
        out += [f"## `examples/{path.name}`", "", doc, "",
                '??? example "The source"', "", "    ```python",
                *[f"    {line}".rstrip() for line in source.splitlines()], "    ```", ""]
        if path.name in EXAMPLES_NOT_RUN:
            out += [f"Not run when this page is built: {EXAMPLES_NOT_RUN[path.name]}.", ""]
            continue
        out += ["What it printed when this page was built:", "",
                '```python exec="on" result="text"',
                _RUN_EXAMPLE.format(root=str(ROOT), name=path.name).rstrip(), "```", ""]
    return "\n".join(out)


def changelog() -> str:
    """``CHANGELOG.md`` without its title (the page has one)."""
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    text = text.replace("](docs/", "](")  # links into the docs, from the site's root
    return re.sub(r"\A# .*\n", "", text)


def api_sections() -> dict[str, list[str]]:
    """The Python API page's sections, module → names: ``casadrone._API`` (what ``import
    casadrone`` re-exports) in its order, each package's own function named like the package
    (``casadrone._PACKAGE_FUNCTIONS``: ``casadrone.export.export``) first in its package's
    section, which comes before its modules'."""
    import casadrone

    sections: dict[str, list[str]] = {}
    for module, names in casadrone._API.items():
        for package, functions in casadrone._PACKAGE_FUNCTIONS.items():
            if (module == package or module.startswith(package + ".")) and package not in sections:
                sections[package] = list(functions)
        sections.setdefault(module, []).extend(names)
    return sections


def api_reference() -> str:
    """The Python API page's body: mkdocstrings directives for :func:`api_sections`, one section
    per module, in the order of the chain."""
    out = []
    for module, names in api_sections().items():
        out += [f"## `{module}`", "", f"::: {module}", "    options:",
                "      show_root_heading: false", "      show_root_toc_entry: false",
                "      members:"]
        out += [f"        - {name}" for name in names]
        out.append("")
    return "\n".join(out)


GENERATORS = {
    "api-reference": api_reference,
    "yaml-reference": yaml_reference,
    "cli-reference": cli_reference,
    "benchmark-summary": benchmark_summary,
    "changelog": changelog,
    "examples": examples_gallery,
}


def on_files(files: Any, config: Any) -> Any:
    """mkdocs hook: one page per result file (``performance/<name>.md``), generated from
    ``benchmarks/RESULTS-<name>.md``."""
    from mkdocs.structure.files import File

    for path in result_files(ROOT / "benchmarks"):
        name = path.stem.removeprefix("RESULTS-")
        files.append(File.generated(config, f"{RESULTS_PAGES}/{name}.md",
                                    content=results_page(path)))
    return files


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    """mkdocs hook: replace each ``<!-- generated: NAME -->`` marker by its generated text."""
    return re.sub(r"<!-- generated: ([a-z-]+) -->", lambda m: GENERATORS[m.group(1)](),
                  markdown)


_SPHINX_ROLE = re.compile(r":(?:mod|class|func|meth|data|attr|exc|obj):<code>(~?)([^<]*)</code>")
_EXPLICIT_TITLE = re.compile(r"(.*?)\s*<([\w.]+)>", re.DOTALL)
_DOTTED_NAME = re.compile(r"\w+(?:\.\s*\w+)*")


def _cross_reference(match: re.Match[str]) -> str:
    """A docstring's Sphinx role (``:func:`~casadrone.limit.lap.limit_lap```, rendered as text and
    code) as an autorefs cross-reference: a link where the API page documents the name, plain
    code where it does not (``optional``). ``~`` shows the last part of the name only; a role
    with its own title (``:mod:`this module <casadrone.thruststand>```) shows the title; a name
    broken after a dot by the docstring's wrapping is joined again. Anything else (a relative
    name, ``.runner``) is shown as plain code."""
    short, text = match.group(1), html_module.unescape(match.group(2))
    titled = _EXPLICIT_TITLE.fullmatch(text)
    if titled:
        shown, name = titled.groups()
    elif _DOTTED_NAME.fullmatch(text):
        name = re.sub(r"\s+", "", text)
        shown = name.rsplit(".", 1)[-1] if short else name
    else:
        return f"<code>{match.group(2)}</code>"
    return (f'<autoref optional identifier="{name}"><code>{html_module.escape(shown)}</code>'
            "</autoref>")


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    """mkdocs hook: the docstrings' Sphinx roles as cross-references (resolved by autorefs when
    every page is rendered)."""
    return _SPHINX_ROLE.sub(_cross_reference, html)
