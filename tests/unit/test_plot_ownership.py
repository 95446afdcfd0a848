"""``--plot`` replaces only what casadrone wrote: every figure carries casadrone's mark (PNG: tEXt
``Software``, SVG: the RDF creator), an existing figure path is replaced only when it holds that
mark (re-running a command into the same folder works), and anything else there (a user's own
picture, a folder, a link) is refused with exit code 2 and one stderr line before any work, with
nothing written. The mark is read back here by independent parsers (PIL, xml.etree) and the
user's files are written by PIL or as raw bytes, then compared byte for byte."""

from __future__ import annotations

import importlib.metadata
import json
import os
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import typer
from matplotlib.figure import Figure
from PIL import Image, PngImagePlugin

from casadrone.cli import app
from casadrone.cli.common import figure_paths, save_figures
from casadrone.cli.design import LQR_FIGURES
from casadrone.cli.flight import SIMULATE_FIGURES
from casadrone.cli.limit import LIMIT_FIGURES
from casadrone.cli.trimstudy import TRIM_STUDY_FIGURES
from casadrone.plots import is_casadrone_figure, save_figure

MARK = f"casadrone {importlib.metadata.version('casadrone')}"
NS = {"dc": "http://purl.org/dc/elements/1.1/", "cc": "http://creativecommons.org/ns#",
      "rdf": "http://www.w3.org/1999/02/22-rdf-syntax-ns#", "svg": "http://www.w3.org/2000/svg"}

#: command arguments (cheap, refused before any work anyway) and the figures it writes
COMMANDS = {
    "lqr": (["lqr", "SY250", "--ensemble", "2"], LQR_FIGURES),
    "simulate": (["simulate", "SY250"], SIMULATE_FIGURES),
    "limit-lap": (["limit-lap", "SY250"], LIMIT_FIGURES),
    "trim-study": (["trim-study", "SY250", "--conditions", "hover", "--starts", "0"],
                   TRIM_STUDY_FIGURES),
}


def png_software(path: Path) -> str | None:
    with Image.open(path) as im:
        return im.info.get("Software")


def svg_creator(path: Path) -> str | None:
    root = ET.parse(path).getroot()
    title = root.find("svg:metadata/rdf:RDF/cc:Work/dc:creator/cc:Agent/dc:title", NS)
    return None if title is None else title.text


def user_png(path: Path, software: str | None = "GIMP 2.10") -> bytes:
    """A picture the user made (PIL, optionally naming its software), its bytes."""
    info = PngImagePlugin.PngInfo()
    if software is not None:
        info.add_text("Software", software)
    Image.new("RGB", (4, 3), (200, 30, 30)).save(path, format="PNG", pnginfo=info)
    return path.read_bytes()


def snapshot(folder: Path) -> dict[str, bytes | str]:
    out: dict[str, bytes | str] = {}
    for p in sorted(folder.rglob("*")):
        key = str(p.relative_to(folder))
        out[key] = ("-> " + os.readlink(p) if p.is_symlink() else "dir" if p.is_dir()
                    else p.read_bytes())
    return out


def invoke(cli_runner, *args):
    return cli_runner.invoke(app, [str(a) for a in args])


def one_line(result) -> str:
    assert result.exit_code == 2, (result.exit_code, result.stdout, result.stderr)
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def small_figure() -> Figure:
    fig = Figure(figsize=(2, 1.5))
    fig.add_subplot().plot([0, 1], [1, 0])
    return fig


# --- the mark ------------------------------------------------------------------------------------


def test_save_figure_marks_png_and_svg(tmp_path):
    png, svg = save_figure(small_figure(), tmp_path / "f")
    assert png_software(png) == MARK and svg_creator(svg) == MARK
    assert is_casadrone_figure(png) and is_casadrone_figure(svg)


