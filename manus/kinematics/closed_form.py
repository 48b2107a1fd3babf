"""The gripper position and the Jacobian's columns in closed form, with :mod:`math`.

For the controller's cycle: no NumPy call per joint. Each equals its NumPy twin of
:mod:`manus.kinematics.forward` (:func:`~manus.kinematics.forward.fk_position`,
:func:`~manus.kinematics.forward.jacobian`); tests keep them equal.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from manus.config import ArmConfig

Vec3 = tuple[float, float, float]
"""A 3-vector as plain floats (the scalar functions below)."""


def gripper_position(q: Sequence[float] | np.ndarray, cfg: ArmConfig) -> Vec3:
    """Gripper position [m] for DH angles ``q`` [rad], shape (6,), in closed form.

    What :func:`fk_position` gives (a test keeps the two equal), with :mod:`math` for the
    controller's cycle: the wrist centre of :mod:`manus.kinematics` plus ``l4`` along the
    approach axis z_6 = R_03 (c4 s5, s4 s5, c5).
    """
    q1, q2, q3, q4, q5, _ = q.tolist() if isinstance(q, np.ndarray) else q
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
    s5 = math.sin(q5)
    a0, a1, a2 = math.cos(q4) * s5, math.sin(q4) * s5, math.cos(q5)
    u = cfg.l2 * c2 + cfg.l3 * s23
    v = cfg.l2 * s2 - cfg.l3 * c23
    # R_03 = [[c1 c23, -s1, c1 s23], [s1 c23, c1, s1 s23], [-s23, 0, c23]]
    zx = c1 * c23 * a0 - s1 * a1 + c1 * s23 * a2
    zy = s1 * c23 * a0 + c1 * a1 + s1 * s23 * a2
    zz = -s23 * a0 + c23 * a2
    return (
        c1 * u - s1 * cfg.l1 + cfg.l4 * zx,
        s1 * u + c1 * cfg.l1 + cfg.l4 * zy,
        -v + cfg.l4 * zz,
    )


def jacobian_columns(
    q: Sequence[float] | np.ndarray, cfg: ArmConfig
) -> list[tuple[float, float, float, float, float, float]]:
    """The geometric Jacobian's columns (what :func:`jacobian` gives) in closed form.

    For the controller's cycle (no NumPy call per joint), from the DH table's
    structure: z_0 = e_z; z_1 = z_2 = (-s1, c1, 0); z_3 = R_03 e_z = (c1 s23, s1 s23, c23);
    z_4 = R_03 (-s4, c4, 0); z_5 = R_03 (c4 s5, s4 s5, c5); origins p_0 = p_1 = 0,
    p_2 = p_3 (the elbow) = R_01 (L2 c2, L2 s2, L1), p_4 = p_5 (the wrist centre)
    = p_2 + L3 z_3, and the gripper p_e = p_4 + L4 z_5. Column i is z_i x (p_e - p_i)
    [m/rad] over z_i [-]; column 5's linear part is z_5 x L4 z_5 = 0. A test keeps it
    equal to :func:`jacobian`.
    """
    q1, q2, q3, q4, q5, _ = q.tolist() if isinstance(q, np.ndarray) else q
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
    c4, s4 = math.cos(q4), math.sin(q4)
    c5, s5 = math.cos(q5), math.sin(q5)
    # R_03 = [[c1 c23, -s1, c1 s23], [s1 c23, c1, s1 s23], [-s23, 0, c23]]
    z1 = (-s1, c1, 0.0)
    z3 = (c1 * s23, s1 * s23, c23)
    a, b = -s4, c4
    z4 = (c1 * c23 * a - s1 * b, s1 * c23 * a + c1 * b, -s23 * a)
    a, b, c = c4 * s5, s4 * s5, c5
    z5 = (
        c1 * c23 * a - s1 * b + c1 * s23 * c,
        s1 * c23 * a + c1 * b + s1 * s23 * c,
        c23 * c - s23 * a,
    )
    r2 = cfg.l2 * c2
    bx, by, bz = c1 * r2 - s1 * cfg.l1, s1 * r2 + c1 * cfg.l1, -cfg.l2 * s2  # elbow
    wx, wy, wz = bx + cfg.l3 * z3[0], by + cfg.l3 * z3[1], bz + cfg.l3 * z3[2]  # wrist
    ex, ey, ez = wx + cfg.l4 * z5[0], wy + cfg.l4 * z5[1], wz + cfg.l4 * z5[2]  # gripper
    columns = [(-ey, ex, 0.0, 0.0, 0.0, 1.0)]
    # z_i x (p_e - p_i): about the base (z_1), the elbow (z_1, z_3), the wrist (z_4)
    for (zx, zy, zz), dx, dy, dz in (
        (z1, ex, ey, ez),
        (z1, ex - bx, ey - by, ez - bz),
        (z3, ex - bx, ey - by, ez - bz),
        (z4, ex - wx, ey - wy, ez - wz),
    ):
        columns.append((zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx, zx, zy, zz))
    columns.append((0.0, 0.0, 0.0, *z5))
    return columns


Rot = tuple[float, float, float, float, float, float, float, float, float]
"""A rotation matrix as plain floats, row by row (the scalar functions below)."""


def gripper_pose(q: Sequence[float] | np.ndarray, cfg: ArmConfig) -> tuple[Vec3, Rot]:
    """Gripper position [m] and rotation (row by row) for DH angles ``q`` [rad], in closed
    form: what :func:`~manus.kinematics.forward.fk` gives (a test keeps them equal), with
    :mod:`math` for the controller's cycle.

    R_06 = R_03 R_36 with R_03 as in :func:`gripper_position` and, from the DH table's
    twists (-90, +90, 0 deg at joints 4, 5, 6), R_36 = [[c4 c5 c6 - s4 s6,
    -c4 c5 s6 - s4 c6, c4 s5], [s4 c5 c6 + c4 s6, -s4 c5 s6 + c4 c6, s4 s5],
    [-s5 c6, s5 s6, c5]].
    """
    q1, q2, q3, q4, q5, q6 = q.tolist() if isinstance(q, np.ndarray) else q
    c1, s1 = math.cos(q1), math.sin(q1)
    c2, s2 = math.cos(q2), math.sin(q2)
    c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
    c4, s4 = math.cos(q4), math.sin(q4)
    c5, s5 = math.cos(q5), math.sin(q5)
    c6, s6 = math.cos(q6), math.sin(q6)
    cols = (
        (c4 * c5 * c6 - s4 * s6, s4 * c5 * c6 + c4 * s6, -s5 * c6),
        (-c4 * c5 * s6 - s4 * c6, -s4 * c5 * s6 + c4 * c6, s5 * s6),
        (c4 * s5, s4 * s5, c5),
    )
    # R_03 v for each column v of R_36
    (xa, ya, za), (xb, yb, zb), (xc, yc, zc) = (
        (
            c1 * c23 * a - s1 * b + c1 * s23 * c,
            s1 * c23 * a + c1 * b + s1 * s23 * c,
            -s23 * a + c23 * c,
        )
        for a, b, c in cols
    )
    u = cfg.l2 * c2 + cfg.l3 * s23
    v = cfg.l2 * s2 - cfg.l3 * c23
    p = (c1 * u - s1 * cfg.l1 + cfg.l4 * xc, s1 * u + c1 * cfg.l1 + cfg.l4 * yc, -v + cfg.l4 * zc)
    return p, (xa, xb, xc, ya, yb, yc, za, zb, zc)
