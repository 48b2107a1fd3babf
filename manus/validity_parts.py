"""The arrays of the fast validity check (:mod:`manus.validity`): arm bodies cut into
convex pieces, their keep-in cover points, and scene primitives as kernel obstacles.

A piece is ``box(half) + disk(rc) + ball(rs)`` about its centre (the disk across its
third axis): a cylinder is cut along its axis into pieces no longer than
:data:`PIECE_M` (each ``half = (0, 0, h)``, ``rc = r``: exactly the cylinder's slice), a
sphere is one piece (``rs = r``), a capsule is cut like a cylinder with ``rs = r`` instead
(each slice a capsule: exactly the capsule's), a box is cut along each side longer than
:data:`PIECE_M`. The pieces' union is the body: no inflation, so a pair's bound is exact
whenever the separating direction found is the true one.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus import distance_bounds as k
from manus.collision import CollisionModel
from manus.scene import Primitive
from manus.shapes import cover
from manus.urdf import Shape

PIECE_M = 0.08
"""Longest side of a piece [m]: the shorter, the tighter the bounds and the more pieces
(0.08: 17 pieces; 9 at 0.15 left 4x as many configurations over-conservative)."""


class Piece(NamedTuple):
    """One convex piece of a body, in its joint's frame.

    Attributes:
        center: its centre [m], shape (3,).
        axes: its axes as rows, shape (3, 3) (the disk lies across the third).
        half: half sizes of its box part along the axes [m], shape (3,).
        rc: radius of its disk part [m].
        rs: radius of its ball part [m].
        rb: the radius of a sphere about its centre that holds it [m].
    """

    center: np.ndarray
    axes: np.ndarray
    half: np.ndarray
    rc: float
    rs: float
    rb: float


def _piece(center: np.ndarray, axes: np.ndarray, half: np.ndarray, rc: float, rs: float) -> Piece:
    rb = math.hypot(math.hypot(half[0], half[1]) + rc, half[2]) + rs
    return Piece(center, axes, half, rc, rs, rb)


def body_pieces(kind: str, size: tuple[float, ...], placement: np.ndarray) -> list[Piece]:
    """The pieces of a ``cylinder`` or ``capsule`` (radius, length), ``sphere``
    (radius,) or ``box`` (x, y, z) [m] placed by ``placement`` (4x4) in its joint's
    frame."""
    R, t = placement[:3, :3], placement[:3, 3]
    axes = R.T.copy()  # rows: the body's axes in the joint frame
    if kind == "sphere":
        return [_piece(t.copy(), np.eye(3), np.zeros(3), 0.0, size[0])]
    if kind in ("cylinder", "capsule"):
        radius, length = size
        n = max(1, math.ceil(length / PIECE_M))
        h = length / (2 * n)
        disk, ball = (radius, 0.0) if kind == "cylinder" else (0.0, radius)
        return [
            _piece(
                t + R[:, 2] * (-length / 2 + (2 * i + 1) * h),
                axes,
                np.array([0, 0, h]),
                disk,
                ball,
            )
            for i in range(n)
        ]
    if kind != "box":
        raise ValueError(f"no pieces for a {kind!r} body (box, cylinder, capsule or sphere)")
    counts = [max(1, math.ceil(side / PIECE_M)) for side in size]
    halves = np.array([side / (2 * n) for side, n in zip(size, counts, strict=True)])
    out = []
    for i in range(counts[0]):
        for j in range(counts[1]):
            for m in range(counts[2]):
                local = np.array(
                    [
                        (2 * c + 1) * hh - side / 2
                        for c, hh, side in zip((i, j, m), halves, size, strict=True)
                    ]
                )
                out.append(_piece(t + R @ local, axes, halves.copy(), 0.0, 0.0))
    return out


def cover_points(
    statics: list[tuple[str, tuple[float, ...], np.ndarray, int]],
    shapes: list[tuple[str, tuple[float, ...], np.ndarray]],
    joints: list[int],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The keep-in cover points (:func:`manus.shapes.cover`, as the collision model uses
    them) of the static bodies (body -1, -2, ...) and of the checked bodies (0, 1, ...):
    local points (m, 3) [m], radii (m,) [m], joints (m,), bodies (m,)."""
    local, radii, joint, body = [], [], [], []
    entries = [(kind, size, M, j, -1 - s) for s, (kind, size, M, j) in enumerate(statics)]
    entries += [
        (kind, size, M, j, b)
        for b, ((kind, size, M), j) in enumerate(zip(shapes, joints, strict=True))
    ]
    for kind, size, M, j, b in entries:
        points, radius = cover(Shape("", "", kind, size, (0.0, 0.0, 0.0)))
        local.append(points @ M[:3, :3].T + M[:3, 3])
        radii += [radius] * len(points)
        joint += [j] * len(points)
        body += [b] * len(points)
    return (
        np.vstack(local),
        np.array(radii),
        np.array(joint, dtype=np.int64),
        np.array(body, dtype=np.int64),
    )


