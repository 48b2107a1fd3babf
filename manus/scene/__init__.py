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

Modules: :mod:`~manus.scene.model` (the data model, classes and clearances),
:mod:`~manus.scene.file` (reading and validating a file; the shipped scene) and
:mod:`~manus.scene.setting` (which scene a service uses). Every name is importable from
``manus.scene``.
"""

from __future__ import annotations

from manus.scene.file import (
    SHIPPED_SOURCE,
    default_scene,
    default_scene_path,
    load_scene,
    parse_scene,
    source_name,
)
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
    describe,
    pose_matrix,
    rpy_matrix,
)
from manus.scene.setting import SCENE_ENV, scene_from_setting, scene_path, start_scene_state

__all__ = [
    "CLASSES",
    "DEFAULT_CLEARANCE_MM",
    "FILE_FORMAT",
    "SCENE_ENV",
    "SHAPES",
    "SHIPPED_SOURCE",
    "ZONE_KINDS",
    "ZONE_LINKS",
    "Primitive",
    "Scene",
    "SceneError",
    "SceneObject",
    "Zone",
    "default_scene",
    "default_scene_path",
    "describe",
    "load_scene",
    "parse_scene",
    "pose_matrix",
    "rpy_matrix",
    "scene_from_setting",
    "scene_path",
    "source_name",
    "start_scene_state",
]
