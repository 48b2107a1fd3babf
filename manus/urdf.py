"""A URDF of the Manus generated from the same DH parameters as :mod:`manus.kinematics`.

Each DH step A_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i) becomes a revolute joint about z
(the Rz(q_i) part) whose child link is followed by the fixed part Tz(d_i) Tx(a_i)
Rx(alpha_i), carried as the origin of the next joint. The last fixed part becomes the
fixed joint to ``gripper_frame``, the frame the whole stack calls "the gripper pose".

The shipped file ``manus/data/manus.urdf`` is this module's output for the default
configuration; a test keeps the two equal. Regenerate with ``manus kin urdf``.
Masses are rough (13 kg in all, docs/protocol.md, Mechanics) and only meant for
visualisation tools.

Collision geometry (:func:`collision_shapes`): one cylinder or sphere per body, in the
frame of the link that carries it, named so that :mod:`manus.collision` and the scene's
error messages can say which part of the arm is meant: the base ``column`` the arm stands
on, the ``shoulder`` housing (joint 1), the ``shoulder_offset`` (the L1 stub along joint
2's axis), the ``upper_arm``, the ``forearm``, the ``wrist`` housing, the gripper's
``gripper_motor`` and the ``gripper`` box (palm and fingers; the URDF holds it fully
open, :class:`manus.collision.CollisionModel` sizes it to the current opening). Radii
are the Manus tubes' (about 90 mm across the upper arm, 80 mm the forearm) rounded up.
"""

from __future__ import annotations

import math
from importlib import resources
from pathlib import Path
from typing import NamedTuple

from manus.config import ArmConfig
from manus.kinematics import dh_table

# Rough link masses [kg] adding to the arm's 13 kg (motors sit in the base).
_MASSES = (6.0, 3.0, 1.5, 1.2, 0.6, 0.7)
_NAMES = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")


def _f(x: float) -> str:
    """Shortest text that reads back as the same float (no -0, no trailing .0)."""
    text = repr(float(x))
    text = text.removesuffix(".0")
    return "0" if text in ("-0", "0") else text


class Shape(NamedTuple):
    """One collision body of the arm, in its link's frame.

    Attributes:
        name: the body's name (unique in the arm).
        link: the URDF link carrying it (``base_link``, ``link1`` .. ``link6``).
        kind: ``cylinder`` (axis along its local z), ``sphere`` or ``box``.
        size: cylinder (radius, length), sphere (radius,), box (x, y, z) sizes [m].
        xyz: its centre in the link frame [m], shape (3,).
        rpy: its orientation in the link frame (roll, pitch, yaw) [rad], shape (3,).
    """

    name: str
    link: str
    kind: str
    size: tuple[float, ...]
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


COLUMN_LENGTH = 0.35
"""Length of the column under the shoulder, down to the mount on the chair [m]."""

GRIPPER_DEPTH = 0.10
"""Length of the gripper box along the approach axis, ending 10 mm past the gripper
frame (the fingertips) [m]."""

FINGER_THICKNESS = 0.015
"""Thickness of one finger [m]: the gripper box is the opening plus two of these wide."""

GRIPPER_FRAME = "gripper_frame"
"""The link of the gripper pose (fixed to ``link6``): what held objects attach to."""


def collision_shapes(cfg: ArmConfig | None = None, opening: float | None = None) -> list[Shape]:
    """The arm's collision bodies for the geometry of ``cfg``.

    Args:
        cfg: arm geometry (default: the thesis arm).
        opening: gripper opening [m] the gripper box is sized for (default: fully open).

    Link frames are the URDF's: link i is DH frame i-1 turned by q_i, so joint i's axis
    is its z; the DH lengths lie along z (d) and then x (a) of that frame.
    """
    cfg = cfg or ArmConfig()
    width = (cfg.gripper_max if opening is None else opening) + 2.0 * FINGER_THICKNESS
    half_pi = math.pi / 2.0
    return [
        Shape(
            "column",
            "base_link",
            "cylinder",
            (0.05, COLUMN_LENGTH),
            (0.0, 0.0, -0.08 - COLUMN_LENGTH / 2.0),
        ),
        Shape("shoulder", "link1", "cylinder", (0.06, 0.12), (0.0, 0.0, -0.02)),
        Shape("shoulder_offset", "link2", "cylinder", (0.05, cfg.l1), (0.0, 0.0, cfg.l1 / 2.0)),
        Shape(
            "upper_arm",
            "link2",
            "cylinder",
            (0.045, cfg.l2),
            (cfg.l2 / 2.0, 0.0, cfg.l1),
            (0.0, half_pi, 0.0),
        ),
        Shape(
            "forearm",
            "link4",
            "cylinder",
            (0.04, cfg.l3 - 0.045),
            (0.0, 0.0, (cfg.l3 - 0.045) / 2.0),
        ),
        Shape("wrist", "link5", "sphere", (0.045,), (0.0, 0.0, 0.0)),
        Shape("gripper_motor", "link6", "cylinder", (0.04, 0.07), (0.0, 0.0, 0.035)),
        Shape(
            "gripper",
            "link6",
            "box",
            (width, 0.05, GRIPPER_DEPTH),
            (0.0, 0.0, cfg.l4 + 0.01 - GRIPPER_DEPTH / 2.0),
        ),
    ]


