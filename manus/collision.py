"""The arm's collision model: distances from its bodies to the scene, the zones and itself.

The arm's bodies are the URDF's collision geometry (:func:`manus.urdf.collision_shapes`),
loaded with Pinocchio into a :class:`pinocchio.GeometryModel`; the scene's objects and
keep-out zones are added to it as fixed bodies (placed through the mount), and
:func:`pinocchio.computeDistances` gives every pair's distance with Coal in one call. Each
class's clearance is baked into the fixed body as Coal's swept-sphere radius, so a
pair's distance is its margin and the call's answer (the closest pair) is the tightest
check; :meth:`CollisionModel.probe` asks one small geometry model per moving body, which
gives each body its own margin. The keep-in workspace is checked apart, exactly, from
each body's convex cover (its end points or corners and a radius): a concave margin over
a convex body is smallest at one of those points.

Every check is one :class:`manus.clearance.Check`: an arm body, what it is checked
against, the class (``person``, ``chair``, ``environment``, ``self`` or ``zone``) and
the clearance that class requires. A configuration's *margin* per check is distance minus clearance;
negative means violated.

Self-collision pairs are declared once, in :data:`SELF_PAIRS`: the gripper, its motor,
the wrist and the forearm against the arm's base (column and shoulder). Adjacent bodies
are excluded, and so is everything between the upper arm and the forearm-wrist-gripper
chain: the DH model puts them in one plane (folded, on one line), while on the arm the
forearm and the gripper fold beside the upper arm, so their distance in this model says
nothing about the arm. Pairs that no configuration can bring within their clearance (an
object beyond the sphere about the shoulder that holds the body) are left out. The
``column`` and the ``shoulder`` do not move (the shoulder turns about its own axis), so
their distances to the scene are checked once, when the model is built
(:meth:`CollisionModel.base_overlaps`), not per configuration.

:func:`manus.sweep.sweep` checks a whole motion through
:meth:`CollisionModel.pair_margins` (each moving body's margin to what it must keep
clear of) and :class:`manus.travel.BodyPoints` (the cover points over the motion, the
keep-in zones), with the pairs that cannot come near the motion set aside
(:meth:`CollisionModel.restrict`); the controller's guard through
:meth:`CollisionModel.probe` (the same margins, and each joint's reach to each body).
"""

from __future__ import annotations

import math
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from manus.clearance import Check, Clearance, Probe
from manus.config import ArmConfig
from manus.scene import Primitive, Scene, SceneError
from manus.shapes import coal_shape, cover, inner_distances, moved_by, partner_boxes
from manus.urdf import FINGER_THICKNESS, build_urdf, collision_shapes

SELF_PAIRS: tuple[tuple[str, str], ...] = (
    ("gripper", "column"),
    ("gripper", "shoulder"),
    ("gripper_motor", "column"),
    ("gripper_motor", "shoulder"),
    ("wrist", "column"),
    ("forearm", "column"),
)
"""Self-collision pairs (arm body, arm body), the only place they are declared."""

MOVE_BOUND_M = 0.25
"""How far a scene object may be moved from its scene pose (:meth:`CollisionModel.move_object`)
while the pairs kept at construction stay right (checked by tests/test_collision.py) [m]."""

GRIPPER_BODIES = ("gripper", "gripper_motor")
"""The bodies a zone with ``links: gripper`` applies to."""

STATIC_BODIES = ("column", "shoulder")
"""Bodies whose distance to the scene does not depend on the joint angles."""


_ONES3 = np.ones(3)


