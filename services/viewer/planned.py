"""A planned trajectory as the viewer draws it: the gripper's path, its via points and the
gripper pose at each knot, in the base frame."""

from __future__ import annotations

import math
from typing import NamedTuple

from manus.config import ArmConfig
from manus.kinematics import fk
from manus.trajectory import JointTrajectory
from schemas.planning import Trajectory
from services.viewer.model import quaternion


class PlannedPath(NamedTuple):
    """What is drawn of one trajectory.

    Attributes:
        points: the gripper's path [m], each (x, y, z): the trajectory's preview, else the
            forward kinematics of samples ``preview_dt_s`` apart.
        via: the via points [m] (the knots' gripper positions when the trajectory has none).
        poses: the gripper pose at each knot: position [m] and quaternion (x, y, z, w).
    """

    points: list[list[float]]
    via: list[list[float]]
    poses: list[tuple[list[float], tuple[float, float, float, float]]]


def planned_path(traj: Trajectory, cfg: ArmConfig, preview_dt_s: float) -> PlannedPath:
    """The drawing of ``traj`` for the arm ``cfg``.

    Raises:
        ManusError, ValueError, IndexError: the trajectory does not sample (the viewer
            counts it as a bad payload).
    """
    poses = []
    for q in traj.positions:
        T = fk(q, cfg)
        poses.append(([float(v) for v in T[:3, 3]], quaternion(T[:3, :3])))
    if traj.preview_xyz:
        points = [list(p) for p in traj.preview_xyz]
    else:
        jt = JointTrajectory(traj)
        n = max(2, math.ceil(jt.duration / preview_dt_s) + 1)
        points = [
            [float(v) for v in fk(jt.sample(jt.duration * i / (n - 1)).q, cfg)[:3, 3]]
            for i in range(n)
        ]
    via = [list(v) for v in traj.via_xyz] if traj.via_xyz else [p for p, _ in poses]
    return PlannedPath(points, via, poses)
