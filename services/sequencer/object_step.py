"""``pick``, ``place`` and ``give`` steps: an object task run as stages (docs/pick.md).

The stages (:mod:`services.sequencer.object_stages`, :mod:`.carry_stages`) are made
when the step begins, from the world model as the planner publishes it, and run one
after the other by the sequencer's own steps (:mod:`.stage_steps`: reach for motions,
gripper for openings, and the attach query). A pick tries its candidate grasps in
order: a pre-grasp pose or an approach the planner refuses moves on to the next. While
the object is approached it is watched: moved farther than ``pick.moved_m`` from where
the approach was aimed, the motion stops and the pick is planned again (at most
``pick.max_replans`` times, then the task stops, saying so); not observed for longer
than the staleness limit (perception lost), the task stops. Every motion planned while
a level object is held is checked for tilt (``pick.max_tilt_deg``) before it runs.
"""

from __future__ import annotations

import math

import numpy as np

from manus.orientation import matrix_to_ypr

from schemas.base import Message
from schemas.control import ControllerFeedback, GoalResult
from schemas.objects import AttachRequest
from schemas.planning import PlanReply
from schemas.sequencing import StepKind, TaskStep
from schemas.state import BridgeState
from services.sequencer.actions import Action
from services.sequencer.carry_stages import (
    carry_fallback,
    give_stages,
    held_object,
    place_stages,
    tilt_problem,
)
from services.sequencer.object_stages import (
    ObjectProblem,
    ObjectView,
    PickPlan,
    Stage,
    held_upright,
    pick_plan,
    pick_stages,
)
from services.sequencer.stage_steps import AttachStage, StageContext, StageGrip, StageReach
from services.sequencer.step import BY_REQUEST, Phase, Step, StepContext

WATCH_REASONS = ("unreachable", "collision", "joint_limit", "singular", "no_path", "invalid")


def object_problems(spec: TaskStep) -> list[str]:
    """What is wrong with an object step by itself."""
    problems = []
    if not spec.object:
        problems.append(f"a {spec.kind} step needs an object")
    if spec.kind == StepKind.PLACE:
        if (spec.at is None) == (not spec.surface):
            problems.append("a place step needs a pose (at) or a surface (on), not both")
        if spec.at is not None and not all(math.isfinite(v) for v in spec.at):
            problems.append(f"place pose must be finite, got {spec.at}")
    return problems


