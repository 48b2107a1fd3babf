"""The steps an object task runs its stages with (:mod:`services.sequencer.object_step`):
the sequencer's own reach and gripper steps, seen through a :class:`StageContext` that
hands their end to the object step, and the attach, a query of its own.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from schemas import endpoints as ep
from schemas.base import Message
from schemas.control import EndCause, GoalResult, GripperGoal, ResultStatus
from schemas.objects import AttachReply, AttachRequest
from schemas.planning import PlanReply
from services.sequencer.actions import Action, Query
from services.sequencer.gripper_step import GripperStep
from services.sequencer.object_stages import Stage
from services.sequencer.reach_step import ReachStep
from services.sequencer.step import Phase, Step, StepContext

if TYPE_CHECKING:
    from schemas.sequencing import Task
    from schemas.state import JointState
    from services.sequencer.config import SequencerConfig
    from services.sequencer.object_stages import ObjectView


class StageOwner(Protocol):
    """What a stage's step reports to (the object step)."""

    ctx: StepContext
    replanning: bool

    def stage_done(self) -> list[Action]: ...
    def stage_failed(self, reason: str) -> list[Action]: ...
    def stage_cancelled(self, reason: str) -> list[Action]: ...
    def stage_progress(self, progress: float) -> list[Action]: ...
    def plan_refused(self, reply: PlanReply) -> list[Action]: ...
    def plan_problem(self, reply: PlanReply) -> list[Action] | None: ...


class StageContext:
    """The task, as a stage's step sees it: everything the object step's own context
    gives, but the step's end, failure, cancel and progress go to the object step."""

    def __init__(self, owner: StageOwner) -> None:
        self.owner = owner
        self.outer = owner.ctx

    @property
    def config(self) -> SequencerConfig:
        return self.outer.config

    @property
    def now(self) -> int:
        return self.outer.now

    @property
    def task(self) -> Task | None:
        return self.outer.task

    @property
    def step_progress(self) -> float:
        return self.outer.step_progress

    @property
    def pause_requested(self) -> bool:
        return self.outer.pause_requested

    @pause_requested.setter
    def pause_requested(self, value: bool) -> None:
        self.outer.pause_requested = value

    @property
    def cancel_requested(self) -> bool:
        return self.outer.cancel_requested or self.owner.replanning

    @property
    def bridge_phase(self) -> str:
        return self.outer.bridge_phase

    @property
    def latest(self) -> JointState | None:
        return self.outer.latest

    def start_configuration(self) -> list[float] | None:
        return self.outer.start_configuration()

    def object_view(self) -> ObjectView:
        return self.outer.object_view()

    def new_goal_id(self) -> str:
        return self.outer.new_goal_id()

    def query(
        self, suffix: str, request: Message, reply_type: type[Message], *, wait: bool = False
    ) -> Query:
        return self.outer.query(suffix, request, reply_type, wait=wait)

    def set_deadline(self, after_s: float) -> None:
        self.outer.set_deadline(after_s)

    def report(self, progress: float) -> list[Action]:
        return self.owner.stage_progress(progress)

    def step_done(self) -> list[Action]:
        return self.owner.stage_done()

    def paused(self, reason: str = "") -> list[Action]:
        return self.outer.paused(reason)

    def cancelled(self, reason: str) -> list[Action]:
        return self.owner.stage_cancelled(reason)

    def fail(self, reason: str) -> list[Action]:
        return self.owner.stage_failed(reason)


