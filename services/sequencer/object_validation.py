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
from schemas.sequencing import TaskStep
from services.sequencer.carry_stages import held_as_world, plan_problem
from services.sequencer.object_attempts import Attempts, attempts, origin
from services.sequencer.object_stages import ObjectView, Stage, predicted_hold


class ObjectValidation:
    """Plans one object step (see the module docstring).

    Args:
        spec: the step.
        view: what the sequencer knows, the objects as the steps before leave them.
        q: where the steps before leave the arm [rad].
        held_now: the objects the planner's world model holds attached now (a lowering
            onto a surface is planned to just outside its clearance: the planner learns
            the surface as a touch object only when the stage before attaches it).

    Use: ``while (req := v.next_request()) is not None: v.on_reply(ask(req))``; then
    :attr:`problems`, :attr:`q` (where it leaves the arm) and :attr:`objects` (the world
    model as it leaves it).
    """

    def __init__(
        self,
        spec: TaskStep,
        view: ObjectView,
        q: np.ndarray,
        held_now: frozenset[str] = frozenset(),
    ) -> None:
        self.spec = spec
        self.held_now = held_now
        self.view = view
        self.q0 = self.q = q
        self.objects = dict(view.objects)
        self.problems: list[str] = []
        self.index = 0
        self._asked: Stage | None = None
        found = attempts(spec, view, q)
        if isinstance(found, str):
            self.problems.append(found)
            self.tries: Attempts | None = None
        else:
            self.tries = found

    def next_request(self) -> PlanRequest | None:
        """The next motion to plan (None: done; see :attr:`problems`)."""
        if self.problems or self.tries is None:
            return None
        stages = self.tries.stages
        while self.index < len(stages):
            stage = stages[self.index]
            if stage.motion is not None:
                self._asked = stage
                motion = stage.motion
                if stage.raised is not None and self.spec.object in self.held_now:
                    motion = stage.raised
                return PlanRequest(motion(self.q), start=list(self.q), preview_dt=0.0)
            if stage.attach is not None:
                self._attach(stage)
            self.index += 1
        return None

    def on_reply(self, reply: PlanReply | None, error: str = "") -> None:
        """The planner's answer to the last request (None with ``error``: none came)."""
        stage, self._asked = self._asked, None
        assert stage is not None and self.tries is not None, "no request is waiting"
        label = f"{self.spec.kind} {self.spec.object!r} ({stage.label})"
        if reply is None:
            self.problems.append(f"{label}: cannot plan: {error or 'the planner did not answer'}")
            return
        if reply.ok and reply.trajectory is not None:
            held = self.objects.get(self.spec.object)
            problem = plan_problem(self.view, stage, reply.trajectory, held, self.tries.margin)
            if not problem:
                self.q = np.array(reply.trajectory.positions[-1])
                self.index += 1
                return
            word, why = ("tight" if "too tight" in problem else "tilt"), problem
        else:
            word = reply.error.reason if reply.error is not None else "invalid"
            message = reply.error.message if reply.error is not None else "no trajectory"
            why = f"planner refused ({word}): {message}"
        if not stage.retry:
            self.problems.append(f"{label}: {why}")
            return
        final = self.tries.refused(stage, word, why)
        if final:
            self.problems.append(final)
            return
        self.index = 0
        self.q = self.q0
        self.objects = dict(self.view.objects)

    def _attach(self, stage: Stage) -> None:
        """The world model after an attach stage: a grasped object held where the grasp
        holds it, a released one in the world where it is let go."""
        obj = self.objects.get(self.spec.object)
        tries = self.tries
        if obj is None or tries is None:
            return
        if stage.attach and not obj.link and tries.pick is not None:
            self.view.origins[obj.id] = origin(obj)
            T = predicted_hold(tries.pick.grasps[tries.index], obj)
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
