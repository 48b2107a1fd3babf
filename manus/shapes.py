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


def inner_distances(zone: Primitive, xyz: np.ndarray) -> np.ndarray:
    """Distance from each point to the boundary of the convex ``zone``, negative outside
    [m] (zone placed in the base frame).

    Args:
        xyz: the points, coordinates first: shape (3, ...) (any number of points in any
            shape: one array per coordinate keeps every step on long contiguous rows).

    Returns:
        shape ``xyz.shape[1:]``.
    """
    T = zone.pose
    d = [xyz[i] - T[i, 3] for i in range(3)]
    x, y, z = (d[0] * T[0, c] + d[1] * T[1, c] + d[2] * T[2, c] for c in range(3))
    if zone.shape == "box":
        hx, hy, hz = (s / 2.0 for s in zone.size)
        return np.asarray(np.minimum(np.minimum(hx - np.abs(x), hy - np.abs(y)), hz - np.abs(z)))
    if zone.shape == "sphere":
        return np.asarray(zone.size[0] - np.sqrt(x * x + y * y + z * z))
    radius, length = zone.size
    if zone.shape == "cylinder":
        return np.asarray(np.minimum(radius - np.hypot(x, y), length / 2.0 - np.abs(z)))
    # capsule: distance to the axis segment
    along = z - np.clip(z, -length / 2.0, length / 2.0)
    return np.asarray(radius - np.sqrt(x * x + y * y + along * along))
