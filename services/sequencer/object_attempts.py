"""The candidates of an object step and the stages of the one being tried: the grasps of
a pick (preferred first), the gripper's yaws at a place or a hand-over
(:data:`.carry_stages.PLACE_TURNS_DEG`, :data:`.carry_stages.GIVE_TURNS_DEG`). Shared by
the running step (:mod:`.object_step`) and the validation (:mod:`.object_validation`), so
both try the same candidates in the same order and name the same reasons.
"""

from __future__ import annotations

import numpy as np

from schemas.objects import WorldObject
from schemas.sequencing import StepKind, TaskStep
from services.sequencer.carry_stages import (
    GIVE_TURNS_DEG,
    PLACE_TURNS_DEG,
    SYMMETRIC,
    give_stages,
    held_object,
    place_stages,
)
from services.sequencer.object_stages import (
    ObjectProblem,
    ObjectView,
    PickPlan,
    Stage,
    pick_plan,
)
from services.sequencer.pick_stages import pick_stages

OUT_OF_REACH = ("unreachable", "joint_limit", "singular", "zone")
"""The planner's reasons that mean a grasp is beyond what the arm may reach (``zone``:
outside the keep-in zone of its work space)."""


def origin(obj: WorldObject) -> list[float]:
    """Where a pick takes ``obj`` from, to put it back (``ObjectView.origins``): its centre
    and its yaw, upright (x, y, z [m], yaw, 0, 0 [rad])."""
    return [*(float(v) for v in obj.xyz), float(obj.ypr[0]), 0.0, 0.0]


class Attempts:
    """The candidates of one object step (see the module docstring).

    Args:
        spec: the step.
        view: what the sequencer knows now.
        q: the arm's configuration when the step begins [rad].

    Raises:
        ObjectProblem: the step cannot be done at all (unknown object, not held, ...).
    """

    def __init__(self, spec: TaskStep, view: ObjectView, q: np.ndarray) -> None:
        self.spec = spec
        self.view = view
        self.q = q
        self.pick: PickPlan | None = None
        self.held: WorldObject | None = None
        self.index = 0
        self.refusals: list[str] = []
        self.turns: tuple[float, ...] = ()  # a place's or give's candidate yaws [deg]
        self.margin = view.config.margin_m
        """The clearance to spare a plan must keep (``pick.margin_m``; once every
        candidate was too tight for it, ``pick.min_margin_m``) [m]."""
        if spec.kind == StepKind.PICK:
            self.pick = pick_plan(view, spec.object)
            self.labels = [g.label for g in self.pick.grasps]
        else:
            self.held = held_object(view, spec.object)
            if spec.kind == StepKind.GIVE:
                # A hand-over pose of the task's own is where it is asked for: no other yaw.
                self.turns = GIVE_TURNS_DEG if spec.at is None else (0.0,)
            elif self.held.shape in SYMMETRIC:
                self.turns = PLACE_TURNS_DEG
            else:
                self.turns = (0.0,)
            self.labels = [f"yaw {t:+.0f} deg" for t in self.turns]
        self.stages = self._stages()

    @property
    def object(self) -> WorldObject:
        """The object (as last seen, or as held)."""
        if self.pick is not None:
            return self.pick.obj
        assert self.held is not None
        return self.held

    def _stages(self) -> list[Stage]:
        spec, view = self.spec, self.view
        if self.pick is not None:
            return pick_stages(self.pick, self.pick.grasps[self.index], view)
        assert self.held is not None
        turn = self.turns[self.index]
        if spec.kind == StepKind.PLACE:
            at = self._origin() if spec.back else spec.at
            return place_stages(view, self.held, self.q, at, spec.surface, turn)
        return give_stages(view, self.held, self.q, turn, spec.at)

    def _origin(self) -> list[float]:
        """Where this task's pick took the object from (a place ``back``)."""
        found = self.view.origins.get(self.spec.object)
        if found is None:
            raise ObjectProblem(
                f"object {self.spec.object!r} cannot be put back: no pick of this task took "
                "it (a place back needs a pick step before it)"
            )
        return found

    def refused(self, stage: Stage, reason: str, why: str) -> str:
        """A plan of ``stage`` of the candidate being tried was refused (``reason``, the
        planner's word or ``tight`` / ``tilt``; ``why``, in words): the next candidate's
        stages become :attr:`stages` (''), or, none left, why the step cannot be done."""
        self.refusals.append(f"{self.labels[self.index]}: {stage.label}: {reason}")
        self.index += 1
        if self.index < len(self.labels):
            self.stages = self._stages()
            return ""
        tight = any(r.endswith(": tight") for r in self.refusals)
        if tight and self.margin > self.view.config.min_margin_m:
            # Every candidate too tight for the margin: once more, with the least one.
            self.margin = self.view.config.min_margin_m
            self.index = 0
            self.refusals.append(f"again with {self.margin * 1e3:.0f} mm to spare")
            self.stages = self._stages()
            return ""
        obj = self.object
        tried = "; ".join(self.refusals)
        if self.pick is None:
            return (
                f"object {obj.id!r} ({obj.cls}) cannot be {self.spec.kind}d: every way tried "
                f"was refused ({tried}); last: {why}"
            )
        if all(r.endswith(OUT_OF_REACH) for r in self.refusals):
            return (
                f"object {obj.id!r} ({obj.cls}) is out of reach: every grasp tried ({tried}); "
                f"last: {why}"
            )
        return (
            f"every grasp pose of object {obj.id!r} ({obj.cls}) collides, has no path or is "
            f"too tight ({tried}); last: {why}"
        )


def attempts(spec: TaskStep, view: ObjectView, q: np.ndarray) -> Attempts | str:
    """The :class:`Attempts` of ``spec``, or why it cannot be done at all."""
    try:
        return Attempts(spec, view, q)
    except ObjectProblem as exc:
        return str(exc)
