"""HTML building blocks of the report: escaped text, number cells, tables, notes, labels with
units, and the embedded figures (saved under ``plots/`` as PNG and SVG)."""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from casadrone import plots
from casadrone.numtext import fixed
from casadrone.report.analysis import Run

PLOTS = "plots"
UNIT_SUFFIX = {"mm": "mm", "deg": "deg", "kgm2": "kg·m²", "kg": "kg", "m2": "m²", "m": "m",
               "s": "s", "v": "V", "n": "N", "kgm3": "kg/m³", "mps2": "m/s²"}
SYMBOL = {"lambda_a_mm": "λa", "lambda_b_mm": "λb", "alpha_deg": "α", "beta_deg": "β",
          "ixx_kgm2": "Ixx", "iyy_kgm2": "Iyy", "izz_kgm2": "Izz"}


class Html(str):
    """Text already in HTML (not escaped again)."""


def esc(value: object) -> str:
    return value if isinstance(value, Html) else html.escape(str(value))


def num(value: Any, fmt: str = ".5g") -> str:
    """A number for a table cell: ``—`` for missing or non-finite."""
    if value is None or isinstance(value, str):
        return "—" if value is None else esc(value)
    v = float(value)
    if not math.isfinite(v):
        return "—"
    return fixed(v, fmt)  # no "-0.000"


def cell(value: Any, fmt: str = ".5g", exact: bool = False) -> Html:
    """A numeric table cell; ``exact`` adds the full value (``repr``) as ``data-value``."""
    data = f' data-value="{float(value)!r}"' if exact and value is not None else ""
    return Html(f'<td class="num"{data}>{num(value, fmt)}</td>')


def table(head: list[str], rows: list[list], cls: str = "") -> Html:
    """A table; a cell that is an :class:`Html` ``<td>`` is inserted as is, anything else is
    escaped (numbers formatted with :func:`num`)."""
    def td(c: object) -> str:
        if isinstance(c, Html) and c.startswith("<td"):
            return c
        if isinstance(c, int | float | np.floating | np.integer) and not isinstance(c, bool):
            return cell(c)
        return f"<td>{esc(c)}</td>"

    h = "".join(f"<th>{esc(x)}</th>" for x in head)
    body = "".join("<tr>" + "".join(td(c) for c in r) + "</tr>" for r in rows)
    return Html(f'<table class="{cls}"><thead><tr>{h}</tr></thead><tbody>{body}</tbody></table>')


def kv_table(pairs: list[tuple[str, object]]) -> Html:
    return table(["item", "value"], [[k, "—" if v is None else str(v)] for k, v in pairs], "kv")


def note(text: str, kind: str = "note") -> Html:
    return Html(f'<p class="{kind}">{esc(text)}</p>')


class Figures:
    """Saves figures under ``plots/`` (PNG and SVG) and embeds the PNG bytes in the page."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.saved: list[Path] = []

    def embed(self, fig: Figure, name: str, caption: str) -> Html:
        paths = plots.save_figure(fig, self.folder / name)
        self.saved += paths
        data = base64.b64encode(paths[0].read_bytes()).decode("ascii")
        return Html(f'<figure><img src="data:image/png;base64,{data}" alt="{esc(caption)}">'
                    f"<figcaption>{esc(caption)} <span class=\"file\">({PLOTS}/{name}.png, "
                    f".svg)</span></figcaption></figure>")


def unit_of(variable: str) -> str:
    """Unit of an airframe config key from its suffix (``alpha_deg`` → deg)."""
    for suffix, unit in sorted(UNIT_SUFFIX.items(), key=lambda kv: -len(kv[0])):
        if variable.endswith("_" + suffix):
            return unit
    return "–"


def variable_label(name: str) -> str:
    return f"{SYMBOL.get(name, name)} ({unit_of(name)})"


def objective_label(run: Run, name: str) -> str:
    return f"{name} ({run.unit(name)})"


def empty_front(run: Run) -> Html:
    """The warning shown instead of a section when the front is empty (evaluation counts)."""
    n = len(run.history)
    done = sum(h["status"] == "completed" for h in run.history)
    return note(f"The Pareto front is empty: no feasible design in {n} evaluations ({done} "
                f"completed the lap, {n - done} failed; completed laps that violate a "
                "constraint are infeasible). There are no candidates to show: see the failures "
                "section and relax the constraints or the bounds.", "warn")
