"""The kinds of task step: one class each, holding that step's state, and the table of them.

The core (:class:`services.sequencer.core.SequencerCore`) keeps what belongs to the task:
the task, the step index, the task state, the pause and cancel requests, the query it
waits for, the step's deadline, progress and events. The object of the running step
keeps what belongs to the step (its :class:`Phase`, its goal, its trajectory, where it
paused) and is dropped when the step ends. It reaches the core only through
:class:`StepContext`.

:data:`STEP_TYPES` maps each :class:`~schemas.sequencing.StepKind` to its class: a new
kind of step is one class and one entry there, its checks before the task starts
included (:meth:`Step.problems`, :meth:`Step.plan`, :meth:`Step.leaves_arm_at`, used by
:class:`services.sequencer.validate.Validator`).

Hooks the core calls while the step runs (each returns the actions to take; ``None``
from :meth:`Step.pause`, :meth:`Step.on_bridge_state` and :meth:`Step.on_tick` means
"not mine": the core does its default):

- :meth:`Step.begin` starts the step, :meth:`Step.resume` goes on after a pause;
- :meth:`Step.on_reply` takes the answer to the query the step waits for;
- :meth:`Step.on_feedback`, :meth:`Step.on_result`, :meth:`Step.on_follow_state`: the
  controller's feedback, results and follow states;
- :meth:`Step.on_bridge_state`, :meth:`Step.on_tick`: bridge phases, time passing;
- :meth:`Step.pause` (``None``: not now, at the end of what is in flight),
  :meth:`Step.cancel`;
- :meth:`Step.on_deadline`: the deadline the step set passed;
- :meth:`Step.cleanup`: the task fails: stop what the step started.
"""

from __future__ import annotations

import dataclasses
import math
from enum import StrEnum
from typing import ClassVar, Protocol

from manus.config import FOLDED_Q_DEG, UNFOLDED_Q_DEG, ArmConfig
from manus.viapoints import ViaPointError, validate_path
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmAction, ArmCommand, ArmCommandReply
from schemas.control import (
    CancelGoal,
    CommandSourceKind,
    ControllerFeedback,
    EndCause,
    GoalAck,
    GoalResult,
    GripperGoal,
    Refusal,
    ResultStatus,
    TrajectoryGoal,
)
from schemas.follow import FollowGoal, FollowPhase, FollowState
from schemas.jog import USER_TOOK_OVER
from schemas.planning import Path, PlanReply, PlanRequest, Trajectory
from schemas.sequencing import DEFAULT_POSE_DURATION_S, StepKind, Task, TaskStep
from schemas.state import BridgePhase, BridgeState
from services.sequencer.actions import Action, Query
from services.sequencer.config import SequencerConfig
from services.sequencer.poses import POSES, pose_path, remainder_path

MAX_OPENING_M = 0.090
"""Largest gripper opening [m]."""

MAX_WAIT_S = 3600.0
"""Longest wait [s]."""

FOLD_END = {
    StepKind.FOLD_OUT: [math.radians(v) for v in UNFOLDED_Q_DEG],
    StepKind.FOLD_IN: [math.radians(v) for v in FOLDED_Q_DEG],
}
"""Where a fold leaves the arm (DH joint angles [rad])."""

FOLDING = {StepKind.FOLD_OUT: BridgePhase.FOLDING_OUT, StepKind.FOLD_IN: BridgePhase.FOLDING_IN}
"""The bridge's phase while it folds."""

NS = 1_000_000_000
BY_REQUEST = "cancelled by request"


class Phase(StrEnum):
    """What the running step is doing (``TaskStatus.message`` while nothing else is said)."""

    IDLE = ""
    PLANNING = "planning"
    ACKING = "acking"
    ACTIVE = "active"
    FOLDING = "folding"
    WAITING = "waiting"
    PAUSING = "pausing"
    PAUSED = "paused"
    CANCELLING = "cancelling"
    STOPPING = "stopping"
    CLEARING = "clearing"


