"""``gripper`` steps: one gripper goal."""

from __future__ import annotations

from schemas import endpoints as ep
from schemas.control import ControllerFeedback, GripperGoal
from schemas.sequencing import TaskStep
from services.sequencer.actions import Action
from services.sequencer.goal_step import GoalStep
from services.sequencer.step import StepContext

MAX_OPENING_M = 0.090
"""Largest gripper opening [m]."""


class GripperStep(GoalStep):
    """``gripper``: one gripper goal; after a pause it is sent again."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.grip0: float | None = None  # opening at the first feedback [m]

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        if not 0.0 <= spec.opening <= MAX_OPENING_M:
            mm, top = spec.opening * 1e3, MAX_OPENING_M * 1e3
            return [f"gripper opening {mm:g} mm is outside 0..{top:g} mm"]
        return []

    def begin(self) -> list[Action]:
        timeout = self.ctx.config.gripper_timeout_s
        self.goal_id = self.ctx.new_goal_id()
        self.grip0 = None
        goal = GripperGoal(
            goal_id=self.goal_id,
            opening=self.spec.opening,
            timeout=timeout,
            heartbeat_timeout=self.ctx.config.heartbeat_timeout_s,
        )
        return self._send(ep.GRIPPER_GOAL, goal, timeout + 5.0)

    def on_feedback(self, fb: ControllerFeedback) -> list[Action]:
        if not self.goal_id or fb.gripper_goal_id != self.goal_id:
            return []
        if self.grip0 is None:
            self.grip0 = fb.gripper
        span = abs(fb.gripper_target - self.grip0)
        done = 1.0 if span < 1e-6 else 1.0 - abs(fb.gripper_target - fb.gripper) / span
        return self.ctx.report(min(1.0, max(0.0, done)))
