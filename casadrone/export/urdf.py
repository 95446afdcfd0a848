"""URDF of an airframe: a body link and one link per rotor on a continuous joint about its spin
axis; together they carry exactly the airframe's mass and inertia tensor about its centre of mass.

URDF's body frame (ROS REP 103: x forward, y left, z up) is casadrone's, so positions are written
as they are. Every link has an ``<inertial>`` (a simulator gives a link without one a mass of its
own, pybullet 1 kg) and ``<collision>`` shapes (pybullet computes nothing from visuals). Each rotor
link is the spinning prop, :data:`ROTOR_LINK_MASS_KG`, a thin disc of the prop's diameter; the body
link holds the rest, with its centre of mass and inertia chosen so that the links sum (parallel-axis
theorem) to the airframe's mass, centre of mass (base_link's origin) and inertia tensor exactly.
A rotor's joint axis is +z for a rotor turning counter-clockwise seen from above (its angular
velocity points up), −z for a clockwise one.

Load it in pybullet with ``flags=pybullet.URDF_USE_INERTIA_FROM_FILE`` (else pybullet derives the
inertia from the collision boxes); at the airframe's hover thrusts, applied at the rotor links
along their z axis, it hovers.
"""

from __future__ import annotations

import math
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from casadrone.airframe import Airframe
from casadrone.config.airframe import ROTOR_LABELS, rotor_label
from casadrone.export.mixers import LABELS, spin_word
from casadrone.export.source import ExportSource

#: Thickness of the drawn arms and prop discs (visual only), m.
ARM_THICKNESS_M = 0.004
PROP_THICKNESS_M = 0.002
ARM_WIDTH_M = 0.014
#: Mass of a rotor link, the spinning prop (kg): a 5-inch tri-blade prop weighs 3-4 g
#: (configs/airframes/SY250-components.yaml); it is part of the airframe's mass, not added to it.
ROTOR_LINK_MASS_KG = 0.004


#: A flat frame's Izz equals Ixx + Iyy; rounding may put the body link's written Izz a hair above
#: the written sum, and pybullet then zeroes the link's inertia ("Bad inertia tensor properties",
#: BulletUrdfImporter.cpp). Such a moment is lowered in steps of this relative size, the precision
#: the file is written to (9 digits), until the written values obey the triangle inequality.
TRIANGLE_MARGIN = 1e-9


def _shift(m: float, d: np.ndarray) -> np.ndarray:
    """Parallel-axis term of a point mass ``m`` (kg) at ``d`` (m): m (|d|² E − d dᵀ)."""
    return m * (float(d @ d) * np.eye(3) - np.outer(d, d))


def link_inertias(a: Airframe, prop_radius_m: float) -> tuple[float, np.ndarray, np.ndarray,
                                                              np.ndarray]:
    """(body mass, body centre of mass, body inertia about it, rotor inertia about its centre):
    the split of the airframe's mass and inertia between the body link and four rotor discs.

    Raises:
        ValueError: the rotors would take more than the airframe has (a frame too light or too
            small for props of this mass).
    """
    m_r = ROTOR_LINK_MASS_KG
    disc = m_r * prop_radius_m ** 2 * np.diag([0.25, 0.25, 0.5])  # thin disc about its centre
    r = np.asarray(a.rotor_positions, float)
    m_b = a.mass - len(r) * m_r
    if m_b <= 0:
        raise ValueError(f"URDF: the four props ({ROTOR_LINK_MASS_KG} kg each) outweigh the "
                         f"airframe ({a.mass:g} kg)")
    c_b = -m_r * r.sum(axis=0) / m_b  # the links' centre of mass stays at base_link's origin
    J_b = np.asarray(a.inertia, float) - sum(disc + _shift(m_r, ri) for ri in r) - _shift(m_b, c_b)
    w = np.linalg.eigvalsh(J_b)
    if w[0] <= 0 or 2 * w.max() > w.sum() * (1 + 1e-9):
        raise ValueError("URDF: the airframe's inertia leaves the body link no possible inertia "
                         "once the props are split off")
    for k in range(3):  # a flat frame has Izz = Ixx + Iyy exactly; keep rounding on the inside
        others = [float(_f(J_b[i, i])) for i in range(3) if i != k]
        while float(_f(J_b[k, k])) > sum(others):
            J_b[k, k] *= 1 - TRIANGLE_MARGIN
    return m_b, c_b, J_b, disc


def _f(x: float) -> str:
    return f"{x + 0.0:.9g}"


