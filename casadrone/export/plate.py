"""The frame plate, 1:1 top view in millimetres: outline, motor holes, prop discs, dimensions; as
SVG (no dependency) or DXF (``ezdxf``, imported when a DXF is asked for).

The outline is exact lines and arcs: a central hub circle (the flight stack), one straight arm of
the given width from the hub to each motor centre, a round motor pad at its end. Drawing axes (both
formats): origin at the hub (the arms' meeting point, where λa and λb are measured from), X to the
right of the drone, Y towards the nose, so X = −y and Y = x in casadrone's body frame (SVG's Y axis
points down the page; it is flipped so the nose is up there too). The centre of mass is marked
(it sits off the hub when the mass properties come from components). Each motor carries its
position label (FR, FL, RL, RR, :data:`casadrone.config.airframe.ROTOR_LABELS`).
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from casadrone.config.airframe import ROTOR_LABELS
from casadrone.export.source import ExportSource

#: 22xx motor mounting patterns: hole-to-hole distances across the motor centre (mm); holes sit
#: on the diagonals at ±45° to the arm.
PATTERNS = {"16x16": (16.0, 16.0), "16x19": (16.0, 19.0)}


@dataclass(frozen=True)
class PlateOptions:
    """Plate drawing choices (mm): a 5-inch racer's usual sizes."""

    arm_width_mm: float = 14.0
    hub_radius_mm: float = 26.0  # clears a 30.5 × 30.5 mm stack (M3 holes 21.6 mm from centre)
    pad_radius_mm: float = 14.0  # a 22xx motor base is 27-28 mm across
    pattern: str = "16x19"
    hole_diameter_mm: float = 3.2  # M3 clearance
    centre_hole_diameter_mm: float = 8.0  # shaft and circlip clearance
    stack_spacing_mm: float = 30.5


def arm_width_problem(o: PlateOptions) -> str:
    """Why the plate cannot be drawn with ``o.arm_width_mm`` (empty when it can): an arm as
    wide as the hub or a motor pad leaves no outline."""
    widest = 2 * min(o.hub_radius_mm, o.pad_radius_mm)
    if o.arm_width_mm < widest:
        return ""
    return (f"arm width {o.arm_width_mm:g} mm: the arm must be narrower than the hub and the "
            f"motor pads (below {widest:g} mm)")


@dataclass(frozen=True)
class Arc:
    centre: tuple[float, float]
    radius: float
    start: float  # rad, counter-clockwise from +X
    end: float


@dataclass(frozen=True)
class Plate:
    """Drawing geometry (mm, drawing axes): the closed outline as alternating straight pieces and
    counter-clockwise arcs, motor centres, holes, prop radius."""

    outline: tuple  # sequence of ("line", p0, p1) and ("arc", Arc)
    motors: np.ndarray  # 4×2, rotor order FR, FL, RL, RR
    com: np.ndarray  # 2, centre of mass
    holes: tuple[tuple[float, float, float], ...]  # (X, Y, diameter)
    prop_radius: float
    options: PlateOptions


def drawing_xy(r_body_m: np.ndarray) -> np.ndarray:
    """Body positions (m; x forward, y left) → drawing (mm; X right, Y forward)."""
    r = np.asarray(r_body_m, dtype=float)
    return np.stack([-1000.0 * r[..., 1], 1000.0 * r[..., 0]], axis=-1) + 0.0


