"""How far the arm's bodies travel: their cover points over many configurations at once.

:func:`manus.sweep.sweep` proves stretches of a motion clear by bounding how far any
point of each body can have moved since the last configuration whose distances were
computed. :class:`BodyPoints` gives it what that takes, vectorised over all the motion's
grid samples in one go: the bodies' cover points (:func:`manus.shapes.cover`: points
and a radius whose hull holds the body) in the base frame, each moving body's margin to
the keep-in zones, and the per-body bounds below.

A rigid motion moves a body's point ``c + u`` (``c`` a cover point, ``|u| <=`` its
radius) by ``d(c) + (R - I) u``: at most the cover point's own displacement plus the
body's rotation angle times the radius, and the rotation angle is at most the sum of the
joint deltas of the joints that move the body. The displacement is convex in the point,
so a body's largest displacement is at its cover points.
"""

from __future__ import annotations

import numpy as np

from manus.clearance import Check
from manus.collision import CollisionModel
from manus.shapes import inner_distances


class BodyPoints:
    """The moving bodies of ``model`` as cover points, batched over configurations.

    Points are kept coordinates first, ``(3, m, G)`` (coordinate, cover point of a moving
    body, configuration): every step then runs on long contiguous rows, and no temporary
    grows past a few hundred kilobytes (larger ones cost page faults on every call, more
    than the arithmetic).

    Args:
        model: the collision model (its bodies, keep-in zones and joint placements).
    """

    def __init__(self, model: CollisionModel) -> None:
        self.model = model
        pm = model.model
        self._placements = [pm.jointPlacements[j].homogeneous for j in range(pm.njoints)]
        self._parents = [int(pm.parents[j]) for j in range(pm.njoints)]
        cover = model.cover
        self.moving = np.array(model.moving)
        """Indices into ``model.shapes`` of the bodies the joints move, shape (B,)."""
        self.names = [model.shapes[i].name for i in model.moving]
        kept = np.flatnonzero(np.isin(cover.point_body, self.moving))  # sorted by body
        self._points = cover.points[kept]
        self._points1 = np.c_[self._points, np.ones(len(kept))]
        self._radii = cover.radii[kept]
        joint = cover.point_joint[kept]
        self._groups = [(int(j), np.flatnonzero(joint == j)) for j in np.unique(joint)]
        self.starts = np.searchsorted(cover.point_body[kept], self.moving)
        """Where each moving body's cover points start, shape (B,)."""
        self._keep_in = [
            (check, zone, np.flatnonzero(np.isin(kept, rows)))
            for check, zone, rows in cover.keep_in
        ]
        joint_of = np.array([model.geom.geometryObjects[i].parentJoint for i in model.moving])
        self.moves = np.array(
            [joint_of >= j for j in range(1, pm.njoints)], dtype=float
        )  # (6, B): 1 where joint j moves body b
        self.radius = np.maximum.reduceat(self._radii, self.starts)
        """Largest cover radius of each moving body [m], shape (B,)."""
        self.levers = self._levers(joint_of)
        """Per joint and moving body, the farthest any point of the body can ever be
        from the joint's origin [m], shape (6, B) (0: the joint does not move it)."""

    def world(self, Q: np.ndarray) -> np.ndarray:
        """Cover points in the base frame at each configuration ``Q`` [rad], shape
        (G, 6) -> (3, m, G) [m] (the same as Pinocchio's placements)."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        G = len(Q)
        c, s = np.cos(Q.T), np.sin(Q.T)  # (6, G)
        # Frames as (4, 4, G): the configurations last, so every step is a few long,
        # contiguous rows (or 4 x 4 matrix products over them).
        frames = [np.repeat(self._placements[0][:, :, None], G, axis=2)]
        for j in range(1, len(self._placements)):
            # (parent @ placement), row by row, then the turn about z by columns.
            A = np.matmul(self._placements[j].T, frames[self._parents[j]])
            F = np.empty_like(A)
            F[:, 0] = A[:, 0] * c[j - 1] + A[:, 1] * s[j - 1]
            F[:, 1] = A[:, 1] * c[j - 1] - A[:, 0] * s[j - 1]
            F[:, 2:] = A[:, 2:]
            frames.append(F)
        out = np.empty((3, len(self._points), G))
        for j, rows in self._groups:
            out[:, rows] = np.matmul(self._points1[rows], frames[j][:3])
        return out

    def keep_in(self, world: np.ndarray) -> list[tuple[Check, np.ndarray]]:
        """Per keep-in zone: its check (no body named) and each moving body's margin to
        it [m] at each configuration, shape (B, G) (inf: a body the zone does not hold);
        ``world`` from :meth:`world`."""
        out = []
        m, G = world.shape[1:]
        for check, zone, rows in self._keep_in:
            inner = np.full((m, G), np.inf)
            held = world if len(rows) == m else world[:, rows]
            inner[rows] = inner_distances(zone, held) - self._radii[rows, None] - check.required
            out.append((check, np.minimum.reduceat(inner, self.starts, axis=0)))
        return out

    def displacement(self, world: np.ndarray, rows: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Per moving body, how far its farthest cover point is at configuration
        ``rows[r]`` (R,) from where it was at ``ends[e, r]`` (E, R), both indices into
        ``world`` (3, m, G) [m], shape (E, R, B)."""
        squared = None
        for plane in world:  # (m, G), one coordinate
            d = plane[:, rows][:, None, :] - plane[:, ends]  # (m, E, R)
            d *= d
            squared = d if squared is None else np.add(squared, d, out=squared)
        assert squared is not None
        np.sqrt(squared, out=squared)
        return np.asarray(np.maximum.reduceat(squared, self.starts, axis=0).transpose(1, 2, 0))

    def _levers(self, joint_of: np.ndarray) -> np.ndarray:
        """The joint placements' lengths from joint ``j`` out to the body, plus the body's
        own farthest cover point and radius (configuration-independent)."""
        pm = self.model.model
        lengths = [
            float(np.linalg.norm(pm.jointPlacements[k].translation)) for k in range(pm.njoints)
        ]
        extent = np.linalg.norm(self._points, axis=1) + self._radii
        own = np.maximum.reduceat(extent, self.starts)
        out = np.zeros((pm.njoints - 1, len(self.moving)))
        for b, joint in enumerate(joint_of):
            for j in range(1, joint + 1):
                out[j - 1, b] = sum(lengths[j + 1 : joint + 1]) + own[b]
        return out
