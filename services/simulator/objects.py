"""The simulator's rigid objects: their shapes, their state, and the file they come from.

An object is a primitive of the scene's kinds (box, sphere, cylinder, capsule) with an id
and a class, placed in the chair frame (the scene's, docs/scene.md). It is in one of
three states: resting on a surface, held by the gripper, or falling to the surface
below it (:mod:`services.simulator.object_world`).

The objects file (the simulator's ``objects`` setting, docs/objects.md), lengths in mm and
angles in degrees like a scene file::

    version: 1
    objects:
      - {id: cup, class: cup, shape: cylinder, radius_mm: 40, length_mm: 100,
         xyz_mm: [1000, -150, 790], rpy_deg: [0, 0, 30]}

Each object starts at rest on the highest surface under its centre, upright, its yaw
kept. Every problem is a :class:`~manus.scene.SceneError` naming the file, the line and
the field.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from manus.errors import ConfigError
from manus.scene import Primitive, SceneError, pose_matrix
from manus.yaml_fields import FieldReader, join
from schemas.objects import SIZE_COUNTS, ObjectShape

RESTING, HELD, FALLING = "resting", "held", "falling"
"""The states of an object."""

SIZE_FIELDS: dict[str, tuple[str, ...]] = {
    ObjectShape.BOX: ("size_mm",),
    ObjectShape.SPHERE: ("radius_mm",),
    ObjectShape.CYLINDER: ("radius_mm", "length_mm"),
    ObjectShape.CAPSULE: ("radius_mm", "length_mm"),
}
"""The size fields of each shape in the objects file."""

OBJECTS_FILE_VERSION = 1
"""The objects file's schema version."""


def half_height(shape: str, size: tuple[float, ...]) -> float:
    """Distance from an upright object's centre down to its bottom [m]."""
    if shape == ObjectShape.BOX:
        return size[2] / 2.0
    if shape == ObjectShape.SPHERE:
        return size[0]
    if shape == ObjectShape.CYLINDER:
        return size[1] / 2.0
    return size[1] / 2.0 + size[0]


def bounding_radius(shape: str, size: tuple[float, ...]) -> float:
    """Radius of the sphere about the centre that holds the object [m]."""
    if shape == ObjectShape.BOX:
        return float(np.linalg.norm(size)) / 2.0
    if shape == ObjectShape.SPHERE:
        return size[0]
    if shape == ObjectShape.CYLINDER:
        return math.hypot(size[0], size[1] / 2.0)
    return size[0] + size[1] / 2.0


def width_along(shape: str, size: tuple[float, ...], u: np.ndarray) -> float:
    """The object's extent along the unit direction ``u`` given in its own frame [m]
    (what the jaws close to when ``u`` is their axis)."""
    ux, uy, uz = (abs(float(v)) for v in u)
    if shape == ObjectShape.BOX:
        return ux * size[0] + uy * size[1] + uz * size[2]
    if shape == ObjectShape.SPHERE:
        return 2.0 * size[0]
    radius, length = size
    if shape == ObjectShape.CYLINDER:
        return 2.0 * radius * math.sqrt(max(0.0, 1.0 - uz * uz)) + length * uz
    return 2.0 * radius + length * uz


def upright(pose: np.ndarray) -> np.ndarray:
    """``pose`` turned upright (roll and pitch 0), its yaw and position kept, (4, 4)."""
    R = pose[:3, :3]
    # The yaw of the object's x axis, or of its y axis when x points up or down.
    heading = R[:, 0] if math.hypot(R[0, 0], R[1, 0]) > 1e-6 else R[:, 1]
    yaw = math.atan2(float(heading[1]), float(heading[0]))
    return pose_matrix([float(v) for v in pose[:3, 3]], [0.0, 0.0, yaw])


@dataclass
class SimObject:
    """One object and its state (changed in place by the simulator, tick by tick).

    Attributes:
        id: its identity (unique).
        cls: class: cup, bottle, phone, ...
        shape: one of :class:`~schemas.objects.ObjectShape`.
        size: box (x, y, z); sphere (r,); cylinder and capsule (r, length) [m].
        pose: its placement in the chair frame [m], (4, 4): where it rests, where it was
            released (falling), or where it was grasped (held).
        state: ``resting``, ``held`` or ``falling``.
        support: the surface it rests on or falls to ('': none yet).
        grip: its placement in the gripper frame while held, (4, 4).
        fall_ns: when it was released (falling) [ns].
        slips: grasps on it that slipped.
        line: its line in the objects file (0: added at run time).
    """

    id: str
    cls: str
    shape: str
    size: tuple[float, ...]
    pose: np.ndarray = field(repr=False)
    state: str = RESTING
    support: str = ""
    grip: np.ndarray = field(default_factory=lambda: np.eye(4), repr=False)
    fall_ns: int = 0
    slips: int = 0
    line: int = 0

    def __post_init__(self) -> None:
        name_ok = self.id.replace("_", "").replace("-", "").isalnum()
        if not name_ok or not self.cls.replace("_", "").replace("-", "").isalnum():
            raise ConfigError(
                f"object {self.id!r} ({self.cls!r}): ids and classes are letters, digits, _ and -"
            )
        wanted = SIZE_COUNTS[ObjectShape(self.shape)]
        if len(self.size) != wanted or not all(0.0 < v <= 2.0 for v in self.size):
            raise ConfigError(
                f"object {self.id!r}: a {self.shape} takes {wanted} size value(s) in (0, 2] m, "
                f"got {self.size}"
            )

    @property
    def half_height(self) -> float:
        """Centre to bottom when upright [m]."""
        return half_height(self.shape, self.size)

    @property
    def radius(self) -> float:
        """Bounding radius [m]."""
        return bounding_radius(self.shape, self.size)

    def primitive(self, pose: np.ndarray) -> Primitive:
        """Its shape at ``pose`` (for :func:`manus.shapes.coal_shape`)."""
        return Primitive(self.shape, self.size, pose)