def plate(src: ExportSource, options: PlateOptions | None = None) -> Plate:
    """The plate of an airframe.

    Raises:
        ValueError: arms too close for the hub, pads touching the hub, an unknown pattern.
    """
    o = options or PlateOptions()
    if o.pattern not in PATTERNS:
        raise ValueError(f"pattern {o.pattern!r}: one of {', '.join(PATTERNS)}")
    a = src.airframe
    motors = drawing_xy(a.rotor_positions + a.com)  # rotor positions are from the CoM
    w2, R, rp = o.arm_width_mm / 2, o.hub_radius_mm, o.pad_radius_mm
    if arm_width_problem(o):
        raise ValueError(arm_width_problem(o))
    order = np.argsort(np.arctan2(motors[:, 1], motors[:, 0]))
    phis = np.arctan2(motors[order, 1], motors[order, 0])
    lengths = np.hypot(motors[order, 0], motors[order, 1])
    if np.any(lengths - rp <= R):
        raise ValueError("a motor pad reaches into the hub: arms too short for this hub")
    half_hub = math.asin(w2 / R)
    gaps = np.diff(np.append(phis, phis[0] + 2 * math.pi))
    if np.any(gaps <= 2 * half_hub):
        raise ValueError("two arms overlap at the hub: the angle between them is too small")
    t_hub, s_pad = math.sqrt(R * R - w2 * w2), math.sqrt(rp * rp - w2 * w2)
    pieces: list = []
    for k, (phi, L) in enumerate(zip(phis, lengths, strict=True)):
        u = np.array([math.cos(phi), math.sin(phi)])
        n = np.array([-u[1], u[0]])
        right_in, right_out = t_hub * u - w2 * n, (L - s_pad) * u - w2 * n
        left_out, left_in = (L - s_pad) * u + w2 * n, t_hub * u + w2 * n
        centre = L * u
        a_right = math.atan2(*(right_out - centre)[::-1])
        a_left = math.atan2(*(left_out - centre)[::-1])
        pieces.append(("line", tuple(right_in), tuple(right_out)))
        pieces.append(("arc", Arc(tuple(centre), rp, a_right, a_left)))
        pieces.append(("line", tuple(left_out), tuple(left_in)))
        nxt = phis[(k + 1) % len(phis)] + (2 * math.pi if k + 1 == len(phis) else 0.0)
        pieces.append(("arc", Arc((0.0, 0.0), R, phi + half_hub, nxt - half_hub)))
    pa, pb = PATTERNS[o.pattern]
    holes: list[tuple[float, float, float]] = []
    for m in motors:
        phi = math.atan2(m[1], m[0])
        holes.append((float(m[0]), float(m[1]), o.centre_hole_diameter_mm))
        for j, d in enumerate((pa, pb, pa, pb)):
            ang = phi + math.pi / 4 + j * math.pi / 2
            holes.append((float(m[0] + d / 2 * math.cos(ang)), float(m[1] + d / 2 * math.sin(ang)),
                          o.hole_diameter_mm))
    s = o.stack_spacing_mm / 2
    holes += [(sx * s, sy * s, o.hole_diameter_mm) for sx in (-1, 1) for sy in (-1, 1)]
    return Plate(tuple(pieces), motors, drawing_xy(a.com), tuple(holes),
                 src.config.prop_diameter_mm / 2, o)


def _dimensions(p: Plate) -> list[tuple[np.ndarray, np.ndarray, str]]:
    """(from, to, label): front and rear motor spans, front-to-rear motor distance (mm)."""
    fr, fl, rl, rr = p.motors
    front_mid, rear_mid = (fr + fl) / 2, (rl + rr) / 2
    return [(fl, fr, f"{np.linalg.norm(fr - fl):.1f}"), (rl, rr, f"{np.linalg.norm(rr - rl):.1f}"),
            (front_mid, rear_mid, f"{np.linalg.norm(front_mid - rear_mid):.1f}")]


def _extent(p: Plate) -> tuple[float, float, float, float]:
    r = p.prop_radius + 15.0
    return (float(p.motors[:, 0].min() - r), float(p.motors[:, 1].min() - r),
            float(p.motors[:, 0].max() + r), float(p.motors[:, 1].max() + r))


