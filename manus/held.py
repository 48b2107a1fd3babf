"""Objects the arm holds, as its collision model carries them (MoveIt's attached objects).

A world object attached to the gripper (:class:`schemas.objects.WorldObject` with
``link`` = :data:`GRIPPER_FRAME`, its pose then in the gripper frame) is a body of the
arm: :class:`manus.collision.CollisionModel` carries it on joint 6, checks it against
the scene (each class's clearance, the zones) and against the arm's own bodies (the
``self`` clearance) except its *touch links* (the gripper's jaws hold it), and leaves
out the scene objects it may touch (its *touch objects*: the table it is lifted from).
Every follower of the world model builds the same bodies from the same objects with
:func:`held_bodies`, so the planner, the controller's guard, the sequencer's fold check
and the viewer all see one held object.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

import numpy as np

from manus.errors import ManusError
from manus.orientation import pose_matrix
from manus.urdf import GRIPPER_FRAME
from schemas.objects import WorldObject

DEFAULT_TOUCH_LINKS = ("gripper",)
"""The arm bodies that may touch an object held in the gripper unless an attach names
others: the gripper box (its palm and fingers)."""


class HeldError(ManusError, ValueError):
    """A held body the collision model cannot carry (its name, shape or link)."""


class HeldBody(NamedTuple):
    """One object the arm holds.

    Attributes:
        name: the object's id (its name in every check).
        cls: its class (cup, bottle, ...).
        shape: ``box``, ``sphere``, ``cylinder`` or ``capsule``.
        size: the shape's sizes [m] (:data:`schemas.objects.SIZE_DOC`).
        xyz: its centre in the gripper frame [m].
        ypr: its (yaw, pitch, roll) in the gripper frame [rad].
        touch_links: arm bodies that may touch it (no ``self`` check against them).
        touch_objects: scene objects it may touch (no check against them).
    """

    name: str
    cls: str
    shape: str
    size: tuple[float, ...]
    xyz: tuple[float, float, float]
    ypr: tuple[float, float, float]
    touch_links: tuple[str, ...] = DEFAULT_TOUCH_LINKS
    touch_objects: tuple[str, ...] = ()

    def placement(self) -> np.ndarray:
        """Its pose in the gripper frame, shape (4, 4)."""
        return pose_matrix(self.xyz, self.ypr)


def held_bodies(objects: Iterable[WorldObject]) -> tuple[HeldBody, ...]:
    """The bodies of the objects attached to the gripper among ``objects``, by id.

    Raises:
        HeldError: an object attached to another link than :data:`GRIPPER_FRAME`.
    """
    out = []
    for obj in sorted(objects, key=lambda o: o.id):
        if not obj.link:
            continue
        if obj.link != GRIPPER_FRAME:
            raise HeldError(
                f"object {obj.id!r} is attached to {obj.link!r}: objects attach to "
                f"{GRIPPER_FRAME!r} only"
            )
        out.append(
            HeldBody(
                obj.id,
                obj.cls,
                obj.shape,
                tuple(obj.size),
                (obj.xyz[0], obj.xyz[1], obj.xyz[2]),
                (obj.ypr[0], obj.ypr[1], obj.ypr[2]),
                tuple(obj.touch_links),
                tuple(obj.touch_objects),
            )
        )
    return tuple(out)
