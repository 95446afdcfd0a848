"""Tiny YAML files cannot hang casadrone or exhaust its memory (issue 20, point 4): alias bombs,
deep nesting and huge files are refused, naming the file, before anything is constructed; every
shipped config reads the same through the C loader as through PyYAML's pure-Python SafeLoader."""

from __future__ import annotations

import os

import pytest
import yaml

from casadrone.config import yamlsafe
from casadrone.config.io import (
    DATA_DIR,
    ConfigError,
    _UniqueKeyLoader,
    apply_overrides,
    read_yaml,
)


def list_bomb(levels: int = 9) -> str:
    """The "billion laughs" as YAML lists: 9**levels strings from a few hundred bytes."""
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, levels):
        prev, cur = chr(ord("a") + i - 1), chr(ord("a") + i)
        lines.append(f"{cur}: &{cur} [{', '.join([f'*{prev}'] * 9)}]")
    return "\n".join(lines) + "\n"


def mapping_bomb(levels: int = 9) -> str:
    lines = ["a: &a {" + ", ".join(f"x{j}: 1" for j in range(9)) + "}"]
    for i in range(1, levels):
        prev, cur = chr(ord("a") + i - 1), chr(ord("a") + i)
        lines.append(f"{cur}: &{cur} {{" + ", ".join(f"y{j}: *{prev}" for j in range(9)) + "}")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize(("text", "why"), [
    (list_bomb(), "expands to more than"),
    (mapping_bomb(), "expands to more than"),
    ("a: " + "[" * 20_000 + "1" + "]" * 20_000 + "\n", "nested more than"),
    ("a:\n" + "".join(" " * (2 * i + 2) + f"k{i}:\n" for i in range(200)) + "\n",
     "nested more than"),
])
def test_costly_yaml_is_refused_naming_the_file(tmp_path, text, why):
    path = tmp_path / "bomb.yaml"
    path.write_text(text)
    assert len(text) < 50_000  # each is small: the cost is in the expansion
    with pytest.raises(ConfigError) as err:
        read_yaml(path)
    (line,) = err.value.lines
    assert line.startswith(f"{path}: ") and why in line


def test_a_file_beyond_the_size_ceiling_is_not_read(tmp_path):
    path = tmp_path / "big.yaml"
    with open(path, "w") as fh:  # plain values, each harmless, too many together
        fh.write("name: big\n")
        fh.writelines(f"k{i}: {i}\n" for i in range(yamlsafe.MAX_BYTES // 8))
    assert path.stat().st_size > yamlsafe.MAX_BYTES
    with pytest.raises(ConfigError, match=rf"{path}: \d+ bytes, more than"):
        read_yaml(path)


def test_the_ceilings_leave_room_for_every_shipped_config():
    shipped = sorted(DATA_DIR.rglob("*.yaml"))
    assert shipped
    largest = max(p.stat().st_size for p in shipped)
    assert 100 * largest < yamlsafe.MAX_BYTES


    class Pure(yaml.SafeLoader):  # PyYAML's pure-Python parser, casadrone's number rules
        yaml_implicit_resolvers = _UniqueKeyLoader.yaml_implicit_resolvers

    for path in shipped:  # the C and the pure-Python parser agree on every shipped file
        assert read_yaml(path) == (yaml.load(path.read_text(), Loader=Pure) or {})


def test_a_few_aliases_are_still_allowed(tmp_path):
    path = tmp_path / "ok.yaml"
    path.write_text("a: &w [1, 2, 3]\nb: *w\nc: {x: *w}\n")
    assert read_yaml(path) == {"a": [1, 2, 3], "b": [1, 2, 3], "c": {"x": [1, 2, 3]}}


def test_an_override_bomb_is_refused(tmp_path):
    value = "[" + ", ".join(["&a [lol, lol, lol, lol, lol, lol, lol, lol, lol]"] + [
        f"&{chr(98 + i)} [{', '.join(['*' + chr(97 + i)] * 9)}]" for i in range(8)]) + "]"
    with pytest.raises(ConfigError, match="quick.yaml: override 'x=…': .*expands to more than"):
        apply_overrides({}, [f"x={value}"], "quick.yaml")


def test_the_c_loader_is_used_when_installed():
    if not getattr(yaml, "__with_libyaml__", False):
        pytest.skip("PyYAML built without libyaml")
    assert issubclass(yamlsafe.BaseLoader, yaml.CSafeLoader)


def test_a_symlink_loop_is_named_as_one(tmp_path):
    loop = tmp_path / "loop.yaml"
    os.symlink(loop.name, loop)
    with pytest.raises(ConfigError, match="symbolic link loop"):
        read_yaml(loop)


class _ShallowParser(yaml.BaseLoader):
    """A parser with a nesting limit of its own far below casadrone's (as libyaml's C parser has
    from PyYAML 6.0.4 on): it stops with its own error before the event pass sees the ceiling."""

    def check_event(self, *choices):
        depth = getattr(self, "_depth", 0)
        found = super().check_event(*choices)
        event = self.peek_event()
        if isinstance(event, yaml.CollectionStartEvent):
            self._depth = depth + 1
            if self._depth > 5:
                raise yaml.YAMLError("exceeded maximum nesting depth")
        elif isinstance(event, yaml.CollectionEndEvent):
            self._depth = depth - 1
        return found


@pytest.mark.parametrize("parser", [yaml.BaseLoader, getattr(yaml, "CBaseLoader", yaml.BaseLoader),
                                    _ShallowParser])
def test_deep_nesting_is_refused_in_casadrones_words_whichever_parser_trips_first(
        tmp_path, monkeypatch, parser):
    monkeypatch.setattr(yamlsafe, "_EventLoader", parser)
    path = tmp_path / "deep.yaml"
    path.write_text("a: " + "[" * 2_000 + "1" + "]" * 2_000 + "\n")
    with pytest.raises(ConfigError) as err:
        read_yaml(path)
    (line,) = err.value.lines
    assert line.startswith(f"{path}: ") and f"nested more than {yamlsafe.MAX_DEPTH}" in line
