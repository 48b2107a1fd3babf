"""Where the gripper goes to grasp an object: the candidate grasps of one object, in the
chair frame, from its class's :class:`~manus.grasps.GraspClass` (docs/pick.md).

The gripper frame (the stack's gripper pose): z along the approach, x the jaw axis, the
origin between the fingertips' pads. A **side** grasp comes in horizontally (or pitched
down by each of the class's ``pitches``, one candidate each) with the gripper's y up (from
the chair's z, not the object's noisy observed axis); its candidate directions turn about
the vertical from the direction the arm's shoulder sees the object in, nearest first. A
**top** grasp comes straight down, its jaws across the object's y extent, turned by the
class's yaw step.

A candidate whose straight approach would run the gripper through another object of the
world is set aside (:func:`blocked_by`): the collision model does not hold free objects
(docs/objects.md, Limits), so this is where a cup beside a bottle is taken care of.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from manus.grasps import Approach, GraspClass
from manus.orientation import pose_matrix
from schemas.objects import ObjectShape, WorldObject

GRIPPER_HALF_WIDTH_M = 0.06
"""Half the gripper's width across its jaw axis and beyond its open fingers [m]: what an
approach must keep off another object."""

GRIPPER_BACK_M = 0.16
"""How far behind the grasp point the gripper body reaches [m] (fingers and palm)."""


class Grasp(NamedTuple):
    """One candidate grasp of an object.

    Attributes:
        label: how messages name it (``side, from yaw 12 deg``).
        grasp: the gripper pose at the grasp, chair frame [m], (4, 4).
        pregrasp: the gripper pose before the straight approach, chair frame [m], (4, 4).
        width: the object's extent along the jaw axis [m].
    """

    label: str
    grasp: np.ndarray
    pregrasp: np.ndarray
    width: float


def object_pose(obj: WorldObject) -> np.ndarray:
    """``obj``'s pose (4, 4) in the chair frame (or its link's, attached) [m]."""
    return pose_matrix(np.array(obj.xyz), (obj.ypr[0], obj.ypr[1], obj.ypr[2]))


def extent_along(obj: WorldObject, axis: np.ndarray) -> float:
    """The object's extent along the unit chair-frame direction ``axis`` [m]."""
    if obj.shape in (ObjectShape.SPHERE, ObjectShape.CYLINDER, ObjectShape.CAPSULE):
        if obj.shape == ObjectShape.SPHERE:
            return 2.0 * obj.size[0]
        R = object_pose(obj)[:3, :3]
        along = abs(float(R[:, 2] @ axis))  # the axis of a cylinder or capsule
        length = obj.size[1] + (2.0 * obj.size[0] if obj.shape == ObjectShape.CAPSULE else 0.0)
        return 2.0 * obj.size[0] * math.sqrt(max(0.0, 1.0 - along**2)) + length * along
    R = object_pose(obj)[:3, :3]
    return float(sum(abs(float(R[:, i] @ axis)) * obj.size[i] for i in range(3)))


