"""Reading a scene file (YAML): every value checked, every problem one
:class:`~manus.scene.model.SceneError` naming the file, the line and the field; the
shipped default scene.
"""

from __future__ import annotations

import math
import os
from importlib import resources
from pathlib import Path

import numpy as np
import yaml

from manus.scene.model import (
    CLASSES,
    DEFAULT_CLEARANCE_MM,
    FILE_FORMAT,
    SHAPES,
    ZONE_KINDS,
    ZONE_LINKS,
    Primitive,
    Scene,
    SceneError,
    SceneObject,
    Zone,
    pose_matrix,
)
from manus.yaml_fields import FieldReader, join


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
    root = reader.root(text, "scene")
    top = reader.mapping(root, "", ("version", "mount", "objects"), ("clearance_mm", "zones"))
    file_format = reader.number(top["version"], "version")
    if file_format != FILE_FORMAT:
        raise reader.fail(
            top["version"],
            "version",
            f"the file format: this stack reads format {FILE_FORMAT}, got {top['version'].value}",
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
