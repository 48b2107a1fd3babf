"""The simulated arm meets the scene: true distances, contacts and the smallest clearance.

The simulator reads the same scene file as the planner (``SimConfig.scene``), but judges
the physical bodies only: no clearances (a contact is a distance of zero or less) and no
protection zones (they are rules for the stack, not walls). A motion that would take a
body deeper into contact with an object or with the arm itself is refused, so the arm
stops where the body meets the object, and reports warning 3 "motor blocked"
(:meth:`services.simulator.arm.ArmModel.step`).

Every sample reports the smallest distance of all and the smallest to a person, both
exact. Coal computes every pair at every new configuration, as it did before the person's
distance was reported; what costs is reading the person's pairs back through Pinocchio's
Python binding (about 1 us each, 32 pairs in the default scene: as much again as the
distances themselves). So the pairs are computed in two geometry data of the same geometry
model, one with the person's pairs and one with the others: each computation gives its
smallest pair, and the two smallest decide the tightest, with the first pair of the
checks' order winning a tie as in one computation over every pair. Each pair's distance is
the same number either way (GJK starts from its default guess at every query:
:func:`manus.shapes.fresh_guesses`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from manus.collision import CollisionModel
from manus.config import ArmConfig
from manus.scene import CLASSES, scene_from_setting
from manus.shapes import fresh_guesses


class Distance(NamedTuple):
    """The smallest true distance of one configuration.

    Attributes:
        distance: between the nearest arm body and object [m] (< 0: penetrating).
        pair: ``body/object`` (e.g. ``gripper/head``).
        person: between the arm and the nearest person object [m] (None: no person).
        person_pair: ``body/object`` of ``person``.
    """

    distance: float
    pair: str
    person: float | None = None
    person_pair: str = ""


class ContactModel:
    """True distances between the arm and the scene (no clearances, no zones).

    Args:
        setting: the scene setting (``default``, ``none`` or a file).
        arm: arm geometry.
        opening: gripper opening the gripper box is sized for [m].
    """

    def __init__(self, setting: str, arm: ArmConfig, opening: float = 0.0) -> None:
        scene = scene_from_setting(setting)
        self.model: CollisionModel | None = None
        if scene is not None:
            physical = dataclasses.replace(
                scene, zones=(), clearance=dict.fromkeys((*CLASSES, "self"), 0.0)
            )
            self.model = CollisionModel(physical, arm, opening=opening)
        self._pairs = None if self.model is None else _Pairs(self.model)
        self._cache: tuple[bytes, Distance] | None = None

    def move(self, name: str, pose: np.ndarray) -> None:
        """Place the scene object ``name`` at ``pose`` (4x4, chair frame): a person that
        moves (the moving target's body, :mod:`services.simulator.target`).

        Raises:
            SceneError: no such object.
        """
        if self.model is None:
            return
        if self.model.move_object(name, pose) > 0.0:
            self._cache = None

    def distance(self, q_deg: np.ndarray, opening_mm: float) -> Distance | None:
        """The smallest distance at DH angles ``q_deg`` [deg] (None: no scene)."""
        model = self.model
        if model is None:
            return None
        q = np.radians(np.asarray(q_deg, dtype=float))
        key = q.tobytes() + np.float64(opening_mm).tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        if not math.isclose(model.opening * 1e3, opening_mm, abs_tol=0.5):
            model.set_opening(opening_mm * 1e-3)
        assert self._pairs is not None  # built with the model
        found = self._pairs.distance(q)
        self._cache = (key, found)
        return found


class _Pairs:
    """The pair checks of ``model`` in two geometry data of its geometry: the pairs with a
    person in one, the others in the other (all in the model's own when no pair has a
    person).

    Args:
        model: the collision model (its checks' rows are its geometry's pair indices).
    """

    def __init__(self, model: CollisionModel) -> None:
        self.model = model
        self.names = [f"{c.body}/{c.other}" for c in model.checks]
        """``body/object`` of each check."""
        persons = {k for k, c in enumerate(model.checks) if c.cls == "person"}
        self.people: Any = None
        if persons:
            others, self.people = (fresh_guesses(pin.GeometryData(model.geom)) for _ in range(2))
            for k in range(len(model.checks)):
                (others if k in persons else self.people).deactivateCollisionPair(k)
            self.others: Any = others
            # The results' vectors, once: each attribute read makes a Python object.
            self._other_results = others.distanceResults
            self._people_results = self.people.distanceResults

    def distance(self, q: np.ndarray) -> Distance:
        """The smallest distance of every pair, and of the pairs with a person, at DH angles
        ``q`` [rad], shape (6,)."""
        model, names = self.model, self.names
        if self.people is None:
            k, margin = model.tightest(q)
            return Distance(float(margin), names[k])
        k = pin.computeDistances(model.model, model.data, model.geom, self.others, q)
        pin.updateGeometryPlacements(model.model, model.data, model.geom, self.people)
        j = pin.computeDistances(model.geom, self.people)
        person = float(self._people_results[j].min_distance)
        other = float(self._other_results[k].min_distance) if k < len(names) else math.inf
        # One computation over every pair names the first of equal smallest.
        if person < other or (person == other and j < k):
            return Distance(person, names[j], person, names[j])
        return Distance(other, names[k], person, names[j])
