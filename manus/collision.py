"""The arm's collision model: distances from its bodies to the scene, the zones and itself.

The arm's bodies are the URDF's collision geometry (:func:`manus.urdf.collision_shapes`),
loaded with Pinocchio into a :class:`pinocchio.GeometryModel`; the scene's objects and
keep-out zones are added to it as fixed bodies (placed through the mount), and
:func:`pinocchio.computeDistances` gives every pair's distance with Coal in one call.
Which pairs it checks, and with which clearance, is :mod:`manus.collision_pairs`: each
class's clearance is baked into the partner as Coal's swept-sphere radius, so a pair's
distance is its margin and the call's answer (the closest pair) is the tightest check;
:meth:`CollisionModel.probe` asks one small geometry model per moving body, which gives
each body its own margin. The keep-in workspace is checked apart, exactly, from each
body's convex cover (:mod:`manus.body_cover`: its end points or corners and a radius): a
concave margin over a convex body is smallest at one of those points. Pairs that no
configuration can bring within their clearance (an object beyond the sphere about the
shoulder that holds the body) are left out.

A configuration's *margin* per check is distance minus clearance; negative means
violated.

Objects the arm holds (:class:`manus.held.HeldBody`) are bodies of the arm on joint 6,
placed in the gripper frame (:meth:`CollisionModel.holding` gives the model with another
set); their pairs are :mod:`manus.collision_pairs`'s. A held body and an arm body that
moves both close a pair's gap: in the per-body margins (:meth:`CollisionModel.probe`,
:meth:`CollisionModel.pair_margins`, what bounds each body's travel) such a pair counts
half its margin for each of the two, and a pair with a body on the held body's own
joint (the gripper's: their distance never changes) bounds neither.

A scene object may be placed elsewhere than the scene puts it (a person who moves,
:meth:`CollisionModel.move_object`, :mod:`manus.moved_objects`).

:func:`manus.sweep.sweep` checks a whole motion through
:meth:`CollisionModel.pair_margins` (each moving body's margin to what it must keep
clear of) and :class:`manus.travel.BodyPoints` (the cover points over the motion, the
keep-in zones), with the pairs that cannot come near the motion set aside
(:meth:`CollisionModel.restrict`); the controller's guard through
:meth:`CollisionModel.probe` (the same margins, and each joint's reach to each body).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import coal
import numpy as np
import pinocchio as pin

from manus.body_cover import BodyCover
from manus.clearance import Check, Clearance, Probe
from manus.collision_pairs import STATIC_BODIES, base_overlaps, build_pairs
from manus.config import ArmConfig
from manus.held import HeldBody, HeldError
from manus.moved_objects import MovedObjects
from manus.scene import Primitive, Scene, SceneError
from manus.shapes import coal_shape, fresh_guesses, partner_boxes
from manus.urdf import FINGER_THICKNESS, GRIPPER_FRAME, Shape, build_urdf, collision_shapes

_GRIPPER_BOX = ("gripper", "gripper+self")
"""The gripper box and its copy inflated by the self clearance (sized to the opening)."""


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
        held: the objects the arm holds.
        moved: scene objects placed elsewhere than the scene puts them (name -> pose,
            4x4, chair frame; :meth:`move_object`).

    Raises:
        HeldError: a held object named like an arm body, or given twice.
    """

    def __init__(
        self,
        scene: Scene | None,
        cfg: ArmConfig,
        opening: float | None = None,
        held: Sequence[HeldBody] = (),
        moved: Mapping[str, np.ndarray] | None = None,
    ) -> None:
        self.cfg = cfg
        self.scene = scene
        self.held = tuple(held)
        """The objects the arm holds (their bodies follow the arm's in :attr:`shapes`)."""
        urdf = build_urdf(self.cfg)
        self.model = pin.buildModelFromXML(urdf)
        self.data = self.model.createData()
        gm = pin.buildGeomFromUrdfString(self.model, urdf, pin.GeometryType.COLLISION)
        self.shapes = collision_shapes(self.cfg)
        # Pinocchio names them <link>_<k>, in URDF order: give them the shapes' names.
        for obj, shape in zip(gm.geometryObjects, self.shapes, strict=True):
            obj.name = shape.name
        self.shapes += [self._add_held(gm, body) for body in self.held]
        self.body_index = {s.name: i for i, s in enumerate(self.shapes)}
        built = build_pairs(gm, self.shapes, scene, self.held)
        # The gripper box, and its inflated copy if a held body is checked against it.
        self._gripper_boxes = [o.geometry for o in gm.geometryObjects if o.name in _GRIPPER_BOX]
        self.geom = gm
        self.moving = [i for i, s in enumerate(self.shapes) if s.name not in STATIC_BODIES]
        """Bodies whose distances depend on the joint angles (indices into shapes)."""
        self.keep_in_bodies = built.keep_in
        """Per keep-in zone: its check, the zone in the base frame, the bodies it holds."""
        self.cover = BodyCover(self.model, gm, self.shapes, self.moving, built.keep_in)
        self.extent = self.cover.extent
        """Farthest any body point is from its joint's origin [m] (a coarse speed bound)."""
        self._static = built.static
        # Pairs no configuration can bring within their clearance are left out.
        reachable = [self._can_meet(first, second) for first, second in built.pairs]
        pairs = [p for p, keep in zip(built.pairs, reachable, strict=True) if keep]
        self.checks: list[Check] = [
            c for c, keep in zip(built.checks, reachable, strict=True) if keep
        ]
        for first, second in pairs:
            gm.addCollisionPair(pin.CollisionPair(first, second))
        self.geom_data = fresh_guesses(pin.GeometryData(gm))
        self._required = np.array([c.required for c in self.checks])
        self._per_body = self._split(pairs)
        self._held_rows = self._held_pairs(pairs, built.mutual)
        self.rigid = np.zeros(len(self.moving), dtype=bool)
        """Per moving body: a held one with a pair on its own joint (the gripper's), whose
        margin no motion changes and so no bound of the body's travel holds."""
        for b, held_rows in self._held_rows:
            self.rigid[b] = any(rigid for _, _, rigid in held_rows)
        self._live = [(b, gm, gd, rows) for b, (gm, gd, rows) in enumerate(self._per_body) if rows]
        self._no_margin = np.full(len(self.moving), math.inf)
        self._set_aside = self._no_margin
        self._inactive: list[tuple[Any, int]] = []
        # Built on the first restrict (the sweep's): a third of building a model, which
        # the controller's guard never needs.
        self._partner_boxes: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.derived: dict[str, object] = {}
        """What other modules build from this model once (the fast check, the sweep's body
        points): it lives and dies with the model (a table keyed by the model, whose
        values refer to their key, would keep every model alive for the process)."""
        self._no_reach = np.zeros((6, len(self.moving)))
        self._no_reach.flags.writeable = False
        overlaps = self.base_overlaps()
        if overlaps:
            raise SceneError(overlaps[0])
        self.set_opening(self.cfg.gripper_max if opening is None else opening)
        self.moved = MovedObjects(scene)
        """The scene objects placed elsewhere than the scene puts them."""
        for name, pose in (moved or {}).items():
            self.move_object(name, pose)

    def move_object(self, name: str, pose: np.ndarray) -> float:
        """Place the scene object ``name`` at ``pose`` (4x4, chair frame) in every check
        against it (:mod:`manus.moved_objects`; within its ``MOVE_BOUND_M`` of its scene
        pose the pairs kept stay right).

        Returns:
            how far any point of the object moved at most [m].

        Raises:
            SceneError: no scene object of that name.
        """
        models = [self.geom, *(gm for gm, _, _ in self._per_body)]
        moved = self.moved.move(name, pose, models)
        self._partner_boxes = []  # built again at the next restrict
        return moved

    # --- configuration queries ----------------------------------------------------------

    def set_opening(self, opening: float) -> None:
        """Size the gripper box for ``opening`` [m] (clamped to 0..gripper_max)."""
        opening = min(max(opening, 0.0), self.cfg.gripper_max)
        for box in self._gripper_boxes:
            half = box.halfSide.copy()
            half[0] = opening / 2.0 + FINGER_THICKNESS
            box.halfSide = half
            box.computeLocalAABB()
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
        world = self.cover.world(self.data)
        return [(margin, check) for margin, check, _ in self.cover.keep_in_at(world)]

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
        return base_overlaps(self.geom, self._static, self.scene)

    # --- motions --------------------------------------------------------------------------

    def probe(
        self,
        q: np.ndarray,
        time: float = 0.0,
        *,
        reach: bool = True,
        skip: Any = None,
        zones: bool = True,
    ) -> Probe:
        """At ``q``, per moving body: its tightest margin (how far it may travel before any
        of its gaps could close) and each joint's reach to it (zeros when ``reach`` is
        False: cheaper); and the tightest check (of the bodies asked: ``skip``, a bool per
        moving body, leaves those bodies' pairs out, their margins inf; ``zones`` False,
        with ``reach`` False, the keep-in zones: for a caller that knows them clear)."""
        q = np.asarray(q, dtype=float)
        (free, tight, tight_row), kept_in = self.pair_margins(q, skip), math.inf
        if zones or reach:
            points = self.cover.world(self.data)
            for margin, check, per_body in self.cover.keep_in_at(points):
                np.minimum(free, per_body, out=free)
                kept_in = min(kept_in, margin)
                if margin < tight:
                    tight, tight_row, zone = margin, -2, check
        if tight_row >= 0:
            check = self.checks[tight_row]
        elif tight_row == -2:
            check = zone
        else:
            check = Check("", "", "self", 0.0)
        best = Clearance(tight, tight + check.required, check, time, q)
        reaches = self.cover.reach(points) if reach else self._no_reach
        return Probe(best, np.maximum(free, 0.0, out=free), reaches, kept_in)

    def pair_margins(self, q: np.ndarray, skip: Any = None) -> tuple[np.ndarray, float, int]:
        """The pair checks at ``q`` [rad] (no keep-in zones): each moving body's tightest
        margin [m] (inf: nothing to keep clear of, or left out by ``skip``, a bool per
        moving body), shape (moving bodies,); the tightest margin of all [m] and its row
        in :attr:`checks` (-1: none)."""
        model, data = self.model, self.data
        pin.forwardKinematics(model, data, q)
        update, distances = pin.updateGeometryPlacements, pin.computeDistances
        free = self._no_margin.copy()
        tight, tight_row = math.inf, -1
        for b, gm, gd, rows in self._live:
            if skip is not None and skip[b]:
                continue
            update(model, data, gm, gd)
            k = distances(gm, gd)
            if k >= len(rows):
                continue  # every pair of the body is set aside (:meth:`restrict`)
            margin = gd.distanceResults[k].min_distance
            free[b] = margin
            if margin < tight:
                tight, tight_row = margin, rows[k]
        for b, held_rows in self._held_rows:
            free[b] = self._held_free(b, held_rows, free)
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
        aside = np.full(len(self.moving), math.inf)
        if not self._partner_boxes:
            self._partner_boxes = [partner_boxes(gm) for _, gm, _, _ in self._live]
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

    def holding(self, held: Sequence[HeldBody]) -> CollisionModel:
        """This model (scene, arm, gripper opening, moved objects) with the arm holding
        ``held``."""
        return CollisionModel(self.scene, self.cfg, self.opening, held, self.moved.poses)

    def _add_held(self, gm: Any, body: HeldBody) -> Shape:
        """Put ``body`` on joint 6 of ``gm``, where the gripper frame holds it."""
        if any(o.name == body.name for o in gm.geometryObjects):
            raise HeldError(f"held object {body.name!r}: an arm body (or held object) has its name")
        if body.shape not in ("box", "sphere", "cylinder", "capsule"):
            raise HeldError(f"held object {body.name!r}: no {body.shape!r} shape")
        frame = self.model.frames[self.model.getFrameId(GRIPPER_FRAME)]
        M = pin.SE3(frame.placement.homogeneous @ body.placement())
        geometry, _ = coal_shape(Primitive(body.shape, body.size, np.eye(4)))
        gm.addGeometryObject(pin.GeometryObject(body.name, frame.parentJoint, M, geometry))
        rpy = pin.rpy.matrixToRpy(M.rotation)
        return Shape(body.name, f"link{frame.parentJoint}", body.shape, body.size,
                     tuple(M.translation), tuple(rpy))  # fmt: skip

    def _can_meet(self, body: int, other: int) -> bool:
        """Whether ``other`` (fixed, its clearance included) reaches into the sphere about
        the shoulder that holds ``body`` in every configuration (the joint placements'
        lengths up to the body, plus its own extent)."""
        radius = self.cover.holding_radius(body, self.geom.geometryObjects[body].parentJoint)
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

    def _held_free(self, b: int, rows: list[tuple[int, int, bool]], free: np.ndarray) -> float:
        """Held body ``b``'s margin for bounding its travel (:data:`_held_rows` ``rows``),
        lowering its mutual partners' in ``free`` to their half."""
        gd = self._per_body[b][1]
        active = gd.activeCollisionPairs
        low = math.inf
        for k, c, rigid in rows:
            if not active[k] or rigid:
                continue  # set aside (:meth:`restrict`), or a distance that never changes
            margin = gd.distanceResults[k].min_distance
            if c >= 0:  # both move: each may close half the gap
                margin = 0.5 * margin if margin > 0.0 else margin
                free[c] = min(free[c], margin)
            low = min(low, margin)
        return min(low, float(self._set_aside[b]))

    def _held_pairs(
        self, pairs: list[tuple[int, int]], mutual: dict[tuple[int, int], tuple[int, bool]]
    ) -> list[tuple[int, list[tuple[int, int, bool]]]]:
        """Per held body (its position in :attr:`moving`): each of its pairs as (index in
        its own geometry model, mutual partner's position in :attr:`moving` or -1, rigid)."""
        position = {body: b for b, body in enumerate(self.moving)}
        held = {self.body_index[h.name] for h in self.held}
        out = []
        for b, (_, _, rows) in enumerate(self._per_body):
            if self.moving[b] in held:
                found = [mutual.get(pairs[k], (-1, False)) for k in rows]
                out.append(
                    (b, [(j, -1 if c < 0 else position[c], r) for j, (c, r) in enumerate(found)])
                )
        return out

    def _split(self, pairs: list[tuple[int, int]]) -> list[tuple[Any, Any, list[int]]]:
        """One geometry model per moving body with its pairs, for per-body margins: the
        body, then its partners; with the rows of :attr:`checks` of its pairs."""
        out = []
        for b in self.moving:
            gm = pin.GeometryModel()
            gm.addGeometryObject(self.geom.geometryObjects[b])
            rows = []
            for k, (first, second) in enumerate(pairs):
                if first == b:
                    index = gm.addGeometryObject(self.geom.geometryObjects[second])
                    gm.addCollisionPair(pin.CollisionPair(0, index))
                    rows.append(k)
            out.append((gm, fresh_guesses(pin.GeometryData(gm)), rows))
        return out
