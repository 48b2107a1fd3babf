"""The scene and protection zones (:mod:`manus.scene`) as the viewer draws them.

A scene is in the chair frame; the arm's URDF hangs from ``base_link`` (the shoulder, DH
frame 0), which the scene places at ``mount``. :func:`solids` expresses every object and
zone in ``base_link`` (``mount⁻¹ · pose``), so they sit where the collision model puts
them relative to the arm, as the primitives Foxglove draws: a box is a cube, a sphere a
sphere, a cylinder a cylinder (both along the local z, as in the scene file), a capsule a
cylinder with a sphere at each end, a plane (an unbounded half-space) a thin square of
:data:`PLANE_SIDE` centred on its point, normal along the square's z. Colour by class
(``person``, ``chair``, ``environment``); keep-out zones translucent red, the keep-in
workspace a faint translucent green.

The builders of Foxglove messages (:func:`services.viewer.scene.solid_entity`) and the
matplotlib rendering of docs/viewer.md (:mod:`manus_stack.view_render`) both draw these solids.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.scene import Primitive, Scene

CLASS_RGBA = {
    "person": (0.93, 0.66, 0.52, 0.85),
    "chair": (0.32, 0.34, 0.40, 0.85),
    "environment": (0.60, 0.45, 0.28, 0.85),
}
"""Colour (r, g, b, a) of each object class."""
PLANE_RGBA = (0.60, 0.45, 0.28, 0.25)
"""A plane (the floor) is drawn fainter: it is large and the arm is above it."""
ZONE_RGBA = {"keep_out": (0.90, 0.12, 0.12, 0.30), "keep_in": (0.20, 0.80, 0.35, 0.07)}
"""Colour of each zone kind: translucent, so the arm inside stays visible."""
PLANE_SIDE = 2.0
"""Side of the square drawn for a plane [m]."""
PLANE_THICKNESS = 0.002
"""Thickness of that square [m]."""


class Solid(NamedTuple):
    """One primitive to draw.

    Attributes:
        shape: Foxglove's primitive: ``cube``, ``sphere`` or ``cylinder``.
        pose: placement in ``base_link``, shape (4, 4) [m].
        size: Foxglove's size (x, y, z) [m]: a cube's edges, a sphere's and a cylinder's
            diameters in x and y (the cylinder's length in z).
        rgba: colour.
    """

    shape: str
    pose: np.ndarray
    size: tuple[float, float, float]
    rgba: tuple[float, float, float, float]


class Drawn(NamedTuple):
    """One scene object or zone, drawn.

    Attributes:
        entity: entity id (``object/<name>``, ``zone/<name>``).
        solids: its primitives.
        metadata: what it is (name, class or kind, shape, scene version and source).
    """

    entity: str
    solids: list[Solid]
    metadata: dict[str, str]


def _z_to(normal: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) taking z to the unit ``normal`` (the shortest one)."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, normal)
    s, c = float(np.linalg.norm(axis)), float(z @ normal)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    angle = math.atan2(s, c)
    return np.asarray(np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K)


def primitive_solids(body: Primitive, to_base: np.ndarray, rgba: tuple[float, ...]) -> list[Solid]:
    """The solids of one primitive; ``to_base`` = mount⁻¹ (chair -> base_link)."""
    colour = (rgba[0], rgba[1], rgba[2], rgba[3])
    s = body.size
    if body.shape == "plane":
        pose = np.eye(4)
        pose[:3, :3] = _z_to(np.asarray(s, dtype=float))
        pose[:3, 3] = body.pose[:3, 3]
        side = (PLANE_SIDE, PLANE_SIDE, PLANE_THICKNESS)
        return [Solid("cube", to_base @ pose, side, (*colour[:3], PLANE_RGBA[3]))]
    pose = to_base @ body.pose
    if body.shape == "box":
        return [Solid("cube", pose, (s[0], s[1], s[2]), colour)]
    if body.shape == "sphere":
        return [Solid("sphere", pose, (2 * s[0], 2 * s[0], 2 * s[0]), colour)]
    radius, length = s
    out = [Solid("cylinder", pose, (2 * radius, 2 * radius, length), colour)]
    if body.shape == "capsule":
        for end in (-0.5, 0.5):
            cap = pose.copy()
            cap[:3, 3] = pose[:3, 3] + pose[:3, 2] * end * length
            out.append(Solid("sphere", cap, (2 * radius, 2 * radius, 2 * radius), colour))
    return out


def solids(scene: Scene) -> list[Drawn]:
    """Every object, then every zone, of ``scene`` in ``base_link``."""
    to_base = np.linalg.inv(scene.mount)
    common = {"scene_version": str(scene.version), "scene_source": scene.source}
    out = []
    for obj in scene.objects:
        rgba = CLASS_RGBA[obj.cls]
        meta = {"name": obj.name, "class": obj.cls, "shape": obj.body.shape, **common}
        out.append(Drawn(f"object/{obj.name}", primitive_solids(obj.body, to_base, rgba), meta))
    for zone in scene.zones:
        meta = {
            "name": zone.name,
            "kind": zone.kind,
            "links": zone.links,
            "shape": zone.body.shape,
            "clearance_mm": f"{zone.clearance * 1e3:g}",
            **common,
        }
        drawn = primitive_solids(zone.body, to_base, ZONE_RGBA[zone.kind])
        out.append(Drawn(f"zone/{zone.name}", drawn, meta))
    return out
