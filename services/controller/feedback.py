"""What a goal's cycle reports: reference against measurement (``ControllerFeedback``)."""

from __future__ import annotations

import math

from manus.config import ArmConfig
from manus.kinematics import Vec3, gripper_position
from schemas.control import ControllerFeedback
from schemas.state import JointState
from services.controller.gripper import GripperRun
from services.controller.tracking import Step, TrajectoryRun


def goal_feedback(
    js: JointState,
    seq: int,
    act_xyz: Vec3,
    ran: tuple[Step, TrajectoryRun] | None,
    grip: GripperRun | None,
    velocity: list[float],
    arm: ArmConfig,
) -> ControllerFeedback:
    """One cycle's reference vs actual.

    Args:
        js: the joint state answered.
        seq: the feedback's number.
        act_xyz: the gripper position of the measured angles [m].
        ran: the trajectory's step this cycle and its run (None: none ran).
        grip: the gripper goal running (None: none).
        velocity: the commanded DH rates [rad/s], 6 values.
        arm: the arm model.
    """
    q = [float(v) for v in js.position]
    step, run = ran if ran is not None else (None, None)
    ref = step.reference if step is not None else q
    ref_xyz = gripper_position(ref, arm) if step is not None else act_xyz
    return ControllerFeedback(
        stamp_ns=js.stamp_ns,
        seq=seq,
        goal_id=run.goal.goal_id if run is not None else "",
        state=step.state if step is not None else "idle",
        segment=step.segment if step is not None else -1,
        t=run.tau if run is not None else 0.0,
        reference=list(ref),
        actual=q,
        error=[r - a for r, a in zip(ref, q, strict=True)],
        command=list(velocity),
        reference_xyz=list(ref_xyz),
        actual_xyz=list(act_xyz),
        position_error=math.dist(ref_xyz, act_xyz),
        gripper_goal_id=grip.goal.goal_id if grip is not None else "",
        gripper_target=grip.goal.opening if grip is not None else 0.0,
        gripper=js.gripper,
        speed_scale=run.scale if run is not None else 1.0,
    )
