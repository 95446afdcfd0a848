"""URDF of an airframe: a body link carrying the whole vehicle's mass and inertia tensor about the
centre of mass, and one link per rotor on a continuous joint about its spin axis.

URDF's body frame (ROS REP 103: x forward, y left, z up) is casadrone's, so positions are written
as they are. The rotor links are visual only (no ``<inertial>``): the rotors' mass and inertia are
already inside the airframe's (``mass_kg``, the inertia tensor), so a parser summing the links gets
the airframe's mass back. A rotor's joint axis is +z for a rotor turning counter-clockwise seen
from above (its angular velocity points up), −z for a clockwise one.
"""

from __future__ import annotations

import math
from xml.sax.saxutils import escape, quoteattr

from casadrone.config.airframe import ROTOR_LABELS
from casadrone.export.mixers import LABELS, spin_word
from casadrone.export.source import ExportSource

#: Thickness of the drawn arms and prop discs (visual only), m.
ARM_THICKNESS_M = 0.004
PROP_THICKNESS_M = 0.002
ARM_WIDTH_M = 0.014


def _f(x: float) -> str:
    return f"{x + 0.0:.9g}"


def urdf(src: ExportSource) -> str:
    """The URDF text (UTF-8 XML)."""
    a, cfg = src.airframe, src.config
    J = a.inertia
    name = quoteattr(cfg.name)
    out = ['<?xml version="1.0" encoding="utf-8"?>', "<!--"]
    out += [f"  {escape(h).replace('--', '- -')}" for h in src.header_lines("URDF")]
    out += ["  Frame: x forward, y left, z up (REP 103, as casadrone); base_link at the centre of "
            "mass.", "-->", f"<robot name={name}>",
            '  <material name="frame"><color rgba="0.15 0.15 0.15 1"/></material>',
            '  <material name="prop"><color rgba="0.2 0.4 0.9 0.5"/></material>',
            '  <link name="base_link">',
            "    <inertial>",
            '      <origin xyz="0 0 0" rpy="0 0 0"/>',
            f'      <mass value="{_f(a.mass)}"/>',
            f'      <inertia ixx="{_f(J[0, 0])}" ixy="{_f(J[0, 1])}" ixz="{_f(J[0, 2])}" '
            f'iyy="{_f(J[1, 1])}" iyz="{_f(J[1, 2])}" izz="{_f(J[2, 2])}"/>',
            "    </inertial>"]
    hub = -a.com  # the arms meet at the hub; base_link is at the centre of mass
    for r in a.rotor_positions:
        arm = r - hub
        length = math.hypot(arm[0], arm[1])
        yaw = math.atan2(arm[1], arm[0])
        mid = hub + arm / 2
        out += ["    <visual>",
                f'      <origin xyz="{_f(mid[0])} {_f(mid[1])} {_f(mid[2])}" '
                f'rpy="0 0 {_f(yaw)}"/>',
                f'      <geometry><box size="{_f(length)} {_f(ARM_WIDTH_M)} '
                f'{_f(ARM_THICKNESS_M)}"/></geometry>',
                '      <material name="frame"/>',
                "    </visual>"]
    out.append("  </link>")
    radius = cfg.prop_diameter_mm / 2000.0
    for i, r in enumerate(a.rotor_positions):
        link = f"rotor_{i + 1}_{ROTOR_LABELS[i]}"
        axis = "0 0 1" if a.rotor_spins[i] < 0 else "0 0 -1"
        out += [f"  <!-- rotor {i + 1}: {LABELS[i]}, turning {spin_word(a.rotor_spins[i])} seen "
                "from above -->",
                f'  <link name="{link}">',
                "    <visual>",
                '      <origin xyz="0 0 0" rpy="0 0 0"/>',
                f'      <geometry><cylinder radius="{_f(radius)}" length="{_f(PROP_THICKNESS_M)}"/>'
                "</geometry>",
                '      <material name="prop"/>',
                "    </visual>",
                "  </link>",
                f'  <joint name="{link}_joint" type="continuous">',
                '    <parent link="base_link"/>',
                f'    <child link="{link}"/>',
                f'    <origin xyz="{_f(r[0])} {_f(r[1])} {_f(r[2])}" rpy="0 0 0"/>',
                f'    <axis xyz="{axis}"/>',
                "  </joint>"]
    out.append("</robot>")
    return "\n".join(out) + "\n"
