"""Steps that run a controller goal: acknowledged, followed, ended by its result."""

from __future__ import annotations

from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmCommandReply
from schemas.control import (
    CancelGoal,
    CommandSourceKind,
    EndCause,
    GoalAck,
    GoalResult,
    GripperGoal,
    Refusal,
    ResultStatus,
    TrajectoryGoal,
)
from schemas.jog import USER_TOOK_OVER
from schemas.sequencing import TaskStep
from services.sequencer.actions import Action
from services.sequencer.step import BY_REQUEST, Phase, Step, StepContext, stop_command


class GoalStep(Step):
    """A step that runs a controller goal: acknowledged, followed, ended by its result.
    Pause and cancel cancel the goal (the controller decelerates within the arm's limits);
    a controller that does not confirm within ``cancel_timeout_s`` gets the bridge's stop."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.goal_id = ""

    def _send(self, suffix: str, goal: TrajectoryGoal | GripperGoal, span_s: float) -> list[Action]:
        self.ctx.set_deadline(span_s)
        self.phase = Phase.ACKING
        return [self.ctx.query(suffix, goal, GoalAck, wait=True)]

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        if self.phase != Phase.ACKING:
            return []
        if not isinstance(reply, GoalAck):
            self.goal_id = ""
            return self.ctx.fail(f"controller: {error or 'bad reply'}")
        if not reply.accepted:
            self.goal_id = ""
            return self._refused(reply)
        self.phase = Phase.ACTIVE
        if self.ctx.cancel_requested:
            return self.cancel()
        if self.ctx.pause_requested:
            self.ctx.pause_requested = False
            return self._stop_goal(Phase.PAUSING)
        return []

    def _refused(self, reply: GoalAck) -> list[Action]:
        if reply.refusal == Refusal.BUSY and reply.held_by == CommandSourceKind.JOG:
            return self.ctx.paused(USER_TOOK_OVER)  # the user jogs: pause, not fail
        return self.ctx.fail(f"controller refused the goal: {reply.reason}")

    def _stop_goal(self, phase: Phase) -> list[Action]:
        self.phase = phase
        self.ctx.set_deadline(self.ctx.config.cancel_timeout_s)
        return [self.ctx.query(ep.CANCEL, CancelGoal(goal_id=self.goal_id), GoalAck)]

    def on_result(self, res: GoalResult) -> list[Action]:
        if not self.goal_id or res.goal_id != self.goal_id:
            return []
        self.goal_id = ""
        if self.phase == Phase.CANCELLING:
            return self.ctx.cancelled(BY_REQUEST)
        if res.status == ResultStatus.SUCCEEDED:
            return self.ctx.step_done()
        if res.status == ResultStatus.CANCELLED and self.phase == Phase.PAUSING:
            self._remember_pause()
            return self.ctx.paused()
        if res.status == ResultStatus.PREEMPTED and res.cause == EndCause.USER_TOOK_OVER:
            self._remember_pause()  # a jog took the arm: pause where it stopped
            return self.ctx.paused(USER_TOOK_OVER)
        return self.ctx.fail(f"controller: goal {res.status}: {res.reason}")

    def _remember_pause(self) -> None:
        """The goal stopped for a pause: keep what :meth:`resume` needs."""

    def pause(self) -> list[Action] | None:
        if self.phase == Phase.ACTIVE and self.goal_id:
            return self._stop_goal(Phase.PAUSING)
        return None  # planning, acking: at the reply

    def cancel(self) -> list[Action]:
        if self.phase == Phase.ACTIVE and self.goal_id:
            return self._stop_goal(Phase.CANCELLING)
        if self.phase == Phase.PAUSING:
            self.phase = Phase.CANCELLING
            return []
        if self.phase in (Phase.PLANNING, Phase.ACKING):
            return []  # at the reply (an accepted goal is then cancelled)
        return self.ctx.cancelled(BY_REQUEST)

    def on_deadline(self) -> list[Action]:
        if self.phase in (Phase.PAUSING, Phase.CANCELLING):
            goal_id, self.goal_id = self.goal_id, ""
            stop = self.ctx.query(ep.BRIDGE_COMMAND, stop_command(), ArmCommandReply)
            what = "pause" if self.phase == Phase.PAUSING else "cancel"
            msg = (
                f"controller did not confirm the {what} of goal {goal_id} within "
                f"{self.ctx.config.cancel_timeout_s:g} s; arm stopped by the bridge"
            )
            if self.phase == Phase.CANCELLING:
                return [stop, *self.ctx.cancelled(msg)]
            return [stop, *self.ctx.fail(msg)]
        if self.phase in (Phase.ACKING, Phase.ACTIVE):
            return self.ctx.fail("no result from the controller in time (goal deadline passed)")
        return []

    def cleanup(self) -> list[Action]:
        live = (Phase.ACKING, Phase.ACTIVE, Phase.PAUSING, Phase.CANCELLING)
        if self.goal_id and self.phase in live:
            return [self.ctx.query(ep.CANCEL, CancelGoal(goal_id=self.goal_id), GoalAck)]
        return []

    @property
    def needs_joint_states(self) -> bool:
        return self.phase in (Phase.ACKING, Phase.ACTIVE, Phase.PAUSING)
