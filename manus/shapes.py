"""Geometry of primitives for the collision model: Coal shapes of scene primitives, the
convex covers of the arm's bodies, and distances to a zone's boundary from inside.
"""

from __future__ import annotations

import coal
import numpy as np

from manus.scene import Primitive
from manus.urdf import Shape


def coal_shape(body: Primitive) -> tuple[coal.CollisionGeometry, np.ndarray]:
    """The Coal geometry of a scene primitive and its placement in the chair frame."""
    s = body.size
    if body.shape == "box":
        return coal.Box(*s), body.pose
    if body.shape == "sphere":
        return coal.Sphere(s[0]), body.pose
    if body.shape == "cylinder":
        return coal.Cylinder(s[0], s[1]), body.pose
    if body.shape == "capsule":
        return coal.Capsule(s[0], s[1]), body.pose
    normal = np.asarray(s, dtype=float)
    return coal.Halfspace(normal, float(normal @ body.pose[:3, 3])), np.eye(4)


def cover(shape: Shape) -> tuple[np.ndarray, float]:
    """Points (k, 3) in the body's own frame and a radius whose hull covers the body."""
    if shape.kind == "sphere":
        return np.zeros((1, 3)), shape.size[0]
    if shape.kind == "cylinder":
        h = shape.size[1] / 2.0
        return np.array([[0.0, 0.0, -h], [0.0, 0.0, h]]), shape.size[0]
    hx, hy, hz = (v / 2.0 for v in shape.size)
    corners = [[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    return np.array(corners), 0.0


def inner_distances(zone: Primitive, points: np.ndarray) -> np.ndarray:
    """Distance from each of ``points`` (k, 3) to the boundary of the convex ``zone``,
    negative outside [m], shape (k,) (zone placed in the base frame)."""
    T = zone.pose
    local = (points - T[:3, 3]) @ T[:3, :3]
    if zone.shape == "box":
        half = np.asarray(zone.size) / 2.0
        inner = half - np.abs(local)
        # Column by column: numpy's reduction over a short last axis is slow.
        return np.asarray(np.minimum(np.minimum(inner[:, 0], inner[:, 1]), inner[:, 2]))
    if zone.shape == "sphere":
        return np.asarray(zone.size[0] - np.linalg.norm(local, axis=1))
    radius, length = zone.size
    if zone.shape == "cylinder":
        radial = radius - np.hypot(local[:, 0], local[:, 1])
        axial = length / 2.0 - np.abs(local[:, 2])
        return np.asarray(np.minimum(radial, axial))
    # capsule: distance to the axis segment
    z = np.clip(local[:, 2], -length / 2.0, length / 2.0)
    return np.asarray(radius - np.linalg.norm(local - np.c_[0 * z, 0 * z, z], axis=1))
