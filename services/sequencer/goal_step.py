"""Steps that run a controller goal: acknowledged, followed, ended by its result.

A goal the controller refuses because the bridge is not ``running`` (``not_ready``) while
the bridge is on its way back there by itself (a ``resync``: a frame lost or late, two
clean cycles to resume) is sent again once the bridge runs, within
``SequencerConfig.resync_wait_s`` of the refusal; past it, or with the bridge in a
phase it does not leave by itself (stopped, e-stopped, an arm error), the task fails
with the refusal. The arm does not move meanwhile: the bridge sends zeros in ``resync``.
"""

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
from schemas.state import ON_ITS_WAY_PHASES, BridgePhase, BridgeState
from services.sequencer.actions import Action
from services.sequencer.step import BY_REQUEST, Phase, Step, StepContext, stop_command


class GoalStep(Step):
    """A step that runs a controller goal: acknowledged, followed, ended by its result.
    Pause and cancel cancel the goal (the controller decelerates within the arm's limits);
    a controller that does not confirm within ``cancel_timeout_s`` gets the bridge's stop."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.goal_id = ""
        self.sent: tuple[str, TrajectoryGoal | GripperGoal, float] | None = None
        """The last goal sent: its endpoint, itself and its deadline [s]."""
        self.refused_at: int | None = None
        """When the controller first refused it as not ready [ns] (None: it has not)."""
        self.refusal = ""

    def _send(self, suffix: str, goal: TrajectoryGoal | GripperGoal, span_s: float) -> list[Action]:
        if self.sent is None or self.sent[1] is not goal:
            self.refused_at = None  # a new goal: a wait of its own
        self.sent = (suffix, goal, span_s)
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
        wait_s = self.ctx.config.resync_wait_s
        if reply.refusal == Refusal.NOT_READY and self.sent is not None and wait_s > 0:
            if self.refused_at is None:
                self.refused_at = self.ctx.now
            left_s = wait_s - (self.ctx.now - self.refused_at) / 1e9
            if left_s > 0 and self._bridge_returns():
                self.refusal = reply.reason
                self.phase = Phase.WAITING_BRIDGE
                self.ctx.set_deadline(left_s)
                return self._again() if self.ctx.bridge_phase == BridgePhase.RUNNING else []
        return self.ctx.fail(f"controller refused the goal: {reply.reason}")

    def _bridge_returns(self) -> bool:
        """The bridge runs, or is on its way back by itself (a resync)."""
        phase = self.ctx.bridge_phase
        return phase == BridgePhase.RUNNING or phase in ON_ITS_WAY_PHASES

    def _again(self) -> list[Action]:
        """Send the refused goal again (the bridge runs)."""
        assert self.sent is not None
        suffix, goal, span_s = self.sent
        self.goal_id = goal.goal_id
        return self._send(suffix, goal, span_s)

    def on_bridge_state(self, bs: BridgeState) -> list[Action] | None:
        if self.phase != Phase.WAITING_BRIDGE:
            return None
        if bs.phase == BridgePhase.RUNNING:
            return self._again()
        if not self._bridge_returns():
            self.phase = Phase.IDLE
            return self.ctx.fail(
                f"controller refused the goal: {self.refusal} (then the bridge went to "
                f"phase {bs.phase!r}: {bs.detail})"
            )
        return None

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
        if self.phase == Phase.WAITING_BRIDGE:
            return self.ctx.fail(
                f"controller refused the goal: {self.refusal} (still so "
                f"{self.ctx.config.resync_wait_s:g} s later)"
            )
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
