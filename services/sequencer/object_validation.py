"""An object step planned before anything moves (:class:`services.sequencer.validate.
Validator`): the stages the step will run (:mod:`.object_stages`, :mod:`.carry_stages`),
each motion planned by the planner from where the previous one ends, the candidate
grasps tried in order and a refused carry line searched instead, as the running step
does (:mod:`.object_step`). A pick leaves the object held (where the grasp will hold
it) for the steps after it, a place leaves it where it is put.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from manus.grasp_poses import object_pose
from manus.orientation import matrix_to_ypr
from manus.urdf import GRIPPER_FRAME
from schemas.objects import WorldObject
from schemas.planning import PlanReply, PlanRequest
from schemas.sequencing import StepKind, TaskStep
from services.sequencer.carry_stages import (
    carry_fallback,
    give_stages,
    held_as_world,
    held_object,
    place_stages,
    tilt_problem,
)
from services.sequencer.object_stages import (
    ObjectProblem,
    ObjectView,
    PickPlan,
    Stage,
    pick_plan,
    pick_stages,
    predicted_hold,
)
from services.sequencer.object_step import no_grasp


class ObjectValidation:
    """Plans one object step (see the module docstring).

    Args:
        spec: the step.
        view: what the sequencer knows, the objects as the steps before leave them.
        q: where the steps before leave the arm [rad].

    Use: ``while (req := v.next_request()) is not None: v.on_reply(ask(req))``; then
    :attr:`problems`, :attr:`q` (where it leaves the arm) and :attr:`objects` (the world
    model as it leaves it).
    """

    def __init__(self, spec: TaskStep, view: ObjectView, q: np.ndarray) -> None:
        self.spec = spec
        self.view = view
        self.q = q
        self.objects = dict(view.objects)
        self.problems: list[str] = []
        self.stages: list[Stage] = []
        self.index = 0
        self.plan: PickPlan | None = None
        self.grasp = 0
        self.refusals: list[str] = []
        self.fallback_used = False
        self._asked: Stage | None = None
        try:
            self.stages = self._make()
        except ObjectProblem as exc:
            self.problems.append(str(exc))

    def _make(self) -> list[Stage]:
        spec, view = self.spec, self.view
        if spec.kind == StepKind.PICK:
            self.plan = pick_plan(view, spec.object)
            return pick_stages(self.plan, self.plan.grasps[0], view)
        held = held_object(view, spec.object)
        if spec.kind == StepKind.PLACE:
            return place_stages(view, held, self.q, spec.at, spec.surface)
        return give_stages(view, held, self.q)

    def next_request(self) -> PlanRequest | None:
        """The next motion to plan (None: done; see :attr:`problems`)."""
        if self.problems:
            return None
        while self.index < len(self.stages):
            stage = self.stages[self.index]
            if stage.motion is not None:
                self._asked = stage
                return PlanRequest(stage.motion(self.q), start=list(self.q), preview_dt=0.0)
            if stage.attach is not None:
                self._attach(stage)
            self.index += 1
        return None

    def on_reply(self, reply: PlanReply | None, error: str = "") -> None:
        """The planner's answer to the last request (None with ``error``: none came)."""
        stage, self._asked = self._asked, None
        assert stage is not None, "no request is waiting for a reply"
        label = f"{self.spec.kind} {self.spec.object!r} ({stage.label})"
        if reply is None:
            self.problems.append(f"{label}: cannot plan: {error or 'the planner did not answer'}")
            return
        if reply.ok and reply.trajectory is not None:
            if stage.carrying:
                obj = self.objects.get(self.spec.object)
                problem = tilt_problem(self.view, obj, reply.trajectory, stage.label) if obj else ""
                if problem:
                    self.problems.append(f"{label}: {problem}")
                    return
            self.q = np.array(reply.trajectory.positions[-1])
            self.index += 1
            return
        why = reply.error.message if reply.error is not None else "no trajectory"
        reason = reply.error.reason if reply.error is not None else "invalid"
        plan = self.plan
        if plan is not None and stage.watch:
            self.refusals.append(f"{plan.grasps[self.grasp].label}: {stage.label}: {reason}")
            self.grasp += 1
            if self.grasp < len(plan.grasps):
                self.stages = pick_stages(plan, plan.grasps[self.grasp], self.view)
                self.index = 0
                return
            self.problems.append(no_grasp(plan, self.refusals, why))
            return
        fallback = carry_fallback(self.view, stage, self.q)
        if fallback is not None and not self.fallback_used:
            self.fallback_used = True
            self.stages[self.index] = fallback
            return
        self.problems.append(f"{label}: planner refused ({reason}): {why}")

    def _attach(self, stage: Stage) -> None:
        """The world model after an attach stage: a grasped object held where the grasp
        holds it, a released one in the world where it is let go."""
        obj = self.objects.get(self.spec.object)
        if obj is None:
            return
        if stage.attach and not obj.link and self.plan is not None:
            T = predicted_hold(self.plan.grasps[self.grasp], obj)
            self.objects[obj.id] = dataclasses.replace(
                obj,
                xyz=[float(v) for v in T[:3, 3]],
                ypr=[float(v) for v in matrix_to_ypr(T[:3, :3])],
                link=GRIPPER_FRAME,
            )
        elif stage.attach == "" and obj.link:
            self.objects[obj.id] = released(obj, self.view.gripper(self.q))


def released(obj: WorldObject, gripper: np.ndarray) -> WorldObject:
    """``obj`` (held) let go with the gripper at ``gripper`` (chair frame): in the world
    where it is."""
    return held_as_world(obj, gripper @ object_pose(obj))
