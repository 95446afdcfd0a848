"""The bill of materials of an airframe: frame, four motors, four propellers and the pack, each
with its mass and where its figures come from, in CSV (``bom-csv``) or Markdown (``bom``).

Read from the airframe itself, so a build's winner (``casadrone build --out``: its airframe
YAML) and any airframe with a ``components`` mass model and a ``propeller`` propulsion section
give one: the motor's mass from ``propulsion.motor``, the propeller's as the rest of the
components model's mass at the rotor (motor + propeller), the pack's from ``components``, the
frame (body and arms) as what is left of the airframe's mass. The lines add up to the mass every
other export states (URDF, the header lines).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass

from casadrone.export.source import ExportSource

#: The bill's columns.
COLUMNS = ("item", "quantity", "unit_mass_g", "mass_g", "part", "source")


@dataclass(frozen=True)
class BomLine:
    """One line of the bill: what, how many, the mass of one (g), and where it comes from."""

    item: str
    quantity: int
    unit_mass_g: float
    part: str
    source: str

    @property
    def mass_g(self) -> float:
        return self.quantity * self.unit_mass_g


def _part_and_source(data: str | None) -> tuple[str, str]:
    """(part name, source) of a section's ``data`` ("parts catalogue NAME: SOURCE", or free
    text)."""
    text = (data or "").strip()
    prefix = "parts catalogue "
    if text.startswith(prefix) and ": " in text:
        name, source = text[len(prefix):].split(": ", 1)
        return name, source
    return text or "-", "the airframe file"


def bom_lines(src: ExportSource) -> list[BomLine]:
    """The bill of ``src`` (module docstring); an airframe without the components mass model
    or the propeller kind's motor mass has no parts to list: one line, the whole airframe."""
    cfg = src.config
    parts = cfg.components
    motor = cfg.propulsion.motor if cfg.propulsion.model == "propeller" else None
    if parts is None or motor is None or motor.mass_kg is None:
        return [BomLine("airframe (no parts listed: its mass is one figure)", 1,
                        1000 * src.airframe.mass, cfg.name, "the airframe file")]
    prop_g = 1000 * (parts.motor_mass_kg - motor.mass_kg)
    battery = cfg.propulsion.battery
    total_g = 1000 * src.airframe.mass
    pack_g = 1000 * parts.battery_mass_kg
    frame_g = total_g - 4 * 1000 * parts.motor_mass_kg - pack_g
    assert cfg.propulsion.propeller is not None  # the propeller kind has one
    return [
        BomLine("frame (body, arms, electronics)", 1, frame_g, cfg.name,
                "components mass model (casadrone massprops)"),
        BomLine("motor", 4, 1000 * motor.mass_kg, *_part_and_source(motor.data)),
        BomLine("propeller", 4, prop_g, *_part_and_source(cfg.propulsion.propeller.data)),
        BomLine("pack", 1, pack_g, *_part_and_source(battery.data if battery else None)),
    ]


def _rows(src: ExportSource) -> list[list[str]]:
    lines = bom_lines(src)
    rows = [[b.item, str(b.quantity), f"{b.unit_mass_g:.1f}", f"{b.mass_g:.1f}", b.part,
             b.source] for b in lines]
    rows.append(["total", "", "", f"{sum(b.mass_g for b in lines):.1f}", "", ""])
    return rows


def bom_csv(src: ExportSource) -> str:
    """The bill as CSV after the export's provenance lines (``#`` comments): :data:`COLUMNS`,
    then a total line."""
    buf = io.StringIO()
    buf.writelines(f"# {line}\n" for line in src.header_lines("bill of materials"))
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    w.writerows(_rows(src))
    return buf.getvalue()


def bom_markdown(src: ExportSource) -> str:
    """The bill as a Markdown table, after the export's provenance lines."""
    head = [f"<!-- {line} -->" for line in src.header_lines("bill of materials")]
    table = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    table += ["| " + " | ".join(c.replace("|", "/") for c in row) + " |" for row in _rows(src)]
    return "\n".join([*head, "", f"# Bill of materials: {src.config.name}", "", *table]) + "\n"
