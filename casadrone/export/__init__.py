"""From the Pareto front to a flying frame: an airframe or a run's candidate written for a flight
controller (Betaflight ``mmix``, PX4 ``CA_ROTOR*``), a simulator (URDF) or the cutter (SVG, DXF).

:func:`export` returns the text of one format; :func:`write_export` writes it to a file; what to
export comes from :func:`casadrone.export.source.source_of` (an airframe, or a run's candidate).
Every file starts with the casadrone version, the airframe or run and the candidate it came from.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from casadrone.export.mixers import betaflight, px4
from casadrone.export.plate import PlateOptions, dxf, svg
from casadrone.export.source import ExportSource
from casadrone.export.urdf import urdf

#: Format name → file suffix.
FORMATS = {"betaflight": ".txt", "px4": ".params", "urdf": ".urdf", "svg": ".svg", "dxf": ".dxf"}


def export(src: ExportSource, fmt: str, plate_options: PlateOptions | None = None) -> str:
    """The text of ``src`` in one format (``betaflight``, ``px4``, ``urdf``, ``svg``, ``dxf``).

    Raises:
        ValueError: an unknown format, or a plate that cannot be drawn (see
            :func:`casadrone.export.plate.plate`).
        RuntimeError: ``dxf`` without ezdxf installed.
    """
    writers: dict[str, Callable[[], str]] = {
        "betaflight": lambda: betaflight(src), "px4": lambda: px4(src), "urdf": lambda: urdf(src),
        "svg": lambda: svg(src, plate_options), "dxf": lambda: dxf(src, plate_options),
    }
    if fmt not in writers:
        raise ValueError(f"format {fmt!r}: one of {', '.join(FORMATS)}")
    return writers[fmt]()


def write_export(src: ExportSource, fmt: str, out: str | Path,
                 plate_options: PlateOptions | None = None) -> Path:
    """Write one format to ``out`` (its folder is created); the path written."""
    text = export(src, fmt, plate_options)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text, encoding="utf-8")
    return out


def default_name(src: ExportSource, fmt: str) -> str:
    """``<airframe name><suffix>``, e.g. ``SY250.txt`` for a Betaflight mix."""
    return f"{src.config.name}-{fmt}{FORMATS[fmt]}"
