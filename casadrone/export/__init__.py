"""From the Pareto front to a flying frame: an airframe or a run's candidate written for a flight
controller (Betaflight ``mmix``, PX4 ``CA_ROTOR*``), a simulator (URDF) or the cutter (SVG, DXF).

:func:`export` returns the text of one format; :func:`write_export` writes it to a file; what to
export comes from :func:`casadrone.export.source.source_of` (an airframe, or a run's candidate).
Every file starts with the casadrone version, the airframe or run and the candidate it came from.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from casadrone.export.bom import bom_csv, bom_markdown
from casadrone.export.mixers import betaflight, px4, px4_shell
from casadrone.export.plate import PlateOptions, dxf, svg
from casadrone.export.source import ExportSource
from casadrone.export.urdf import urdf
from casadrone.outfile import check_out, write_out


@dataclass(frozen=True)
class ExportFormat:
    """One export format: its file suffix, what it is, and its writer (source, plate options →
    the file's text)."""

    suffix: str
    description: str
    write: Callable[[ExportSource, PlateOptions | None], str]


#: The export formats, by the name the API and the CLI (``--format``) use. A new format is one
#: entry here and its writer.
FORMATS: dict[str, ExportFormat] = {
    "betaflight": ExportFormat(".txt", "Betaflight custom mix (mmix lines)",
                               lambda src, _: betaflight(src)),
    "px4": ExportFormat(".params", "PX4 CA_ROTOR* parameters (QGroundControl parameter file)",
                        lambda src, _: px4(src)),
    "px4-shell": ExportFormat(".txt", "PX4 CA_ROTOR* parameters (param set lines, NSH console)",
                              lambda src, _: px4_shell(src)),
    "urdf": ExportFormat(".urdf", "URDF robot description for a simulator",
                         lambda src, _: urdf(src)),
    "svg": ExportFormat(".svg", "the frame plate, 1:1 SVG outline (mm)", svg),
    "dxf": ExportFormat(".dxf", "the frame plate, 1:1 DXF outline (mm)", dxf),
    "bom": ExportFormat(".md", "bill of materials (frame, motors, propellers, pack), Markdown",
                        lambda src, _: bom_markdown(src)),
    "bom-csv": ExportFormat(".csv", "bill of materials (frame, motors, propellers, pack), CSV",
                            lambda src, _: bom_csv(src)),
}


def export(src: ExportSource, fmt: str, plate_options: PlateOptions | None = None) -> str:
    """The text of ``src`` in one format (``betaflight``, ``px4`` (QGroundControl's parameter
    file), ``px4-shell`` (``param set`` lines), ``urdf``, ``svg``, ``dxf``).

    Raises:
        ValueError: an unknown format, or a plate that cannot be drawn (see
            :func:`casadrone.export.plate.plate`).
        RuntimeError: ``dxf`` without ezdxf installed.
    """
    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r}: one of {', '.join(FORMATS)}")
    return FORMATS[fmt].write(src, plate_options)


def write_export(src: ExportSource, fmt: str, out: str | Path,
                 plate_options: PlateOptions | None = None, force: bool = False) -> Path:
    """Write one format to ``out`` (its folder is created); the path written.

    An existing file is replaced only with ``force``; a path inside a run directory is always
    refused; the file appears whole or not at all (:func:`casadrone.outfile.write_out`).

    Raises:
        casadrone.outfile.OutputRefused: ``out`` must not be written (a ValueError).
        OSError: the write failed (a full disk), naming ``out``.
    """
    check_out(out, force)  # before any work
    return write_out(out, export(src, fmt, plate_options), force)


def default_name(src: ExportSource, fmt: str) -> str:
    """``<airframe name><suffix>``, e.g. ``SY250.txt`` for a Betaflight mix."""
    return f"{src.config.name}-{fmt}{FORMATS[fmt].suffix}"
