"""Limits on what a YAML text may cost before it is built into Python objects.

A YAML file of a few kilobytes can expand to billions of nodes through aliases (the "billion
laughs" of XML, as a list or a mapping), a value nested thousands of levels deep exhausts the
recursion of any loader, and a file of tens of megabytes takes minutes to read. No config of this
model needs any of that: the largest shipped file (a controller) is about 3 kB, ~200 nodes, nested
5 levels. So before a text is constructed, one pass over the parser's events (libyaml's C parser
where it is installed, PyYAML's own otherwise) counts the nodes the document expands to, with each
alias counting the whole node it repeats, and the nesting depth; beyond the ceilings below the
text is refused with a one-line reason. The ceilings are ~300 times what a config needs.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import yaml

#: Largest config file read, bytes (the largest shipped config is ~3 kB).
MAX_BYTES = 1 << 20
#: Most nodes a document may expand to, aliases expanded (shipped configs: at most ~200).
MAX_NODES = 100_000
#: Deepest nesting of lists and mappings (shipped configs: 5 levels).
MAX_DEPTH = 64

#: libyaml's parser when installed (~20x faster than the pure-Python one), else PyYAML's.
if TYPE_CHECKING:
    BaseLoader = yaml.SafeLoader
else:
    BaseLoader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_EventLoader = getattr(yaml, "CBaseLoader", yaml.BaseLoader)


def _line(event: yaml.Event) -> int:
    mark = event.start_mark
    return mark.line + 1 if mark is not None else 0


class TooCostly(ValueError):
    """A YAML text beyond :data:`MAX_BYTES`, :data:`MAX_NODES` or :data:`MAX_DEPTH`."""


def check_size(n_bytes: int) -> None:
    """Refuse a text longer than :data:`MAX_BYTES`."""
    if n_bytes > MAX_BYTES:
        raise TooCostly(f"{n_bytes} bytes, more than the {MAX_BYTES} bytes any config may have "
                        "(the largest shipped one has ~3 kB); not read")


def check_cost(text: str) -> None:
    """Refuse ``text`` when its documents expand to more than :data:`MAX_NODES` nodes or nest
    deeper than :data:`MAX_DEPTH`; one pass over the parser's events, before any construction.

    A parser may stop before this pass sees the ceiling: libyaml (PyYAML ≥ 6.0.4's C parser) has
    its own nesting limit and raises "exceeded maximum nesting depth" while scanning ahead. So a
    text the C parser stops on is counted again with PyYAML's pure-Python parser, which has no
    limit of its own: the refusal and its wording are casadrone's, whichever parser is installed.
    Malformed YAML passes here (the loader reports it with its line)."""
    check_size(len(text.encode("utf-8", "surrogatepass")))
    parsers = [_EventLoader] if _EventLoader is yaml.BaseLoader else [_EventLoader, yaml.BaseLoader]
    for parser in parsers:
        try:
            _count(yaml.parse(text, Loader=parser))
            return
        except yaml.YAMLError:
            continue


def _count(events: Iterator[yaml.Event]) -> None:
    """Raise :class:`TooCostly` when ``events`` nest deeper than :data:`MAX_DEPTH` or expand to
    more than :data:`MAX_NODES` nodes (each alias counts the whole node it repeats)."""
    sizes: dict[str, int] = {}  # anchor → expanded size of its node
    stack: list[list] = [[None, 0]]  # open collections: [anchor, expanded size so far]
    for event in events:
        if isinstance(event, yaml.CollectionStartEvent):
            stack.append([event.anchor, 1])
            if len(stack) - 1 > MAX_DEPTH:
                raise TooCostly(f"line {_line(event)}: nested more than "
                                f"{MAX_DEPTH} levels deep (a config needs a few)")
            continue
        if isinstance(event, yaml.CollectionEndEvent):
            anchor, size = stack.pop()
        elif isinstance(event, yaml.ScalarEvent):
            anchor, size = event.anchor, 1
        elif isinstance(event, yaml.AliasEvent):
            anchor, size = None, sizes.get(event.anchor or "", 1)
        else:
            continue
        if anchor is not None:
            sizes[anchor] = size
        stack[-1][1] += size
        if sum(s for _, s in stack) > MAX_NODES:
            raise TooCostly(f"line {_line(event)}: expands to more than "
                            f"{MAX_NODES} values (aliases repeating aliases?); a config "
                            "needs a few hundred")


def safe_load(text: str, loader: type) -> object:
    """``yaml.load(text, loader)`` after :func:`check_cost` (raises :class:`TooCostly`)."""
    check_cost(text)
    return yaml.load(text, Loader=loader)  # noqa: S506 (callers pass SafeLoader subclasses)
