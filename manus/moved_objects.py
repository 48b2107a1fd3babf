"""Scene objects placed where a tracker sees them rather than where the scene file puts
them: a person who moves (docs/follow.md, The person moves).

A collision model (:class:`manus.collision.CollisionModel`) keeps one
:class:`MovedObjects`: which objects moved and where they are now. Moving one places it
anew in every geometry model that holds a copy of it (the model's own and its per-body
ones), so every check against it sees the new place; its fast check
(:class:`manus.validity.ValidityChecker`) follows the :attr:`MovedObjects.version`, and a
model built from it for another set of held objects
(:meth:`~manus.collision.CollisionModel.holding`) starts with the same places. The pairs
the model left out at construction (an object no configuration could bring within its
clearance) stay left out: an object moved within :data:`MOVE_BOUND_M` of its scene pose
meets no body it could not meet there (tested).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from manus.scene import Primitive, Scene, SceneError, SceneObject

MOVE_BOUND_M = 0.25
"""How far a scene object may be moved from its scene pose while the pairs kept at
construction stay right [m] (tests/test_collision.py checks the person's head)."""


class MovedObjects:
    """The moved objects of one collision model's scene (see the module docstring).

    Args:
        scene: the model's scene (None: nothing to move).
    """

    def __init__(self, scene: Scene | None) -> None:
        self.scene = scene
        self.poses: dict[str, np.ndarray] = {}
        """Each moved object's pose now (4x4, chair frame)."""
        self.version = 0
        """Counts every move (a fast check rebuilt from the model follows it)."""
        self._copies: dict[str, list[tuple[Any, int]]] = {}

    def body(self, obj: SceneObject) -> Primitive:
        """``obj``'s shape where it is now (chair frame)."""
        pose = self.poses.get(obj.name)
        return obj.body if pose is None else Primitive(obj.body.shape, obj.body.size, pose)

    def move(self, name: str, pose: np.ndarray, models: Sequence[Any]) -> float:
        """Place the object ``name`` at ``pose`` (4x4, chair frame) in every geometry
        model of ``models`` that holds it (a fixed body of that name).

        Returns:
            how far any point of the object moved at most [m] (its translation plus its
            turn times its farthest point from its frame).

        Raises:
            SceneError: no scene object of that name.
        """
        scene = self.scene
        obj = next((o for o in scene.objects if o.name == name), None) if scene else None
        if scene is None or obj is None:
            names = [o.name for o in scene.objects] if scene is not None else []
            raise SceneError(f"no scene object {name!r} to move (objects: {names})")
        copies = self._copies.get(name)
        if copies is None:
            copies = self._copies[name] = [
                (gm, k)
                for gm in models
                for k, placed in enumerate(gm.geometryObjects)
                if placed.name == name and placed.parentJoint == 0
            ]
        before = self.poses.get(name, obj.body.pose)
        placement = pin.SE3(np.linalg.inv(scene.mount) @ pose)
        for gm, k in copies:
            gm.geometryObjects[k].placement = placement
        self.poses[name] = np.array(pose, dtype=float)
        self.version += 1
        return moved_by(before, pose, obj.body)


def moved_by(before: np.ndarray, after: np.ndarray, body: Primitive) -> float:
    """How far any point of ``body`` moves at most [m] when its pose goes from ``before``
    to ``after`` (4x4 each): its frame's translation plus the angle it turns times its
    farthest point from that frame (a plane: its translation alone)."""
    shift = math.dist(after[:3, 3].tolist(), before[:3, 3].tolist())
    turn = before[:3, :3].T @ after[:3, :3]
    trace = float(turn[0, 0] + turn[1, 1] + turn[2, 2])
    angle = math.acos(max(-1.0, min(1.0, (trace - 1.0) / 2.0)))
    if angle == 0.0 or body.shape == "plane":
        return shift
    size = body.size
    if body.shape == "box":
        radius = 0.5 * math.hypot(*size)
    elif body.shape == "sphere":
        radius = size[0]
    elif body.shape == "capsule":  # radius and length: an end ball's far side
        radius = size[1] / 2.0 + size[0]
    else:  # cylinder: a rim of an end disk
        radius = math.hypot(size[0], size[1] / 2.0)
    return shift + angle * radius
