"""The simulated arm meets the scene: true distances, contacts and the smallest clearance.

The simulator reads the same scene file as the planner (``SimConfig.scene``), but judges
the physical bodies only: no clearances (a contact is a distance of zero or less) and no
protection zones (they are rules for the stack, not walls). A motion that would take a
body deeper into contact with an object or with the arm itself is refused, so the arm
stops where the body meets the object, and reports warning 3 "motor blocked"
(:meth:`services.simulator.arm.ArmModel.step`).
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from manus.collision import CollisionModel
from manus.config import ArmConfig
from manus.scene import CLASSES, scene_from_setting


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
        self._persons: list[int] = []
        if self.model is not None:
            self._persons = [k for k, c in enumerate(self.model.checks) if c.cls == "person"]
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
        k, margin = model.tightest(q)
        check = model.checks[k]
        results = model.geom_data.distanceResults
        person, person_pair = None, ""
        if self._persons:
            j = min(self._persons, key=lambda i: results[i].min_distance)
            person = float(results[j].min_distance)
            person_pair = f"{model.checks[j].body}/{model.checks[j].other}"
        found = Distance(float(margin), f"{check.body}/{check.other}", person, person_pair)
        self._cache = (key, found)
        return found
