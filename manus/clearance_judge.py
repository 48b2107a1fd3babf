"""A run's clearances judged on the simulator's truth, by the scene's rules.

The simulator reports the smallest *physical* distance of the true arm (``SimTruth.
clearance``: any body against any object or against the arm itself, no clearances), which
alone cannot say whether a rule was kept: 12 mm between the gripper motor and the
shoulder keeps the arm's self clearance (10 mm), 12 mm from an armrest breaks the
chair's (15 mm). :class:`ClearanceJudge` takes the true joint angles and gripper opening
of each truth sample and finds, with the scene's collision model
(:class:`~manus.collision.CollisionModel`: every class's clearance, the protection zones,
the arm's self clearance), the tightest check of each sample and of the whole run, so
that what is shown and asserted names the pair and the clearance it needs.
"""

from __future__ import annotations

import math

import numpy as np

from manus.clearance import Clearance
from manus.collision import CollisionModel
from manus.config import ArmConfig
from manus.scene import Scene

OPENING_STEP_M = 0.0005
"""The gripper box is resized when the true opening moved this much [m]."""


class ClearanceJudge:
    """The tightest clearance check of true configurations, sample by sample.

    Args:
        arm: the arm's geometry.
        scene: the scene whose rules apply (None: self clearance only).
    """

    def __init__(self, arm: ArmConfig, scene: Scene | None) -> None:
        self.arm = arm
        self.model = CollisionModel(scene, arm, opening=0.0)
        self.tightest: Clearance | None = None
        """The tightest check of every sample so far (its ``time``: the sample's)."""

    def set_scene(self, scene: Scene | None) -> None:
        """Judge the next samples by ``scene`` (a scene replaced at run time)."""
        opening = self.model.opening
        self.model = CollisionModel(scene, self.arm, opening=opening)

    def add(self, t: float, q: np.ndarray | list[float], opening: float) -> Clearance:
        """The tightest check of the true configuration ``q`` [rad], shape (6,), with the
        gripper ``opening`` [m], at time ``t`` [s]; it also updates :attr:`tightest`."""
        if not math.isclose(self.model.opening, opening, abs_tol=OPENING_STEP_M):
            self.model.set_opening(opening)
        found = self.model.clearance(np.asarray(q, dtype=float), t)
        if self.tightest is None or found.margin < self.tightest.margin:
            self.tightest = found
        return found
