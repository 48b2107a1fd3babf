"""Whether straight segments from one point pass through primitives: the camera's lines
of sight, all of them against all occluders in a few vectorised steps.

Each occluder is a scene-style primitive (box, sphere, cylinder, capsule) with a pose;
each segment runs from ``eye`` to one of ``points``. Exact tests, in the primitive's own
frame: a box by its slabs, a sphere by the segment's distance to its centre, a cylinder
by clipping the segment to the slab between its caps and taking the clipped part's
distance to its axis, a capsule as its cylinder and the two spheres at its ends.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Primitive(NamedTuple):
    """An occluder.

    Attributes:
        shape: ``box``, ``sphere``, ``cylinder`` or ``capsule``.
        size: box (x, y, z); sphere (r,); cylinder and capsule (r, length) [m].
        pose: its placement, (4, 4) [m].
    """

    shape: str
    size: tuple[float, ...]
    pose: np.ndarray


def _local(eye: np.ndarray, points: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Segment starts (K, 1, 3) and directions (K, N, 3) in each of K frames."""
    R, c = poses[:, :3, :3], poses[:, :3, 3]
    start = np.matmul((eye - c)[:, None, :], R)
    return start, np.matmul(points - eye, R)


def _inverse(d: np.ndarray) -> np.ndarray:
    """1 / d, with a zero taken as the tiniest number of its sign: a direction along a
    slab then gives (-)huge ends, which act as the infinities they stand for."""
    return 1.0 / np.where(d == 0.0, 1e-300, d)


def _boxes(start: np.ndarray, d: np.ndarray, half: np.ndarray) -> np.ndarray:
    inv = _inverse(d)
    t1 = (-half[:, None, :] - start) * inv
    t2 = (half[:, None, :] - start) * inv
    enter, leave = np.minimum(t1, t2).max(axis=2), np.maximum(t1, t2).min(axis=2)
    hit: np.ndarray = (enter <= leave) & (leave >= 0.0) & (enter <= 1.0)
    return hit


def _spheres(start: np.ndarray, d: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Segments against spheres of ``radius`` (K,): ``start`` (K, 1, 3) relative to each
    centre, directions ``d`` (N, 3)."""
    dd = np.maximum((d * d).sum(axis=1), 1e-30)
    t = np.clip(-(start @ d.T)[:, 0, :] / dd, 0.0, 1.0)  # (K, N)
    gap = start + t[:, :, None] * d
    hit: np.ndarray = (gap * gap).sum(axis=2) <= (radius * radius)[:, None]
    return hit


def _cylinders(
    start: np.ndarray, d: np.ndarray, radius: np.ndarray, length: np.ndarray
) -> np.ndarray:
    h = (length / 2.0)[:, None]
    sz, inv = start[:, :, 2], _inverse(d[:, :, 2])
    ta, tb = (-h - sz) * inv, (h - sz) * inv
    # The part of the segment between the caps, t in [t0, t1] (t0 > t1: none).
    t0 = np.maximum(np.minimum(ta, tb), 0.0)
    t1 = np.minimum(np.maximum(ta, tb), 1.0)
    a, b = start[:, :, :2], d[:, :, :2]
    bb = np.maximum((b * b).sum(axis=2), 1e-30)
    # Nearest point to the axis on that part (kept within [0, 1] when there is none).
    t = np.clip(-(a * b).sum(axis=2) / bb, np.minimum(t0, 1.0), np.maximum(t1, 0.0))
    p = a + t[:, :, None] * b
    hit: np.ndarray = (t0 <= t1) & ((p * p).sum(axis=2) <= (radius * radius)[:, None])
    return hit


class Occluders:
    """Primitives grouped by kind, their arrays made once (the scene's, for every frame).

    Args:
        primitives: the occluders, in the order :meth:`blocked` reports them.
    """

    def __init__(self, primitives: list[Primitive]) -> None:
        self.count = len(primitives)
        boxes = [k for k, p in enumerate(primitives) if p.shape == "box"]
        rounds = [k for k, p in enumerate(primitives) if p.shape in ("cylinder", "capsule")]
        self._boxes = (boxes, *self._frames(primitives, boxes))
        self._rounds = (rounds, *self._frames(primitives, rounds))
        # Spheres, and a capsule's two end spheres, in the common frame.
        balls: list[tuple[int, np.ndarray, float]] = []
        for k, p in enumerate(primitives):
            if p.shape == "sphere":
                balls.append((k, p.pose[:3, 3], p.size[0]))
            elif p.shape == "capsule":
                for end in (-0.5, 0.5):
                    balls.append((k, p.pose[:3, 3] + p.pose[:3, 2] * end * p.size[1], p.size[0]))
        self._balls = (
            [k for k, _, _ in balls],
            np.array([c for _, c, _ in balls]).reshape(-1, 3),
            np.array([r for _, _, r in balls]),
        )

    @staticmethod
    def _frames(primitives: list[Primitive], rows: list[int]) -> tuple[np.ndarray, np.ndarray]:
        poses = np.array([primitives[k].pose for k in rows]).reshape(-1, 4, 4)
        sizes = np.array([primitives[k].size[:3] for k in rows] or np.zeros((0, 3)))
        return poses, sizes

    def blocked(self, eye: np.ndarray, points: np.ndarray) -> np.ndarray:
        """Which occluder blocks which segment ``eye`` -> ``points[n]``, shape (K, N).

        Args:
            eye: the common start, shape (3,) [m].
            points: the ends, shape (N, 3) [m].
        """
        out = np.zeros((self.count, len(points)), dtype=bool)
        rows, poses, size = self._boxes
        if rows:
            start, d = _local(eye, points, poses)
            out[rows] = _boxes(start, d, size / 2.0)
        rows, poses, size = self._rounds
        if rows:
            start, d = _local(eye, points, poses)
            out[rows] |= _cylinders(start, d, size[:, 0], size[:, 1])
        rows, centres, radius = self._balls
        if rows:
            np.logical_or.at(out, rows, _spheres((eye - centres)[:, None, :], points - eye, radius))
        return out