class StageReach(ReachStep):
    """A motion stage: a reach step whose refused plan goes to the object step (another
    candidate), and whose plan is checked by it (clearance to spare, tilt while a level
    object is held) before it is run."""

    def __init__(self, spec: object, ctx: StageContext, stage: Stage) -> None:
        super().__init__(spec, ctx)  # type: ignore[arg-type]
        self.owner = ctx.owner
        self.stage = stage

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        if self.phase == Phase.PLANNING and isinstance(reply, PlanReply):
            if not reply.ok or reply.trajectory is None:
                return self.owner.plan_refused(reply)
            stopped = self.owner.plan_problem(reply)
            if stopped is not None:
                return stopped
        return super().on_reply(reply, error)

    def on_result(self, res: GoalResult) -> list[Action]:
        """A goal that ended short of its end by no more than the stage allows
        (``stage.reach_tolerance``: by default the goal's own 2 mm) is reached: when the
        arm did not come to rest there (the controller's dither at a goal, docs/reach.md,
        Known limits), or when the collision guard stopped it there (a last correction
        near the table that its bounds could not prove clear, seen live at a pick's
        approach): the controller holds the arm still from then on."""
        if (
            self.goal_id
            and res.goal_id == self.goal_id
            and self.phase == Phase.ACTIVE
            and res.status == ResultStatus.ABORTED
            and res.cause in (EndCause.TOLERANCE, EndCause.COLLISION)
            and res.final_error <= max(self.stage.reach_tolerance, DITHER_TOLERANCE_M)
        ):
            self.goal_id = ""
            return self.ctx.step_done()
        return super().on_result(res)


DITHER_TOLERANCE_M = 0.002
"""A trajectory goal's default ``position_tolerance`` [m]: ended within it, the arm is
where the stage wanted it."""

CLOSE_TIMEOUT_S = 2.5
"""How long the jaws close on an object [s]: they stop at its width well within it, and
the gripper goal ends at its timeout, short of its target."""

HOLD_SLACK_M = 0.002
"""The jaws stopped at most this much narrower than the object: they hold it [m]."""


class StageGrip(GripperStep):
    """A gripper stage. Closing on an object (``stage.holds``): the target lies past the
    object's width, so the jaws stop on it and the goal ends at its timeout; that end is
    the grasp, if the jaws stopped at the object's width. Reaching the target means they
    closed past it: the grasp did not hold."""

    def __init__(self, spec: object, ctx: StageContext, stage: Stage) -> None:
        super().__init__(spec, ctx)  # type: ignore[arg-type]
        self.stage = stage

    def begin(self) -> list[Action]:
        timeout = CLOSE_TIMEOUT_S if self.stage.holds else self.ctx.config.gripper_timeout_s
        self.goal_id = self.ctx.new_goal_id()
        self.grip0 = None
        goal = GripperGoal(
            goal_id=self.goal_id,
            opening=self.stage.opening,
            tolerance=self.stage.tolerance,
            timeout=timeout,
            heartbeat_timeout=self.ctx.config.heartbeat_timeout_s,
        )
        return self._send(ep.GRIPPER_GOAL, goal, timeout + 5.0)

    def on_result(self, res: GoalResult) -> list[Action]:
        width = self.stage.holds
        if not width or not self.goal_id or res.goal_id != self.goal_id:
            return super().on_result(res)
        if self.phase != Phase.ACTIVE:
            return super().on_result(res)
        latest = self.ctx.latest
        opening = latest.gripper if latest is not None else 0.0
        if res.status == ResultStatus.ABORTED and opening >= width - HOLD_SLACK_M:
            self.goal_id = ""
            return self.ctx.step_done()
        if res.status in (ResultStatus.SUCCEEDED, ResultStatus.ABORTED):
            self.goal_id = ""
            return self.ctx.fail(
                f"the grasp did not hold: the jaws closed to {opening * 1e3:.1f} mm, past the "
                f"object's {width * 1e3:.1f} mm (it slipped, or it is not where perception "
                "saw it)"
            )
        return super().on_result(res)


class AttachStage(Step):
    """Attach the object to the gripper (or detach it): one ``planner/attach`` query.

    Args:
        request: the request.
        ctx: the stage's context.
    """

    def __init__(self, request: AttachRequest, ctx: StageContext) -> None:
        self.request = request
        self.ctx = ctx
        self.phase = Phase.IDLE

    def begin(self) -> list[Action]:
        self.phase = Phase.PLANNING
        return [self.ctx.query(ep.ATTACH, self.request, AttachReply, wait=True)]

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        self.phase = Phase.IDLE
        if not isinstance(reply, AttachReply):
            return self.ctx.fail(f"planner (attach): {error or 'bad reply'}")
        if not reply.accepted:
            return self.ctx.fail(f"the world model refused the attach: {reply.error}")
        return self.ctx.step_done()

    def cancel(self) -> list[Action]:
        if self.phase == Phase.PLANNING:
            return []  # at the reply: an attach is not undone halfway
        return self.ctx.cancelled("cancelled by request")
