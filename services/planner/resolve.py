"""Absolute gripper poses of a path's via points, and its boundary joint velocities.

Via point 0 stands for the start: it becomes the gripper pose of the start configuration
(FK). The others resolve by type (docs/protocol.md, Thesis via-point format): 0 absolute, 1
added to via point 0's resolved pose, 2 added to the previous via point's resolved pose.
Positions add as vectors, angles component-wise in (yaw, pitch, roll), as the thesis does.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.config import ArmConfig
from manus.kinematics import fk, jacobian
from manus.orientation import matrix_to_ypr
from schemas.planning import Path, ViaPoint
from services.planner.errors import refuse
from services.planner.labels import KnotLabels

# Condition number of the Jacobian above which a Cartesian boundary velocity is refused.
MAX_JACOBIAN_CONDITION = 1e8


class ResolvedPath(NamedTuple):
    """Every via point as an absolute pose.

    Attributes:
        xyz: gripper positions [m], shape (n, 3).
        ypr: orientations (yaw, pitch, roll) [rad], shape (n, 3).
        poses: homogeneous transforms [m], shape (n, 4, 4).
    """

    xyz: np.ndarray
    ypr: np.ndarray
    poses: np.ndarray


def resolve_path(path: Path, q_start: np.ndarray, arm: ArmConfig) -> ResolvedPath:
    """Absolute poses of ``path``'s via points, the first being the start's FK."""
    T0 = fk(q_start, arm)
    first = [*T0[:3, 3].tolist(), *matrix_to_ypr(T0[:3, :3])]
    rows = [first]
    for vp in path.via_points[1:]:
        row = [*vp.xyz, *vp.ypr]
        if vp.type:
            base = first if vp.type == 1 else rows[-1]
            row = [b + r for b, r in zip(base, row, strict=True)]
        rows.append(row)
    a = np.array(rows)
    poses = np.zeros((len(a), 4, 4))
    poses[:, :3, :3] = ypr_to_matrices(a[:, 3:])
    poses[:, :3, 3] = a[:, :3]
    poses[:, 3, 3] = 1.0
    poses[0] = T0  # exactly the start's pose, not its (yaw, pitch, roll) round trip
    return ResolvedPath(a[:, :3], a[:, 3:], poses)


def ypr_to_matrices(ypr: np.ndarray) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) for rows of (yaw, pitch, roll) [rad]: (n, 3) -> (n, 3, 3).

    The batched twin of :func:`manus.orientation.ypr_to_matrix` (a test keeps them equal).
    """
    cy, sy = np.cos(ypr[:, 0]), np.sin(ypr[:, 0])
    cp, sp = np.cos(ypr[:, 1]), np.sin(ypr[:, 1])
    cr, sr = np.cos(ypr[:, 2]), np.sin(ypr[:, 2])
    R = np.empty((len(ypr), 3, 3))
    R[:, 0, 0] = cy * cp
    R[:, 0, 1] = cy * sp * sr - sy * cr
    R[:, 0, 2] = cy * sp * cr + sy * sr
    R[:, 1, 0] = sy * cp
    R[:, 1, 1] = sy * sp * sr + cy * cr
    R[:, 1, 2] = sy * sp * cr - cy * sr
    R[:, 2, 0] = -sp
    R[:, 2, 1] = cp * sr
    R[:, 2, 2] = cp * cr
    return R


def ypr_rates_to_angular_velocity(ypr: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """Angular velocity [rad/s] (base frame) of R = Rz(yaw) Ry(pitch) Rx(roll) when
    (yaw, pitch, roll) change at ``rates`` [rad/s], shape (3,)."""
    yaw, pitch = float(ypr[0]), float(ypr[1])
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    # omega = yaw' z + pitch' Rz(yaw) y + roll' Rz(yaw) Ry(pitch) x
    E = np.array([[0.0, -sy, cy * cp], [0.0, cy, sy * cp], [1.0, 0.0, -sp]])
    return np.asarray(E @ rates)


def boundary_twist(vp: ViaPoint, ypr: np.ndarray) -> np.ndarray:
    """Via point ``vp``'s Cartesian velocity as a twist (linear [m/s], angular [rad/s],
    base frame), shape (6,), at its orientation ``ypr`` [rad]."""
    linear = np.array(vp.velocity, dtype=float)
    rates = np.array(vp.angular_velocity, dtype=float)
    if not (linear.any() or rates.any()):
        return np.zeros(6)
    return np.concatenate([linear, ypr_rates_to_angular_velocity(ypr, rates)])


def twist_joint_velocity(
    twist: np.ndarray, q: np.ndarray, arm: ArmConfig, labels: KnotLabels, k: int
) -> np.ndarray:
    """Joint velocities [rad/s] giving ``twist`` (shape (6,), as :func:`boundary_twist`)
    at knot ``k``'s configuration ``q`` [rad].

    Raises:
        PlanningError: ``singular`` when the twist is not zero and the Jacobian at ``q``
            cannot be inverted.
    """
    if not twist.any():
        return np.zeros(len(q))
    J = jacobian(q, arm)
    cond = float(np.linalg.cond(J))
    if not cond < MAX_JACOBIAN_CONDITION:
        raise refuse(
            "singular",
            f"{labels.label(k)}: its velocity cannot be turned into joint "
            f"velocities: the Jacobian there is singular (condition number {cond:.3g}, "
            f"limit {MAX_JACOBIAN_CONDITION:.0e}); give this via point zero velocity",
            via_point=labels.via_indices[k],
            line=labels.lines[k],
            value=cond,
            limit=MAX_JACOBIAN_CONDITION,
        )
    return np.asarray(np.linalg.solve(J, twist))
