"""Geometry of primitives for the collision model: Coal shapes of scene primitives, the
convex covers of the arm's bodies, distances to a zone's boundary from inside, the
boxes of a geometry model's fixed bodies, and Coal queries that do not depend on the
ones before.
"""

from __future__ import annotations

import itertools
import math
import warnings
from typing import Any

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
    if shape.kind in ("cylinder", "capsule"):  # a capsule's exactly, a cylinder's over
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
    flat = np.asarray(xyz, dtype=float).reshape(3, -1)
    local = T[:3, :3].T @ (flat - T[:3, 3:4])  # (3, N): one product, small or large
    if zone.shape == "box":
        inner = (np.asarray(zone.size)[:, None] / 2.0 - np.abs(local)).min(axis=0)
    elif zone.shape == "sphere":
        inner = zone.size[0] - np.sqrt((local * local).sum(axis=0))
    else:
        radius, length = zone.size
        x, y, z = local
        if zone.shape == "cylinder":
            inner = np.minimum(radius - np.hypot(x, y), length / 2.0 - np.abs(z))
        else:  # capsule: distance to the axis segment
            along = z - np.clip(z, -length / 2.0, length / 2.0)
            inner = radius - np.sqrt(x * x + y * y + along * along)
    return np.asarray(inner).reshape(np.shape(xyz)[1:])


def partner_boxes(gm: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each pair of a body's geometry model (the body first, its partners after):
    whether the partner is fixed (on the base), and its box in the base frame, grown by
    its swept-sphere radius (the clearance it carries) [m], (pairs, 3) each (an
    unbounded partner, a plane, gets an infinite box)."""
    fixed, lows, highs = [], [], []
    for cp in gm.collisionPairs:
        obj = gm.geometryObjects[cp.second]
        geometry = obj.geometry
        geometry.computeLocalAABB()
        a, b = geometry.aabb_local.min_, geometry.aabb_local.max_
        fixed.append(obj.parentJoint == 0)
        if not (np.all(np.abs(a) < 1e6) and np.all(np.abs(b) < 1e6)):
            lows.append(np.full(3, -math.inf))
            highs.append(np.full(3, math.inf))
            continue
        corners = np.array(list(itertools.product(*zip(a, b, strict=True))))
        M = obj.placement
        world = corners @ M.rotation.T + M.translation
        grow = geometry.getSweptSphereRadius()
        lows.append(world.min(axis=0) - grow)
        highs.append(world.max(axis=0) + grow)
    return np.array(fixed, dtype=bool), np.array(lows), np.array(highs)


def fresh_guesses(data: Any) -> Any:
    """``data`` (a ``pin.GeometryData``) with GJK starting from its default guess at every
    query: Pinocchio's data starts each query from the last one's answer, which makes a
    distance depend (by ~1e-7 m) on what was asked before, and a planner that answered
    other requests report another number than a fresh one (no faster either)."""
    with warnings.catch_warnings():
        # The flag is deprecated in favour of gjk_initial_guess, which it still overrides.
        warnings.simplefilter("ignore", DeprecationWarning)
        for request in data.distanceRequests:
            request.enable_cached_gjk_guess = False
    return data
