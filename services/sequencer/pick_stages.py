"""The stages of a pick: open, pre-grasp pose, straight approach, close, attach, lift
off, lift, retreat.

**Lift off.** A cup grasped standing on the table still has its bottom flat on it. The
straight line up that lifts it starts with one-count steps of several joints (5 deg/s
for a cycle each), which tip the cup by a fraction of a degree before it rises: an edge
of its bottom went tenths of a millimetre into the table in 3 of 20 live drinks (the
simulator's truth counts that as a contact; the arm stops for the tick). So an object
taken from a surface first leaves it on the shoulder (joint 2) alone: every point of it
rises, by :data:`LIFT_OFF_M` at the gripper, and the line up starts clear.
"""

from __future__ import annotations

import numpy as np

from manus.grasp_poses import Grasp
from manus.kinematics import jacobian
from manus.urdf import GRIPPER_FRAME
from schemas.goals import JointGoal
from services.sequencer.object_stages import (
    APPROACH_TOLERANCE_M,
    MAX_OPENING_M,
    MotionOf,
    ObjectView,
    PickPlan,
    Stage,
    line_tool,
    line_toward,
    line_up,
    pose_goal,
)

LIFT_OFF_M = 0.004
"""How far the shoulder alone raises the gripper off the surface [m] (the line up's first
steps tip the object by tenths of a millimetre at its bottom's edge)."""


def lift_off(view: ObjectView, rise: float = LIFT_OFF_M) -> MotionOf:
    """A move of joint 2 alone that raises the gripper by ``rise`` [m] (chair z): the
    shoulder turns the whole arm about a horizontal axis well away from the object, so
    that every point of a held object rises, none tips down first."""

    def motion(q: np.ndarray) -> JointGoal:
        dz = float((view.mount[:3, :3] @ jacobian(q, view.arm)[:3, 1])[2])  # chair z [m/rad]
        target = q.copy()
        target[1] += rise / dz if abs(dz) > 1e-6 else 0.0
        return JointGoal(joints=[float(v) for v in target])

    return motion


def pick_stages(plan: PickPlan, grasp: Grasp, view: ObjectView) -> list[Stage]:
    """Open, pre-grasp pose (a search), straight approach, close, attach, (from a surface:
    lift off), lift, retreat."""
    how = plan.how
    touch = (plan.surface,) if plan.surface else ()
    stages = [
        Stage("open", opening=min(MAX_OPENING_M, grasp.width + how.open_margin)),
        Stage(
            "pre-grasp",
            motion=pose_goal(view, grasp.pregrasp),
            watch=True,
            retry=True,
            search=True,
        ),
        Stage(
            "approach",
            motion=line_tool(how.pregrasp),
            watch=True,
            retry=True,
            aim=True,
            reach_tolerance=APPROACH_TOLERANCE_M,
        ),
        Stage("close", opening=max(0.0, grasp.width - how.squeeze), holds=grasp.width),
        Stage("attach", attach=GRIPPER_FRAME, touch_objects=touch, upright=how.keep_level),
    ]
    if touch:
        stages.append(Stage("lift off", motion=lift_off(view), carrying=True))
    stages.append(Stage("lift", motion=line_up(view, how.lift), carrying=True, retry=True))
    if touch:
        stages.append(Stage("clear of the surface", attach=GRIPPER_FRAME))
    retreat = line_toward(view, view.mount[:3, 3], how.pregrasp)
    stages.append(Stage("retreat", motion=retreat, carrying=True))
    return stages
