"""The arm as Foxglove draws it: a URDF with visual geometry, and its link transforms.

The joints are those of :mod:`manus.urdf` (same names, origins and axes: each DH step
A_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i) is a revolute joint about z whose origin is
the fixed part of step i - 1), so link ``link<i>`` sits at T_0^(i-1) Rz(q_i) and
``gripper_frame`` at T_0^6, the pose the whole stack calls "the gripper pose". What this
module adds, for drawing only: cylinders along each link's offsets (d along z, then a
along x), a column under the base, a palm and two fingers whose prismatic joints
(``finger_left``, ``finger_right``, along the gripper frame's y) open by half the
gripper opening each. No meshes: the file needs nothing but itself (the app may be
offline).

:func:`link_transforms` gives the parent -> child transform of every joint for joint
angles and a gripper opening: what the viewer publishes as ``foxglove.FrameTransforms``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from manus.config import ArmConfig
from manus.kinematics import dh_table
from manus.urdf import GRIPPER_FRAME

ROOT_FRAME = "base_link"
JOINT_NAMES = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")
LINK_NAMES = ("link1", "link2", "link3", "link4", "link5", "link6")
FINGERS = (("finger_left", 1.0), ("finger_right", -1.0))
"""Finger links and the sign of their motion along the gripper frame's y axis."""

_RADIUS = 0.035  # link tube radius [m]
_HOUSING = (0.045, 0.10)  # joint housing radius, length [m]
_COLUMN = (0.06, 0.30)  # base column radius, height below base_link [m]
_PALM = (0.04, 0.11, 0.05)  # palm box x, y, z [m], behind the gripper frame
_FINGER = (0.025, 0.012, 0.07)  # finger box x, y, z [m], ending at the gripper frame
_COLORS = {
    "base": "0.35 0.35 0.38 1",
    "arm": "0.85 0.85 0.88 1",
    "joint": "0.20 0.45 0.80 1",
    "gripper": "0.95 0.55 0.10 1",
}


def fmt(x: float) -> str:
    """Shortest text that reads back as the same float (as :mod:`manus.urdf` writes)."""
    text = repr(float(x)).removesuffix(".0")
    return "0" if text in ("-0", "0") else text


class Transform(NamedTuple):
    """One parent -> child transform (a point p in the child is R p + t in the parent).

    Attributes:
        parent: parent frame id.
        child: child frame id.
        translation: t [m], (x, y, z).
        rotation: R as a unit quaternion (x, y, z, w).
    """

    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