def _inertial(mass: float, at: np.ndarray, J: np.ndarray, indent: str) -> list[str]:
    return [f"{indent}<inertial>",
            f'{indent}  <origin xyz="{_f(at[0])} {_f(at[1])} {_f(at[2])}" rpy="0 0 0"/>',
            f'{indent}  <mass value="{_f(mass)}"/>',
            f'{indent}  <inertia ixx="{_f(J[0, 0])}" ixy="{_f(J[0, 1])}" ixz="{_f(J[0, 2])}" '
            f'iyy="{_f(J[1, 1])}" iyz="{_f(J[1, 2])}" izz="{_f(J[2, 2])}"/>',
            f"{indent}</inertial>"]


def _arm(mid: np.ndarray, yaw: float, length: float, tag: str) -> list[str]:
    lines = [f"    <{tag}>",
             f'      <origin xyz="{_f(mid[0])} {_f(mid[1])} {_f(mid[2])}" rpy="0 0 {_f(yaw)}"/>',
             f'      <geometry><box size="{_f(length)} {_f(ARM_WIDTH_M)} '
             f'{_f(ARM_THICKNESS_M)}"/></geometry>']
    if tag == "visual":
        lines.append('      <material name="frame"/>')
    return lines + [f"    </{tag}>"]


def urdf(src: ExportSource) -> str:
    """The URDF text (UTF-8 XML).

    Raises:
        ValueError: see :func:`link_inertias`.
    """
    a, cfg = src.airframe, src.config
    radius = cfg.prop_diameter_mm / 2000.0
    m_b, c_b, J_b, disc = link_inertias(a, radius)
    name = quoteattr(cfg.name)
    out = ['<?xml version="1.0" encoding="utf-8"?>', "<!--"]
    out += [f"  {escape(h).replace('--', '- -')}" for h in src.header_lines("URDF")]
    out += ["  Frame: x forward, y left, z up (REP 103, as casadrone); base_link at the centre of "
            "mass.",
            f"  Links: base_link {m_b:.6g} kg and four props {ROTOR_LINK_MASS_KG:g} kg each; "
            "together the airframe's mass and inertia exactly.",
            "  pybullet: loadURDF(path, flags=pybullet.URDF_USE_INERTIA_FROM_FILE); hover: each "
            "rotor link's hover thrust along its z axis.",
            "-->", f"<robot name={name}>",
            '  <material name="frame"><color rgba="0.15 0.15 0.15 1"/></material>',
            '  <material name="prop"><color rgba="0.2 0.4 0.9 0.5"/></material>',
            '  <link name="base_link">']
    out += _inertial(m_b, c_b, J_b, "    ")
    hub = -a.com  # the arms meet at the hub; base_link is at the centre of mass
    for tag in ("visual", "collision"):
        for r in a.rotor_positions:
            arm = r - hub
            out += _arm(hub + arm / 2, math.atan2(arm[1], arm[0]), math.hypot(arm[0], arm[1]),
                        tag)
    out.append("  </link>")
    disc_shape = (f'<geometry><cylinder radius="{_f(radius)}" length="{_f(PROP_THICKNESS_M)}"/>'
                  "</geometry>")
    for i, r in enumerate(a.rotor_positions):
        link = f"rotor_{ROTOR_LABELS[i]}"
        axis = "0 0 1" if a.rotor_spins[i] < 0 else "0 0 -1"
        out += [f"  <!-- rotor {rotor_label(i, 'betaflight', 'px4')}: {LABELS[i]}, turning "
                f"{spin_word(a.rotor_spins[i])} seen from above -->",
                f'  <link name="{link}">']
        out += _inertial(ROTOR_LINK_MASS_KG, np.zeros(3), disc, "    ")
        out += ["    <visual>",
                '      <origin xyz="0 0 0" rpy="0 0 0"/>',
                f"      {disc_shape}",
                '      <material name="prop"/>',
                "    </visual>",
                "    <collision>",
                '      <origin xyz="0 0 0" rpy="0 0 0"/>',
                f"      {disc_shape}",
                "    </collision>",
                "  </link>",
                f'  <joint name="{link}_joint" type="continuous">',
                '    <parent link="base_link"/>',
                f'    <child link="{link}"/>',
                f'    <origin xyz="{_f(r[0])} {_f(r[1])} {_f(r[2])}" rpy="0 0 0"/>',
                f'    <axis xyz="{axis}"/>',
                "  </joint>"]
    out.append("</robot>")
    return "\n".join(out) + "\n"