def rotor_marks(p: Plate) -> list[tuple[str, float, float]]:
    """(position label, drawing x, drawing y) of each rotor's label (mm): beside its motor pad,
    away from the hub, inside the prop disc."""
    out = []
    for i, m in enumerate(p.motors):
        out_dir = m / max(float(np.hypot(m[0], m[1])), 1e-9)
        x, y = m + (p.options.pad_radius_mm + 6.0) * out_dir
        out.append((ROTOR_LABELS[i], float(x), float(y)))
    return out


def svg(src: ExportSource, options: PlateOptions | None = None) -> str:
    """The plate as a 1:1 SVG (width and height in mm, one user unit = 1 mm)."""
    from xml.sax.saxutils import escape

    p = plate(src, options)
    x0, y0, x1, y1 = _extent(p)
    W, H = x1 - x0, y1 - y0

    def pt(xy: np.ndarray | tuple[float, float]) -> str:  # drawing (Y up) → SVG (Y down)
        return f"{xy[0] + 0.0:.4f},{-xy[1] + 0.0:.4f}"

    d: list[str] = []
    for piece in p.outline:
        if piece[0] == "line":
            d.append(("M" if not d else "L") + pt(piece[1]) + " L" + pt(piece[2]))
        else:
            a: Arc = piece[1]
            sweep = (a.end - a.start) % (2 * math.pi)
            end = (a.centre[0] + a.radius * math.cos(a.end),
                   a.centre[1] + a.radius * math.sin(a.end))
            # counter-clockwise in Y-up is clockwise on the Y-down page: sweep-flag 0
            d.append(f"A{a.radius:.4f},{a.radius:.4f} 0 {int(sweep > math.pi)} 0 {pt(end)}")
    head = "\n".join(escape(h) for h in src.header_lines("1:1 frame plate, top view, mm"))
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W:.3f}mm" height="{H:.3f}mm" '
           f'viewBox="{x0:.3f} {-y1:.3f} {W:.3f} {H:.3f}">',
           f"<title>{escape(src.config.name)} frame plate (1:1, mm)</title>",
           f"<desc>{head}\nDrawing X = right of the drone, up the page = nose; 1 unit = 1 mm."
           "</desc>",
           f'<path id="outline" d="{" ".join(d)} Z" fill="none" stroke="black" '
           'stroke-width="0.2"/>']
    for i, (hx, hy, dia) in enumerate(p.holes):
        cls = "motor-centre" if i < 20 and i % 5 == 0 else "hole"
        out.append(f'<circle class="{cls}" cx="{hx + 0.0:.4f}" cy="{-hy + 0.0:.4f}" '
                   f'r="{dia / 2:.4f}" fill="none" stroke="black" stroke-width="0.2"/>')
    for m in p.motors:
        out.append(f'<circle class="prop" cx="{m[0]:.4f}" cy="{-m[1] + 0.0:.4f}" '
                   f'r="{p.prop_radius:.4f}" fill="none" stroke="#3366cc" stroke-width="0.2" '
                   'stroke-dasharray="4 2"/>')
    for label, lx, ly in rotor_marks(p):
        out.append(f'<text class="rotor-label" x="{lx:.4f}" y="{-ly + 0.0:.4f}" font-size="5" '
                   f'text-anchor="middle" dominant-baseline="middle">{label}</text>')
    cx, cy = p.com
    out.append(f'<circle class="com" cx="{cx + 0.0:.4f}" cy="{-cy + 0.0:.4f}" r="1.5" '
               'fill="#cc3333"/>')
    for p1, p2, label in _dimensions(p):
        mid = (p1 + p2) / 2
        out.append(f'<line class="dimension" x1="{p1[0]:.4f}" y1="{-p1[1] + 0.0:.4f}" '
                   f'x2="{p2[0]:.4f}" y2="{-p2[1] + 0.0:.4f}" stroke="#cc3333" '
                   'stroke-width="0.15"/>')
        out.append(f'<text x="{mid[0]:.4f}" y="{-mid[1] - 1.5 + 0.0:.4f}" font-size="4" '
                   f'text-anchor="middle" fill="#cc3333">{label} mm</text>')
    out.append(f'<text x="{x0 + 3:.3f}" y="{-y1 + 6:.3f}" font-size="3.5">'
               f"{escape(src.config.name)}: arm {p.options.arm_width_mm:g} mm, motors "
               f"{p.options.pattern} mm, props {2 * p.prop_radius:g} mm (dashed), nose up</text>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


def _require_ezdxf() -> Any:
    try:
        import ezdxf
    except ImportError:
        raise RuntimeError("DXF export needs ezdxf: pip install ezdxf (or pip install "
                           "'.[export]' from the casadrone checkout)") from None
    return ezdxf


def dxf(src: ExportSource, options: PlateOptions | None = None) -> str:
    """The plate as DXF R2010 text (units mm): layers OUTLINE (one closed polyline of lines and
    arcs), HOLES, MOTOR_CENTRES (a point per motor), PROPS (dashed construction circles),
    DIMENSIONS, ROTORS (each rotor's position label, FR, FL, RL, RR, beside its motor); the
    header lines are custom header properties and a TEXT on NOTES."""
    ezdxf = _require_ezdxf()
    from ezdxf import units

    p = plate(src, options)
    doc = ezdxf.new("R2010", setup=True)
    doc.units = units.MM
    doc.header["$MEASUREMENT"] = 1
    for name, color, ltype in (("OUTLINE", 7, "CONTINUOUS"), ("HOLES", 7, "CONTINUOUS"),
                               ("MOTOR_CENTRES", 1, "CONTINUOUS"), ("PROPS", 5, "DASHED"),
                               ("DIMENSIONS", 3, "CONTINUOUS"), ("NOTES", 8, "CONTINUOUS"),
                               ("COM", 1, "CONTINUOUS"), ("ROTORS", 1, "CONTINUOUS")):
        doc.layers.add(name, color=color, linetype=ltype)
    for i, line in enumerate(src.header_lines("1:1 frame plate, top view, mm")):
        doc.header.custom_vars.append(f"casadrone_{i}", line)
    msp = doc.modelspace()
    verts = []  # (x, y, bulge) of a closed LWPOLYLINE
    for piece in p.outline:
        if piece[0] == "line":
            verts.append((*piece[1], 0.0))
        else:
            a: Arc = piece[1]
            sweep = (a.end - a.start) % (2 * math.pi)
            # a line piece adds only its start: the arc's start vertex carries the arc's bulge
            start = (a.centre[0] + a.radius * math.cos(a.start),
                     a.centre[1] + a.radius * math.sin(a.start))
            verts.append((*start, math.tan(sweep / 4)))
    msp.add_lwpolyline(verts, format="xyb", close=True, dxfattribs={"layer": "OUTLINE"})
    for hx, hy, dia in p.holes:
        msp.add_circle((hx, hy), dia / 2, dxfattribs={"layer": "HOLES"})
    for m in p.motors:
        msp.add_point((float(m[0]), float(m[1])), dxfattribs={"layer": "MOTOR_CENTRES"})
        msp.add_circle((float(m[0]), float(m[1])), p.prop_radius, dxfattribs={"layer": "PROPS"})
    for label, lx, ly in rotor_marks(p):
        msp.add_text(label, height=5.0, dxfattribs={"layer": "ROTORS", "insert": (lx, ly)})
    msp.add_point((float(p.com[0]), float(p.com[1])), dxfattribs={"layer": "COM"})
    for p1, p2, _ in _dimensions(p):
        msp.add_aligned_dim(p1=tuple(p1), p2=tuple(p2), distance=8.0,
                            dxfattribs={"layer": "DIMENSIONS"}).render()
    x0, y0, _, y1 = _extent(p)
    msp.add_text(f"{src.config.name}: X right, Y nose; mm", height=3.5,
                 dxfattribs={"layer": "NOTES", "insert": (x0 + 3, y1 - 6)})
    buf = io.StringIO()
    doc.write(buf)
    return buf.getvalue()