class StepContext(Protocol):
    """What a step may see and do of its task (the core implements it)."""

    config: SequencerConfig
    now: int  # time of the input being handled [ns]
    task: Task | None
    step_progress: float  # fraction of the running step done, 0..1
    pause_requested: bool
    cancel_requested: bool

    def start_configuration(self) -> list[float] | None: ...
    def new_goal_id(self) -> str: ...
    def query(
        self, suffix: str, request: Message, reply_type: type[Message], *, wait: bool = False
    ) -> Query: ...
    def set_deadline(self, after_s: float) -> None: ...
    def report(self, progress: float) -> list[Action]: ...
    def step_done(self) -> list[Action]: ...
    def paused(self, reason: str = "") -> list[Action]: ...
    def cancelled(self, reason: str) -> list[Action]: ...
    def fail(self, reason: str) -> list[Action]: ...


def _stop_command() -> ArmCommand:
    return ArmCommand(action=ArmAction.STOP, source="sequencer")


class Step:
    """Base of the step kinds (see the module docstring).

    Args:
        spec: the step as the task gives it.
        ctx: its task (the core).
    """

    planned: ClassVar[bool] = False
    """Validation plans the step (from where the previous steps leave the arm)."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        self.spec = spec
        self.ctx = ctx
        self.phase = Phase.IDLE

    # -- before the task starts --------------------------------------------------------------

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        """What is wrong with ``spec`` by itself (no planning)."""
        return []

    @classmethod
    def plan(
        cls, spec: TaskStep, start: list[float] | None, arm: ArmConfig, path: Path | None = None
    ) -> PlanRequest:
        """The request that plans ``spec`` (or ``path`` instead of its own) from ``start``
        for the arm ``arm`` (only for kinds with :attr:`planned`)."""
        raise TypeError(f"a {spec.kind} step is not planned")

    @classmethod
    def leaves_arm_at(cls, spec: TaskStep) -> list[float] | None:
        """Where the step leaves the arm whatever its start (DH [rad]), or None."""
        return None

    # -- while it runs -----------------------------------------------------------------------

    def begin(self) -> list[Action]:
        """Start the step (its first query, or its timer)."""
        raise NotImplementedError

    def resume(self) -> list[Action]:
        """Go on after a pause (by default: begin again)."""
        return self.begin()

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        """The answer to the query the step waits for (None and ``error``: none came)."""
        return []

    def on_feedback(self, fb: ControllerFeedback) -> list[Action]:
        """The controller's feedback (any goal's)."""
        return []

    def on_result(self, res: GoalResult) -> list[Action]:
        """A goal's result (any goal's)."""
        return []

    def on_follow_state(self, state: FollowState) -> list[Action]:
        """The controller's follow state (any goal's)."""
        return []

    def done(self) -> list[Action] | None:
        """The supervisor's ``done`` (None: this step cannot be told it is done)."""
        return None

    def on_bridge_state(self, bs: BridgeState) -> list[Action] | None:
        """The bridge's state (None: the core checks for arm errors and e-stops)."""
        return None

    def on_tick(self) -> list[Action] | None:
        """Time passed (None: the core checks the link and the deadline)."""
        return None

    def pause(self) -> list[Action] | None:
        """Stop for a pause now (None: not now; the core keeps the request for later)."""
        return None

    def cancel(self) -> list[Action]:
        """Stop for good (by default at once: the task is cancelled)."""
        return self.ctx.cancelled(BY_REQUEST)

    def on_deadline(self) -> list[Action]:
        """The deadline the step set (:meth:`StepContext.set_deadline`) passed."""
        return []

    def cleanup(self) -> list[Action]:
        """The task fails: the queries that stop what the step started."""
        return []

    @property
    def needs_joint_states(self) -> bool:
        """Joint states must keep coming (a controller goal is on its way or running)."""
        return False


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
            stop = self.ctx.query(ep.BRIDGE_COMMAND, _stop_command(), ArmCommandReply)
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


