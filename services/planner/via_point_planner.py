"""The via-point planners: a path's, the thesis's pipeline (docs/protocol.md, Thesis
planning steps), and a running path's continuation, behind
:class:`~services.planner.planner.Planner`.

A whole path (:meth:`ViaPointPlanner.route` without ``resume``):

1. validate the path (the via-point file rules, :func:`manus.viapoints.validate_path`);
2. check the start configuration and replace via point 0 by its gripper pose
   (:mod:`.resolve`);
3. solve every via point on the start's IK branch (:mod:`.knots`);
4. turn the first and last Cartesian velocities into joint velocities (Jacobian);
5. interpolate: clamped cubic spline (docs/protocol.md, Thesis interpolation), or quintic
   segments with the same knot velocities, continuous accelerations and zero acceleration
   at both ends (:mod:`.spline`);
6. check joint limits, the wrist singularity and the IK branch along the whole curve
   (:func:`~services.planner.checks.check_geometry`).

The speed limits, the collision sweep and the trajectory are the shared stages of
:meth:`Planner.plan <services.planner.planner.Planner.plan>`. Knot i is via point i and is
reached at the file's time (times ``time_scale``).

The rest of a paused plan (with ``resume``): the via points of the paused trajectory not
reached yet, in order, each at its planned configuration's gripper pose, solved again on
the branch of where the arm is now, timed at the plan's pace from the time reached plus
:attr:`~services.planner.config.PlannerConfig.resume_lead_s` (the arm starts from rest),
ending as the plan ended (its last joint velocity, as a twist), then steps 3 to 6 as
above, always allowed to stretch time. Knot 0 is the start (no via point); each other knot
keeps its via point's index and line in the path.

A continuation (:class:`ContinuationPlanner`, streamed via points: docs/follow.md,
Streamed via points): steps 1 to 6 as a path's, but the first knot moves at the joint
velocities the request gives (the running reference's: position and velocity continue
across the splice, no Jacobian's round trip), and time is never stretched (its knots keep
the path's clock; one the limits do not allow is refused). Knot 0 is the start (no via
point); knot i is the streamed path's via point ``first_index + i - 1``.
"""

from __future__ import annotations

from typing import TypeVar

import numpy as np

from manus.kinematics import branch_of, fk_batch, jacobian
from manus.viapoints import ViaPointError, validate_path
from schemas.planning import (
    Interpolation,
    KnotKind,
    PlanResume,
    Trajectory,
    ViaPointContinuation,
    ViaPointPath,
)
from services.planner.checks import check_geometry
from services.planner.errors import refuse
from services.planner.knots import check_start, solve_knots
from services.planner.labels import KnotLabels
from services.planner.planner import Planner, Route, SceneInUse
from services.planner.resolve import boundary_twist, resolve_path, twist_joint_velocity
from services.planner.spline import (
    PiecewisePolynomial,
    clamped_cubic_velocities,
    quintic_knot_accelerations,
)

QUINTIC_NOTE = (
    "quintic: knot velocities of the clamped cubic spline, accelerations continuous at the "
    "interior via points and zero at both ends"
)


P = TypeVar("P", bound=ViaPointPath | ViaPointContinuation)


class _ViaPoints(Planner[P]):
    """What the via-point kinds share: the rest of a paused plan, and steps 3 to 6."""

    def _rest(self, motion: P, start: np.ndarray, resume: PlanResume) -> Route:
        """What is left of the paused plan ``resume``, from ``start``."""
        traj, reached = resume.trajectory, resume.reached
        source = f"{motion.path.source or 'the path'} (resumed at t = {reached:.2f} s)"
        _check_paused(traj, source)
        rest = [
            j
            for j in range(len(traj.times))
            if traj.knot_kind(j) == KnotKind.VIA_POINT and traj.times[j] > reached + 1e-9
        ]
        if not rest:
            raise refuse(
                "invalid",
                f"{source}: nothing is left to plan: the paused plan had reached every via "
                f"point by t = {reached:.3f} s",
            )
        lines = traj.via_lines or [0] * len(traj.times)
        labels = KnotLabels(
            source=source,
            kinds=(KnotKind.START, *(KnotKind.VIA_POINT,) * len(rest)),
            via_indices=(-1, *(traj.via_index(j) for j in rest)),
            lines=(0, *(lines[j] for j in rest)),
        )
        check_start(start, labels, self.config)
        planned = np.asarray(traj.positions, dtype=float)[rest]
        poses = fk_batch(np.vstack([start, planned]), self.config.arm)
        lead = self.config.resume_lead_s
        times = np.array([0.0, *(traj.times[j] - reached + lead for j in rest)])
        end_twist = np.zeros(6)
        if rest[-1] == len(traj.times) - 1:  # the plan's own end: end as it did
            end_twist = jacobian(planned[-1], self.config.arm) @ np.asarray(traj.velocities[-1])
        twists = np.zeros(6), end_twist
        return self._through(
            poses, times, twists, labels, start, motion.interpolation, speed_scaling=True
        )

    def _through(
        self,
        poses: np.ndarray,
        times: np.ndarray,
        twists: tuple[np.ndarray, np.ndarray],
        labels: KnotLabels,
        start: np.ndarray,
        interpolation: str,
        speed_scaling: bool,
        start_velocity: np.ndarray | None = None,
    ) -> Route:
        """Steps 3 to 6: the knots of ``poses`` (row 0: the start's) at ``times`` [s], the
        first and last knots moving at ``twists`` (shape (6,) each); the first at
        ``start_velocity`` [rad/s] (6,) instead when given (a moving start)."""
        arm = self.config.arm
        knots = solve_knots(labels, poses, start, self.config)
        v_first = (
            twist_joint_velocity(twists[0], knots[0], arm, labels, 0)
            if start_velocity is None
            else start_velocity
        )
        v_last = twist_joint_velocity(twists[1], knots[-1], arm, labels, len(knots) - 1)
        velocities = clamped_cubic_velocities(times, knots, v_first, v_last)
        notes: list[str] = []
        accelerations: np.ndarray | None = None
        if interpolation == Interpolation.QUINTIC:
            accelerations = quintic_knot_accelerations(times, knots, velocities)
            notes.append(QUINTIC_NOTE)
        curve = PiecewisePolynomial.hermite(times, knots, velocities, accelerations)
        check_geometry(curve, labels, branch_of(start, arm), self.config)
        return Route(times, knots, velocities, accelerations, curve, labels, speed_scaling, notes)


