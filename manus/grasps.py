"""How each class of object is grasped: the grasps file (``manus/data/grasps.yaml``,
docs/pick.md), read into :class:`GraspClass` values in SI units.

::

    version: 1
    classes:
      cup: {approach: side, height_mm: 8, pitch_deg: [15, 5], yaw_step_deg: 15,
            yaw_span_deg: 75,
            pregrasp_mm: 80, lift_mm: 60, open_margin_mm: 25, squeeze_mm: 4,
            keep_level: true}

Errors name the file, the line and the field (:class:`GraspError`), as a scene file's do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from importlib import resources
from pathlib import Path

import yaml

from manus.errors import ManusError
from manus.yaml_fields import FieldReader, join

GRASPS_VERSION = 1
"""The file format version this module reads."""

SHIPPED_SOURCE = "manus/data/grasps.yaml"
"""The shipped file's name in messages (the same on every machine)."""


class GraspError(ManusError, ValueError):
    """A grasps file is malformed, or a class has no grasps; the message says where."""


class Approach(StrEnum):
    """How the gripper comes onto the object."""

    SIDE = "side"
    """horizontally, jaw axis horizontal, the gripper's y up: the object is kept level"""
    TOP = "top"
    """downwards, the jaws closing across the object's y extent"""


@dataclass(frozen=True)
class GraspClass:
    """How one class of object is grasped (SI units).

    Attributes:
        cls: the class (``cup``).
        approach: :class:`Approach`.
        height: grasp point above the object's centre [m].
        yaw_step: between two candidate approach directions [rad].
        yaw_span: candidates within this of the preferred direction [rad].
        pitches: a side approach points this far down from horizontal [rad] (its wrist
            then stays higher above the surface the object stands on; the gripper's
            front lower): one candidate per pitch at each yaw, in this order.
        pregrasp: length of the straight approach and retreat [m].
        lift: straight up after the grasp, before the release [m].
        open_margin: the jaws open this much wider than the object [m].
        squeeze: the jaws are asked to close this much narrower than the object [m].
        keep_level: while held, its tilt stays under the tilt limit.
        source: ``file:line`` it was defined at.
    """

    cls: str
    approach: Approach
    height: float
    yaw_step: float
    yaw_span: float
    pitches: tuple[float, ...]
    pregrasp: float
    lift: float
    open_margin: float
    squeeze: float
    keep_level: bool
    source: str


LENGTHS = ("height_mm", "pregrasp_mm", "lift_mm", "open_margin_mm", "squeeze_mm")
ANGLES = ("yaw_step_deg", "yaw_span_deg")


def shipped_grasps_path() -> Path:
    """The shipped grasps file."""
    return Path(str(resources.files("manus") / "data" / "grasps.yaml"))


def parse_grasps(text: str, source: str = "<grasps>") -> dict[str, GraspClass]:
    """The grasp classes in YAML ``text`` (see the module docstring), by class.

    Raises:
        GraspError: the first problem, naming ``source``, the line and the field.
    """
    reader = FieldReader(source, GraspError)
    root = reader.root(text, "grasps")
    top = reader.mapping(root, "", ("version", "classes"), ())
    if reader.number(top["version"], "version") != GRASPS_VERSION:
        raise reader.fail(top["version"], "version", f"this stack reads version {GRASPS_VERSION}")
    classes = top["classes"]
    if not isinstance(classes, yaml.MappingNode):
        raise reader.fail(classes, "classes", "must be a mapping (class: {...})")
    out: dict[str, GraspClass] = {}
    for key_node, node in classes.value:
        cls = reader.text(key_node, "classes")
        path = join("classes", cls)
        if cls in out:
            raise reader.fail(key_node, path, "given twice")
        fields = reader.mapping(
            node, path, ("approach", *LENGTHS, *ANGLES, "pitch_deg", "keep_level"), ()
        )
        approach = reader.text(fields["approach"], join(path, "approach"), tuple(Approach))
        mm, deg = _numbers(reader, fields, path)
        level = fields["keep_level"]
        if not isinstance(level, yaml.ScalarNode) or level.tag != "tag:yaml.org,2002:bool":
            raise reader.fail(level, join(path, "keep_level"), "must be true or false")
        out[cls] = GraspClass(
            cls=cls,
            approach=Approach(approach),
            height=mm["height_mm"] * 1e-3,
            yaw_step=math.radians(deg["yaw_step_deg"]),
            yaw_span=math.radians(deg["yaw_span_deg"]),
            pitches=_pitches(reader, fields["pitch_deg"], join(path, "pitch_deg")),
            pregrasp=mm["pregrasp_mm"] * 1e-3,
            lift=mm["lift_mm"] * 1e-3,
            open_margin=mm["open_margin_mm"] * 1e-3,
            squeeze=mm["squeeze_mm"] * 1e-3,
            keep_level=str(level.value).lower() == "true",
            source=f"{source}:{node.start_mark.line + 1}",
        )
    return out


