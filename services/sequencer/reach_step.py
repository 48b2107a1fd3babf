"""``reach`` steps: a goal the planner finds its own way to (docs/reach.md).

A :class:`~services.sequencer.move_step.MoveStep` whose plan request carries the step's
goal motion (:mod:`schemas.goals`) instead of a path; planned from where the previous
step leaves the arm when the task is validated, again from the newest joint state when
it runs, and after a pause by the goal's planner from where the arm stopped (the same
goal; a line goes on to the end it was planned to).
"""

from __future__ import annotations

from manus.config import ArmConfig
from schemas.goals import GOAL_MOTIONS
from schemas.planning import PlanRequest
from schemas.sequencing import TaskStep
from services.sequencer.move_step import MoveStep


class ReachStep(MoveStep):
    """``reach``: see the module docstring."""

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        if not isinstance(spec.goal, GOAL_MOTIONS):
            kinds = ", ".join(m.__name__ for m in GOAL_MOTIONS)
            return [f"a reach step needs a goal ({kinds})"]
        return []

    @classmethod
    def plan(cls, spec: TaskStep, start: list[float] | None, arm: ArmConfig) -> PlanRequest:
        assert spec.goal is not None, "a reach step without a goal is never planned"
        return PlanRequest(spec.goal, start=start, preview_dt=0.0)
