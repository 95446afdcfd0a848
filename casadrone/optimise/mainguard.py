"""Worker processes and a script without ``if __name__ == "__main__":``.

A spawned worker (the ``processes`` backend, a Dask LocalCluster) normally imports the main script
again before it runs anything; a script that calls :func:`casadrone.run` at its top level, outside
that guard, would start the run again inside every worker (``BrokenProcessPool``, a
``FileExistsError`` on the run directory). casadrone's workers need nothing from the main script
(the problem and its ``plugins:`` travel with the study), so the ``processes`` backend starts its
workers without importing it when the call is unguarded; a Dask LocalCluster cannot, so such a
call is refused, in one line, before the run directory exists.
"""

from __future__ import annotations

import ast
import multiprocessing.context
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Any


def _is_main_test(node: ast.expr) -> bool:
    """``__name__ == "__main__"`` (either way round)."""
    if not (isinstance(node, ast.Compare) and len(node.ops) == 1
            and isinstance(node.ops[0], ast.Eq)):
        return False
    sides = [node.left, node.comparators[0]]
    names = [s for s in sides if isinstance(s, ast.Name) and s.id == "__name__"]
    consts = [s for s in sides if isinstance(s, ast.Constant) and s.value == "__main__"]
    return len(names) == 1 and len(consts) == 1


def unguarded_main_call() -> str | None:
    """``"FILE:LINE"`` when the main script is executing a top-level statement that is not inside
    an ``if __name__ == "__main__":`` block (so a spawned worker would execute it again), else
    None (an interactive session, ``python -c``, a guarded call, a call from an imported module
    not reached from the script's top level)."""
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if not path or not Path(path).is_file():
        return None
    line = None
    frame: FrameType | None = sys._getframe(1)
    while frame is not None:
        if (frame.f_code.co_name == "<module>"
                and frame.f_globals.get("__name__") in ("__main__", "__mp_main__")
                and Path(frame.f_code.co_filename).resolve() == Path(path).resolve()):
            line = frame.f_lineno
        frame = frame.f_back
    if line is None:
        return None
    try:
        tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    except (OSError, SyntaxError, UnicodeDecodeError):
        return None
    for node in tree.body:
        if (isinstance(node, ast.If) and _is_main_test(node.test)
                and node.lineno <= line <= (node.end_lineno or node.lineno)):
            return None
    return f"{path}:{line}"


def unguarded_message(where: str, what: str) -> str:
    return (f"{where}: {what} runs at the top level of a script without "
            "'if __name__ == \"__main__\":', which the Dask LocalCluster's worker processes "
            "import again; put the call under that guard (or use the serial or processes backend)")


@contextmanager
def main_hidden() -> Iterator[None]:
    """While starting a process: no ``__main__`` module for the child to import."""
    main = sys.modules["__main__"]
    saved: dict[str, Any] = {k: main.__dict__[k] for k in ("__spec__", "__file__")
                             if k in main.__dict__}
    main.__dict__["__spec__"] = None
    main.__dict__.pop("__file__", None)
    try:
        yield
    finally:
        main.__dict__.pop("__spec__", None)
        main.__dict__.update(saved)


class _SpawnWithoutMain(multiprocessing.context.SpawnProcess):
    def start(self) -> None:
        with main_hidden():
            super().start()


class SpawnWithoutMainContext(multiprocessing.context.SpawnContext):
    """The spawn context, except that its processes do not import the main script."""

    Process = _SpawnWithoutMain
