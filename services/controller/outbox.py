"""What the controller publishes: commands, feedback and results, numbered per stream.

Results are queued where a goal ends (a request, a status, a joint state) and published
with the stamp of the message that is being answered when they leave
(:meth:`Outbox.flush`), so every output carries a time taken from the inputs.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from manus.config import ArmConfig
from manus.joint_map import encoder_increments_to_dh_list
from manus.kinematics import Vec3, gripper_position
from manus.quantize import COUNT_RAD_S
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import JointVelocityCommand
from schemas.control import ControllerFeedback, GoalResult
from schemas.state import JointState
from services.controller.gripper import GripperRun, gripper_speed
from services.controller.tracking import Step, TrajectoryRun

Output = list[tuple[str, Message]]
"""(key suffix, message) pairs to publish, in order."""


class Outbox:
    """Builds and numbers the controller's messages.

    Args:
        arm: the arm model (gripper positions in the feedback).
    """

    def __init__(self, arm: ArmConfig) -> None:
        self.arm = arm
        self._queued: list[GoalResult] = []
        self._cmd_seq = 0
        self._fb_seq = 0
        self._res_seq = 0

    def queue(self, result: GoalResult) -> None:
        """A result to publish with the next :meth:`flush`."""
        self._queued.append(result)

    def flush(self, stamp_ns: int) -> Output:
        """The queued results, stamped ``stamp_ns`` [ns] and numbered."""
        out: Output = []
        for r in self._queued:
            out.append((ep.RESULT, dataclasses.replace(r, stamp_ns=stamp_ns, seq=self._res_seq)))
            self._res_seq += 1
        self._queued.clear()
        return out

    def command(self, js: JointState, counts: np.ndarray, grip: int) -> JointVelocityCommand:
        """The command answering ``js``: motor ``counts`` (6,) and gripper ``grip`` counts."""
        motor: list[int] = counts.tolist()
        # counts_to_joint_rates on plain floats (the same products; a zero rate is +0.0)
        velocity = [r * COUNT_RAD_S for r in encoder_increments_to_dh_list(motor)]
        cmd = JointVelocityCommand(
            stamp_ns=js.stamp_ns,
            seq=self._cmd_seq,
            source="controller",
            ref_seq=js.seq,
            velocity=velocity,
            gripper_velocity=gripper_speed(grip),
            counts=[0, *motor, int(grip)],
        )
        self._cmd_seq += 1
        return cmd

    def feedback(
        self,
        js: JointState,
        act_xyz: Vec3,
        step: Step | None,
        run: TrajectoryRun | None,
        grip: GripperRun | None,
        velocity: list[float],
    ) -> ControllerFeedback:
        """One cycle's reference vs actual (``act_xyz``: the gripper position of the
        measured angles [m]; ``velocity``: the commanded DH rates [rad/s])."""
        q = [float(v) for v in js.position]
        ref = step.reference if step is not None else q
        ref_xyz = gripper_position(ref, self.arm) if step is not None else act_xyz
        fb = ControllerFeedback(
            stamp_ns=js.stamp_ns,
            seq=self._fb_seq,
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
        self._fb_seq += 1
        return fb
