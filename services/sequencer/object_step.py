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
from dataclasses import replace

import numpy as np

from manus.orientation import matrix_to_ypr
from schemas.base import Message
from schemas.control import ControllerFeedback, GoalResult
from schemas.motion import Motion
from schemas.objects import AttachRequest
from schemas.planning import PlanReply
from schemas.sequencing import StepKind, TaskStep
from schemas.state import BridgeState
from services.sequencer.actions import Action
from services.sequencer.carry_stages import plan_problem
from services.sequencer.object_attempts import Attempts, attempts, origin
from services.sequencer.object_stages import (
    NEAR_SPEED,
    ObjectProblem,
    ObjectView,
    Stage,
    held_upright,
    line_to,
)
from services.sequencer.stage_steps import AttachStage, StageContext, StageGrip, StageReach
from services.sequencer.step import BY_REQUEST, Phase, Step, StepContext


def object_problems(spec: TaskStep) -> list[str]:
    """What is wrong with an object step by itself."""
    problems = []
    if not spec.object:
        problems.append(f"a {spec.kind} step needs an object")
    if spec.kind == StepKind.PLACE:
        if (spec.at is not None) + bool(spec.surface) + spec.back != 1:
            problems.append("a place step needs a pose (at), a surface (on) or back, one of them")
    elif spec.back:
        problems.append(f"back is for a place step, not {spec.kind}")
    if spec.kind == StepKind.PICK and spec.at is not None:
        problems.append("a pick step takes no pose (at): it picks the object where it is")
    if spec.at is not None and not all(math.isfinite(v) for v in spec.at):
        problems.append(f"{spec.kind} pose must be finite, got {spec.at}")
    return problems


SIGHTINGS = 20
"""How many of perception's recent sightings the object's position is averaged over."""


