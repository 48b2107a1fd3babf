"""Named poses: ``home``, ``drink``, ``folded``, ``unfolded`` and any a user adds in a file.

A named pose is a joint configuration or a gripper pose (with tolerances, as a pose
goal). ``folded`` and ``unfolded`` are the arm's own fold poses (:mod:`manus.config`) and
cannot be redefined; ``home`` and ``drink`` come from the shipped file
``manus/data/poses.yaml`` and a user's file may redefine them (a drinking position
depends on the person). The user's file is named by ``$MANUS_POSES`` or a command's
``--poses`` option.

The file (YAML, lengths in mm, angles in deg, orientation as (yaw, pitch, roll) like
``manus kin fk`` prints it)::

    version: 1
    poses:
      - {name: drink, joints_deg: [-13, -92, -39, -80, -102, -48]}
      - {name: shelf, xyz_mm: [450, 150, 250], ypr_deg: [0, 90, 0],
         free_axis: true, position_tolerance_mm: 5, angle_tolerance_deg: 5}

Each pose has exactly one of ``joints_deg`` and ``xyz_mm`` (with ``ypr_deg``). Every
problem is a :class:`NamedPoseError` naming the file, the line and the field
(``poses.yaml:4: poses[1].joints_deg: must be a list of 6 numbers``).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import yaml

from manus.config import FOLDED_Q_DEG, UNFOLDED_Q_DEG
from manus.errors import ManusError
from manus.yaml_fields import FieldReader, join

POSES_VERSION = 1
"""The file format version this module reads."""

POSES_ENV = "MANUS_POSES"
"""Environment variable naming the user's poses file."""

FIXED = {"folded": FOLDED_Q_DEG, "unfolded": UNFOLDED_Q_DEG}
"""The arm's own fold poses [deg]: no file may redefine them."""

MAX_POSITION_TOLERANCE_MM = 100.0
MAX_ANGLE_TOLERANCE_DEG = 28.0


class NamedPoseError(ManusError, ValueError):
    """A poses file is malformed, or a name is unknown; the message says where."""


@dataclass(frozen=True)
class NamedPose:
    """One named pose, in SI units.

    Attributes:
        name: its name.
        joints: the configuration (DH) [rad], shape (6,); None for a gripper pose.
        xyz: the gripper position in the base frame [m]; None for a configuration.
        ypr: the gripper orientation (yaw, pitch, roll) [rad]; None for a configuration.
        position_tolerance: how far the gripper may end from ``xyz`` [m].
        angle_tolerance: how far its orientation may turn from ``ypr`` [rad].
        free_axis: any rotation about the gripper's approach axis is fine.
        source: ``file:line`` it was defined at (``manus.config`` for the fold poses).
    """

    name: str
    joints: tuple[float, ...] | None = None
    xyz: tuple[float, ...] | None = None
    ypr: tuple[float, ...] | None = None
    position_tolerance: float = 0.0
    angle_tolerance: float = 0.0
    free_axis: bool = False
    source: str = ""


def shipped_poses_path() -> Path:
    """The shipped poses file (``home`` and ``drink``)."""
    return Path(str(resources.files("manus") / "data" / "poses.yaml"))


SHIPPED_SOURCE = "manus/data/poses.yaml"
"""The shipped file's name in messages (the same on every machine, for replays)."""


def parse_poses(text: str, source: str = "<poses>") -> dict[str, NamedPose]:
    """The poses in YAML ``text`` (see the module docstring), by name.

    Raises:
        NamedPoseError: the first problem, naming ``source``, the line and the field.
    """
    reader = FieldReader(source, NamedPoseError)
    root = reader.root(text, "poses")
    top = reader.mapping(root, "", ("version", "poses"), ())
    if reader.number(top["version"], "version") != POSES_VERSION:
        raise reader.fail(
            top["version"],
            "version",
            f"this stack reads version {POSES_VERSION}, got {top['version'].value}",
        )
    out: dict[str, NamedPose] = {}
    for i, item in enumerate(reader.items(top["poses"], "poses")):
        path = f"poses[{i}]"
        fields = reader.mapping(
            item,
            path,
            ("name",),
            (
                "joints_deg",
                "xyz_mm",
                "ypr_deg",
                "position_tolerance_mm",
                "angle_tolerance_deg",
                "free_axis",
            ),
        )
        name = reader.text(fields["name"], join(path, "name"))
        where = f"{source}:{item.start_mark.line + 1}"
        if name in FIXED:
            raise reader.fail(
                fields["name"],
                join(path, "name"),
                f"{name!r} is the arm's own fold pose and cannot be redefined",
            )
        if name in out:
            raise reader.fail(
                fields["name"],
                join(path, "name"),
                f"{name!r} already defined at {out[name].source}",
            )
        out[name] = _pose(reader, fields, item, path, name, where)
    return out


