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
    """

    distance: float
    pair: str


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
        self._cache: tuple[bytes, Distance] | None = None

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
        found = Distance(float(margin), f"{check.body}/{check.other}")
        self._cache = (key, found)
        return found
