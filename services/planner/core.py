"""The planner's deterministic core: a path of via points -> a joint trajectory.

Steps (docs/protocol.md, Thesis planning steps):

1. validate the path (the via-point file rules, :func:`manus.viapoints.validate_path`);
2. take the start configuration (the request's, else the newest valid joint state),
   check it, and replace via point 0 by its gripper pose (:mod:`.resolve`);
3. solve every via point on the start's IK branch (:mod:`.knots`);
4. turn the first and last Cartesian velocities into joint velocities (Jacobian);
5. interpolate: clamped cubic spline (docs/protocol.md, Thesis interpolation), or quintic
   segments with the same knot velocities, continuous accelerations and zero acceleration at
   both ends (:mod:`.spline`);
6. check joint limits, the wrist singularity and the IK branch along the whole curve,
   then joint speeds and accelerations, stretching time if asked (:mod:`.checks`);
7. sweep the final curve through the collision model: the scene, the protection zones
   and the arm itself, with each class's clearance (:mod:`.collisions`);
8. reply with the knots (piecewise Hermite), their Cartesian positions and a preview.

No clock, no randomness, no I/O: the same request and joint state give the same reply.
Trajectory time 0 is the first via point (the start configuration); knot i is via
point i and is reached at ``times[i]`` (the file's time, times ``time_scale``).
"""

from __future__ import annotations

import dataclasses
import math
import threading
from typing import Any

import numpy as np

from manus.collision import CollisionModel
from manus.kinematics import branch_of, fk_batch
from manus.scene import Scene, SceneError, parse_scene, scene_from_setting, start_scene_state
from manus.viapoints import ViaPointError, validate_path
from manus.world import WorldModel
from schemas.collision import SceneReply, SceneState, SceneUpdate
from schemas.planning import PlanReply, PlanRequest, Trajectory
from schemas.state import JointState
from services.planner.checks import check_geometry, check_rates
from services.planner.collisions import check_collisions
from services.planner.config import PlannerConfig
from services.planner.errors import PlanningError, refuse
from services.planner.knots import check_start, solve_knots
from services.planner.resolve import boundary_joint_velocity, resolve_path
from services.planner.spline import (
    PiecewisePolynomial,
    clamped_cubic_velocities,
    quintic_knot_accelerations,
)

QUINTIC_NOTE = (
    "quintic: knot velocities of the clamped cubic spline, accelerations continuous at the "
    "interior via points and zero at both ends"
)


class PlannerCore:
    """Plans trajectories; remembers only the newest valid joint state.

    Args:
        config: arm model and planning margins.
    """

    def __init__(self, config: PlannerConfig | None = None) -> None:
        self.config = config or PlannerConfig()
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
        self.set_scene(scene_from_setting(self.config.scene))
        self.scene_state = start_scene_state(self.config.scene)

    def set_scene(self, scene: Scene | None) -> None:
        """Check every later plan against ``scene`` (None: no collision check)."""
        model = None if scene is None else CollisionModel(scene, self.config.arm)
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
            model = CollisionModel(scene, self.config.arm)
        except SceneError as exc:
            return SceneReply(accepted=False, version=version, error=str(exc))
        with self.checking:
            self.collision = model
        self.scene_state = SceneState(version=scene.version, text=update.text, source=scene.source)
        return SceneReply(accepted=True, version=scene.version)

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
            request: the path and options.
            latest: joint state to start from when the request gives no start (None:
                the newest valid one passed to :meth:`on_joint_state`).

        Returns:
            ``ok`` with the trajectory, or not ``ok`` with a :class:`PlanError` naming the
            via point, line, joint, value and limit. ``compute_ms`` is left 0 (the core
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
            return np.array(request.start, dtype=float)
        js = latest if latest is not None else self.latest
        if js is None:
            raise refuse(
                "no_state",
                "no start configuration: the request gives none and no valid joint state "
                "has been received (is the bridge running?)",
            )
        if not js.valid:
            raise refuse("no_state", f"the joint state (seq {js.seq}) is not valid")
        return np.array(js.position, dtype=float)

    def _plan(self, request: PlanRequest, q_start: np.ndarray) -> Trajectory:
        config, path = self.config, request.path
        if len(q_start) != 6 or not np.isfinite(q_start).all():
            raise refuse("invalid", f"start configuration must be 6 finite angles, got {q_start}")
        try:
            validate_path(path)
        except ViaPointError as exc:
            raise refuse("parse", str(exc), via_point=exc.via_point, line=exc.line) from exc
        check_start(q_start, path, config)
        resolved = resolve_path(path, q_start, config.arm)
        knots = solve_knots(path, resolved.poses, q_start, config)
        times = np.array([vp.time for vp in path.via_points])
        ends = ((0, path.via_points[0]), (len(knots) - 1, path.via_points[-1]))
        v_first, v_last = (
            boundary_joint_velocity(vp, i, knots[i], resolved.ypr[i], config.arm, path.source)
            for i, vp in ends
        )
        velocities = clamped_cubic_velocities(times, knots, v_first, v_last)
        notes: list[str] = []
        accelerations: np.ndarray | None = None
        if request.interpolation == "quintic":
            accelerations = quintic_knot_accelerations(times, knots, velocities)
            notes.append(QUINTIC_NOTE)
        curve = PiecewisePolynomial.hermite(times, knots, velocities, accelerations)
        check_geometry(curve, path, branch_of(q_start, config.arm), config)
        rates = check_rates(curve, path, config, speed_scaling=request.speed_scaling)
        notes.extend(rates.notes)
        clearance, version = None, -1
        with self.checking:
            if self.collision is not None:
                clearance = check_collisions(self.collision, rates.curve, path)
                version = self.collision.scene.version if self.collision.scene else -1
        k = rates.time_scale
        duration = rates.curve.duration
        preview_dt = 0.0
        preview_t: np.ndarray = np.zeros(0)
        if request.preview_dt > 0.0:
            preview_dt = max(request.preview_dt, duration / (config.max_preview_points - 1))
            preview_t = np.arange(math.floor(duration / preview_dt) + 1) * preview_dt
            if duration - preview_t[-1] > 1e-9:
                preview_t = np.append(preview_t, duration)
        # One FK call for the knots and the preview.
        xyz = fk_batch(np.vstack([knots, rates.curve.evaluate(preview_t)]), config.arm)[:, :3, 3]
        via_xyz, preview_xyz = xyz[: len(knots)], xyz[len(knots) :]
        return Trajectory(
            times=_rows(times * k),
            positions=_rows(knots),
            velocities=_rows(velocities / k),
            accelerations=[] if accelerations is None else _rows(accelerations / (k * k)),
            via_xyz=_rows(via_xyz),
            via_lines=[vp.line for vp in path.via_points],
            preview_xyz=_rows(preview_xyz),
            preview_dt=preview_dt,
            time_scale=k,
            notes=notes,
            clearance=clearance,
            scene_version=version,
        )


def _rows(a: np.ndarray) -> list[Any]:
    """Plain floats for the message (a list, or a list of rows)."""
    out: list[Any] = np.asarray(a, dtype=float).tolist()
    return out