class ObjectStep(Step):
    """``pick``, ``place`` and ``give``: see the module docstring."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.stages: list[Stage] = []
        self.index = 0
        self.sub: Step | None = None
        self.plan_: PickPlan | None = None
        self.grasp = 0
        self.refusals: list[str] = []
        self.aimed: np.ndarray | None = None  # the object's position the grasp aims at
        self.replans = 0
        self.replanning = False
        self.fallback_used = False
        self.stage_ctx = StageContext(self)

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        return object_problems(spec)

    @property
    def phase(self) -> Phase:
        return self.sub.phase if self.sub is not None else Phase.IDLE

    @phase.setter
    def phase(self, value: Phase) -> None:
        pass  # the running stage's step holds it

    # -- making the stages ------------------------------------------------------------------

    def view(self) -> ObjectView:
        return self.ctx.object_view()

    def _q(self) -> np.ndarray | None:
        start = self.ctx.start_configuration()
        return None if start is None else np.array(start)

    def begin(self) -> list[Action]:
        q = self._q()
        if q is None:
            return self.ctx.fail("no valid joint state from the arm (is the bridge running?)")
        try:
            self.stages = self._make(self.view(), q)
        except ObjectProblem as exc:
            return self.ctx.fail(str(exc))
        self.index = 0
        return self._run()

    def _make(self, view: ObjectView, q: np.ndarray) -> list[Stage]:
        spec = self.spec
        if spec.kind == StepKind.PICK:
            self.plan_ = pick_plan(view, spec.object)
            self.grasp, self.refusals = 0, []
            self.aimed = np.array(self.plan_.obj.xyz)
            return pick_stages(self.plan_, self.plan_.grasps[0], view)
        held = held_object(view, spec.object)
        if spec.kind == StepKind.PLACE:
            return place_stages(view, held, q, spec.at, spec.surface)
        return give_stages(view, held, q)

    # -- running them -----------------------------------------------------------------------

    def _run(self) -> list[Action]:
        if self.index >= len(self.stages):
            return self.ctx.step_done()
        stage = self.stages[self.index]
        q = self._q()
        if q is None:
            return self.ctx.fail("no valid joint state from the arm (is the bridge running?)")
        if stage.motion is not None:
            spec = TaskStep(kind=StepKind.REACH, goal=stage.motion(q), where=self.spec.where)
            self.sub = StageReach(spec, self.stage_ctx, stage)
        elif stage.attach is not None:
            self.sub = AttachStage(self._attach_request(stage, q), self.stage_ctx)
        else:
            spec = TaskStep(kind=StepKind.GRIPPER, opening=stage.opening, where=self.spec.where)
            self.sub = StageGrip(spec, self.stage_ctx, stage)
        return self.sub.begin()

    def _attach_request(self, stage: Stage, q: np.ndarray) -> AttachRequest:
        latest = self.ctx.latest
        stamp = latest.stamp_ns if latest is not None else self.ctx.now
        xyz = ypr = None
        obj = self.view().objects.get(self.spec.object)
        if stage.upright and obj is not None and not obj.link:
            T = held_upright(self.view(), obj, q)
            xyz = [float(v) for v in T[:3, 3]]
            ypr = [float(v) for v in matrix_to_ypr(T[:3, :3])]
        return AttachRequest(
            object_id=self.spec.object,
            link=stage.attach or "",
            position=[float(v) for v in q],
            stamp_ns=stamp,
            touch_objects=list(stage.touch_objects),
            xyz=xyz,
            ypr=ypr,
        )

    def _label(self) -> str:
        stage = self.stages[self.index] if self.index < len(self.stages) else None
        return f"{self.spec.kind} {self.spec.object!r}" + (f" ({stage.label})" if stage else "")

    def stage_done(self) -> list[Action]:
        stage = self.stages[self.index]
        if stage.holds > 0.0:
            latest = self.ctx.latest
            opening = latest.gripper if latest is not None else 0.0
            if opening < stage.holds:
                return self.stage_failed(
                    f"the grasp did not hold: the jaws closed to {opening * 1e3:.1f} mm, the "
                    f"object is {(stage.holds * 1e3):.0f} mm wide or more there (it slipped, "
                    "or is not where perception saw it)"
                )
        self.index += 1
        self.sub = None
        if self.ctx.cancel_requested:
            return self.ctx.cancelled(BY_REQUEST)
        if self.ctx.pause_requested:
            self.ctx.pause_requested = False
            return self.ctx.paused()
        return self._run()

    def stage_failed(self, reason: str) -> list[Action]:
        return self.ctx.fail(f"{self._label()}: {reason}")

    def stage_cancelled(self, reason: str) -> list[Action]:
        if not self.replanning:
            return self.ctx.cancelled(reason)
        self.replanning = False
        self.sub = None
        q = self._q()
        if q is None:
            return self.ctx.fail("no valid joint state from the arm (is the bridge running?)")
        try:
            self.stages = self._make(self.view(), q)
        except ObjectProblem as exc:
            return self.ctx.fail(str(exc))
        self.index = 0
        return self._run()

    def stage_progress(self, progress: float) -> list[Action]:
        n = max(1, len(self.stages))
        return self.ctx.report(min(1.0, (self.index + progress) / n))

    def plan_problem(self, reply: PlanReply) -> str:
        stage = self.stages[self.index]
        if not stage.carrying or reply.trajectory is None:
            return ""
        obj = self.view().objects.get(self.spec.object)
        return tilt_problem(self.view(), obj, reply.trajectory, stage.label) if obj else ""

    def plan_refused(self, reply: PlanReply) -> list[Action]:
        why = reply.error.message if reply.error is not None else "no trajectory"
        reason = reply.error.reason if reply.error is not None else "invalid"
        stage = self.stages[self.index]
        plan = self.plan_
        if plan is not None and stage.watch:
            self.refusals.append(f"{plan.grasps[self.grasp].label}: {stage.label}: {reason}")
            self.grasp += 1
            if self.grasp < len(plan.grasps):
                self.stages = pick_stages(plan, plan.grasps[self.grasp], self.view())
                self.index = 0
                return self._run()
            return self.ctx.fail(no_grasp(plan, self.refusals, why))
        q = self._q()
        fallback = carry_fallback(self.view(), stage, q) if q is not None else None
        if fallback is not None and not self.fallback_used:
            self.fallback_used = True
            self.stages[self.index] = fallback
            return self._run()
        return self.stage_failed(f"planner refused ({reason}): {why}")

    # -- watching the object ---------------------------------------------------------------

    def on_objects(self) -> list[Action]:
        """The world model changed: the object approached moved?"""
        stage = self.stages[self.index] if self.index < len(self.stages) else None
        if stage is None or not stage.watch or self.aimed is None or self.replanning:
            return []
        obj = self.view().objects.get(self.spec.object)
        if obj is None:
            return self.ctx.fail(
                f"object {self.spec.object!r} left the world model during the approach"
            )
        moved = float(np.linalg.norm(np.array(obj.xyz) - self.aimed))
        limit = self.ctx.config.pick.moved_m
        if moved <= limit:
            return []
        bound = self.ctx.config.pick.max_replans
        if self.replans >= bound:
            return self.ctx.fail(
                f"object {self.spec.object!r} moved {moved * 1e3:.0f} mm during the approach "
                f"(more than {limit * 1e3:.0f} mm) after {self.replans} re-plan(s), the most "
                "allowed: stopped"
            )
        self.replans += 1
        self.replanning = True
        assert self.sub is not None
        return self.sub.cancel()

    def on_tick(self) -> list[Action] | None:
        stage = self.stages[self.index] if self.index < len(self.stages) else None
        if stage is not None and stage.watch:
            obj = self.view().objects.get(self.spec.object)
            if obj is not None:
                try:
                    self.view().check_fresh(obj, "during the approach")
                except ObjectProblem as exc:
                    return self.ctx.fail(str(exc))
        return self.sub.on_tick() if self.sub is not None else None

    # -- the hooks the core calls, handed to the running stage ------------------------------

    def resume(self) -> list[Action]:
        if self.sub is None:
            return self._run() if self.stages else self.begin()
        return self.sub.resume()

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        return self.sub.on_reply(reply, error) if self.sub is not None else []

    def on_feedback(self, fb: ControllerFeedback) -> list[Action]:
        return self.sub.on_feedback(fb) if self.sub is not None else []

    def on_result(self, res: GoalResult) -> list[Action]:
        return self.sub.on_result(res) if self.sub is not None else []

    def on_bridge_state(self, bs: BridgeState) -> list[Action] | None:
        return self.sub.on_bridge_state(bs) if self.sub is not None else None

    def pause(self) -> list[Action] | None:
        return self.sub.pause() if self.sub is not None else None

    def cancel(self) -> list[Action]:
        return self.sub.cancel() if self.sub is not None else self.ctx.cancelled(BY_REQUEST)

    def on_deadline(self) -> list[Action]:
        return self.sub.on_deadline() if self.sub is not None else []

    def cleanup(self) -> list[Action]:
        return self.sub.cleanup() if self.sub is not None else []

    @property
    def needs_joint_states(self) -> bool:
        return self.sub.needs_joint_states if self.sub is not None else False


def no_grasp(plan: PickPlan, refusals: list[str], last: str) -> str:
    """Why no grasp of ``plan``'s object can be planned: out of reach, or every grasp
    collides (each grasp and its planner's reason)."""
    obj = plan.obj
    tried = "; ".join(refusals)
    if all(r.endswith(("unreachable", "joint_limit", "singular")) for r in refusals):
        return (
            f"object {obj.id!r} ({obj.cls}) is out of reach: every grasp tried ({tried}); "
            f"last: {last}"
        )
    return (
        f"every grasp pose of object {obj.id!r} ({obj.cls}) collides or has no path "
        f"({tried}); last: {last}"
    )
