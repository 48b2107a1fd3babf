"""Whole-task validation before anything moves (deterministic; the core asks the planner).

Every step is checked on its own (openings in range, known pose names, via points that
obey the via-point rules: each kind's :meth:`~services.sequencer.step.Step.problems`),
and every move is planned from where the previous steps leave the arm: the arm's current
configuration at first, the fold poses after a fold, the last knot of the previous plan
after a move. A fold is the arm's own motion (a straight line in joint space to the fold
pose), so it is checked against the scene here, the objects the arm holds included
(``fold_check``: :class:`FoldChecker`, :func:`manus.sweep.straight_motion_problem`).
The :class:`Validator` hands out one :class:`~schemas.planning.PlanRequest` at a time
(with an explicit ``start``) and takes the planner's reply; when it has none left,
:attr:`Validator.errors` lists every problem in step order, each as ``<where>: step N
(kind): <problem>``. :meth:`SequencerCore.submit
<services.sequencer.core.SequencerCore.submit>` drives it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence

import numpy as np

from manus.collision import CollisionModel
from manus.config import ArmConfig
from manus.held import HeldBody
from manus.scene import SceneError, parse_scene, scene_from_setting
from manus.sweep import straight_motion_problem
from manus.validity import checker_for
from schemas.collision import SceneState
from schemas.objects import WorldObject
from schemas.planning import PlanReply, PlanRequest, Trajectory
from schemas.sequencing import StepKind, Task, TaskStep
from services.sequencer.fold_step import FOLD_END
from services.sequencer.object_stages import ObjectView
from services.sequencer.object_validation import ObjectValidation
from services.sequencer.steps import STEP_TYPES

OBJECT_KINDS = (StepKind.PICK, StepKind.PLACE, StepKind.GIVE)
"""Steps planned as stages (:mod:`services.sequencer.object_validation`)."""


def step_label(step: TaskStep, index: int) -> str:
    """``<where>: step N (kind)`` (N 1-based), the prefix of every message about a step."""
    head = f"{step.where}: " if step.where else ""
    return f"{head}step {index + 1} ({step.kind})"


FoldCheck = Callable[[list[float], list[float], str], str | None]
"""Checks a fold's motion (from, to [rad], step kind): None when clear, else the problem."""