def primitive_arrays(
    prims: list[Primitive],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Primitives placed in the base frame as kernel obstacles: kinds (n,), rotations
    (n, 3, 3), origins (n, 3), sizes (n, 3) (:data:`manus.validity_kernels.BOX` ...)."""
    n = len(prims)
    kind = np.zeros(n, dtype=np.int64)
    R = np.zeros((n, 3, 3))
    t = np.zeros((n, 3))
    s = np.zeros((n, 3))
    for i, p in enumerate(prims):
        R[i], t[i] = p.pose[:3, :3], p.pose[:3, 3]
        if p.shape == "box":
            kind[i], s[i] = k.BOX, np.asarray(p.size) / 2.0
        elif p.shape == "sphere":
            kind[i], s[i, 0] = k.SPHERE, p.size[0]
        elif p.shape in ("cylinder", "capsule"):
            kind[i] = k.CYLINDER if p.shape == "cylinder" else k.CAPSULE
            s[i, :2] = p.size[0], p.size[1] / 2.0
        else:  # plane: local z along its normal, through its point
            normal = np.asarray(p.size, dtype=float)
            R[i] = _frame_with_z(normal / np.linalg.norm(normal))
            kind[i] = k.HALFSPACE
    return kind, R, t, s


def _frame_with_z(z: np.ndarray) -> np.ndarray:
    """A rotation whose third column is the unit vector ``z``."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    return np.column_stack((x, np.cross(z, x), z))


def primitive_box(p: Primitive) -> np.ndarray:
    """The box in the base frame that holds a placed primitive [m], (2, 3) low and high
    corners (a plane: unbounded)."""
    R, t = p.pose[:3, :3], p.pose[:3, 3]
    if p.shape == "box":
        half = np.abs(R) @ (np.asarray(p.size) / 2.0)
    elif p.shape == "sphere":
        half = np.full(3, p.size[0])
    elif p.shape in ("cylinder", "capsule"):
        radius, length = p.size
        # The disk's extent along each base axis, plus the axis segment's (and a
        # capsule's end balls: its radius along the axis too).
        axial = length / 2.0 + (radius if p.shape == "capsule" else 0.0)
        half = radius * np.sqrt(np.maximum(0.0, 1.0 - R[:, 2] ** 2)) + axial * np.abs(R[:, 2])
    else:
        return np.array([np.full(3, -math.inf), np.full(3, math.inf)])
    return np.array([t - half, t + half])


def lever_table(
    model: CollisionModel, arm: tuple[np.ndarray, ...], joints: list[int]
) -> np.ndarray:
    """Per joint and body, the farthest any point of the body can ever be from the
    joint's origin [m], shape (6, B): the joint placements' lengths out to the body's
    joint plus its farthest piece or cover point (``arm``: the kernels' arm arrays)."""
    pm = model.model
    lengths = [float(np.linalg.norm(pm.jointPlacements[j].translation)) for j in range(pm.njoints)]
    own = np.zeros(len(joints))
    for points, body, radius in ((arm[3], arm[2], arm[8]), (arm[15], arm[14], arm[16])):
        for b, extent in zip(body, np.linalg.norm(points, axis=1) + radius, strict=True):
            if b >= 0:
                own[b] = max(own[b], extent)
    out = np.zeros((pm.njoints - 1, len(joints)))
    for b, joint in enumerate(joints):
        for j in range(1, joint + 1):
            out[j - 1, b] = sum(lengths[j + 1 : joint + 1]) + own[b]
    return out
