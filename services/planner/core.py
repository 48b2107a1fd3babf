"""The planner's deterministic core: a plan request -> a joint trajectory.

It keeps what every kind of motion shares: the start configuration (the request's, else
the newest valid joint state), the scene every plan is checked against (replaced at run
time by ``planner/scene``, announced on ``planner/scene_state``), the world model of
objects (``perception/objects`` in, ``planner/objects`` out; an object attached to the
gripper by ``planner/attach`` is part of the arm in every check from then on), and the
planner of each kind of motion (:data:`services.planner.registry.PLANNERS`; the interface:
:mod:`services.planner.planner`), to which it hands the request.

No clock, no randomness, no I/O: the same request and joint state give the same reply.
Trajectory time 0 is the start configuration.
"""

from __future__ import annotations

import dataclasses
import threading
from typing import Any

import numpy as np

from manus.collision import CollisionModel
from manus.held import HeldBody, held_bodies
from manus.scene import Scene, SceneError, parse_scene, scene_from_setting, start_scene_state
from manus.validity import checker_for
from manus.world import WorldModel
from schemas.collision import SceneReply, SceneState, SceneUpdate
from schemas.motion import Motion
from schemas.objects import AttachReply, AttachRequest, WorldUpdate
from schemas.planning import PlanReply, PlanRequest, Trajectory
from schemas.state import JointState
from services.planner import attach
from services.planner.config import PlannerConfig
from services.planner.errors import PlanningError, refuse
from services.planner.planner import Planner
from services.planner.registry import PLANNERS


