"""``follow`` steps: the controller follows a tracker's target and the step holds it."""

from __future__ import annotations

import dataclasses

from schemas import endpoints as ep
from schemas.control import EndCause, GoalAck, GoalResult
from schemas.follow import FollowGoal, FollowPhase, FollowState
from schemas.sequencing import TaskStep
from services.sequencer.actions import Action
from services.sequencer.goal_step import GoalStep
from services.sequencer.step import MAX_WAIT_S, NS, Phase, StepContext


class FollowStep(GoalStep):
    """``follow``: the controller follows a tracker's target to a standoff and holds it
    (``controller/follow``, the step's ``follow`` settings); the step ends ``duration``
    after the tracked point first holds the standoff point (``controller/follow_state``),
    or when the supervisor says ``done`` (``TaskControl`` action ``done``): the goal is
    stopped and the step succeeds. A fault of the goal (the target lost, a jump, out of
    reach) fails the step; a jog pauses it; resume starts a new goal (holding again for
    the whole ``duration``). Validation leaves the arm where it was before the step: the
    moves after it are planned again from where the arm is when they run."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.holding_since: int | None = None
        """When the tracked point first held the standoff point [ns] (None: not yet)."""
        self.finishing = False
        """The goal is being stopped because the step is done."""

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        out = []
        if spec.follow is None or not spec.follow.source:
            out.append("a follow step needs `follow` with the tracker to follow (its source)")
        if not 0.0 <= spec.duration <= MAX_WAIT_S:
            out.append(f"follow for {spec.duration:g} s is outside 0..{MAX_WAIT_S:g} s")
        return out

    def begin(self) -> list[Action]:
        assert self.spec.follow is not None
        self.goal_id = self.ctx.new_goal_id()
        self.holding_since, self.finishing = None, False
        goal = dataclasses.replace(self.spec.follow, goal_id=self.goal_id, stop=False)
        self.ctx.set_deadline(MAX_WAIT_S + self.spec.duration)
        self.phase = Phase.ACKING
        return [self.ctx.query(ep.FOLLOW, goal, GoalAck, wait=True)]

    def on_follow_state(self, state: FollowState) -> list[Action]:
        """The follow goal's state: when it first holds the standoff point."""
        if state.goal_id != self.goal_id or self.phase != Phase.ACTIVE:
            return []
        if self.holding_since is None and state.state == FollowPhase.HOLDING:
            self.holding_since = self.ctx.now
        return []

    def on_tick(self) -> list[Action] | None:
        since, duration = self.holding_since, self.spec.duration
        if self.phase != Phase.ACTIVE or since is None or duration <= 0.0 or self.finishing:
            return None
        held = (self.ctx.now - since) / NS
        if held < duration:
            return self.ctx.report(held / duration)
        return self.done()

    def done(self) -> list[Action]:
        """The step is done (its time held, or the supervisor's ``done``): stop the goal."""
        if self.phase != Phase.ACTIVE or self.finishing:
            return []
        self.finishing = True
        return self._stop_goal(Phase.ACTIVE)

    def on_result(self, res: GoalResult) -> list[Action]:
        if self.finishing and res.goal_id == self.goal_id and res.cause == EndCause.CANCEL_REQUEST:
            self.goal_id, self.finishing = "", False
            return self.ctx.step_done()
        return super().on_result(res)

    def _stop_goal(self, phase: Phase) -> list[Action]:
        self.phase = phase
        self.ctx.set_deadline(self.ctx.config.cancel_timeout_s)
        return [self.ctx.query(ep.FOLLOW, FollowGoal(goal_id=self.goal_id, stop=True), GoalAck)]

    def cleanup(self) -> list[Action]:
        live = (Phase.ACKING, Phase.ACTIVE, Phase.PAUSING, Phase.CANCELLING)
        if self.goal_id and self.phase in live:
            return [self.ctx.query(ep.FOLLOW, FollowGoal(goal_id=self.goal_id, stop=True), GoalAck)]
        return []