class MoveStep(GoalStep):
    """``move`` (a path) and ``pose`` (a named pose): planned from the newest joint state,
    sent to the controller; after a pause the via points not yet reached are planned
    again from where the arm stopped, at their planned pace."""

    planned = True

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.traj: Trajectory | None = None
        self.t = 0.0  # trajectory time of the newest feedback of the running goal [s]
        self.resume_at: tuple[Trajectory, float] | None = None
        self.base = 0.0  # step progress reached before a resume

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        if spec.kind == StepKind.POSE:
            problems = []
            if spec.pose not in POSES:
                problems.append(f"unknown pose {spec.pose!r} (known: {', '.join(POSES)})")
            if not 0.0 <= spec.duration <= MAX_WAIT_S:  # 0: the default
                problems.append(
                    f"pose duration {spec.duration:g} s is outside [0, {MAX_WAIT_S:g}] s"
                )
            return problems
        if spec.path is None:
            return ["a move step needs a path"]
        try:
            validate_path(spec.path)
        except ViaPointError as exc:
            return [str(exc)]
        return []

    @classmethod
    def plan(
        cls, spec: TaskStep, start: list[float] | None, arm: ArmConfig, path: Path | None = None
    ) -> PlanRequest:
        """A pose step always asks for speed scaling: its duration is a shortest time."""
        chosen = path if path is not None else step_path(spec, start, arm)
        assert chosen is not None, "a move step without a path or a bad pose is never planned"
        return PlanRequest(
            path=chosen,
            start=start,
            interpolation=spec.interpolation,
            speed_scaling=spec.speed_scaling or spec.kind == StepKind.POSE,
            preview_dt=0.0,
        )

    def begin(self, path: Path | None = None) -> list[Action]:
        """Plan the step (after a pause: the rest ``path``) from the newest joint state."""
        start = self.ctx.start_configuration()
        if start is None:
            return self.ctx.fail("no valid joint state from the arm (is the bridge running?)")
        request = self.plan(self.spec, start, self.ctx.config.arm, path)
        if path is not None:  # the rest of a paused path starts from rest: let it stretch
            request = dataclasses.replace(request, speed_scaling=True)
        self.phase = Phase.PLANNING
        return [self.ctx.query(ep.PLAN, request, PlanReply, wait=True)]

    def resume(self) -> list[Action]:
        if self.resume_at is None:
            return self.begin()
        traj, t = self.resume_at  # cleared once the rest is planned
        source = self.spec.where or self.spec.kind
        rest = remainder_path(traj, t, source=source, cfg=self.ctx.config.arm)
        if rest is None:
            return self.ctx.step_done()
        return self.begin(rest)

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        if self.phase != Phase.PLANNING:
            return super().on_reply(reply, error)
        ctx = self.ctx
        if not isinstance(reply, PlanReply):
            return ctx.fail(f"planner: {error or 'bad reply'}")
        if not reply.ok or reply.trajectory is None:
            why = reply.error.message if reply.error is not None else "no trajectory"
            return ctx.fail(f"planner refused: {why}")
        if ctx.cancel_requested:
            return ctx.cancelled(BY_REQUEST)
        self.traj = reply.trajectory
        self.resume_at = None
        if ctx.pause_requested:
            return ctx.paused()
        self.goal_id = ctx.new_goal_id()
        self.t = 0.0
        assert ctx.task is not None
        goal = TrajectoryGoal(
            goal_id=self.goal_id,
            trajectory=reply.trajectory,
            mode=ctx.task.mode,
            heartbeat_timeout=ctx.config.heartbeat_timeout_s,
        )
        span = reply.trajectory.times[-1] + goal.goal_time_tolerance + ctx.config.result_margin_s
        return self._send(ep.GOAL, goal, span)

    def on_feedback(self, fb: ControllerFeedback) -> list[Action]:
        if not self.goal_id or fb.goal_id != self.goal_id or self.traj is None:
            return []
        self.t = fb.t
        frac = min(1.0, max(0.0, fb.t / max(self.traj.times[-1], 1e-9)))
        return self.ctx.report(self.base + (1.0 - self.base) * frac)

    def _remember_pause(self) -> None:
        if self.traj is not None:
            self.resume_at = (self.traj, self.t)
            self.base = self.ctx.step_progress


