"""The controller's collision guard as its core uses it: per joint state, the smallest
clearance of each goal while it runs, and one guard per scene (:class:`Guard` is the
per-cycle check itself)."""

from __future__ import annotations

import dataclasses
import math
import weakref
from collections.abc import Mapping, Sequence

import numpy as np

from manus.collision import CollisionModel
from manus.config import ArmConfig
from manus.held import HeldBody
from manus.scene import Scene, SceneError, parse_scene, scene_from_setting
from schemas.collision import ClearanceReport, SceneState
from schemas.state import JointState
from services.controller.guard import OPENING_M, Guard, Verdict

_NOTHING = (0.0,) * 6
"""The DH velocities in flight when the frame in flight is not a joint move [rad/s]."""


class RunGuard:
    """The :class:`Guard` as the controller core uses it: per joint state, and the
    smallest clearance of each goal while it runs.

    Args:
        guard: the guard.
    """

    def __init__(self, guard: Guard) -> None:
        self.guard = guard
        self.lowest: dict[str, ClearanceReport] = {}

    def command(self, js: JointState, counts: np.ndarray, goal_id: str) -> Verdict:
        """Guard the command answering ``js`` for goal ``goal_id`` ("" : none)."""
        applied = js.applied_velocity if js.applied_kind == "joint" else _NOTHING
        low = self.lowest.get(goal_id)
        # Only a clearance below the goal's smallest so far is worth Coal's time.
        self.guard.report_below = (
            -math.inf if not goal_id else math.inf if low is None else low.distance - low.required
        )
        verdict = self.guard.filter(js.position, applied, counts, js.gripper)
        found = verdict.clearance
        if (goal_id and found is not None) and (
            low is None or found.distance - found.check.required < low.distance - low.required
        ):
            self.lowest[goal_id] = dataclasses.replace(found.report(), time=js.stamp_ns / 1e9)
        return verdict

    def prepare(self, js: JointState) -> None:
        """Build now what a command answering a state like ``js`` would build in its cycle
        (the fast check for a new gripper opening, about 1 ms): a source was admitted."""
        g = self.guard
        if abs(g.model.opening - js.gripper) > OPENING_M:
            g.advance.checker.prepare(js.gripper)

    def move_object(self, name: str, pose: np.ndarray) -> None:
        """Place the scene object ``name`` at ``pose`` (4x4, chair frame).

        Raises:
            SceneError: no such object.
        """
        self.guard.object_moved(self.guard.model.move_object(name, pose))

    def result(self, goal_id: str) -> ClearanceReport | None:
        """The smallest clearance of the goal (forgotten once read)."""
        return self.lowest.pop(goal_id, None)

    def hold(self, held: Sequence[HeldBody]) -> None:
        """Keep ``held`` (the objects the arm holds) clear too, from the next command on:
        the same guard on the model that carries them (nothing it proved holds for it)."""
        g = self.guard
        model = g.model.holding(held)
        self.guard = Guard(model, cycle_s=g.cycle_s, runout_s=g.runout_s, slow_zone_m=g.slow_zone_m)


def scene_guard(
    state: SceneState,
    arm: ArmConfig,
    held: Sequence[HeldBody] = (),
    moved: Mapping[str, np.ndarray] | None = None,
) -> RunGuard | None:
    """The guard for a scene published by the planner, the arm holding ``held``, its
    objects of ``moved`` where a tracker last put them (name -> pose, 4x4, chair frame;
    one the scene does not have is left out) (None: it does not build)."""
    try:
        scene = parse_scene(state.text, state.source)
        scene = dataclasses.replace(scene, version=state.version)
    except SceneError:
        return None
    names = {o.name for o in scene.objects}
    there = {name: pose for name, pose in (moved or {}).items() if name in names}
    try:
        return RunGuard(Guard(CollisionModel(scene, arm, held=held, moved=there)))
    except SceneError:
        return None


def run_guard(scene: str, arm: ArmConfig) -> RunGuard | None:
    """The guard for a scene setting (``default``, ``none`` or a file; None: no guard).

    Its collision model is one a guard of the same scene and arm left unchanged (its
    objects where the scene puts them) when there is one: building a model is most of a
    core's start (5 ms), and a process (a replay check, a benchmark, lock-step runs)
    starts many cores. Distances do not depend on what was asked before (Coal starts
    each query afresh, :func:`manus.shapes.fresh_guesses`), so the model used again
    answers as a new one would; its gripper opening is set back to the built one's.
    """
    loaded = scene_from_setting(scene)
    if loaded is None:
        return None
    guard = Guard(_spare_model(loaded, arm))
    weakref.finalize(guard, _give_back, loaded, arm, guard.model)
    return RunGuard(guard)


_SPARE: dict[tuple[int, ArmConfig], tuple[Scene, list[CollisionModel]]] = {}
"""Per scene (a loaded file's, shared by the process: :func:`manus.scene.load_scene`)
and arm: the models of guards that are gone, as they were built."""


def _spare_model(scene: Scene, arm: ArmConfig) -> CollisionModel:
    """A model of ``scene`` and ``arm`` no guard uses, or a new one."""
    entry = _SPARE.get((id(scene), arm))
    try:
        model = entry[1].pop() if entry is not None and entry[0] is scene else None
    except IndexError:  # none left
        model = None
    if model is None:
        return CollisionModel(scene, arm)
    model.set_opening(arm.gripper_max)  # as built (the fast check follows it)
    return model


def _give_back(scene: Scene, arm: ArmConfig, model: CollisionModel) -> None:
    """Keep ``model`` (its guard is gone) for the next guard of ``scene`` and ``arm``,
    unless something in it changed that a new model would not have (a moved object)."""
    if model.moved.version != 0 or model.held:
        return
    key = (id(scene), arm)
    entry = _SPARE.get(key)
    if entry is None or entry[0] is not scene:
        entry = _SPARE[key] = (scene, [])
    entry[1].append(model)
