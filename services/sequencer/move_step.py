"""``move`` and ``pose`` steps: a planned trajectory, run as a controller goal."""

from __future__ import annotations

import dataclasses

from manus.config import ArmConfig
from manus.viapoints import ViaPointError, validate_path
from schemas import endpoints as ep
from schemas.base import Message
from schemas.control import ControllerFeedback, TrajectoryGoal
from schemas.planning import Path, PlanReply, PlanRequest, PlanResume, Trajectory, ViaPointPath
from schemas.sequencing import DEFAULT_POSE_DURATION_S, StepKind, TaskStep
from services.sequencer.actions import Action
from services.sequencer.goal_step import GoalStep
from services.sequencer.poses import POSES, pose_path
from services.sequencer.step import BY_REQUEST, MAX_WAIT_S, Phase, StepContext


class MoveStep(GoalStep):
    """``move`` (a path) and ``pose`` (a named pose): planned from the newest joint state,
    sent to the controller; after a pause the same motion is planned again from where the
    arm stopped, by the planner that made the plan, told the plan and how far it got
    (:class:`~schemas.planning.PlanResume`: for a path, the via points not yet reached, at
    their planned pace)."""

    planned = True

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.request: PlanRequest | None = None  # the step's first plan request
        self.traj: Trajectory | None = None
        self.t = 0.0  # trajectory time of the newest feedback of the running goal [s]
        self.resume_at: PlanResume | None = None  # the plan that paused, how far it got
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
    def plan(cls, spec: TaskStep, start: list[float] | None, arm: ArmConfig) -> PlanRequest:
        """A pose step always asks for speed scaling: its duration is a shortest time."""
        path = step_path(spec, start, arm)
        assert path is not None, "a move step without a path or a bad pose is never planned"
        motion = ViaPointPath(
            path=path,
            interpolation=spec.interpolation,
            speed_scaling=spec.speed_scaling or spec.kind == StepKind.POSE,
        )
        return PlanRequest(motion, start=start, preview_dt=0.0)

    def begin(self) -> list[Action]:
        """Plan the step from the newest joint state."""
        start = self.ctx.start_configuration()
        if start is None:
            return self.ctx.fail("no valid joint state from the arm (is the bridge running?)")
        self.request = self.plan(self.spec, start, self.ctx.config.arm)
        self.phase = Phase.PLANNING
        return [self.ctx.query(ep.PLAN, self.request, PlanReply, wait=True)]

    def resume(self) -> list[Action]:
        """Plan what is left of the paused plan (cleared once planned) from the newest
        joint state: the same motion, with the plan and how far it got."""
        paused = self.resume_at
        if paused is None or self.request is None:
            return self.begin()
        if paused.reached >= paused.trajectory.times[-1] - 1e-9:
            return self.ctx.step_done()  # it had got to the end: nothing is left
        start = self.ctx.start_configuration()
        if start is None:
            return self.ctx.fail("no valid joint state from the arm (is the bridge running?)")
        request = dataclasses.replace(self.request, start=start, resume=paused)
        self.phase = Phase.PLANNING
        return [self.ctx.query(ep.PLAN, request, PlanReply, wait=True)]

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
            self.resume_at = PlanResume(trajectory=self.traj, reached=max(0.0, self.t))
            self.base = self.ctx.step_progress


def step_path(step: TaskStep, start: list[float] | None, arm: ArmConfig) -> Path | None:
    """The path a move or pose step follows from ``start`` on the arm ``arm`` (None for
    other kinds or a bad pose name)."""
    if step.kind == StepKind.MOVE:
        return step.path
    if step.kind == StepKind.POSE and step.pose in POSES and step.duration >= 0.0:
        return pose_path(step.pose, step.duration or DEFAULT_POSE_DURATION_S, arm, start=start)
    return None