def _frame(x: np.ndarray, y: np.ndarray, z: np.ndarray, origin: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, origin
    return T


def _turns(step: float, span: float) -> list[float]:
    """0, +step, -step, +2 step, ... within ``span`` [rad], no turn twice (mod 2 pi)."""
    out: list[float] = []
    k = 0
    while k * step <= span + 1e-9:
        for turn in (k * step, -k * step):
            if all(abs(math.remainder(turn - t, math.tau)) > 1e-6 for t in out):
                out.append(turn)
        k += 1
    return out


def grasps_of(obj: WorldObject, how: GraspClass, shoulder: np.ndarray) -> list[Grasp]:
    """The candidate grasps of ``obj`` (in the world, chair frame), preferred first; it is
    taken as standing upright (objects rest upright), its observed yaw kept.

    Args:
        obj: the object.
        how: its class's grasps.
        shoulder: the arm's shoulder in the chair frame [m], shape (3,).
    """
    obj = replace(obj, ypr=[obj.ypr[0], 0.0, 0.0])  # it rests upright: no noisy lean
    centre = np.array(obj.xyz) + np.array([0.0, 0.0, how.height])
    up = np.array([0.0, 0.0, 1.0])
    out: list[Grasp] = []
    if how.approach == Approach.SIDE:
        seen = centre - shoulder
        base = math.atan2(seen[1], seen[0])
        for turn in _turns(how.yaw_step, how.yaw_span):
            yaw = base + turn
            for pitch in how.pitches:
                c = math.cos(pitch)
                z = np.array([c * math.cos(yaw), c * math.sin(yaw), -math.sin(pitch)])
                y = up - (up @ z) * z
                y /= np.linalg.norm(y)
                T = _frame(np.cross(y, z), y, z, centre)
                label = f"side, from yaw {math.degrees(math.remainder(yaw, math.tau)):.0f} deg" + (
                    f" pitch {math.degrees(pitch):.0f}" if len(how.pitches) > 1 else ""
                )
                out.append(_grasp(label, T, how, extent_along(obj, T[:3, 0])))
        return out
    R = object_pose(obj)[:3, :3]
    across = R[:, 1] - (R[:, 1] @ up) * up
    base = math.atan2(across[1], across[0])
    for turn in _turns(how.yaw_step, how.yaw_span):
        yaw = base + turn
        x = np.array([math.cos(yaw), math.sin(yaw), 0.0])
        z = -up
        T = _frame(x, np.cross(z, x), z, centre)
        label = f"top, jaws at yaw {math.degrees(math.remainder(yaw, math.tau)):.0f} deg"
        out.append(_grasp(label, T, how, extent_along(obj, x)))
    return out


def _grasp(label: str, T: np.ndarray, how: GraspClass, width: float) -> Grasp:
    pre = T.copy()
    pre[:3, 3] = T[:3, 3] - how.pregrasp * T[:3, 2]
    return Grasp(label, T, pre, width)


def blocked_by(grasp: Grasp, others: list[WorldObject]) -> str:
    """The id of another object the gripper would run through on ``grasp``'s straight
    approach ('' when none): the corridor from behind the pregrasp pose to the grasp,
    as wide as the gripper, against each object's bounding cylinder (upright)."""
    a = grasp.pregrasp[:3, 3] - GRIPPER_BACK_M * grasp.pregrasp[:3, 2]
    b = grasp.grasp[:3, 3]
    for obj in others:
        radius = _footprint_radius(obj)
        half_height = _half_height(obj)
        c = np.array(obj.xyz)
        if min(a[2], b[2]) - GRIPPER_HALF_WIDTH_M > c[2] + half_height:
            continue  # the corridor passes above it
        if max(a[2], b[2]) + GRIPPER_HALF_WIDTH_M < c[2] - half_height:
            continue
        if _segment_distance_xy(a, b, c) < radius + GRIPPER_HALF_WIDTH_M:
            return obj.id
    return ""


def _footprint_radius(obj: WorldObject) -> float:
    if obj.shape == ObjectShape.BOX:
        return 0.5 * math.hypot(obj.size[0], obj.size[1])
    return obj.size[0]


def _half_height(obj: WorldObject) -> float:
    if obj.shape == ObjectShape.BOX:
        return 0.5 * obj.size[2]
    if obj.shape == ObjectShape.SPHERE:
        return obj.size[0]
    extra = obj.size[0] if obj.shape == ObjectShape.CAPSULE else 0.0
    return 0.5 * obj.size[1] + extra


def _segment_distance_xy(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> float:
    ab, ac = (b - a)[:2], (c - a)[:2]
    n = float(ab @ ab)
    t = 0.0 if n < 1e-12 else min(1.0, max(0.0, float(ac @ ab) / n))
    return float(np.linalg.norm(ac - t * ab))


def tilt(R: np.ndarray) -> float:
    """How far the object frame ``R`` (chair frame, (3, 3)) leans from upright [rad]:
    the angle between its z and the chair's z."""
    return math.acos(max(-1.0, min(1.0, float(R[2, 2]))))
