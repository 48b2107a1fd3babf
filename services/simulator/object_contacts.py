"""Contacts of the simulator's objects: what the truth records, tick by tick.

Checked at every tick on which something moved:

- a **held** object against every scene object (person, chair, environment: the true
  bodies, no clearances) and every other object: its distance now (the truth's
  ``held_clearance``), the smallest to the person since power-up (``held_min_person``),
  and a contact when they penetrate. The held object is part of the arm: it is not
  checked against the arm's bodies (the fingers hold it);
- every **free** object (resting or falling) against the arm's bodies, the fingers
  included (an arm that sweeps a cup off the table touches it). Pairs whose bounding
  spheres are apart are skipped without asking Coal.

A resting object touching the surface it stands on is no contact. Contacts are recorded,
they do not stop the arm (the scene's do, :mod:`services.simulator.contact`): keeping a
held object clear is the stack's job, judged on this truth. One record per pair since
power-up (:class:`~schemas.objects.ObjectContact`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from manus.scene import Scene
from manus.shapes import coal_shape
from schemas.objects import ContactClass, ObjectContact
from services.simulator.arm_bodies import Body, distance, transform
from services.simulator.contact import Distance
from services.simulator.objects import HELD, SimObject

CONTACT_DEPTH = 1e-4
"""A pair penetrating deeper than this is in contact [m] (touching is not)."""


@dataclass
class _Record:
    cls: str
    since_ns: int
    ticks: int = 0
    depth: float = 0.0


@dataclass(frozen=True)
class _Fixed:
    name: str
    cls: str
    geometry: Any
    where: Any  # its Coal placement


class ObjectContacts:
    """The contact record of the objects (see the module docstring).

    Args:
        scene: the scene (None: nothing fixed to touch).
    """

    def __init__(self, scene: Scene | None) -> None:
        self._fixed: list[_Fixed] = []
        centres, radii = [], []
        for obj in scene.objects if scene is not None else ():
            geometry, pose = coal_shape(obj.body)
            if obj.body.shape == "plane":
                centres.append(np.zeros(3))
                radii.append(math.inf)  # its gap is -inf: always asked
            else:
                geometry.computeLocalAABB()
                centres.append(pose[:3, 3] + pose[:3, :3] @ geometry.aabb_center)
                radii.append(float(geometry.aabb_radius))
            self._fixed.append(_Fixed(obj.name, obj.cls, geometry, transform(pose)))
        self._centres = np.array(centres).reshape(-1, 3)
        self._radii = np.array(radii)
        self._person = np.array([f.cls == ContactClass.PERSON for f in self._fixed], dtype=bool)
        self._shapes: dict[str, Any] = {}
        self._records: dict[tuple[str, str], _Record] = {}
        self._current: list[tuple[str, str]] = []
        self.held_clearance: tuple[float, str] | None = None
        """(distance [m], ``object/other``) of the held object now (None: none held)."""
        self.held_min_person: float | None = None
        """Smallest distance between a held object and the person since power-up [m]."""

    def shape(self, obj: SimObject) -> Any:
        """The Coal shape of ``obj`` (made once per object)."""
        found = self._shapes.get(obj.id)
        if found is None:
            found = self._shapes[obj.id] = coal_shape(obj.primitive(np.eye(4)))[0]
        return found

    def update(
        self, t_ns: int, bodies: list[Body], objects: list[SimObject], poses: list[np.ndarray]
    ) -> None:
        """Check one tick: the arm's ``bodies`` and the ``objects`` at ``poses`` (chair
        frame, in the objects' order)."""
        self.held_clearance = None
        touching: list[tuple[str, str, str, float]] = []
        centres = np.array([b.pose[:3, 3] for b in bodies]).reshape(-1, 3)
        radii = np.array([b.radius for b in bodies])
        for i, obj in enumerate(objects):
            if obj.state == HELD:
                self._held(obj, poses[i], objects, poses, touching)
                continue
            # Bounding spheres first: only the bodies whose spheres meet the object's.
            gaps = np.linalg.norm(centres - poses[i][:3, 3], axis=1) - radii - obj.radius
            near = [bodies[k] for k in np.flatnonzero(gaps <= 0.0)]
            if near:
                self._free(obj, poses[i], near, touching)
        self._current = [(first, second) for first, second, _, _ in touching]
        for first, second, cls, depth in touching:
            record = self._records.get((first, second))
            if record is None:
                record = self._records[(first, second)] = _Record(cls, t_ns)
            record.ticks += 1
            record.depth = max(record.depth, depth)

    def again(self) -> None:
        """Nothing moved since the last tick: the same contacts last one tick longer."""
        for pair in self._current:
            self._records[pair].ticks += 1

    def scene_distance(self, obj: SimObject, pose: np.ndarray) -> Distance:
        """The smallest distance of ``obj`` at ``pose`` to the scene's objects [m]: exact
        for those whose bounding spheres meet it, else the gap between the spheres (a
        lower bound: enough to tell that they do not touch)."""
        gaps = self._gaps(obj, pose)
        best = Distance(math.inf, "")
        where, shape = transform(pose), self.shape(obj)
        for k, gap in enumerate(gaps):
            fixed = self._fixed[k]
            d = float(gap) if gap > 0.0 else distance(shape, where, fixed.geometry, fixed.where)
            if d < best.distance:
                best = Distance(d, f"{obj.id}/{fixed.name}")
        return best

    def _gaps(self, obj: SimObject, pose: np.ndarray) -> np.ndarray:
        """Per scene object, the gap between its bounding sphere and ``obj``'s at ``pose``
        [m]: a lower bound of their distance (-inf for a plane)."""
        gaps: np.ndarray = (
            np.linalg.norm(self._centres - pose[:3, 3], axis=1) - self._radii - obj.radius
        )
        return gaps

    def blocked(self, t_ns: int, pair: str) -> None:
        """The arm stopped because the held object would have gone into ``pair``'s scene
        object (``object/scene object``): a contact of depth 0 (it never got in)."""
        first, _, second = pair.partition("/")
        cls = next((f.cls for f in self._fixed if f.name == second), ContactClass.ENVIRONMENT)
        record = self._records.get((first, second))
        if record is None:
            record = self._records[(first, second)] = _Record(cls, t_ns)
        record.ticks += 1

    def contacts(self) -> list[ObjectContact]:
        """Every pair that touched since power-up, in the order they first did."""
        return [
            ObjectContact(
                first=a, second=b, cls=r.cls, since_ns=r.since_ns, ticks=r.ticks, depth=r.depth
            )
            for (a, b), r in self._records.items()
        ]

    # -- the checks --------------------------------------------------------------------------

    def _held(
        self,
        obj: SimObject,
        pose: np.ndarray,
        objects: list[SimObject],
        poses: list[np.ndarray],
        touching: list[tuple[str, str, str, float]],
    ) -> None:
        shape, where = self.shape(obj), transform(pose)
        nearest = math.inf, ""
        person = math.inf
        gaps = self._gaps(obj, pose)
        # Nearest gaps first: an exact distance only where it may be the nearest, the
        # person's nearest, or a contact (a gap is a lower bound of the distance).
        for k in np.argsort(gaps):
            gap, fixed = float(gaps[k]), self._fixed[k]
            if gap > 0.0 and gap >= nearest[0] and (not self._person[k] or gap >= person):
                continue
            d = distance(shape, where, fixed.geometry, fixed.where)
            if d < nearest[0]:
                nearest = d, f"{obj.id}/{fixed.name}"
            if self._person[k]:
                person = min(person, d)
            if d < -CONTACT_DEPTH:
                touching.append((obj.id, fixed.name, fixed.cls, -d))
        for other, other_pose in zip(objects, poses, strict=True):
            if other is obj:
                continue
            d = distance(shape, where, self.shape(other), other_pose)
            if d < nearest[0]:
                nearest = d, f"{obj.id}/{other.id}"
            if d < -CONTACT_DEPTH:
                touching.append((obj.id, other.id, ContactClass.OBJECT, -d))
        if math.isfinite(nearest[0]):
            self.held_clearance = nearest
        if math.isfinite(person):
            low = self.held_min_person
            self.held_min_person = person if low is None else min(low, person)

    def _free(
        self,
        obj: SimObject,
        pose: np.ndarray,
        bodies: list[Body],
        touching: list[tuple[str, str, str, float]],
    ) -> None:
        shape = self.shape(obj)
        for body in bodies:
            d = distance(body.geometry, body.pose, shape, pose)
            if d < -CONTACT_DEPTH:
                touching.append((body.name, obj.id, ContactClass.OBJECT, -d))