class ObjectStep(Step):
    """``pick``, ``place`` and ``give``: see the module docstring."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.tries: Attempts | None = None
        self.index = 0  # the stage running
        self.sub: Step | None = None  # its step
        self.committed = False  # the object was grasped or let go: no other candidate now
        self.aimed: np.ndarray | None = None  # the object's position the grasp aims at
        self.replans = 0
        self.replanning = False
        self.sightings: list[tuple[int, np.ndarray]] = []  # (stamp [ns], position [m])
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

    @property
    def stages(self) -> list[Stage]:
        """The stages of the candidate being tried."""
        return self.tries.stages if self.tries is not None else []

    def begin(self) -> list[Action]:
        q = self._q()
        if q is None:
            return self.ctx.fail("no valid joint state from the arm (is the bridge running?)")
        found = attempts(self.spec, self.view(), q)
        if isinstance(found, str):
            return self.ctx.fail(found)
        self.tries, self.index = found, 0
        self.aimed = np.array(found.object.xyz) if found.pick is not None else None
        return self._run()

    # -- running them -----------------------------------------------------------------------

    def _run(self) -> list[Action]:
        if self.index >= len(self.stages):
            return self.ctx.step_done()
        stage = self.stages[self.index]
        q = self._q()
        if q is None:
            return self.ctx.fail("no valid joint state from the arm (is the bridge running?)")
        obj = self.view().objects.get(self.spec.object)
        if stage.watch and obj is not None:
            try:  # seen until the approach begins (the gripper then hides it)
                self.view().check_fresh(obj, f"before the {stage.label}")
            except ObjectProblem as exc:
                return self.ctx.fail(str(exc))
        if stage.motion is not None:
            motion = stage.motion(q)
            if stage.aim:
                motion = self._aimed_approach(q) or motion
            spec = TaskStep(kind=StepKind.REACH, goal=motion, where=self.spec.where)
            self.sub = StageReach(spec, self.stage_ctx, stage)
        elif stage.attach is not None:
            self.sub = AttachStage(self._attach_request(stage, q), self.stage_ctx)
        else:
            spec = TaskStep(kind=StepKind.GRIPPER, opening=stage.opening, where=self.spec.where)
            self.sub = StageGrip(spec, self.stage_ctx, stage)
        return self.sub.begin()

    def estimate(self) -> np.ndarray | None:
        """Where the object is, from perception's recent sightings: the mean of the last
        :data:`SIGHTINGS` within ``pick.moved_m`` of the newest (each is noisy: 3 mm per
        axis in the simulator's camera), chair frame [m]; None: none seen."""
        if not self.sightings:
            return None
        newest = self.sightings[-1][1]
        near = [
            p
            for _, p in self.sightings
            if np.linalg.norm(p - newest) <= self.ctx.config.pick.moved_m
        ]
        return np.asarray(np.mean(near, axis=0))

    def _aimed_approach(self, q: np.ndarray) -> Motion | None:
        """The straight approach to the grasp aimed at :meth:`estimate` (None: no
        sightings, or not a pick)."""
        tries, found = self.tries, self.estimate()
        if tries is None or tries.pick is None or found is None:
            return None
        T = tries.pick.grasps[tries.index].grasp.copy()
        T[:3, 3] += found - np.array(tries.pick.obj.xyz)
        return line_to(self.view(), T, speed=NEAR_SPEED)(q)

    def _attach_request(self, stage: Stage, q: np.ndarray) -> AttachRequest:
        latest = self.ctx.latest
        stamp = latest.stamp_ns if latest is not None else self.ctx.now
        xyz = ypr = None
        obj = self.view().objects.get(self.spec.object)
        if stage.attach and obj is not None and not obj.link:
            found = self.estimate()
            if found is not None:
                obj = replace(obj, xyz=[float(v) for v in found])
            self.view().origins[obj.id] = origin(obj)
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
        if stage.holds or stage.attach == "":
            self.committed = True
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
        return self.begin()

    def stage_progress(self, progress: float) -> list[Action]:
        n = max(1, len(self.stages))
        return self.ctx.report(min(1.0, (self.index + progress) / n))

    def plan_problem(self, reply: PlanReply) -> list[Action] | None:
        """A planned stage that must not run: another candidate, or the task fails."""
        stage = self.stages[self.index]
        assert reply.trajectory is not None
        held = self.view().objects.get(self.spec.object)
        margin = self.tries.margin if self.tries is not None else None
        problem = plan_problem(self.view(), stage, reply.trajectory, held, margin)
        if not problem:
            return None
        word = "tight" if "too tight" in problem else "tilt"
        return self._another(stage, word, problem)

    def plan_refused(self, reply: PlanReply) -> list[Action]:
        why = reply.error.message if reply.error is not None else "no trajectory"
        reason = reply.error.reason if reply.error is not None else "invalid"
        return self._another(self.stages[self.index], reason, f"planner refused ({reason}): {why}")

    def _another(self, stage: Stage, reason: str, why: str) -> list[Action]:
        """Try the next candidate (grasp, yaw), or fail naming every one tried."""
        if self.tries is None or not stage.retry or self.committed:
            return self.stage_failed(why)
        final = self.tries.refused(stage, reason, why)
        if final:
            return self.ctx.fail(final)
        self.index = 0
        self.sub = None
        return self._run()

    # -- watching the object ---------------------------------------------------------------

    def on_objects(self) -> list[Action]:
        """The world model changed: a new sighting of the object; has it moved?"""
        seen = self.view().objects.get(self.spec.object)
        newest = self.sightings[-1][0] if self.sightings else -1
        if seen is not None and not seen.link and seen.stamp_ns > newest:
            self.sightings = [
                *self.sightings[-(SIGHTINGS - 1) :],
                (seen.stamp_ns, np.array(seen.xyz)),
            ]
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
        if stage is not None and stage.watch and stage.search:
            obj = self.view().objects.get(self.spec.object)
            if obj is not None:
                try:
                    self.view().check_fresh(obj, f"during the {stage.label}")
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
