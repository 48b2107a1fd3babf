"""The scene's data model: primitives, objects, protection zones and the scene itself,
in SI units in the chair frame; the classes and their default clearances.

The file that describes a scene is read by :mod:`manus.scene.file`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from manus.errors import ManusError

CLASSES = ("person", "chair", "environment")
"""Object classes, each with its own clearance."""

SHAPES = {
    "box": ("size_mm",),
    "sphere": ("radius_mm",),
    "cylinder": ("radius_mm", "length_mm"),
    "capsule": ("radius_mm", "length_mm"),
    "plane": ("normal",),
}
"""Primitives and the size fields each needs (cylinders and capsules along their z)."""

ZONE_KINDS = ("keep_out", "keep_in")
ZONE_LINKS = ("all", "gripper")

DEFAULT_CLEARANCE_MM = {"person": 50.0, "chair": 15.0, "environment": 15.0, "self": 10.0}
"""Smallest allowed distance per class [mm] (``self``: between the arm's own bodies)."""

FILE_FORMAT = 1
"""The scene file format this stack reads: the file's ``version:`` key. Not the *scene
version* (:attr:`Scene.version`), which counts a running stack's updates of the scene."""


class SceneError(ManusError, ValueError):
    """A scene file or scene value is malformed; the message names file, line and field."""


@dataclass(frozen=True)
class Primitive:
    """One shape, placed in the chair frame.

    Attributes:
        shape: one of :data:`SHAPES`.
        size: box (x, y, z) [m]; sphere (r,); cylinder and capsule (r, length) [m];
            plane: the unit normal (x, y, z), pointing out of the solid side.
        pose: 4x4 placement in the chair frame [m] (a plane: a point on it and its frame).
    """

    shape: str
    size: tuple[float, ...]
    pose: np.ndarray = field(repr=False)


@dataclass(frozen=True)
class SceneObject:
    """A named obstacle.

    Attributes:
        name: unique among objects and zones.
        cls: ``person``, ``chair`` or ``environment``.
        body: its shape and placement.
        line: line of its entry in the scene file (0: not from a file).
    """

    name: str
    cls: str
    body: Primitive
    line: int = 0


@dataclass(frozen=True)
class Zone:
    """A protection zone.

    Attributes:
        name: unique among objects and zones.
        kind: ``keep_out`` (no body may enter) or ``keep_in`` (no body may leave).
        links: ``all`` (every body of the arm) or ``gripper`` (the gripper's bodies only).
        body: its shape (box, sphere, cylinder or capsule) and placement.
        clearance: margin kept from its boundary [m].
        line: line in the scene file.
    """

    name: str
    kind: str
    links: str
    body: Primitive
    clearance: float = 0.0
    line: int = 0


@dataclass(frozen=True)
class Scene:
    """The arm's surroundings, in the chair frame (x forward, y left, z up, origin on the
    floor under the seat's centre).

    Attributes:
        mount: pose of the arm's base frame (the shoulder, DH frame 0) in the chair frame.
        objects: the obstacles.
        zones: the protection zones (at most one ``keep_in``).
        clearance: smallest distance per class and ``self`` [m].
        source: the file it came from (for messages).
        version: the scene version, a run-time count (0: as read from the file; each
            update a supervisor makes counts up). Not the file format
            (:data:`FILE_FORMAT`, the file's ``version:`` key).
    """

    mount: np.ndarray = field(repr=False)
    objects: tuple[SceneObject, ...] = ()
    zones: tuple[Zone, ...] = ()
    clearance: dict[str, float] = field(
        default_factory=lambda: {k: v * 1e-3 for k, v in DEFAULT_CLEARANCE_MM.items()}
    )
    source: str = ""
    version: int = 0

    def in_base(self, pose: np.ndarray) -> np.ndarray:
        """A chair-frame pose expressed in the arm's base frame."""
        return np.asarray(np.linalg.solve(self.mount, pose))

    def where(self, line: int) -> str:
        """``file:line`` (or the file alone) for messages."""
        return f"{self.source}:{line}" if line else self.source


def rpy_matrix(rpy: tuple[float, float, float] | list[float] | np.ndarray) -> np.ndarray:
    """Rotation Rz(yaw) Ry(pitch) Rx(roll) of (roll, pitch, yaw) [rad], shape (3, 3)."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def pose_matrix(
    xyz: tuple[float, ...] | list[float], rpy: tuple[float, ...] | list[float]
) -> np.ndarray:
    """4x4 pose from a position [m] and (roll, pitch, yaw) [rad]."""
    T = np.eye(4)
    T[:3, :3] = rpy_matrix((rpy[0], rpy[1], rpy[2]))
    T[:3, 3] = xyz
    return T


def describe(scene: Scene) -> dict[str, Any]:
    """A short JSON-able summary (object and zone names by class)."""
    by_class: dict[str, list[str]] = {c: [] for c in CLASSES}
    for obj in scene.objects:
        by_class[obj.cls].append(obj.name)
    return {
        "source": scene.source,
        "file_format": FILE_FORMAT,
        "scene_version": scene.version,
        "objects": by_class,
        "zones": {z.name: z.kind for z in scene.zones},
        "clearance_mm": {k: round(v * 1e3, 3) for k, v in scene.clearance.items()},
    }