class GripperStep(GoalStep):
    """``gripper``: one gripper goal; after a pause it is sent again."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.grip0: float | None = None  # opening at the first feedback [m]

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        if not 0.0 <= spec.opening <= MAX_OPENING_M:
            mm, top = spec.opening * 1e3, MAX_OPENING_M * 1e3
            return [f"gripper opening {mm:g} mm is outside 0..{top:g} mm"]
        return []

    def begin(self) -> list[Action]:
        timeout = self.ctx.config.gripper_timeout_s
        self.goal_id = self.ctx.new_goal_id()
        self.grip0 = None
        goal = GripperGoal(
            goal_id=self.goal_id,
            opening=self.spec.opening,
            timeout=timeout,
            heartbeat_timeout=self.ctx.config.heartbeat_timeout_s,
        )
        return self._send(ep.GRIPPER_GOAL, goal, timeout + 5.0)

    def on_feedback(self, fb: ControllerFeedback) -> list[Action]:
        if not self.goal_id or fb.gripper_goal_id != self.goal_id:
            return []
        if self.grip0 is None:
            self.grip0 = fb.gripper
        span = abs(fb.gripper_target - self.grip0)
        done = 1.0 if span < 1e-6 else 1.0 - abs(fb.gripper_target - fb.gripper) / span
        return self.ctx.report(min(1.0, max(0.0, done)))


class FoldStep(Step):
    """``fold_in`` / ``fold_out``: the bridge's fold command, with the deadman of moves
    (``heartbeat_timeout``: the bridge stops the fold when the heartbeats or the
    controller's commands stop); done once ``state/bridge`` has shown the fold
    (``folding_*``) and then ``running``; failed when the bridge stops it (``stopped``). A
    fold cannot be paused half-way (a pause waits for its end); a cancel stops it
    (``stop``, then ``clear``)."""

    @classmethod
    def leaves_arm_at(cls, spec: TaskStep) -> list[float] | None:
        return list(FOLD_END[StepKind(spec.kind)])

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.seen_fold = False

    def begin(self) -> list[Action]:
        self.seen_fold = False
        self.ctx.set_deadline(self.ctx.config.fold_timeout_s)
        self.phase = Phase.FOLDING
        cmd = ArmCommand(
            action=self.spec.kind,
            source="sequencer",
            heartbeat_timeout=self.ctx.config.fold_heartbeat_timeout_s,
        )
        return [self.ctx.query(ep.BRIDGE_COMMAND, cmd, ArmCommandReply, wait=True)]

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        if self.phase == Phase.FOLDING:
            return self._on_fold_reply(reply, error)
        if self.phase == Phase.STOPPING:
            # stop answered: clear, so the arm is back in joint mode and ready.
            if (
                isinstance(reply, ArmCommandReply)
                and reply.ok
                and reply.phase == BridgePhase.STOPPED
            ):
                self.phase = Phase.CLEARING
                clear = ArmCommand(action=ArmAction.CLEAR, source="sequencer")
                return [self.ctx.query(ep.BRIDGE_COMMAND, clear, ArmCommandReply, wait=True)]
            return self.ctx.cancelled(f"{BY_REQUEST}; fold stopped")
        if self.phase == Phase.CLEARING:
            return self.ctx.cancelled(f"{BY_REQUEST}; fold stopped")
        return []

    def _on_fold_reply(self, reply: Message | None, error: str) -> list[Action]:
        if not isinstance(reply, ArmCommandReply):
            return self.ctx.fail(f"can_bridge: {error or 'no answer to the fold'}")
        if not reply.ok:
            return self.ctx.fail(f"can_bridge refused {self.spec.kind}: {reply.message}")
        # Done only after a state/bridge in folding_* and then running: a state published
        # before the bridge took the command may still be on its way.
        return []

    def on_bridge_state(self, bs: BridgeState) -> list[Action] | None:
        if self.phase != Phase.FOLDING:
            return None
        if bs.phase == FOLDING[StepKind(self.spec.kind)]:
            self.seen_fold = True
        elif self.seen_fold and bs.phase == BridgePhase.RUNNING:
            return self.ctx.step_done()
        elif self.seen_fold and bs.phase == BridgePhase.STOPPED:
            return self.ctx.fail(f"can_bridge: phase {bs.phase}: {bs.detail}")
        return None

    @property
    def needs_joint_states(self) -> bool:
        return self.phase == Phase.FOLDING  # the fold's deadman echoes them

    def cancel(self) -> list[Action]:
        if self.phase != Phase.FOLDING:
            return self.ctx.cancelled(BY_REQUEST)
        self.phase = Phase.STOPPING
        return [self.ctx.query(ep.BRIDGE_COMMAND, _stop_command(), ArmCommandReply, wait=True)]

    def on_deadline(self) -> list[Action]:
        if self.phase != Phase.FOLDING:
            return []
        timeout = self.ctx.config.fold_timeout_s
        return self.ctx.fail(f"the fold did not complete within {timeout:g} s")

    def cleanup(self) -> list[Action]:
        if self.phase != Phase.FOLDING:
            return []
        return [self.ctx.query(ep.BRIDGE_COMMAND, _stop_command(), ArmCommandReply)]


class WaitStep(Step):
    """``wait``: time from the inputs; a pause keeps the time left."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.end: int | None = None  # when the wait ends [ns]
        self.left = 0.0  # time left at a pause [s] (0: the whole duration)

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        if not 0.0 <= spec.duration <= MAX_WAIT_S:
            return [f"wait {spec.duration:g} s is outside 0..{MAX_WAIT_S:g} s"]
        return []

    def begin(self) -> list[Action]:
        left = self.left if self.left > 0.0 else self.spec.duration
        self.left = 0.0
        self.end = self.ctx.now + int(left * NS)
        self.phase = Phase.WAITING
        return []

    def on_tick(self) -> list[Action] | None:
        if self.phase != Phase.WAITING or self.end is None:
            return None
        left = (self.end - self.ctx.now) / NS
        if left <= 0.0:
            self.end = None
            return self.ctx.step_done()
        duration = self.spec.duration
        return self.ctx.report(1.0 - left / duration if duration > 0 else 1.0)

    def pause(self) -> list[Action] | None:
        if self.phase != Phase.WAITING or self.end is None:
            return None
        self.left = max(0.0, (self.end - self.ctx.now) / NS)
        self.end = None
        return self.ctx.paused()


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
        stop = FollowGoal(goal_id=self.goal_id, stop=True)
        return [self.ctx.query(ep.FOLLOW, stop, GoalAck)]

    def cleanup(self) -> list[Action]:
        live = (Phase.ACKING, Phase.ACTIVE, Phase.PAUSING, Phase.CANCELLING)
        if self.goal_id and self.phase in live:
            return [self.ctx.query(ep.FOLLOW, FollowGoal(goal_id=self.goal_id, stop=True), GoalAck)]
        return []


STEP_TYPES: dict[str, type[Step]] = {
    StepKind.MOVE: MoveStep,
    StepKind.POSE: MoveStep,
    StepKind.GRIPPER: GripperStep,
    StepKind.FOLD_IN: FoldStep,
    StepKind.FOLD_OUT: FoldStep,
    StepKind.WAIT: WaitStep,
    StepKind.FOLLOW: FollowStep,
}
"""The class of each kind of step."""


def step_path(step: TaskStep, start: list[float] | None, arm: ArmConfig) -> Path | None:
    """The path a move or pose step follows from ``start`` on the arm ``arm`` (None for
    other kinds or a bad pose name)."""
    if step.kind == StepKind.MOVE:
        return step.path
    if step.kind == StepKind.POSE and step.pose in POSES and step.duration >= 0.0:
        return pose_path(step.pose, step.duration or DEFAULT_POSE_DURATION_S, arm, start=start)
    return None