class Validator:
    """Checks a whole task; plans its moves one request at a time.

    Args:
        task: the task.
        start: the arm's configuration now (DH [rad]); None: unknown (no joint state).
        arm: the arm's geometry (named poses become via points by its kinematics).
        fold_check: checks a fold's own motion (from, to [rad], step kind) against the
            scene: None when clear, else the problem (:func:`fold_checker`).

    Use: ``while (req := v.next_request()) is not None: v.on_reply(ask(req))``, with
    ``on_reply(None, error)`` when the planner could not be asked; then :attr:`errors`.
    :attr:`plans` holds each planned step's trajectory (index -> Trajectory).
    """

    def __init__(
        self,
        task: Task,
        start: list[float] | None,
        arm: ArmConfig,
        fold_check: FoldCheck | None = None,
        view: Callable[[], ObjectView] | None = None,
    ) -> None:
        self.task = task
        self._view = view
        self._objects: dict[str, WorldObject] | None = None  # as the steps so far leave them
        self._origins: dict[str, list[float]] = {}  # where the picks so far took them from
        self._object: ObjectValidation | None = None  # the object step being planned
        self.arm = arm
        self._fold_check = fold_check
        self._problems: list[list[str]] = [[] for _ in task.steps]
        self.plans: dict[int, Trajectory] = {}
        self._q: list[float] | None = list(start) if start is not None else None
        self._unknown = "no joint state from the arm yet (is the bridge running?)"
        self._cursor = 0
        self._object_step = -1
        self._asked: int | None = None
        self._planner_down = ""
        if not task.steps:
            self._top = ["the task has no steps"]
        else:
            self._top = []
        for i, step in enumerate(task.steps):
            self._problems[i].extend(STEP_TYPES[step.kind].problems(step))

    @property
    def errors(self) -> list[str]:
        """Every problem found, in step order, each with its location."""
        out = list(self._top)
        for i, problems in enumerate(self._problems):
            label = step_label(self.task.steps[i], i)
            out.extend(f"{label}: {p}" for p in problems)
        return out

    def next_request(self) -> PlanRequest | None:
        """The next plan to ask for (None: validation is complete)."""
        assert self._asked is None, "on_reply() must answer the previous request first"
        steps = self.task.steps
        if self._object is not None:
            request = self._object_request()
            if request is not None:
                return request
        while self._cursor < len(steps):
            i = self._cursor
            step = steps[i]
            self._cursor += 1
            kind = STEP_TYPES[step.kind]
            end = kind.leaves_arm_at(step)
            if end is not None:
                if self._q is not None and self._fold_check is not None:
                    problem = self._fold_check(self._q, end, step.kind)
                    if problem is not None:
                        self._problems[i].append(problem)
                self._q = end
                continue
            if not kind.planned and step.kind not in OBJECT_KINDS:
                continue
            if self._problems[i]:
                self._q, self._unknown = None, f"step {i + 1} is invalid"
                continue
            if self._planner_down:
                self._problems[i].append(f"not planned: {self._planner_down}")
                continue
            if self._q is None:
                self._problems[i].append(f"not planned: its start is unknown ({self._unknown})")
                continue
            if step.kind in OBJECT_KINDS:
                request = self._begin_object(i, step)
                if request is not None:
                    return request
                continue
            self._asked = i
            return kind.plan(step, self._q, self.arm)
        return None

    def _begin_object(self, i: int, step: TaskStep) -> PlanRequest | None:
        """Start planning the object step ``i`` (its first request, or None: done)."""
        if self._view is None:
            self._problems[i].append("not planned: no world model of objects here")
            self._q, self._unknown = None, f"step {i + 1} could not be planned"
            return None
        view = self._view()
        held_now = frozenset(o.id for o in view.objects.values() if o.link)
        if self._objects is None:
            self._objects = dict(view.objects)
        assert self._q is not None
        view = dataclasses.replace(view, objects=self._objects, origins=self._origins)
        self._object = ObjectValidation(step, view, np.array(self._q), held_now)
        self._object_step = i
        return self._object_request()

    def _object_request(self) -> PlanRequest | None:
        """The object step's next request; at its end, its problems and where it leaves
        the arm and the objects."""
        planning = self._object
        assert planning is not None
        i = self._object_step
        request = planning.next_request()
        if request is not None:
            self._asked = i
            return request
        self._object = None
        if planning.problems:
            self._problems[i].extend(planning.problems)
            self._q, self._unknown = None, f"step {i + 1} could not be planned"
        else:
            self._q = [float(v) for v in planning.q]
            self._objects = planning.objects
        return None

    def on_reply(self, reply: PlanReply | None, error: str = "") -> None:
        """The planner's answer to the last request (None with ``error``: no answer)."""
        assert self._asked is not None, "no request is waiting for a reply"
        i, self._asked = self._asked, None
        if self._object is not None:
            self._object.on_reply(reply, error)
            return
        if reply is None:
            self._planner_down = error or "the planner did not answer"
            self._problems[i].append(f"cannot plan: {self._planner_down}")
            self._q, self._unknown = None, f"step {i + 1} could not be planned"
            return
        if not reply.ok or reply.trajectory is None:
            message = reply.error.message if reply.error is not None else "no trajectory"
            reason = reply.error.reason if reply.error is not None else "invalid"
            self._problems[i].append(f"planner refused ({reason}): {message}")
            if self._q is not None and _near(self._q, FOLD_END[StepKind.FOLD_IN]):
                self._problems[i].append(
                    "the arm is folded there: unfold it first (a fold_out step; "
                    "`manus run --fold-out ...` for the thesis form)"
                )
            self._q, self._unknown = None, f"step {i + 1} could not be planned"
            return
        self.plans[i] = reply.trajectory
        self._q = list(reply.trajectory.positions[-1])


class FoldChecker:
    """A :data:`FoldCheck` against a collision model: the scene, and what the arm holds.

    Args:
        model: the collision model.
    """

    def __init__(self, model: CollisionModel) -> None:
        self.model = model
        checker_for(model)  # the sweep's fast check: built (and compiled) now, not mid-task

    def __call__(self, q_from: list[float], q_to: list[float], kind: str) -> str | None:
        return straight_motion_problem(
            self.model, np.asarray(q_from), np.asarray(q_to), f"{kind.replace('_', ' ')}"
        )

    def holding(self, held: Sequence[HeldBody]) -> FoldChecker:
        """The same check with the arm holding ``held`` (the world model's attached
        objects)."""
        return FoldChecker(self.model.holding(held))


def fold_checker(scene: str, arm: ArmConfig) -> FoldChecker | None:
    """The ``fold_check`` of a :class:`Validator` for the scene setting ``scene``
    (``default``, ``none`` or a file; None when ``none``).

    Raises:
        SceneError: the scene file is malformed.
    """
    loaded = scene_from_setting(scene)
    if loaded is None:
        return None
    return FoldChecker(CollisionModel(loaded, arm))


def scene_fold_checker(
    state: SceneState, arm: ArmConfig, held: Sequence[HeldBody] = ()
) -> FoldChecker | None:
    """The ``fold_check`` for a scene the planner published, the arm holding ``held``
    (None: it does not build)."""
    try:
        scene = dataclasses.replace(parse_scene(state.text, state.source), version=state.version)
        model = CollisionModel(scene, arm, held=held)
    except SceneError:
        return None
    return FoldChecker(model)


def _near(q: list[float], ref: list[float], tol_deg: float = 5.0) -> bool:
    """Every joint of ``q`` within ``tol_deg`` of ``ref``."""
    return all(abs(a - b) <= math.radians(tol_deg) for a, b in zip(q, ref, strict=True))