def _numbers(
    reader: FieldReader, fields: dict[str, yaml.Node], path: str
) -> tuple[dict[str, float], dict[str, float]]:
    """The lengths [mm] and angles [deg] of one class, checked."""
    mm = {k: reader.number(fields[k], join(path, k)) for k in LENGTHS}
    for k in ("pregrasp_mm", "open_margin_mm"):
        if mm[k] <= 0.0:
            raise reader.fail(fields[k], join(path, k), f"must be > 0, got {mm[k]:g}")
    for k in ("lift_mm", "squeeze_mm"):
        if mm[k] < 0.0:
            raise reader.fail(fields[k], join(path, k), f"must be >= 0, got {mm[k]:g}")
    deg = {k: reader.number(fields[k], join(path, k)) for k in ANGLES}
    if not 0.0 < deg["yaw_step_deg"] <= 360.0:
        raise reader.fail(fields["yaw_step_deg"], join(path, "yaw_step_deg"), "must be in (0, 360]")
    if not 0.0 <= deg["yaw_span_deg"] <= 180.0:
        raise reader.fail(fields["yaw_span_deg"], join(path, "yaw_span_deg"), "must be in [0, 180]")
    return mm, deg


def _pitches(reader: FieldReader, node: yaml.Node, path: str) -> tuple[float, ...]:
    """One pitch or a list of them [deg] -> [rad], each in [0, 45]."""
    items = node.value if isinstance(node, yaml.SequenceNode) else [node]
    if not items:
        raise reader.fail(node, path, "give at least one pitch")
    out = []
    for i, item in enumerate(items):
        where = f"{path}[{i}]" if isinstance(node, yaml.SequenceNode) else path
        value = reader.number(item, where)
        if not 0.0 <= value <= 45.0:
            raise reader.fail(item, where, f"must be in [0, 45], got {value:g}")
        out.append(math.radians(value))
    return tuple(out)


def load_grasps(path: str | Path = "") -> dict[str, GraspClass]:
    """The grasps file ``path`` ('': the shipped one).

    Raises:
        GraspError: it cannot be read or is malformed.
    """
    if not path:
        return parse_grasps(shipped_grasps_path().read_text(encoding="utf-8"), SHIPPED_SOURCE)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise GraspError(f"{path}: cannot read the grasps file: {exc.strerror}") from exc
    return parse_grasps(text, str(path))


def grasp_class(classes: dict[str, GraspClass], cls: str, object_id: str) -> GraspClass:
    """How objects of class ``cls`` are grasped.

    Raises:
        GraspError: no grasps for that class (naming the object and the known classes).
    """
    found = classes.get(cls)
    if found is None:
        known = ", ".join(sorted(classes))
        raise GraspError(f"object {object_id!r}: no grasps for class {cls!r} (known: {known})")
    return found
