"""The import graph of casadrone/: no circle, no module imports from a later floor of the chain, and
no lazy import of casadrone's own modules but where it keeps a heavy library out.

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
    "casadrone.progress",  # the progress events every stage may emit (the CLI shows them)
    "casadrone.codegen",
    "casadrone.heap",  # the process's malloc settings (the command line calls them)
    "casadrone.parentdeath",  # child processes that die with their parent
    "casadrone.lifeline",  # pool workers that end with their coordinator
    "casadrone.pool",  # independent tasks side by side: processes here, a Dask cluster beyond
    "casadrone.results",
    "casadrone.numtext",  # numbers as printed text (no negative zero): every table's
    "casadrone.num",  # Num, a number or a CasADi expression: the model's and propulsion's values
    "casadrone.massprops",
    "casadrone.drag",  # the body-drag forms: propulsion models and the airframe schema read them
    "casadrone.propulsion",  # the propulsion models: the airframe schema reads their kinds
    "casadrone.parts",  # the parts catalogue (static data): config.parts makes sections of it
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
    "casadrone.build",  # parts chosen with the frame: co-design per combination on a pool
    "casadrone.benchmark",
    "casadrone.compare",
    "casadrone.verdict",  # candidates against the baseline, with the evaluation's noise
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
    assert "casadrone.evaluate" in graph["casadrone.optimise.problem"]  # inside a function
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


# ------------------------------------------------------------------------------------------------
# Lazy imports: only where they keep a heavy library out of a module that does not need it
# ------------------------------------------------------------------------------------------------

#: The libraries whose import is heavy (tenths of a second to seconds) and that a caller may not
#: need: a function-level import of one of casadrone's modules is right where it brings one of
#: these that the importing module does not load already.
HEAVY: dict[str, str] = {
    "casadi": "the symbolic and compiled chain: `casadrone validate`, `--help` and the schemas "
              "import none of it",
    "pymoo": "the optimiser: only `casadrone run`/`resume` and co-design's front need it",
    "matplotlib": "figures: only --plot, reports and the docs draw",
    "scipy": "linear algebra and optimisers of the design stages",
    "dask": "the distributed backend, an optional extra",
    "distributed": "dask's cluster client (casadrone.pool), the same optional extra",
    "ezdxf": "DXF export, an optional extra",
}

#: Function-level imports of casadrone modules that bring no heavy library the importer lacks, and
#: why each stays lazy: (importing module, imported module) → reason. The one list of them, and
#: empty: every other function-level import of a casadrone module keeps a HEAVY library out.
LAZY_ALLOWED: dict[tuple[str, str], str] = {}


def _type_checking(node: ast.stmt) -> bool:
    """``if TYPE_CHECKING:`` (or ``typing.TYPE_CHECKING``): a block the type checker reads and an
    import never runs."""
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING"
            or isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _top_level_imports(path: Path) -> list[ast.stmt]:
    """The import statements a module runs when it is imported (not inside a function, nor under
    ``if TYPE_CHECKING:``)."""
    found: list[ast.stmt] = []

    def visit(nodes: list[ast.stmt]) -> None:
        for node in nodes:
            if isinstance(node, ast.Import | ast.ImportFrom):
                found.append(node)
            elif isinstance(node, ast.If | ast.Try | ast.With):
                for block in ("orelse",) if _type_checking(node) else ("body", "orelse",
                                                                        "finalbody"):
                    visit(getattr(node, block, []))
                for handler in getattr(node, "handlers", []):
                    visit(handler.body)

    visit(ast.parse(path.read_text(encoding="utf-8")).body)
    return found


def _targets(node: ast.stmt, mod: str, path: Path, mods: dict[str, Path]) -> list[str]:
    """The modules an import statement names: casadrone's by module name, others by their top
    package."""
    package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    assert isinstance(node, ast.ImportFrom)
    base = node.module or ""
    if node.level:
        parts = package.split(".")[: len(package.split(".")) - node.level + 1]
        base = ".".join(parts + ([base] if base else []))
    return [f"{base}.{a.name}" if f"{base}.{a.name}" in mods else base for a in node.names]


def heavy_at_import() -> dict[str, frozenset[str]]:
    """module → the HEAVY libraries importing it loads (its module-level imports, its parent
    packages', transitively)."""
    mods = modules()

    def owner(name: str) -> str | None:
        while name and name not in mods:
            name = name.rpartition(".")[0]
        return name or None

    direct: dict[str, set[str]] = {}
    deps: dict[str, set[str]] = {}
    for mod, path in mods.items():
        direct[mod], deps[mod] = set(), set()
        for node in _top_level_imports(path):
            for target in _targets(node, mod, path, mods):
                top = target.split(".")[0]
                if top in HEAVY:
                    direct[mod].add(top)
                elif top == "casadrone" and (dest := owner(target)) not in (None, mod, FACADE):
                    deps[mod].add(dest)
        parts = mod.split(".")
        deps[mod].update(p for i in range(2, len(parts)) if (p := ".".join(parts[:i])) in mods)

    def heavy(mod: str) -> frozenset[str]:
        """Every library that importing ``mod`` loads: what any module it reaches (its imports,
        their parent packages' ``__init__``, transitively) imports. A package's ``__init__`` that
        imports its submodules is a circle through the parent edge (casadrone.cli), so this is
        a search over all it reaches, whatever the order the modules are visited in."""
        seen, todo = {mod}, [mod]
        while todo:
            for d in deps[todo.pop()] - seen:
                seen.add(d)
                todo.append(d)
        return frozenset().union(*(direct[m] for m in seen))

    return {mod: heavy(mod) for mod in mods}


def lazy_imports() -> list[tuple[str, int, str]]:
    """(importing module, line, imported casadrone module) of every import inside a function (the
    package facade, loaded before any of its modules, aside)."""
    mods = modules()
    found = []
    for mod, path in mods.items():
        for fn in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(fn, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            for node in ast.walk(fn):
                if not isinstance(node, ast.Import | ast.ImportFrom):
                    continue
                for target in _targets(node, mod, path, mods):
                    name = target
                    while name and name not in mods:
                        name = name.rpartition(".")[0]
                    if target.split(".")[0] == "casadrone" and name not in ("", mod, FACADE):
                        found.append((mod, node.lineno, name))
    return sorted(set(found))


def test_heavy_and_lazy_are_read_from_the_source():
    heavy = heavy_at_import()
    assert heavy["casadrone.model"] >= {"casadi"} and not heavy["casadrone.config.airframe"]
    lazy = {(mod, dest) for mod, _, dest in lazy_imports()}
    assert ("casadrone.optimise.problem", "casadrone.evaluate") in lazy
    assert ("casadrone.cli.optimisation", "casadrone.optimise.runner") in lazy  # pymoo, lazily
    assert heavy["casadrone.optimise.runner"] - heavy["casadrone.cli.optimisation"] == {"pymoo"}


#: Prints the HEAVY libraries that importing one module loads.
LOADED = """
import importlib, sys
importlib.import_module({!r})
print(",".join(sorted({{m.split(".")[0] for m in sys.modules}} & {})))
"""


@pytest.mark.parametrize("name", [
    "casadrone.optimise.problem",  # the chain (CasADi) only under TYPE_CHECKING: pymoo alone
    "casadrone.verdict",  # its evaluation's types only under TYPE_CHECKING: none
    "casadrone.cli",  # the commands: CasADi (the limit lap's results), not SciPy nor pymoo
])
def test_heavy_at_import_is_what_importing_loads(name):
    # the oracle: a fresh interpreter imports the module and lists what it loaded
    import os
    import subprocess
    import sys

    root = PACKAGE.parent
    env = {**os.environ, "PYTHONPATH": str(root)}
    run = subprocess.run([sys.executable, "-c", LOADED.format(name, set(HEAVY))],
                         capture_output=True, text=True, cwd=root, timeout=120, env=env)
    assert run.returncode == 0, run.stderr
    loaded = set(run.stdout.strip().split(",")) - {""}
    assert heavy_at_import()[name] == loaded


def test_lazy_imports_of_casadrone_modules_keep_a_heavy_library_out():
    """An import of one of casadrone's modules inside a function hides an edge of the import
    graph; it is right only where it keeps a HEAVY library out of a module (and of everything
    that imports it) that does not load it already, or where LAZY_ALLOWED says why."""
    heavy = heavy_at_import()
    wrong = [f"{mod}:{line} imports {dest} inside a function, but it brings no heavy library "
             f"{mod} lacks ({', '.join(sorted(heavy[dest])) or 'none'}): import it at the top"
             for mod, line, dest in lazy_imports()
             if (mod, dest) not in LAZY_ALLOWED and heavy[dest] <= heavy[mod]]
    assert wrong == []


def test_every_allowed_lazy_import_is_still_there_and_says_why():
    seen = {(mod, dest) for mod, _, dest in lazy_imports()}
    assert all(reason for reason in LAZY_ALLOWED.values())
    assert set(LAZY_ALLOWED) <= seen