def _quat_rx_rz(alpha: float, q: float) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w) of Rx(alpha) Rz(q)."""
    ca, sa = math.cos(alpha / 2), math.sin(alpha / 2)
    cq, sq = math.cos(q / 2), math.sin(q / 2)
    # (sa i + ca)(sq k + cq) = sa cq i - sa sq j + ca sq k + ca cq
    return (sa * cq, -sa * sq, ca * sq, ca * cq)


def link_transforms(q: Sequence[float], gripper: float, cfg: ArmConfig) -> list[Transform]:
    """Parent -> child transform of every joint of :func:`build_visual_urdf`.

    Args:
        q: DH joint angles q1..q6 [rad], shape (6,).
        gripper: gripper opening [m] (clipped to 0..gripper_max).
        cfg: the arm's geometry.

    Returns:
        base_link -> link1, ..., link5 -> link6, link6 -> gripper_frame, and
        gripper_frame -> each finger: 9 transforms.
    """
    out: list[Transform] = []
    parent = ROOT_FRAME
    fixed = (0.0, 0.0, 0.0)  # (d, a, alpha) of the previous DH step
    for (a, alpha, d), link, angle in zip(dh_table(cfg), LINK_NAMES, q, strict=True):
        d_prev, a_prev, alpha_prev = fixed
        out.append(
            Transform(parent, link, (a_prev, 0.0, d_prev), _quat_rx_rz(alpha_prev, float(angle)))
        )
        fixed = (d, a, alpha)
        parent = link
    d_last, a_last, alpha_last = fixed
    out.append(
        Transform(parent, GRIPPER_FRAME, (a_last, 0.0, d_last), _quat_rx_rz(alpha_last, 0.0))
    )
    half = min(max(gripper, 0.0), cfg.gripper_max) / 2
    for name, sign in FINGERS:
        out.append(
            Transform(GRIPPER_FRAME, name, (0.0, sign * (half + _FINGER[1] / 2), 0.0), (0, 0, 0, 1))
        )
    return out


def _cylinder(radius: float, length: float, xyz: str, rpy: str, color: str) -> list[str]:
    return [
        "    <visual>",
        f'      <origin xyz="{xyz}" rpy="{rpy}"/>',
        f'      <geometry><cylinder radius="{fmt(radius)}" length="{fmt(length)}"/></geometry>',
        f'      <material name="{color}"><color rgba="{_COLORS[color]}"/></material>',
        "    </visual>",
    ]


def _box(size: tuple[float, float, float], xyz: str, color: str) -> list[str]:
    return [
        "    <visual>",
        f'      <origin xyz="{xyz}" rpy="0 0 0"/>',
        f'      <geometry><box size="{" ".join(fmt(s) for s in size)}"/></geometry>',
        f'      <material name="{color}"><color rgba="{_COLORS[color]}"/></material>',
        "    </visual>",
    ]


def _link_visuals(a: float, d: float) -> list[str]:
    """A housing around the joint axis, then a tube d along z and a tube a along x."""
    lines = _cylinder(_HOUSING[0], _HOUSING[1], "0 0 0", "0 0 0", "joint")
    if d > 0:
        lines += _cylinder(_RADIUS, d, f"0 0 {fmt(d / 2)}", "0 0 0", "arm")
    if a > 0:
        lines += _cylinder(_RADIUS, a, f"{fmt(a / 2)} 0 {fmt(d)}", f"0 {fmt(math.pi / 2)} 0", "arm")
    return lines


def build_visual_urdf(cfg: ArmConfig) -> str:
    """URDF text of the arm with visual geometry (joints as :func:`manus.urdf.build_urdf`)."""
    lines = [
        '<?xml version="1.0"?>',
        "<!-- Generated by services.viewer.model for Foxglove; joints as manus/urdf.py. -->",
        '<robot name="manus">',
        f'  <link name="{ROOT_FRAME}">',
        *_cylinder(
            _COLUMN[0], _COLUMN[1], f"0 0 {fmt(-_COLUMN[1] / 2 - _HOUSING[1] / 2)}", "0 0 0", "base"
        ),
        "  </link>",
    ]
    parent = ROOT_FRAME
    fixed = (0.0, 0.0, 0.0)
    for i, ((a, alpha, d), joint, link) in enumerate(
        zip(dh_table(cfg), JOINT_NAMES, LINK_NAMES, strict=True)
    ):
        d_prev, a_prev, alpha_prev = fixed
        lines += [
            f'  <joint name="{joint}" type="revolute">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{link}"/>',
            f'    <origin xyz="{fmt(a_prev)} 0 {fmt(d_prev)}" rpy="{fmt(alpha_prev)} 0 0"/>',
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{fmt(cfg.lower[i])}" upper="{fmt(cfg.upper[i])}" '
            f'effort="20" velocity="{fmt(cfg.max_speed[i])}"/>',
            "  </joint>",
            f'  <link name="{link}">',
            *_link_visuals(a, d),
            "  </link>",
        ]
        fixed = (d, a, alpha)
        parent = link
    d_last, a_last, alpha_last = fixed
    palm_z = -_FINGER[2] - _PALM[2] / 2
    lines += [
        '  <joint name="gripper_fixed" type="fixed">',
        f'    <parent link="{parent}"/>',
        f'    <child link="{GRIPPER_FRAME}"/>',
        f'    <origin xyz="{fmt(a_last)} 0 {fmt(d_last)}" rpy="{fmt(alpha_last)} 0 0"/>',
        "  </joint>",
        f'  <link name="{GRIPPER_FRAME}">',
        *_box(_PALM, f"0 0 {fmt(palm_z)}", "gripper"),
        "  </link>",
    ]
    for name, sign in FINGERS:
        lines += [
            f'  <joint name="{name}" type="prismatic">',
            f'    <parent link="{GRIPPER_FRAME}"/>',
            f'    <child link="{name}"/>',
            '    <origin xyz="0 0 0" rpy="0 0 0"/>',
            f'    <axis xyz="0 {fmt(sign)} 0"/>',
            f'    <limit lower="0" upper="{fmt(cfg.gripper_max / 2 + _FINGER[1] / 2)}" '
            'effort="20" velocity="0.1"/>',
            "  </joint>",
            f'  <link name="{name}">',
            *_box(_FINGER, f"0 0 {fmt(-_FINGER[2] / 2)}", "gripper"),
            "  </link>",
        ]
    lines += ["</robot>", ""]
    return "\n".join(lines)


def quaternion(R: np.ndarray) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) of a rotation matrix, shape (3, 3)."""
    m = R
    tr = float(m[0, 0] + m[1, 1] + m[2, 2])
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        return ((m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4)
    i = int(np.argmax([m[0, 0], m[1, 1], m[2, 2]]))
    j, k = (i + 1) % 3, (i + 2) % 3
    s = math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k]) * 2
    q = [0.0, 0.0, 0.0, 0.0]
    q[i] = s / 4
    q[j] = (m[j, i] + m[i, j]) / s
    q[k] = (m[k, i] + m[i, k]) / s
    q[3] = (m[k, j] - m[j, k]) / s
    return (q[0], q[1], q[2], q[3])