class CollisionModel:
    """The arm's bodies, a scene and the checks between them.

    Raises:
        SceneError: a scene object overlaps the arm's base (column or shoulder), naming
            the file, its line and the object.

    Args:
        scene: the surroundings (None: self-collision only).
        cfg: arm geometry (passed explicitly, as the kinematics take it).
        opening: gripper opening the gripper box is sized for [m] (default: fully open,
            the planner's choice: it does not know the opening a move will have).
    """

    def __init__(self, scene: Scene | None, cfg: ArmConfig, opening: float | None = None) -> None:
        self.cfg = cfg
        self.scene = scene
        urdf = build_urdf(self.cfg)
        self.model = pin.buildModelFromXML(urdf)
        self.data = self.model.createData()
        gm = pin.buildGeomFromUrdfString(self.model, urdf, pin.GeometryType.COLLISION)
        self.shapes = collision_shapes(self.cfg)
        # Pinocchio names them <link>_<k>, in URDF order: give them the shapes' names.
        for obj, shape in zip(gm.geometryObjects, self.shapes, strict=True):
            obj.name = shape.name
        self.body_index = {s.name: i for i, s in enumerate(self.shapes)}
        self._gripper_box = gm.geometryObjects[self.body_index["gripper"]].geometry
        self.checks: list[Check] = []
        self._keep_in_bodies: list[tuple[Check, Primitive, list[int]]] = []
        self._static: list[tuple[int, int, Check]] = []
        pairs = self._self_pairs(gm, scene.clearance["self"] if scene is not None else 0.01)
        if scene is not None:
            pairs += self._scene_pairs(gm, scene)
            self._keep_in_zones(scene)
        self.geom = gm
        self._covers = [cover(s) for s in self.shapes]
        self._holding: dict[int, float] = {}
        self._prepare_points()
        # Pairs no configuration can bring within their clearance are left out.
        reachable = [self._can_meet(first, second) for first, second in pairs]
        pairs = [p for p, keep in zip(pairs, reachable, strict=True) if keep]
        self.checks = [c for c, keep in zip(self.checks, reachable, strict=True) if keep]
        for first, second in pairs:
            gm.addCollisionPair(pin.CollisionPair(first, second))
        self.geom_data = pin.GeometryData(gm)
        self._required = np.array([c.required for c in self.checks])
        self._per_body = self._split(pairs)
        self._live = [(b, gm, gd, rows) for b, (gm, gd, rows) in enumerate(self._per_body) if rows]
        self._no_margin = np.full(len(self._moving), math.inf)
        self._set_aside = self._no_margin
        self._inactive: list[tuple[Any, int]] = []
        self._partner_boxes = [partner_boxes(gm) for _, gm, _, _ in self._live]
        self._boxes_stale = False
        self._copies: dict[str, list[tuple[Any, int]]] = {}
        self._to_base = np.linalg.inv(scene.mount) if scene is not None else np.eye(4)
        self._no_reach = np.zeros((6, len(self._moving)))
        self._no_reach.flags.writeable = False
        overlaps = self.base_overlaps()
        if overlaps:
            raise SceneError(overlaps[0])
        self.set_opening(self.cfg.gripper_max if opening is None else opening)

    def _self_pairs(self, gm: Any, required: float) -> list[tuple[int, int]]:
        """The pairs of :data:`SELF_PAIRS`. Each clearance is baked into the other body
        as Coal's swept-sphere radius, so every pair's distance is its margin and
        computeDistances' argmin the tightest; the self pairs' bodies get inflated
        copies (the originals face the scene)."""
        pairs: list[tuple[int, int]] = []
        copies: dict[str, int] = {}
        for a, b in SELF_PAIRS:
            if b not in copies:
                original = gm.geometryObjects[self.body_index[b]]
                geometry = original.geometry.clone()
                geometry.setSweptSphereRadius(required)
                copies[b] = gm.addGeometryObject(
                    pin.GeometryObject(
                        f"{b}+self", original.parentJoint, original.placement, geometry
                    )
                )
            pairs.append((self.body_index[a], copies[b]))
            self.checks.append(Check(a, b, "self", required))
        return pairs

    def _scene_pairs(self, gm: Any, scene: Scene) -> list[tuple[int, int]]:
        """The scene's objects and keep-out zones as fixed bodies (their clearance as
        swept-sphere radius) and their pairs with the arm's moving bodies; the static
        bodies' pairs go to :meth:`base_overlaps`."""
        to_base = np.linalg.inv(scene.mount)
        fixed = [(o.name, o.cls, o.body, scene.clearance[o.cls], "all") for o in scene.objects]
        fixed += [
            (z.name, "zone", z.body, z.clearance, z.links)
            for z in scene.zones
            if z.kind == "keep_out"
        ]
        pairs: list[tuple[int, int]] = []
        for name, cls, body, required, links in fixed:
            geometry, pose = coal_shape(body)
            geometry.setSweptSphereRadius(required)
            placement = pin.SE3(to_base @ pose)
            index = gm.addGeometryObject(pin.GeometryObject(name, 0, placement, geometry))
            for i, shape in enumerate(self.shapes):
                if links == "gripper" and shape.name not in GRIPPER_BODIES:
                    continue
                check = Check(shape.name, name, cls, required)
                if shape.name in STATIC_BODIES:
                    self._static.append((i, index, check))
                else:
                    pairs.append((i, index))
                    self.checks.append(check)
        return pairs

    def _keep_in_zones(self, scene: Scene) -> None:
        to_base = np.linalg.inv(scene.mount)
        for zone in scene.zones:
            if zone.kind == "keep_in":
                bodies = [
                    i
                    for i, arm_body in enumerate(self.shapes)
                    if zone.links == "all" or arm_body.name in GRIPPER_BODIES
                ]
                check = Check("", f"keep_in {zone.name}", "zone", zone.clearance)
                body = Primitive(zone.body.shape, zone.body.size, to_base @ zone.body.pose)
                self._keep_in_bodies.append((check, body, bodies))

    def move_object(self, name: str, pose: np.ndarray) -> float:
        """Place the scene object ``name`` at ``pose`` (4x4, chair frame), in every check
        against it (a person the tracker follows: docs/follow.md, The person moves). The
        pairs kept at construction stay as they are: an object moved within
        :data:`MOVE_BOUND_M` of its scene pose meets no body it could not meet there.

        Returns:
            how far any point of the object moved at most [m] (its translation plus its
            turn times its radius).

        Raises:
            SceneError: no scene object of that name.
        """
        copies = self._copies.get(name)
        if copies is None:
            copies = self._copies[name] = [
                (gm, k)
                for gm in (self.geom, *(m for m, _, _ in self._per_body))
                for k, obj in enumerate(gm.geometryObjects)
                if obj.name == name and obj.parentJoint == 0
            ]
        if not copies or self.scene is None:
            raise SceneError(f"no scene object {name!r} to move (objects: {self._object_names()})")
        placement = pin.SE3(self._to_base @ pose)
        first = copies[0][0].geometryObjects[copies[0][1]]
        moved = moved_by(first.placement.homogeneous, placement.homogeneous, first.geometry)
        for gm, k in copies:
            gm.geometryObjects[k].placement = placement
        self._boxes_stale = True  # :meth:`restrict` builds them again when it needs them
        return moved

    def _object_names(self) -> list[str]:
        return [o.name for o in self.scene.objects] if self.scene is not None else []

    # --- configuration queries ----------------------------------------------------------

    def set_opening(self, opening: float) -> None:
        """Size the gripper box for ``opening`` [m] (clamped to 0..gripper_max)."""
        opening = min(max(opening, 0.0), self.cfg.gripper_max)
        half = self._gripper_box.halfSide.copy()
        half[0] = opening / 2.0 + FINGER_THICKNESS
        self._gripper_box.halfSide = half
        self._gripper_box.computeLocalAABB()
        self.opening = opening

    def margins(self, q: np.ndarray) -> np.ndarray:
        """Distance minus clearance of every pair check at ``q`` [m], shape (len(checks),);
        keep-in zones are not included (:meth:`keep_in_margins`)."""
        pin.computeDistances(
            self.model, self.data, self.geom, self.geom_data, np.asarray(q, dtype=float)
        )
        return np.array([r.min_distance for r in self.geom_data.distanceResults])

    def tightest(self, q: np.ndarray) -> tuple[int, float]:
        """The tightest pair check at ``q``: its index in :attr:`checks` and its margin [m]."""
        k = pin.computeDistances(self.model, self.data, self.geom, self.geom_data, q)
        return k, self.geom_data.distanceResults[k].min_distance

    def keep_in_margins(self) -> list[tuple[float, Check]]:
        """For each keep-in zone: the smallest inner distance of its bodies to its boundary
        minus its clearance, at the configuration of the last :meth:`margins` call."""
        return [(margin, check) for margin, check, _ in self._keep_in_at(self._world_points())]

    def clearance(self, q: np.ndarray, time: float = 0.0) -> Clearance:
        """The tightest check at ``q``."""
        q = np.asarray(q, dtype=float)
        m = self.margins(q)
        k = int(np.argmin(m)) if len(m) else -1
        best = (
            Clearance(float(m[k]), float(m[k] + self._required[k]), self.checks[k], time, q)
            if k >= 0
            else Clearance(math.inf, math.inf, Check("", "", "self", 0.0), time, q)
        )
        for margin, check in self.keep_in_margins():
            if margin < best.margin:
                best = Clearance(margin, margin + check.required, check, time, q)
        return best

    def base_overlaps(self) -> list[str]:
        """Scene objects that touch the arm's fixed base (column, shoulder), one line each."""
        out = []
        for i, j, check in self._static:
            res = coal.DistanceResult()
            placement = self.geom.geometryObjects[i].placement
            other = self.geom.geometryObjects[j]
            distance = coal.distance(
                self.geom.geometryObjects[i].geometry,
                coal.Transform3s(placement.rotation, placement.translation),
                other.geometry,
                coal.Transform3s(other.placement.rotation, other.placement.translation),
                coal.DistanceRequest(),
                res,
            )
            distance += check.required  # the object carries its clearance
            if distance <= 0.0:
                where = self.scene.where(_line_of(self.scene, check.other)) if self.scene else ""
                out.append(
                    f"{where}: objects.{check.other}: overlaps the arm's {check.body} (its "
                    f"base, at the mount) by {-distance * 1e3:.1f} mm: move the object or "
                    "the mount"
                )
        return out

    # --- motions --------------------------------------------------------------------------

    def probe(self, q: np.ndarray, time: float = 0.0, *, reach: bool = True) -> Probe:
        """At ``q``, per moving body: its tightest margin (how far it may travel before any
        of its gaps could close) and each joint's reach to it (zeros when ``reach`` is
        False: cheaper); and the tightest check."""
        q = np.asarray(q, dtype=float)
        free, tight, tight_row = self.pair_margins(q)
        points = self._world_points()
        for margin, check, per_body in self._keep_in_at(points):
            np.minimum(free, per_body, out=free)
            if margin < tight:
                tight, tight_row, keep_in = margin, -2, check
        if tight_row >= 0:
            check = self.checks[tight_row]
        elif tight_row == -2:
            check = keep_in
        else:
            check = Check("", "", "self", 0.0)
        best = Clearance(tight, tight + check.required, check, time, q)
        reaches = self._reach_at(points) if reach else self._no_reach
        return Probe(best, np.maximum(free, 0.0, out=free), reaches)

    def pair_margins(self, q: np.ndarray) -> tuple[np.ndarray, float, int]:
        """The pair checks at ``q`` [rad] (no keep-in zones): each moving body's tightest
        margin [m] (inf: nothing to keep clear of), shape (moving bodies,); the tightest
        margin of all [m] and its row in :attr:`checks` (-1: none)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q)
        update, distances = pin.updateGeometryPlacements, pin.computeDistances
        free = self._no_margin.copy()
        tight, tight_row = math.inf, -1
        for b, gm, gd, rows in self._live:
            update(model, data, gm, gd)
            k = distances(gm, gd)
            if k >= len(rows):
                continue  # every pair of the body is set aside (:meth:`restrict`)
            margin = gd.distanceResults[k].min_distance
            free[b] = margin
            if margin < tight:
                tight, tight_row = margin, rows[k]
        return np.minimum(free, self._set_aside, out=free), tight, tight_row

    def restrict(self, lo: np.ndarray, hi: np.ndarray, near: float) -> np.ndarray:
        """Set aside, until :meth:`unrestrict`, the pairs of each moving body with a
        fixed object that cannot come within ``near`` [m] of the box ``lo`` .. ``hi``
        (3, bodies) [m] that holds the body: :meth:`pair_margins` then asks Coal only
        for the others and caps each body's margin by what the set-aside pairs are
        sure to leave (the gap between the boxes; an object's box holds its
        clearance). The tightest check it names is the tightest of the pairs kept.

        Returns:
            per moving body, the least margin of its set-aside pairs [m] (inf: none).
        """
        if self._boxes_stale:
            self._partner_boxes = [partner_boxes(gm) for _, gm, _, _ in self._live]
            self._boxes_stale = False
        aside = np.full(len(self._moving), math.inf)
        for (b, _, gd, _), (fixed, box_lo, box_hi) in zip(
            self._live, self._partner_boxes, strict=True
        ):
            gaps = np.maximum(np.maximum(box_lo - hi[:, b], lo[:, b] - box_hi), 0.0)
            gap = np.sqrt((gaps * gaps).sum(axis=1))  # (pairs,): 0 when the boxes meet
            for k in np.flatnonzero(fixed):
                if gap[k] >= near:
                    gd.deactivateCollisionPair(int(k))
                    self._inactive.append((gd, int(k)))
                    aside[b] = min(aside[b], float(gap[k]))
        self._set_aside = aside
        return aside

    def unrestrict(self) -> None:
        """Every pair checked again (undo :meth:`restrict`)."""
        for gd, k in self._inactive:
            gd.activateCollisionPair(k)
        self._inactive.clear()
        self._set_aside = self._no_margin

    def _world_points(self) -> np.ndarray:
        """The bodies' cover points in the base frame at the last :meth:`margins`, (n, 3)."""
        oMi = self.data.oMi
        H = np.array([m.homogeneous for m in oMi])
        self._joints_now = H
        Hp = H[self._point_joint]
        return np.asarray((Hp[:, :3, :] @ self._points1)[:, :, 0])

    def _reach_at(self, world: np.ndarray) -> np.ndarray:
        """Per joint and moving body, the farthest point of the body from the joint's axis
        (0 for a body the joint does not move) [m], shape (6, moving bodies)."""
        H = self._joints_now[1:]
        origins, axes = H[:, :3, 3], H[:, :3, 2]  # (6, 3) each
        # |d|^2 - (d . z)^2 with d = p - o, expanded so that one product does the work.
        wo_wz = world @ np.hstack((origins.T, axes.T))  # (n, 12)
        squared = (world * world) @ _ONES3  # (n,): numpy's sum over a short axis is slow
        d2 = squared[:, None] - 2.0 * wo_wz[:, :6] + (origins * origins) @ _ONES3
        along = wo_wz[:, 6:] - (origins * axes) @ _ONES3
        radial = np.sqrt(np.maximum(d2 - along * along, 0.0)).T  # (6, n)
        radial = np.where(self._beyond_mask, radial + self._radii, 0.0)
        per_body = np.maximum.reduceat(radial, self._body_starts, axis=1)
        return np.asarray(per_body[:, self._moving])

    def _keep_in_at(self, world: np.ndarray) -> list[tuple[float, Check, np.ndarray]]:
        """Per keep-in zone: its tightest margin [m], the check naming the body, and each
        moving body's margin to it [m] (inf: a body the zone does not hold)."""
        out = []
        for check, zone, rows in self._keep_in:
            inner = self._outside.copy()
            inside = inner_distances(zone, world[rows].T)
            inner[rows] = inside - self._radii[rows] - check.required
            k = int(np.argmin(inner))
            body = self.shapes[int(self._point_body[k])].name
            per_body = np.minimum.reduceat(inner, self._body_starts)[self._moving]
            out.append((float(inner[k]), check._replace(body=body), per_body))
        return out

    def _can_meet(self, body: int, other: int) -> bool:
        """Whether ``other`` (fixed, its clearance included) reaches into the sphere about
        the shoulder that holds ``body`` in every configuration (the joint placements'
        lengths up to the body, plus its own extent)."""
        radius = self._holding_radius(body)
        fixed = self.geom.geometryObjects[other]
        if fixed.parentJoint != 0:
            return True  # another arm body (a self pair)
        M = fixed.placement
        gap = coal.distance(
            coal.Sphere(radius),
            coal.Transform3s(),
            fixed.geometry,
            coal.Transform3s(M.rotation, M.translation),
            coal.DistanceRequest(),
            coal.DistanceResult(),
        )
        return bool(gap <= 0.0)

    def _holding_radius(self, body: int) -> float:
        """The radius of the sphere about the shoulder that holds ``body`` in every
        configuration [m] (computed once per body)."""
        if body in self._holding:
            return self._holding[body]
        obj = self.geom.geometryObjects[body]
        rows = self._point_body == body
        radius = sum(
            float(np.linalg.norm(self.model.jointPlacements[k].translation))
            for k in range(1, obj.parentJoint + 1)
        )
        radius += float((np.linalg.norm(self._points[rows], axis=1) + self._radii[rows]).max())
        self._holding[body] = radius
        return radius

    def _split(self, pairs: list[tuple[int, int]]) -> list[tuple[Any, Any, list[int]]]:
        """One geometry model per moving body with its pairs, for per-body margins: the
        body, then its partners; with the rows of :attr:`checks` of its pairs."""
        out = []
        for b in self._moving:
            gm = pin.GeometryModel()
            gm.addGeometryObject(self.geom.geometryObjects[b])
            rows = []
            for k, (first, second) in enumerate(pairs):
                if first == b:
                    index = gm.addGeometryObject(self.geom.geometryObjects[second])
                    gm.addCollisionPair(pin.CollisionPair(0, index))
                    rows.append(k)
            out.append((gm, pin.GeometryData(gm), rows))
        return out

    def _prepare_points(self) -> None:
        """Stack every body's cover points in its joint's frame (for reach and keep-in)."""
        points, radii, joints, bodies = [], [], [], []
        for i, (local, radius) in enumerate(self._covers):
            obj = self.geom.geometryObjects[i]
            M = obj.placement
            points.append(local @ M.rotation.T + M.translation)
            radii += [radius] * len(local)
            joints += [obj.parentJoint] * len(local)
            bodies += [i] * len(local)
        self._points = np.vstack(points)
        self._radii = np.array(radii)
        self.extent = float(np.linalg.norm(self._points, axis=1).max() + self._radii.max())
        """Farthest any body point is from its joint's origin [m] (a coarse speed bound)."""
        self._point_joint = np.array(joints)
        self._point_body = np.array(bodies)
        self._rows_by_joint = [
            (j, np.flatnonzero(self._point_joint == j)) for j in sorted(set(joints))
        ]
        self._beyond_mask = np.array([self._point_joint >= j for j in range(1, self.model.njoints)])
        self._outside = np.full(len(self._points), math.inf)
        self._points1 = np.c_[self._points, np.ones(len(self._points))][:, :, None]
        self._body_starts = np.searchsorted(self._point_body, np.arange(len(self.shapes)))
        self._moving = [i for i, s in enumerate(self.shapes) if s.name not in STATIC_BODIES]
        """Arm bodies whose distances depend on the joint angles (indices into shapes)."""
        self._keep_in = [
            (check, zone, np.flatnonzero(np.isin(self._point_body, bodies)))
            for check, zone, bodies in self._keep_in_bodies
        ]


def _line_of(scene: Scene, name: str) -> int:
    for obj in scene.objects:
        if obj.name == name:
            return obj.line
    return 0
