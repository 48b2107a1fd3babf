"""What is around the arm: the scene file, its validation and the default wheelchair scene.

A scene (YAML, schema in docs/scene.md) places the arm's base on the chair (``mount``)
and lists named objects as primitives (box, sphere, capsule, cylinder, plane), each with a
class: ``person`` (the user: the largest clearance), ``chair`` (the wheelchair) or
``environment`` (table, wall, floor). ``zones`` are Kortex-like protection zones: named
``keep_out`` volumes and at most one ``keep_in`` workspace, each for every link or the
gripper only. Lengths are in mm and angles in degrees in the file (an edge of the stack,
like a via-point file); :class:`Scene` holds SI units, in the chair frame.

Every problem is a :class:`SceneError` naming the file, the line and the field
(``scene.yaml:14: objects[2].radius_mm: must be > 0, got -5``): PyYAML's node tree
carries a position for every value, which ``tomllib`` does not
(:mod:`manus.yaml_fields`). The check that an object does not overlap the arm's base is
made by the collision model, which knows the base
(:meth:`manus.collision.CollisionModel.base_overlaps`; building the model refuses it).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from manus.errors import ManusError
from manus.yaml_fields import FieldReader, join
from schemas.collision import SceneState

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

SCENE_VERSION = 1
"""The schema version this module reads."""


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
        version: run-time version (0: as loaded; a supervisor's update counts up).
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


# --- reading -------------------------------------------------------------------------


class _Reader(FieldReader):
    """A :class:`FieldReader` that also reads poses and primitives."""

    def pose(self, fields: dict[str, yaml.Node], path: str) -> np.ndarray:
        xyz = [v * 1e-3 for v in self.vector(fields["xyz_mm"], join(path, "xyz_mm"))]
        rpy = [0.0, 0.0, 0.0]
        if "rpy_deg" in fields:
            rpy = [math.radians(v) for v in self.vector(fields["rpy_deg"], join(path, "rpy_deg"))]
        return pose_matrix(xyz, rpy)

    def primitive(
        self, fields: dict[str, yaml.Node], path: str, shapes: tuple[str, ...]
    ) -> Primitive:
        shape = self.text(fields["shape"], join(path, "shape"), shapes)
        wanted = SHAPES[shape]
        for key in ("size_mm", "radius_mm", "length_mm", "normal"):
            if key in fields and key not in wanted:
                raise self.fail(fields[key], join(path, key), f"not a field of a {shape}")
        for key in wanted:
            if key not in fields:
                raise self.fail(
                    fields["shape"], join(path, key), f"missing field (a {shape} needs it)"
                )
        pose = self.pose(fields, path)
        if shape == "box":
            size = tuple(
                v * 1e-3
                for v in self.vector(fields["size_mm"], join(path, "size_mm"), positive=True)
            )
        elif shape == "sphere":
            size = (
                self.number(fields["radius_mm"], join(path, "radius_mm"), positive=True) * 1e-3,
            )
        elif shape == "plane":
            normal = np.array(self.vector(fields["normal"], join(path, "normal")))
            norm = float(np.linalg.norm(normal))
            if norm < 1e-9:
                raise self.fail(fields["normal"], join(path, "normal"), "must not be zero")
            size = tuple(float(v) for v in normal / norm)
        else:
            size = (
                self.number(fields["radius_mm"], join(path, "radius_mm"), positive=True) * 1e-3,
                self.number(fields["length_mm"], join(path, "length_mm"), positive=True) * 1e-3,
            )
        return Primitive(shape=shape, size=size, pose=pose)


_BODY_FIELDS = ("rpy_deg", "size_mm", "radius_mm", "length_mm", "normal")


def parse_scene(text: str, source: str = "<scene>") -> Scene:
    """Read a scene from YAML text.

    Raises:
        SceneError: the first problem, naming ``source``, the line and the field.
    """
    reader = _Reader(source, SceneError)
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        line = mark.line + 1 if mark is not None else 0
        raise SceneError(f"{source}:{line}: not valid YAML: {exc.problem}") from exc
    if root is None:
        raise SceneError(f"{source}: the scene file is empty")
    top = reader.mapping(root, "", ("version", "mount", "objects"), ("clearance_mm", "zones"))
    version = reader.number(top["version"], "version")
    if version != SCENE_VERSION:
        raise reader.fail(
            top["version"],
            "version",
            f"this stack reads version {SCENE_VERSION}, got {top['version'].value}",
        )
    mount_fields = reader.mapping(top["mount"], "mount", ("xyz_mm",), ("rpy_deg",))
    mount = reader.pose(mount_fields, "mount")
    clearance = {k: v * 1e-3 for k, v in DEFAULT_CLEARANCE_MM.items()}
    if "clearance_mm" in top:
        given = reader.mapping(top["clearance_mm"], "clearance_mm", (), tuple(DEFAULT_CLEARANCE_MM))
        for key, node in given.items():
            clearance[key] = reader.number(node, f"clearance_mm.{key}", minimum=0.0) * 1e-3
    names: dict[str, int] = {}

    def unique(node: yaml.Node, path: str) -> str:
        name = reader.text(node, path)
        if name in names:
            raise reader.fail(node, path, f"name {name!r} already used on line {names[name]}")
        names[name] = node.start_mark.line + 1
        return name

    objects = []
    for i, item in enumerate(reader.items(top["objects"], "objects")):
        path = f"objects[{i}]"
        fields = reader.mapping(item, path, ("name", "class", "shape", "xyz_mm"), _BODY_FIELDS)
        name = unique(fields["name"], f"{path}.name")
        cls = reader.text(fields["class"], f"{path}.class", CLASSES)
        body = reader.primitive(fields, path, tuple(SHAPES))
        objects.append(SceneObject(name, cls, body, line=item.start_mark.line + 1))
    zones = []
    keep_in_line = 0
    for i, item in enumerate(reader.items(top.get("zones", yaml.SequenceNode("", [])), "zones")):
        path = f"zones[{i}]"
        fields = reader.mapping(
            item,
            path,
            ("name", "kind", "shape", "xyz_mm"),
            ("links", "clearance_mm", *_BODY_FIELDS),
        )
        name = unique(fields["name"], f"{path}.name")
        kind = reader.text(fields["kind"], f"{path}.kind", ZONE_KINDS)
        if kind == "keep_in":
            if keep_in_line:
                raise reader.fail(
                    fields["kind"],
                    f"{path}.kind",
                    f"a second keep_in zone (the first is on line "
                    f"{keep_in_line}): one workspace only",
                )
            keep_in_line = item.start_mark.line + 1
        links = (
            reader.text(fields["links"], f"{path}.links", ZONE_LINKS)
            if "links" in fields
            else "all"
        )
        body = reader.primitive(fields, path, ("box", "sphere", "cylinder", "capsule"))
        margin = 0.0
        if "clearance_mm" in fields:
            margin = (
                reader.number(fields["clearance_mm"], f"{path}.clearance_mm", minimum=0.0) * 1e-3
            )
        zones.append(Zone(name, kind, links, body, margin, line=item.start_mark.line + 1))
    return Scene(
        mount=mount,
        objects=tuple(objects),
        zones=tuple(zones),
        clearance=clearance,
        source=source,
    )


def load_scene(path: str | os.PathLike[str]) -> Scene:
    """Read the scene file at ``path`` (parsed once per file contents: a scene is not
    changed after it is read, so every service of a process shares it).

    Raises:
        SceneError: unreadable, or any problem of :func:`parse_scene`.
    """
    file = Path(path)
    try:
        text = file.read_text()
    except OSError as exc:
        raise SceneError(f"{file}: cannot read the scene file: {exc.strerror}") from exc
    key = (str(file), text)
    scene = _PARSED.get(key)
    if scene is None:
        scene = parse_scene(text, source_name(file))
        if len(_PARSED) >= 16:
            _PARSED.clear()
        _PARSED[key] = scene
    return scene


_PARSED: dict[tuple[str, str], Scene] = {}
"""Scenes already parsed, by file name and text."""


def default_scene_path() -> Path:
    """The shipped default scene: a Manus on the right of a powered wheelchair, user seated."""
    return Path(str(resources.files("manus") / "data" / "wheelchair.yaml"))


SHIPPED_SOURCE = "manus/data/wheelchair.yaml"
"""The shipped scene's name in messages: the same on every machine and in every clone, so
that a recording (plans, scene states) replays byte for byte wherever the code lives."""


def source_name(path: Path) -> str:
    """A scene file's name in messages: :data:`SHIPPED_SOURCE` for the shipped one, else
    the path as given."""
    try:
        shipped = path.resolve() == default_scene_path().resolve()
    except OSError:
        shipped = False
    return SHIPPED_SOURCE if shipped else str(path)


def default_scene() -> Scene:
    """:func:`load_scene` of :func:`default_scene_path`."""
    return load_scene(default_scene_path())


SCENE_ENV = "MANUS_SCENE"
"""Environment variable naming the scene every service uses when its setting is empty."""


def scene_path(setting: str) -> Path | None:
    """The file a service's ``scene`` setting names: ``""`` -> ``$MANUS_SCENE`` if set,
    else the shipped one; ``default`` -> the shipped one; ``none`` -> None (no scene: no
    collision checks); else the setting is the file's path. Every service's setting
    defaults to ``""``, so one environment variable gives the planner, sequencer,
    controller and simulator the same scene."""
    if setting == "":
        setting = os.environ.get(SCENE_ENV, "") or "default"
    if setting == "default":
        return default_scene_path()
    if setting == "none":
        return None
    return Path(setting)


def scene_from_setting(setting: str) -> Scene | None:
    """The scene of :func:`scene_path` (None: none)."""
    path = scene_path(setting)
    return None if path is None else load_scene(path)


def start_scene_state(setting: str) -> SceneState | None:
    """The scene of a service's ``scene`` setting as the planner announces it before any
    run-time update (version 0, the file's text, its name); None: no scene.

    Raises:
        SceneError: the file cannot be read.
    """
    path = scene_path(setting)
    if path is None:
        return None
    try:
        return SceneState(version=0, text=path.read_text(), source=source_name(path))
    except OSError as exc:
        raise SceneError(f"{path}: cannot read the scene file: {exc.strerror}") from exc


def describe(scene: Scene) -> dict[str, Any]:
    """A short JSON-able summary (object and zone names by class)."""
    by_class: dict[str, list[str]] = {c: [] for c in CLASSES}
    for obj in scene.objects:
        by_class[obj.cls].append(obj.name)
    return {
        "source": scene.source,
        "version": scene.version,
        "objects": by_class,
        "zones": {z.name: z.kind for z in scene.zones},
        "clearance_mm": {k: round(v * 1e3, 3) for k, v in scene.clearance.items()},
    }