# --- the file --------------------------------------------------------------------------------


def shipped_objects_path() -> Path:
    """The shipped objects file: a cup, a bottle and a phone on the default scene's table."""
    return Path(str(resources.files("manus") / "data" / "objects.yaml"))


OBJECTS_ENV = "MANUS_OBJECTS"
"""Environment variable naming the objects file when the setting is empty."""


def objects_path(setting: str) -> Path | None:
    """The file of an ``objects`` setting: ``""`` -> ``$MANUS_OBJECTS`` if set, else none;
    ``default`` -> the shipped one; ``none`` -> None; else the setting is the path."""
    if setting == "":
        setting = os.environ.get(OBJECTS_ENV, "") or "none"
    if setting == "none":
        return None
    return shipped_objects_path() if setting == "default" else Path(setting)


def load_objects(setting: str) -> list[SimObject]:
    """The objects of an ``objects`` setting (:func:`objects_path`), in file order, at the
    poses the file gives (not settled yet).

    Raises:
        SceneError: the file cannot be read or holds a bad entry (file, line, field).
    """
    path = objects_path(setting)
    if path is None:
        return []
    try:
        text = path.read_text()
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the objects file: {exc.strerror}") from exc
    return parse_objects(text, str(path))


def parse_objects(text: str, source: str) -> list[SimObject]:
    """Read an objects file's text (see the module docstring).

    Raises:
        SceneError: the first problem, naming ``source``, the line and the field.
    """
    reader = FieldReader(source, SceneError)
    root = reader.root(text, "objects")
    top = reader.mapping(root, "", ("version", "objects"), ())
    if reader.number(top["version"], "version") != OBJECTS_FILE_VERSION:
        raise reader.fail(
            top["version"], "version", f"this stack reads version {OBJECTS_FILE_VERSION}"
        )
    out: list[SimObject] = []
    lines: dict[str, int] = {}
    for i, item in enumerate(reader.items(top["objects"], "objects")):
        obj = _entry(reader, item, f"objects[{i}]")
        if obj.id in lines:
            raise reader.fail(
                item, f"objects[{i}].id", f"{obj.id!r} already on line {lines[obj.id]}"
            )
        lines[obj.id] = obj.line
        out.append(obj)
    return out


def _entry(reader: FieldReader, item: yaml.Node, path: str) -> SimObject:
    optional = ("rpy_deg", "size_mm", "radius_mm", "length_mm")
    fields = reader.mapping(item, path, ("id", "class", "shape", "xyz_mm"), optional)
    name = reader.text(fields["id"], join(path, "id"))
    cls = reader.text(fields["class"], join(path, "class"))
    shape = ObjectShape(reader.text(fields["shape"], join(path, "shape"), tuple(ObjectShape))).value
    for key in optional[1:]:
        if key in fields and key not in SIZE_FIELDS[shape]:
            raise reader.fail(fields[key], join(path, key), f"not a field of a {shape}")
    size: list[float] = []
    for key in SIZE_FIELDS[shape]:
        if key not in fields:
            raise reader.fail(item, join(path, key), f"missing field (a {shape} needs it)")
        if key == "size_mm":
            size += reader.vector(fields[key], join(path, key), positive=True)
        else:
            size.append(reader.number(fields[key], join(path, key), positive=True))
    if max(size) > 2000.0:
        raise reader.fail(item, path, f"sizes must be at most 2000 mm, got {size}")
    xyz = [v * 1e-3 for v in reader.vector(fields["xyz_mm"], join(path, "xyz_mm"))]
    rpy = [0.0, 0.0, 0.0]
    if "rpy_deg" in fields:
        rpy = [math.radians(v) for v in reader.vector(fields["rpy_deg"], join(path, "rpy_deg"))]
    size_m = tuple(v * 1e-3 for v in size)
    pose = pose_matrix(xyz, rpy)
    return SimObject(name, cls, shape, size_m, pose, line=item.start_mark.line + 1)
