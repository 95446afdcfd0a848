"""The import graph of casadrone/: no circle, and no module imports from a later floor of the chain.

The graph is read from the source with :mod:`ast` (every ``import`` and ``from … import``, at module
level or inside a function: a lazy import that closes a circle is still a circle), so the test
sees what the code says, not what an import order happened to execute.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "casadrone"

#: The floors of the chain, earliest first (docs/architecture.md#layers): each a folder (a
#: subpackage, all its modules) or a top-level module, never interleaved. A module imports only from
#: its own floor or an earlier one; within a floor, only the absence of circles orders it.
FLOORS: tuple[str, ...] = (
    "casadrone.data",
    "casadrone.codegen",
    "casadrone.heap",  # the process's malloc settings (the command line calls them)
    "casadrone.parentdeath",  # child processes that die with their parent
    "casadrone.results",
    "casadrone.massprops",
    "casadrone.propulsion",  # the propulsion models: the airframe schema reads their kinds
    "casadrone.targets",  # the limit lap's target kinds: the track schema reads their shapes
    "casadrone.config",
    "casadrone.outfile",
    "casadrone.thruststand",
    "casadrone.airframe",
    "casadrone.model",
    "casadrone.conditions",
    "casadrone.trim",
    "casadrone.trimstudy",
    "casadrone.linearise",
    "casadrone.control",
    "casadrone.guidance",
    "casadrone.lapdriver",
    "casadrone.simulate",
    "casadrone.limit",
    "casadrone.indices",
    "casadrone.evaluate",
    "casadrone.decide",
    "casadrone.rundir",  # the run directory: optimise, codesign, compare, report, export read it
    "casadrone.codesign",
    "casadrone.precompile",  # compiles the limit lap's and co-design's blocks side by side
    "casadrone.optimise",  # ev-MOGA's polish (optimise.hybrid) is the co-design NLP
    "casadrone.benchmark",
    "casadrone.compare",
    "casadrone.plots",
    "casadrone.trimplots",
    "casadrone.export",
    "casadrone.report",
    "casadrone.cli",
    "casadrone.__main__",  # ``python -m casadrone``: the command line
)
#: The package itself is the public API facade, after every stage; the one name a module may take
#: from it is ``__version__`` (set before the facade imports anything).
FACADE = "casadrone"


def modules() -> dict[str, Path]:
    found = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def import_graph() -> dict[str, dict[str, tuple[int, list[str]]]]:
    """module → {imported casadrone module: (line, names taken)}."""
    mods = modules()

    def owner(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, dict[str, tuple[int, list[str]]]] = {}
    for mod, path in mods.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        edges: dict[str, tuple[int, list[str]]] = {}
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            pairs: list[tuple[str, str]] = []
            if isinstance(node, ast.Import):
                pairs = [(alias.name, "*") for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")[: len(package.split(".")) - node.level + 1]
                    base = ".".join(parts + ([base] if base else []))
                pairs = [(f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base, a.name)
                         for a in node.names]
            for target, name in pairs:
                dest = owner(target) if target.split(".")[0] == "casadrone" else None
                if dest and dest != mod:
                    line, names = edges.setdefault(dest, (node.lineno, []))
                    names.append(name)
        graph[mod] = edges
    return graph


def cycles(graph: dict[str, dict]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, {}):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def floor(mod: str) -> int:
    for i, prefix in enumerate(FLOORS):
        if mod == prefix or mod.startswith(prefix + "."):
            return i
    raise AssertionError(f"{mod} is on no floor of FLOORS: add it where it belongs")


def test_cycle_finder_finds_a_planted_circle():
    planted = {"a": {"b": 0}, "b": {"c": 0}, "c": {"a": 0}, "d": {"a": 0}}
    assert cycles(planted) == [["a", "b", "c"]]
    assert cycles({"a": {"b": 0}, "b": {}}) == []


def test_graph_sees_lazy_and_relative_imports():
    graph = import_graph()
    assert "casadrone.config.airframe" in graph["casadrone.airframe"]  # module-level
    assert "casadrone.rundir.plugins" in graph["casadrone.optimise.problem"]  # inside a function
    assert "casadrone.cli.common" in graph["casadrone.cli"]


def test_no_import_circle():
    assert cycles(import_graph()) == []


def test_floors_are_folders_and_top_level_modules_in_chain_order():
    """Every floor is a subpackage or a top-level module (no floor is a module inside a folder,
    so no folder's modules are interleaved with another floor's), each listed once, and every
    module is on one."""
    mods = modules()
    assert len(set(FLOORS)) == len(FLOORS)
    for name in FLOORS:
        assert name in mods and name.count(".") == 1, name
    assert all(floor(m) >= 0 for m in mods if m != FACADE)


def test_no_module_imports_from_a_later_stage():
    wrong = []
    for mod, edges in import_graph().items():
        if mod == FACADE:
            continue
        for dest, (line, names) in edges.items():
            if dest == FACADE:
                if set(names) != {"__version__"}:
                    wrong.append(f"{mod}:{line} takes {names} from the package facade")
                continue
            if floor(dest) > floor(mod):
                wrong.append(f"{mod}:{line} imports {dest}, on a higher floor")
    assert wrong == []


@pytest.mark.parametrize("name", ["casadrone.benchmark", "casadrone.cli", "casadrone.report"])
def test_no_reexports(name):
    # version 0.x: names are imported from the module where they are defined
    path = modules()[name]
    assert "re-export" not in path.read_text(encoding="utf-8")


def test_package_code_imports_config_names_from_their_modules():
    # casadrone.config's __init__ gathers the common names for users; the package's own modules
    # import each from the module that defines it (casadrone.config.airframe …)
    wrong = [f"{mod}:{line} takes {names} from casadrone.config"
             for mod, edges in import_graph().items()
             for dest, (line, names) in edges.items() if dest == "casadrone.config"]
    assert wrong == []


#: Prints the heavy libraries a snippet of code imported (none expected).
LIGHT = """
import sys
{}
heavy = sorted(m for m in ("casadi", "pymoo", "matplotlib") if m in sys.modules)
print(",".join(heavy))
"""


@pytest.mark.parametrize("code", [
    "import casadrone.config",
    "import casadrone",
    # what `casadrone validate` runs on each file: a problem checks its airframe, controller, track
    "from casadrone.config.validation import check_config_file\n"
    "check_config_file('problems/quick.yaml')\n"
    "check_config_file('configs/references/paper-table4.yaml')",
])
def test_the_config_package_imports_no_solver(code):
    # schemas and YAML only: checking a file or building the docs loads no CasADi, pymoo or
    # matplotlib (measured with python -X importtime in the change's note)
    import os
    import subprocess
    import sys

    root = PACKAGE.parent
    env = {**os.environ, "PYTHONPATH": str(root)}
    run = subprocess.run([sys.executable, "-c", LIGHT.format(code)], capture_output=True,
                         text=True, cwd=root, timeout=120, env=env)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == ""

