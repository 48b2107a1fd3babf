"""The arm's bodies as cover points: where each body is, how far each joint reaches it,
and how much room it has inside the keep-in zones.

Each body is covered by a few points and a radius whose hull holds it
(:func:`manus.shapes.cover`: a cylinder's two end points, a box's corners, a sphere's
centre). A concave margin over a convex body is smallest at one of those points, so the
keep-in zones are checked exactly at them; and a body moves no faster than its farthest
cover point from a joint's axis times that joint's speed (the reach the controller's
guard bounds its travel with).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from manus.clearance import Check
from manus.scene import Primitive
from manus.shapes import cover, inner_distances
from manus.urdf import Shape

_ONES3 = np.ones(3)


class BodyCover:
    """Cover points of every body of a geometry model, in its joint's frame.

    Args:
        model: the arm's kinematic model (Pinocchio).
        geom: its geometry model (the bodies first, in the order of ``shapes``).
        shapes: the bodies.
        moving: indices of the bodies the joints move (into ``shapes``).
        keep_in: per keep-in zone: its check, the zone in the base frame, the indices of
            the bodies it must hold.
    """

    def __init__(
        self,
        model: Any,
        geom: Any,
        shapes: list[Shape],
        moving: list[int],
        keep_in: list[tuple[Check, Primitive, list[int]]],
    ) -> None:
        self.model = model
        self.names = [s.name for s in shapes]
        self.moving = moving
        points, radii, joints, bodies = [], [], [], []
        for i, shape in enumerate(shapes):
            local, radius = cover(shape)
            M = geom.geometryObjects[i].placement
            points.append(local @ M.rotation.T + M.translation)
            radii += [radius] * len(local)
            joints += [geom.geometryObjects[i].parentJoint] * len(local)
            bodies += [i] * len(local)
        self.points = np.vstack(points)
        """Every cover point in its joint's frame [m], shape (n, 3), grouped by body."""
        self.radii = np.array(radii)
        """Each point's radius [m], shape (n,)."""
        self.point_joint = np.array(joints)
        self.point_body = np.array(bodies)
        self.extent = float(np.linalg.norm(self.points, axis=1).max() + self.radii.max())
        """Farthest any body point is from its joint's origin [m] (a coarse speed bound)."""
        self._beyond = np.array([self.point_joint >= j for j in range(1, model.njoints)])
        self._outside = np.full(len(self.points), math.inf)
        self._points1 = np.c_[self.points, np.ones(len(self.points))][:, :, None]
        self.starts = np.searchsorted(self.point_body, np.arange(len(shapes)))
        """Where each body's points start, shape (bodies,)."""
        self.keep_in = [
            (check, zone, np.flatnonzero(np.isin(self.point_body, members)))
            for check, zone, members in keep_in
        ]
        """Per keep-in zone: its check, the zone, the rows of the points it holds."""
        self._holding: dict[int, float] = {}
        self._joints_now = np.zeros((model.njoints, 4, 4))

    def world(self, data: Any) -> np.ndarray:
        """The cover points in the base frame at the joint placements of ``data`` (a
        ``pin.Data`` after forward kinematics), shape (n, 3) [m]."""
        H = np.array([m.homogeneous for m in data.oMi])
        self._joints_now = H
        Hp = H[self.point_joint]
        return np.asarray((Hp[:, :3, :] @ self._points1)[:, :, 0])

    def reach(self, world: np.ndarray) -> np.ndarray:
        """Per joint and moving body, the farthest point of the body from the joint's axis
        (0 for a body the joint does not move) [m], shape (6, moving bodies), at the
        configuration of the last :meth:`world`."""
        H = self._joints_now[1:]
        origins, axes = H[:, :3, 3], H[:, :3, 2]  # (6, 3) each
        # |d|^2 - (d . z)^2 with d = p - o, expanded so that one product does the work.
        wo_wz = world @ np.hstack((origins.T, axes.T))  # (n, 12)
        squared = (world * world) @ _ONES3  # (n,): numpy's sum over a short axis is slow
        d2 = squared[:, None] - 2.0 * wo_wz[:, :6] + (origins * origins) @ _ONES3
        along = wo_wz[:, 6:] - (origins * axes) @ _ONES3
        radial = np.sqrt(np.maximum(d2 - along * along, 0.0)).T  # (6, n)
        radial = np.where(self._beyond, radial + self.radii, 0.0)
        per_body = np.maximum.reduceat(radial, self.starts, axis=1)
        return np.asarray(per_body[:, self.moving])

    def keep_in_at(self, world: np.ndarray) -> list[tuple[float, Check, np.ndarray]]:
        """Per keep-in zone: its tightest margin [m], the check naming the body, and each
        moving body's margin to it [m] (inf: a body the zone does not hold)."""
        out = []
        for check, zone, rows in self.keep_in:
            inner = self._outside.copy()
            inside = inner_distances(zone, world[rows].T)
            inner[rows] = inside - self.radii[rows] - check.required
            k = int(np.argmin(inner))
            body = self.names[int(self.point_body[k])]
            per_body = np.minimum.reduceat(inner, self.starts)[self.moving]
            out.append((float(inner[k]), check._replace(body=body), per_body))
        return out

    def levers(self) -> np.ndarray:
        """Per joint and moving body, the farthest any of the body's cover points can ever
        be from the joint's origin [m], shape (6, moving bodies) (0: the joint does not
        move it): the joint placements' lengths from the joint to the point's, plus the
        point's own distance from its joint. Whatever the configuration, a cover point
        (and so a keep-in margin) moves no further than ``|dq| @ levers`` in a joint
        motion ``dq`` [rad]."""
        n = self.model.njoints
        length = [
            float(np.linalg.norm(self.model.jointPlacements[k].translation)) for k in range(n)
        ]
        own = np.linalg.norm(self.points, axis=1)
        out = np.zeros((n - 1, len(self.names)))
        for i, (joint, body) in enumerate(zip(self.point_joint, self.point_body, strict=True)):
            for j in range(1, int(joint) + 1):
                out[j - 1, body] = max(out[j - 1, body], sum(length[j + 1 : joint + 1]) + own[i])
        return out[:, self.moving]

    def holding_radius(self, body: int, joint: int) -> float:
        """The radius of the sphere about the shoulder that holds ``body`` (on joint
        ``joint``) in every configuration [m]: the joint placements' lengths up to it,
        plus its own extent (computed once per body)."""
        if body in self._holding:
            return self._holding[body]
        rows = self.point_body == body
        radius = sum(
            float(np.linalg.norm(self.model.jointPlacements[k].translation))
            for k in range(1, joint + 1)
        )
        radius += float((np.linalg.norm(self.points[rows], axis=1) + self.radii[rows]).max())
        self._holding[body] = radius
        return radius