def _pose(
    reader: FieldReader,
    fields: dict[str, yaml.Node],
    item: yaml.Node,
    path: str,
    name: str,
    where: str,
) -> NamedPose:
    has_joints, has_xyz = "joints_deg" in fields, "xyz_mm" in fields
    if has_joints == has_xyz:
        raise reader.fail(item, path, "give exactly one of joints_deg and xyz_mm (with ypr_deg)")
    if has_joints:
        extra = sorted(set(fields) - {"name", "joints_deg"})
        if extra:
            raise reader.fail(
                fields[extra[0]], join(path, extra[0]), "only a gripper pose (xyz_mm) takes it"
            )
        q = reader.vector(fields["joints_deg"], join(path, "joints_deg"), 6)
        return NamedPose(name, joints=tuple(math.radians(v) for v in q), source=where)
    if "ypr_deg" not in fields:
        raise reader.fail(item, join(path, "ypr_deg"), "missing field (a gripper pose needs it)")
    xyz = reader.vector(fields["xyz_mm"], join(path, "xyz_mm"))
    ypr = reader.vector(fields["ypr_deg"], join(path, "ypr_deg"))
    tol_mm = _bounded(reader, fields, path, "position_tolerance_mm", MAX_POSITION_TOLERANCE_MM)
    tol_deg = _bounded(reader, fields, path, "angle_tolerance_deg", MAX_ANGLE_TOLERANCE_DEG)
    free = False
    if "free_axis" in fields:
        node = fields["free_axis"]
        if node.tag != "tag:yaml.org,2002:bool":
            raise reader.fail(
                node, join(path, "free_axis"), f"must be true or false, got {node.value!r}"
            )
        free = str(node.value).lower() in ("true", "yes", "on")
    return NamedPose(
        name,
        xyz=tuple(v * 1e-3 for v in xyz),
        ypr=tuple(math.radians(v) for v in ypr),
        position_tolerance=tol_mm * 1e-3,
        angle_tolerance=math.radians(tol_deg),
        free_axis=free,
        source=where,
    )


def _bounded(
    reader: FieldReader, fields: dict[str, yaml.Node], path: str, key: str, limit: float
) -> float:
    if key not in fields:
        return 0.0
    value = reader.number(fields[key], join(path, key), minimum=0.0)
    if value > limit:
        raise reader.fail(fields[key], join(path, key), f"must be <= {limit:g}, got {value:g}")
    return value


def load_poses_file(path: str | os.PathLike[str]) -> dict[str, NamedPose]:
    """Read the poses file at ``path``.

    Raises:
        NamedPoseError: unreadable, or any problem of :func:`parse_poses`.
    """
    file = Path(path)
    try:
        text = file.read_text()
    except OSError as exc:
        raise NamedPoseError(f"{file}: cannot read the poses file: {exc.strerror}") from exc
    try:
        shipped = file.resolve() == shipped_poses_path().resolve()
    except OSError:
        shipped = False
    return parse_poses(text, SHIPPED_SOURCE if shipped else str(file))


def named_poses(user_file: str = "") -> dict[str, NamedPose]:
    """Every named pose: the fold poses, the shipped file's, then the user's file
    (``user_file``, else ``$MANUS_POSES``, else none), later ones replacing earlier ones.

    Raises:
        NamedPoseError: a file is unreadable or malformed.
    """
    out = {
        name: NamedPose(name, joints=tuple(math.radians(v) for v in q), source="manus.config")
        for name, q in FIXED.items()
    }
    out.update(load_poses_file(shipped_poses_path()))
    chosen = user_file or os.environ.get(POSES_ENV, "")
    if chosen:
        out.update(load_poses_file(chosen))
    return out


def find_pose(poses: dict[str, NamedPose], name: str) -> NamedPose:
    """The pose called ``name``.

    Raises:
        NamedPoseError: unknown, listing the known names.
    """
    found = poses.get(name)
    if found is None:
        raise NamedPoseError(f"unknown named pose {name!r} (known: {', '.join(sorted(poses))})")
    return found