class PlannerCore:
    """Plans trajectories; remembers only the newest valid joint state.

    Args:
        config: arm model and planning margins.
    """

    def __init__(self, config: PlannerConfig | None = None) -> None:
        self.config = config or PlannerConfig()
        self.planners: dict[type[Motion], Planner[Any]] = {
            kind: planner(self.config) for kind, planner in PLANNERS.items()
        }
        """The planner of each kind of motion."""
        self.latest: JointState | None = None
        self.collision: CollisionModel | None = None
        self.scene_state: SceneState | None = None
        """The scene in use, as published (None: no scene, no collision check)."""
        self._announced_ns: int | None = None  # stamp of the joint state it last went out at
        self.checking = threading.Lock()
        """Held while the collision model is used or replaced: its Pinocchio data is
        scratch space shared by every check (a live shell plans on several threads)."""
        self.world = WorldModel(self.config.world)
        """The objects perception reports (``perception/objects`` -> ``planner/objects``)."""
        self.held: tuple[HeldBody, ...] = ()
        """The objects attached to the gripper: bodies of the arm in every check."""
        self.set_scene(scene_from_setting(self.config.scene))
        self.scene_state = start_scene_state(self.config.scene)

    def set_scene(self, scene: Scene | None) -> None:
        """Check every later plan against ``scene`` (None: no collision check)."""
        model = None if scene is None else CollisionModel(scene, self.config.arm, held=self.held)
        if model is not None:
            checker_for(model)  # the sweep's fast check: built (and compiled) at start
        with self.checking:
            self.collision = model

    def update_scene(self, update: SceneUpdate) -> SceneReply:
        """Replace the scene (the ``planner/scene`` queryable): validated whole, then
        used from the next plan on with the next version; never raises."""
        current = self.collision.scene if self.collision is not None else None
        version = current.version if current is not None else 0
        if update.base_version not in (-1, version):
            return SceneReply(
                accepted=False,
                version=version,
                error=f"the update replaces scene version {update.base_version}, but scene "
                f"version {version} is in use: read it again",
            )
        try:
            scene = parse_scene(update.text, update.source or "<scene update>")
            scene = dataclasses.replace(scene, version=version + 1)
            model = CollisionModel(scene, self.config.arm, held=self.held)
            checker_for(model)
        except SceneError as exc:
            return SceneReply(accepted=False, version=version, error=str(exc))
        with self.checking:
            if model.held != self.held:  # an attach while it was built
                model = model.holding(self.held)
                checker_for(model)
            self.collision = model
        self.scene_state = SceneState(version=scene.version, text=update.text, source=scene.source)
        return SceneReply(accepted=True, version=scene.version)

    def attach(self, request: AttachRequest) -> tuple[AttachReply, list[WorldUpdate]]:
        """Attach an object to the gripper or detach it (``planner/attach``,
        :mod:`services.planner.attach`): the reply and the world model's updates; the
        collision model carries what the arm holds from the next plan on. Never raises."""
        scene = self.collision.scene if self.collision is not None else None
        mount = scene.mount if scene is not None else np.eye(4)
        names = [o.name for o in scene.objects] if scene is not None else []
        reply, updates = attach.answer(self.world, request, mount, self.config.arm, names)
        held = held_bodies(self.world.objects.values())
        if held != self.held:
            with self.checking:  # a scene update (another thread, live) sees one or the other
                self.held = held
                if self.collision is not None:
                    self.collision = self.collision.holding(held)
                    checker_for(self.collision)
        return reply, updates

    def on_joint_state(self, js: JointState) -> SceneState | None:
        """Remember ``js`` as the default start if it is valid (invalid ones are ignored).

        Returns:
            The scene in use when it is due on ``planner/scene_state`` (at the first joint
            state, then every ``scene_every_ms`` of the joint states' stamps), else None.
        """
        if js.valid:
            self.latest = js
        every_ns = round(self.config.scene_every_ms * 1e6)
        if self.scene_state is None or every_ns <= 0:
            return None
        if self._announced_ns is not None and 0 <= js.stamp_ns - self._announced_ns < every_ns:
            return None  # (a stamp going back: a restarted bridge; announce now)
        self._announced_ns = js.stamp_ns
        return self.scene_state

    def plan(self, request: PlanRequest, latest: JointState | None = None) -> PlanReply:
        """Plan ``request``; never raises for a bad request.

        Args:
            request: the motion and options.
            latest: joint state to start from when the request gives no start (None:
                the newest valid one passed to :meth:`on_joint_state`).

        Returns:
            ``ok`` with the trajectory, or not ``ok`` with a :class:`PlanError` naming the
            via point (or knot), line, joint, value and limit. ``compute_ms`` is left 0 (the core
            has no clock; the shell fills it in).
        """
        q_start: np.ndarray | None = None
        try:
            q_start = self._start(request, latest)
            trajectory = self._plan(request, q_start)
        except PlanningError as exc:
            start = None if q_start is None else [float(v) for v in q_start]
            return PlanReply(ok=False, error=exc.error, start=start)
        return PlanReply(ok=True, trajectory=trajectory, start=[float(v) for v in q_start])

    def _start(self, request: PlanRequest, latest: JointState | None) -> np.ndarray:
        if request.start is not None:
            q = np.array(request.start, dtype=float)
        else:
            js = latest if latest is not None else self.latest
            if js is None:
                raise refuse(
                    "no_state",
                    "no start configuration: the request gives none and no valid joint state "
                    "has been received (is the bridge running?)",
                )
            if not js.valid:
                raise refuse("no_state", f"the joint state (seq {js.seq}) is not valid")
            q = np.array(js.position, dtype=float)
        return q

    def _plan(self, request: PlanRequest, q_start: np.ndarray) -> Trajectory:
        if len(q_start) != 6 or not np.isfinite(q_start).all():
            raise refuse("invalid", f"start configuration must be 6 finite angles, got {q_start}")
        planner = self.planners.get(type(request.motion))
        if planner is None:  # the schema declares only the kinds served: a build of its own
            kind = getattr(request.motion, "kind", type(request.motion).__name__)
            raise refuse("invalid", f"no planner serves motions of kind {kind!r}")
        return planner.plan(
            request.motion,
            q_start,
            resume=request.resume,
            preview_dt=request.preview_dt,
            scene=self,
        )