class ViaPointPlanner(_ViaPoints[ViaPointPath]):
    """Plans a :class:`~schemas.planning.ViaPointPath` (see the module docstring)."""

    def route(
        self,
        motion: ViaPointPath,
        start: np.ndarray,
        resume: PlanResume | None,
        scene: SceneInUse,
    ) -> Route:
        if resume is not None:
            return self._rest(motion, start, resume)
        path = motion.path
        try:
            validate_path(path)
        except ViaPointError as exc:
            raise refuse("parse", str(exc), via_point=exc.via_point, line=exc.line) from exc
        labels = KnotLabels.of_path(path)
        check_start(start, labels, self.config)
        resolved = resolve_path(path, start, self.config.arm)
        first, last = path.via_points[0], path.via_points[-1]
        twists = boundary_twist(first, resolved.ypr[0]), boundary_twist(last, resolved.ypr[-1])
        times = np.array([vp.time for vp in path.via_points])
        return self._through(
            resolved.poses, times, twists, labels, start, motion.interpolation,
            motion.speed_scaling,
        )  # fmt: skip


class ContinuationPlanner(_ViaPoints[ViaPointContinuation]):
    """Plans a :class:`~schemas.planning.ViaPointContinuation`: steps 1 to 6 as a path's,
    from the running reference's state (``start`` and the motion's joint ``velocity``, no
    Jacobian on the way), never stretched in time (the path's clock)."""

    def route(
        self,
        motion: ViaPointContinuation,
        start: np.ndarray,
        resume: PlanResume | None,
        scene: SceneInUse,
    ) -> Route:
        if resume is not None:
            return self._rest(motion, start, resume)
        path = motion.path
        try:
            validate_path(path)
        except ViaPointError as exc:
            raise refuse("parse", str(exc), via_point=exc.via_point, line=exc.line) from exc
        n = len(path.via_points)
        labels = KnotLabels(
            source=path.source,
            kinds=(KnotKind.START, *(KnotKind.VIA_POINT,) * (n - 1)),
            via_indices=(-1, *range(motion.first_index, motion.first_index + n - 1)),
            lines=(0, *(vp.line for vp in path.via_points[1:])),
        )
        check_start(start, labels, self.config)
        resolved = resolve_path(path, start, self.config.arm)
        last = path.via_points[-1]
        twists = np.zeros(6), boundary_twist(last, resolved.ypr[-1])
        times = np.array([vp.time for vp in path.via_points])
        return self._through(
            resolved.poses, times, twists, labels, start, motion.interpolation,
            speed_scaling=False, start_velocity=np.asarray(motion.velocity, dtype=float),
        )  # fmt: skip


def _check_paused(traj: Trajectory, source: str) -> None:
    """Refuse a paused trajectory whose times do not increase or whose per-knot lists do
    not match its times."""
    n = len(traj.times)
    if n < 2 or traj.times[0] != 0.0 or not all(np.diff(traj.times) > 0.0):
        raise refuse(
            "invalid",
            f"{source}: the paused trajectory's knot times must start at 0 and increase, "
            f"got {traj.times[:4]}{' ...' if n > 4 else ''}",
        )
    sizes = {
        "positions": len(traj.positions),
        "velocities": len(traj.velocities),
        "knot_kinds": len(traj.knot_kinds) or n,
        "via_indices": len(traj.via_indices) or n,
        "via_lines": len(traj.via_lines) or n,
    }
    wrong = {name: size for name, size in sizes.items() if size != n}
    rows = {len(row) for row in (*traj.positions, *traj.velocities)}
    if wrong or rows - {6}:
        raise refuse(
            "invalid",
            f"{source}: the paused trajectory is malformed: {n} knot times, but "
            f"{wrong or sizes} per-knot entries and rows of {sorted(rows)} values "
            "(6 expected)",
        )
