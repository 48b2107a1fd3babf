"""What the controller publishes for every source: commands and goal results, numbered.

A goal's outcome is queued where it ends (a request, a status, a joint state) and its
``GoalResult`` is built when it leaves (:meth:`Outbox.flush`): stamped with the message
being answered then and numbered in publication order, so every output carries a time
taken from the inputs.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from manus.quantize import step_rates
from schemas import endpoints as ep
from schemas.base import Message
from schemas.collision import ClearanceReport
from schemas.commands import JointVelocityCommand
from schemas.control import EndCause, GoalKind, GoalResult, ResultStatus
from schemas.state import JointState
from services.controller.gripper import gripper_speed

Output = list[tuple[str, Message]]
"""(key suffix, message) pairs to publish, in order."""


class GoalOutcome(NamedTuple):
    """How one goal ended: a ``GoalResult`` but for its stamp and number.

    Attributes:
        goal_id: the goal.
        kind: trajectory or gripper.
        status: how it ended.
        cause: why.
        reason: why, in words.
        via_errors: gripper error at each knot time [m].
        via_stamps: when each was measured [ns].
        final_error: gripper error at the end [m].
        duration: from its start to its end [s].
        clearance: the smallest clearance the guard computed while it ran.
    """

    goal_id: str
    kind: GoalKind
    status: ResultStatus
    cause: EndCause
    reason: str
    via_errors: tuple[float, ...] = ()
    via_stamps: tuple[int, ...] = ()
    final_error: float = 0.0
    duration: float = 0.0
    clearance: ClearanceReport | None = None


class Outbox:
    """Builds and numbers the commands and the goal results."""

    def __init__(self) -> None:
        self._queued: list[GoalOutcome] = []
        self._cmd_seq = 0
        self._res_seq = 0

    def queue(self, outcome: GoalOutcome) -> None:
        """A goal's outcome, published with the next :meth:`flush`."""
        self._queued.append(outcome)

    def flush(self, stamp_ns: int) -> Output:
        """The queued outcomes as results, stamped ``stamp_ns`` [ns] and numbered."""
        out: Output = []
        for o in self._queued:
            result = GoalResult(
                stamp_ns=stamp_ns,
                seq=self._res_seq,
                goal_id=o.goal_id,
                kind=o.kind,
                status=o.status,
                cause=o.cause,
                reason=o.reason,
                via_errors=list(o.via_errors),
                via_stamps=list(o.via_stamps),
                final_error=o.final_error,
                duration=o.duration,
                clearance=o.clearance,
            )
            out.append((ep.RESULT, result))
            self._res_seq += 1
        self._queued.clear()
        return out

    def command(self, js: JointState, counts: np.ndarray, grip: int) -> JointVelocityCommand:
        """The command answering ``js``: the velocities of the motor speed steps
        ``counts`` (6,) and the gripper's ``grip`` (on the arm's speed table, so the bridge
        sends exactly these steps)."""
        cmd = JointVelocityCommand(
            stamp_ns=js.stamp_ns,
            seq=self._cmd_seq,
            source="controller",
            ref_seq=js.seq,
            velocity=step_rates(counts.tolist()),
            gripper_velocity=gripper_speed(grip),
        )
        self._cmd_seq += 1
        return cmd
