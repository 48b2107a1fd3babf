"""A goal (:mod:`schemas.goals`) as the planner aims at it: a joint configuration, or a
gripper pose in the base frame with its tolerances.

``named`` goals are looked up in the named poses (:mod:`manus.named_poses`), ``object``
goals in the scene in use: the object's frame in the base frame times the offset.
Everything the goal leaves unclear is refused here as ``invalid``, naming the field.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.named_poses import NamedPose, NamedPoseError, find_pose
from manus.orientation import matrix_to_ypr, pose_matrix
from manus.scene import Scene
from schemas.goals import JointGoal, NamedGoal, ObjectGoal, TargetGoal
from services.planner.errors import refuse


class Target(NamedTuple):
    """Where a goal ends, in the base frame.

    Attributes:
        label: how messages name it (``pose (560.0, 100.0, -150.0) mm ...``).
        joints: the configuration [rad], shape (6,); None for a pose.
        pose: the gripper pose [m], shape (4, 4); None for a configuration.
        position_tolerance: [m].
        angle_tolerance: [rad].
        free_axis: any rotation about the gripper's approach axis is fine.
    """

    label: str
    joints: np.ndarray | None = None
    pose: np.ndarray | None = None
    position_tolerance: float = 0.0
    angle_tolerance: float = 0.0
    free_axis: bool = False


def describe_pose(T: np.ndarray) -> str:
    """``(560.0, 100.0, -150.0) mm, ypr (0.0, 90.0, 0.0) deg`` of a base-frame pose."""
    p = T[:3, 3] * 1e3 + 0.0  # (+ 0.0: no "-0.0")
    ypr = np.round(np.degrees(matrix_to_ypr(T[:3, :3])), 6) + 0.0
    return (
        f"({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm, "
        f"ypr ({ypr[0]:.1f}, {ypr[1]:.1f}, {ypr[2]:.1f}) deg"
    )


def resolve_target(goal: TargetGoal, scene: Scene | None, poses: dict[str, NamedPose]) -> Target:
    """The :class:`Target` of ``goal``.

    Raises:
        PlanningError: ``invalid``: a value not finite, the name unknown, or the object
            not in the scene.
    """
    if isinstance(goal, JointGoal):
        q = np.array(goal.joints, dtype=float)
        if not np.isfinite(q).all():
            raise refuse("invalid", f"joints goal: `joints` must be finite, got {goal.joints}")
        deg = ", ".join(f"{v:.1f}" for v in np.degrees(q) + 0.0)
        return Target(f"joints ({deg}) deg", joints=q)
    if isinstance(goal, NamedGoal):
        try:
            named = find_pose(poses, goal.name)
        except NamedPoseError as exc:
            raise refuse("invalid", str(exc)) from exc
        label = f"named pose {named.name!r} ({named.source})"
        if named.joints is not None:
            return Target(label, joints=np.array(named.joints))
        assert named.xyz is not None and named.ypr is not None
        T = pose_matrix(np.array(named.xyz), (named.ypr[0], named.ypr[1], named.ypr[2]))
        return Target(
            label, None, T, named.position_tolerance, named.angle_tolerance, named.free_axis
        )
    T = _pose(goal.kind, goal.xyz, goal.ypr)
    label = f"pose {describe_pose(T)}"
    if isinstance(goal, ObjectGoal):
        label = f"object {goal.name!r} offset {describe_pose(T)}"
        T = object_frame(goal.name, scene) @ T
        label = f"{label}: {describe_pose(T)}"
    tol = goal.tolerance
    return Target(label, None, T, tol.position, tol.angle, tol.free_axis)


def _pose(kind: str, xyz: list[float], ypr: list[float]) -> np.ndarray:
    values = [*xyz, *ypr]
    if not all(math.isfinite(v) for v in values):
        raise refuse("invalid", f"{kind} goal: `xyz` and `ypr` must be finite, got {values}")
    return pose_matrix(np.array(xyz), (ypr[0], ypr[1], ypr[2]))


def object_frame(name: str, scene: Scene | None) -> np.ndarray:
    """The frame of the scene object ``name`` in the arm's base frame [m], (4, 4).

    Raises:
        PlanningError: ``invalid``: no scene, or no such object (listing them).
    """
    if scene is None:
        raise refuse("invalid", f"object goal {name!r}: no scene is in use (scene 'none')")
    for obj in scene.objects:
        if obj.name == name:
            return scene.in_base(obj.body.pose)
    known = ", ".join(o.name for o in scene.objects)
    raise refuse(
        "invalid",
        f"object goal: {name!r} is not an object of the scene {scene.source} "
        f"version {scene.version} (objects: {known})",
    )
