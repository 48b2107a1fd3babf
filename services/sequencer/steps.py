"""The kinds of task step and the table of them (:data:`STEP_TYPES`).

Each kind is one class, holding that step's state, in a module of its own, derived from
:class:`services.sequencer.step.Step` (whose docstring lists the hooks the core calls):

- ``move`` and ``pose``: :class:`~services.sequencer.move_step.MoveStep` (a planned
  trajectory; a :class:`~services.sequencer.goal_step.GoalStep`, as the gripper's);
- ``gripper``: :class:`~services.sequencer.gripper_step.GripperStep`;
- ``fold_in`` and ``fold_out``: :class:`~services.sequencer.fold_step.FoldStep`;
- ``wait``: :class:`~services.sequencer.wait_step.WaitStep`;
- ``follow``: :class:`~services.sequencer.follow_step.FollowStep` (a controller follow
  goal, held for a time or until the supervisor's ``done``).
- ``reach``: :class:`~services.sequencer.reach_step.ReachStep` (a goal the planner finds
  its way to);
- ``pick``, ``place`` and ``give``: :class:`~services.sequencer.object_step.ObjectStep`
  (an object task run as stages by the steps above, docs/pick.md).

A new kind of step is one class and one entry here, its checks before the task starts
included.
"""

from __future__ import annotations

from schemas.sequencing import StepKind
from services.sequencer.fold_step import FoldStep
from services.sequencer.follow_step import FollowStep
from services.sequencer.gripper_step import GripperStep
from services.sequencer.move_step import MoveStep
from services.sequencer.object_step import ObjectStep
from services.sequencer.reach_step import ReachStep
from services.sequencer.step import Step
from services.sequencer.wait_step import WaitStep

STEP_TYPES: dict[str, type[Step]] = {
    StepKind.MOVE: MoveStep,
    StepKind.POSE: MoveStep,
    StepKind.GRIPPER: GripperStep,
    StepKind.FOLD_IN: FoldStep,
    StepKind.FOLD_OUT: FoldStep,
    StepKind.WAIT: WaitStep,
    StepKind.FOLLOW: FollowStep,
    StepKind.REACH: ReachStep,
    StepKind.PICK: ObjectStep,
    StepKind.PLACE: ObjectStep,
    StepKind.GIVE: ObjectStep,
}
"""The class of each kind of step."""