def test_only_the_mark_is_recognised(tmp_path):
    """PNGs written by PIL: the mark of any version is casadrone's, other software is not."""
    cases = {"old.png": "casadrone 0.0.9", "gimp.png": "GIMP 2.10", "none.png": None,
             "near.png": "casadrone-fork 1.0", "bare.png": "casadrone"}
    for name, software in cases.items():
        user_png(tmp_path / name, software)
    assert [is_casadrone_figure(tmp_path / n) for n in cases] == [True, False, False, False,
                                                                 False]
    (tmp_path / "raw.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 40)
    (tmp_path / "text.png").write_text("Software casadrone 0.1.0")
    plain = small_figure()
    plain.savefig(tmp_path / "mpl.png")  # matplotlib's own mark, not casadrone's
    plain.savefig(tmp_path / "mpl.svg")
    (tmp_path / "dir.png").mkdir()
    (tmp_path / "link.png").symlink_to(save_figure(plain, tmp_path / "real")[0])
    for name in ("raw.png", "text.png", "mpl.png", "mpl.svg", "dir.png", "link.png"):
        assert not is_casadrone_figure(tmp_path / name), name


def test_a_hand_written_svg_with_the_creator_is_recognised(tmp_path):
    path = tmp_path / "a.svg"
    path.write_text(
        '<?xml version="1.0"?>\n<svg xmlns="http://www.w3.org/2000/svg">\n <metadata>\n'
        f'  <rdf:RDF xmlns:dc="{NS["dc"]}" xmlns:cc="{NS["cc"]}" xmlns:rdf="{NS["rdf"]}">\n'
        f"   <cc:Work><dc:creator><cc:Agent><dc:title>{MARK}</dc:title></cc:Agent></dc:creator>"
        "</cc:Work>\n  </rdf:RDF>\n </metadata>\n</svg>\n")
    assert svg_creator(path) == MARK and is_casadrone_figure(path)
    path.write_text(path.read_text().replace(MARK, "Inkscape"))
    assert svg_creator(path) == "Inkscape" and not is_casadrone_figure(path)


# --- every --plot command: a user's file refused before any work -------------------------------


def _no_work(monkeypatch):
    """Any work of the commands fails the test: the refusal must come first. The airframe's
    loading is replaced in every module that holds it, by whatever name each command calls it."""
    def work(*args, **kwargs):
        raise AssertionError("the command worked before refusing")

    from casadrone.config.airframe import load_airframe

    holders = [m for name, m in sys.modules.items()
               if name.startswith("casadrone")
               and getattr(m, "load_airframe", None) is load_airframe]
    assert len(holders) >= 2  # its own module and the commands' (casadrone.cli.common)
    for module in holders:
        monkeypatch.setattr(module, "load_airframe", work)


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("kind", ["PIL png", "raw svg", "folder", "link"])
def test_a_users_file_at_a_figure_path_is_refused(tmp_path, cli_runner, monkeypatch, command,
                                                  kind):
    args, names = COMMANDS[command]
    folder = tmp_path / "figs"
    folder.mkdir()
    first = figure_paths(folder, names)
    target = first[-1] if kind == "raw svg" else first[0]
    if kind == "PIL png":
        user_png(target)
    elif kind == "raw svg":
        target.write_bytes(b"<svg xmlns='http://www.w3.org/2000/svg'><!-- mine --></svg>")
    elif kind == "folder":
        target.mkdir()
    else:
        target.symlink_to(save_figure(small_figure(), tmp_path / "elsewhere")[0])
    before = snapshot(tmp_path)
    _no_work(monkeypatch)
    line = one_line(invoke(cli_runner, *args, "--plot", folder))
    assert line.startswith(f"--plot: {target}: ") and "not a casadrone figure" in line
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("command", COMMANDS)
def test_a_plot_folder_under_a_file_is_refused_before_any_work(tmp_path, cli_runner,
                                                                monkeypatch, command):
    """``--plot afile/sub``: the folder can never be made (a file is on its way). Found only when
    the figures were saved, a limit lap had flown for minutes and its result was lost."""
    args, _ = COMMANDS[command]
    (tmp_path / "afile").write_bytes(b"mine")
    before = snapshot(tmp_path)
    _no_work(monkeypatch)
    line = one_line(invoke(cli_runner, *args, "--plot", tmp_path / "afile" / "sub"))
    assert line.startswith(f"--plot: {tmp_path / 'afile' / 'sub'}: ")
    assert f"{tmp_path / 'afile'} is a file" in line
    assert snapshot(tmp_path) == before


def test_the_refusal_counts_the_other_foreign_files(tmp_path, cli_runner, monkeypatch):
    for path in figure_paths(tmp_path, LQR_FIGURES)[:3]:
        user_png(path)
    _no_work(monkeypatch)
    line = one_line(invoke(cli_runner, "lqr", "SY250", "--plot", tmp_path))
    assert "eigenvalue-cloud.png" in line and "2 more" in line


def test_save_figures_writes_none_when_one_path_is_foreign(tmp_path):
    """Figures named only after the work are checked before the first is written."""
    mine = user_png(tmp_path / "b.svg")
    with pytest.raises(typer.Exit) as exc:
        save_figures({"a": small_figure(), "b": small_figure()}, tmp_path)
    assert exc.value.exit_code == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.svg"]
    assert (tmp_path / "b.svg").read_bytes() == mine


# --- a casadrone figure is replaced: re-running into the same folder ----------------------------


def _age(paths: list[Path]) -> None:
    for p in paths:
        os.utime(p, ns=(10**18, 10**18))  # 2001


def test_simulate_rerun_replaces_its_own_figures(tmp_path, cli_runner):
    folder = tmp_path / "figs"
    first = invoke(cli_runner, "simulate", "SY250", "--plot", folder, "--json")
    assert first.exit_code == 0, first.stderr
    expected = figure_paths(folder, SIMULATE_FIGURES)
    assert json.loads(first.stdout)["figures"] == [str(p) for p in expected]
    assert sorted(folder.iterdir()) == sorted(expected)
    for p in expected:
        assert (png_software(p) if p.suffix == ".png" else svg_creator(p)) == MARK, p
    user_png(tmp_path / "mine.png")  # a file of another name beside them: never touched
    _age(expected)
    second = invoke(cli_runner, "simulate", "SY250", "--plot", folder)
    assert second.exit_code == 0 and second.stderr == "", second.stderr
    assert all(p.stat().st_mtime_ns > 10**18 for p in expected)
    assert all(is_casadrone_figure(p) for p in expected)