def _collision_xml(shape: Shape) -> list[str]:
    if shape.kind == "cylinder":
        geometry = f'<cylinder radius="{_f(shape.size[0])}" length="{_f(shape.size[1])}"/>'
    elif shape.kind == "sphere":
        geometry = f'<sphere radius="{_f(shape.size[0])}"/>'
    else:
        geometry = f'<box size="{" ".join(_f(v) for v in shape.size)}"/>'
    xyz = " ".join(_f(v) for v in shape.xyz)
    rpy = " ".join(_f(v) for v in shape.rpy)
    return [
        f'    <collision name="{shape.name}">',
        f'      <origin xyz="{xyz}" rpy="{rpy}"/>',
        f"      <geometry>{geometry}</geometry>",
        "    </collision>",
    ]


def build_urdf(cfg: ArmConfig | None = None) -> str:
    """URDF text of the arm with geometry and limits from ``cfg``."""
    cfg = cfg or ArmConfig()
    table = dh_table(cfg)
    shapes = collision_shapes(cfg)

    def collisions(link: str) -> list[str]:
        return [text for s in shapes if s.link == link for text in _collision_xml(s)]

    lines = [
        '<?xml version="1.0"?>',
        "<!-- Generated by manus.urdf from the DH table of docs/protocol.md; do not edit. -->",
        '<robot name="manus">',
        '  <link name="base_link">',
        *collisions("base_link"),
        "  </link>",
    ]
    previous = "base_link"
    # The fixed part that precedes joint i is the (d, a, alpha) of DH step i - 1.
    fixed = (0.0, 0.0, 0.0)
    for i, name in enumerate(_NAMES):
        d_prev, a_prev, alpha_prev = fixed
        link = f"link{i + 1}"
        lines += [
            f'  <joint name="{name}" type="revolute">',
            f'    <parent link="{previous}"/>',
            f'    <child link="{link}"/>',
            f'    <origin xyz="{_f(a_prev)} 0 {_f(d_prev)}" rpy="{_f(alpha_prev)} 0 0"/>',
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{_f(cfg.lower[i])}" upper="{_f(cfg.upper[i])}" '
            f'effort="20" velocity="{_f(cfg.max_speed[i])}"/>',
            "  </joint>",
            f'  <link name="{link}">',
            "    <inertial>",
            '      <origin xyz="0 0 0" rpy="0 0 0"/>',
            f'      <mass value="{_f(_MASSES[i])}"/>',
            '      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>',
            "    </inertial>",
            *collisions(link),
            "  </link>",
        ]
        a, alpha, d = table[i]
        fixed = (d, a, alpha)
        previous = link
    d_last, a_last, alpha_last = fixed
    lines += [
        '  <joint name="gripper_fixed" type="fixed">',
        f'    <parent link="{previous}"/>',
        f'    <child link="{GRIPPER_FRAME}"/>',
        f'    <origin xyz="{_f(a_last)} 0 {_f(d_last)}" rpy="{_f(alpha_last)} 0 0"/>',
        "  </joint>",
        f'  <link name="{GRIPPER_FRAME}"/>',
        "</robot>",
        "",
    ]
    return "\n".join(lines)


def shipped_urdf_path() -> Path:
    """Path of the URDF shipped with the package (default geometry)."""
    return Path(str(resources.files("manus") / "data" / "manus.urdf"))
