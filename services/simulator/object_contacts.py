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
from services.simulator.arm_bodies import Body, distance
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
    pose: np.ndarray
    centre: np.ndarray
    radius: float  # inf: a plane


class ObjectContacts:
    """The contact record of the objects (see the module docstring).

    Args:
        scene: the scene (None: nothing fixed to touch).
    """

    def __init__(self, scene: Scene | None) -> None:
        self._fixed: list[_Fixed] = []
        for obj in scene.objects if scene is not None else ():
            geometry, pose = coal_shape(obj.body)
            if obj.body.shape == "plane":
                radius, centre = math.inf, np.zeros(3)
            else:
                geometry.computeLocalAABB()
                radius = float(geometry.aabb_radius)
                centre = pose[:3, 3] + pose[:3, :3] @ geometry.aabb_center
            self._fixed.append(_Fixed(obj.name, obj.cls, geometry, pose, centre, radius))
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
        centre, radius = pose[:3, 3], obj.radius
        best = Distance(math.inf, "")
        for fixed in self._fixed:
            gap = float(np.linalg.norm(fixed.centre - centre)) - radius - fixed.radius
            d = gap if gap > 0.0 else distance(self.shape(obj), pose, fixed.geometry, fixed.pose)
            if d < best.distance:
                best = Distance(d, f"{obj.id}/{fixed.name}")
        return best

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
        shape = self.shape(obj)
        nearest = math.inf, ""
        person = math.inf
        for fixed in self._fixed:
            d = distance(shape, pose, fixed.geometry, fixed.pose)
            if d < nearest[0]:
                nearest = d, f"{obj.id}/{fixed.name}"
            if fixed.cls == ContactClass.PERSON:
                person = min(person, d)
            if d < -CONTACT_DEPTH:
                touching.append((obj.id, fixed.name, fixed.cls, -d))
        for other, other_pose in zip(objects, poses, strict=True):
            if other is obj:
                continue
            d = distance(shape, pose, self.shape(other), other_pose)
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
