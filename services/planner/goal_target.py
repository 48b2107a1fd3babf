"""A :class:`schemas.goals.Goal` as the planner aims at it: a joint configuration, or a
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
from schemas.goals import Goal, GoalKind
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


def resolve_target(goal: Goal, scene: Scene | None, poses: dict[str, NamedPose]) -> Target:
    """The :class:`Target` of ``goal`` (``line`` goals are :mod:`.line`'s).

    Raises:
        PlanningError: ``invalid``: a field the kind needs is missing, the name is
            unknown, or the object is not in the scene.
    """
    kind = goal.kind
    if kind == GoalKind.JOINTS:
        if goal.joints is None:
            raise refuse("invalid", "a joints goal needs `joints` (6 DH angles)")
        q = np.array(goal.joints, dtype=float)
        if not np.isfinite(q).all():
            raise refuse("invalid", f"joints goal: `joints` must be finite, got {goal.joints}")
        deg = ", ".join(f"{v:.1f}" for v in np.degrees(q))
        return Target(f"joints ({deg}) deg", joints=q)
    if kind == GoalKind.NAMED:
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
    if kind in (GoalKind.POSE, GoalKind.OBJECT):
        T = _pose_of(goal)
        label = f"pose {describe_pose(T)}"
        if kind == GoalKind.OBJECT:
            frame = object_frame(goal.name, scene)
            T = frame @ T
            label = (
                f"object {goal.name!r} offset {describe_pose(_pose_of(goal))}: {describe_pose(T)}"
            )
        return Target(label, None, T, goal.position_tolerance, goal.angle_tolerance, goal.free_axis)
    raise refuse("invalid", f"a {kind} goal is not a target (it is planned by its own planner)")


def _pose_of(goal: Goal) -> np.ndarray:
    if goal.xyz is None or goal.ypr is None:
        raise refuse("invalid", f"a {goal.kind} goal needs `xyz` and `ypr`")
    values = [*goal.xyz, *goal.ypr]
    if not all(math.isfinite(v) for v in values):
        raise refuse("invalid", f"{goal.kind} goal: `xyz` and `ypr` must be finite, got {values}")
    return pose_matrix(np.array(goal.xyz), (goal.ypr[0], goal.ypr[1], goal.ypr[2]))


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
