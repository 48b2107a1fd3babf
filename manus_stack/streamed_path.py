"""Streamed via points: via points appended to (or replacing the rest of) a running path,
without stopping (docs/follow.md, Streamed via points).

A client (a supervisor; ``manus bench follow``) keeps a :class:`StreamedPath`. The path
starts as any plan does (:meth:`StreamedPath.start`: a ``PlanRequest`` from the arm at
rest). Each time via points arrive (:meth:`StreamedPath.append`, or
:meth:`StreamedPath.replace` for the ones not yet reached), it asks the planner for a
**continuation** (:class:`~schemas.planning.ViaPointContinuation`, a kind of motion of its
own): a plan from the running reference's state at the splice time (its joint angles as
``start``, its joint velocities as the continuation's ``velocity``: the planner's clamped
spline starts with them, so position and velocity are continuous across the splice),
through the via points not yet reached and the new ones, at their times on the path's
one clock, never stretched. Its knots are labelled with the via points' indices in the
whole streamed path (``first_index``). The planner checks the new part as any plan
(limits, the collision sweep), and refuses it the same way (the running path then goes
on to its own end). The
continuation goes to the controller as a ``TrajectoryGoal`` with ``replace`` and
``splice_at`` (the running trajectory's time its time 0 stands for), so its knots keep
the path's clock whenever the controller splices it in, and the controller's splice
blend absorbs what is left (the accelerations).

Times: via point ``time`` is the path's own clock [s] (0: the start of the first plan);
the running trajectory's time 0 is at the path time :attr:`StreamedPath.offset`. The
newest ``ControllerFeedback.t`` of the running goal tells where it is.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from manus.config import ArmConfig
from manus.errors import ManusError
from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from manus.trajectory import JointTrajectory
from schemas.control import TrajectoryGoal
from schemas.planning import (
    Path,
    PlanRequest,
    Trajectory,
    ViaPoint,
    ViaPointContinuation,
    ViaPointPath,
)

SOURCE = "streamed via points"
"""The plans' source (their refusals name it)."""

GAP_S = 0.2
"""A via point closer than this after the splice counts as reached [s]: the continuation
needs room to bend toward the next one."""


class StreamError(ManusError, ValueError):
    """A streamed via point that cannot be taken (the message names it)."""


class StreamedPath:
    """One streamed path (see the module docstring).

    Args:
        arm: the arm's geometry.
        interpolation: the plans' interpolation.
    """

    def __init__(self, arm: ArmConfig, interpolation: str = "cubic") -> None:
        self.arm = arm
        self.interpolation = interpolation
        self.pending: list[ViaPoint] = []
        """Via points not yet reached (absolute, times on the path's clock)."""
        self.running: Trajectory | None = None
        """The trajectory the controller runs (None: none yet)."""
        self.offset = 0.0
        """The path time of the running trajectory's time 0 [s]."""
        self.numbered = 0
        """Via points the path has been given so far (the next one's index is this + 1;
        index 0 is the start)."""
        self._asked: tuple[float, list[ViaPoint], int] | None = None

    def start(self, q: list[float], via_points: list[ViaPoint]) -> PlanRequest:
        """The first plan: from the arm at rest at ``q`` [rad] through ``via_points``
        (absolute; times on the path's clock, the first after 0).

        Raises:
            StreamError: a via point not after the one before it.
        """
        self._check(0.0, via_points)
        rest = self._state_point(np.asarray(q, dtype=float))
        self._asked = (0.0, list(via_points), len(via_points))
        path = Path(via_points=[rest, *via_points], source=SOURCE)
        return PlanRequest(ViaPointPath(path=path, interpolation=self.interpolation), start=q)

    def append(self, via_points: list[ViaPoint], now_s: float) -> PlanRequest:
        """A continuation through the via points not yet reached and ``via_points``,
        spliced at path time ``now_s`` [s].

        Raises:
            StreamError: no running trajectory, or a via point not after the one before it.
        """
        return self._continue(now_s, via_points, keep=True)

    def replace(self, via_points: list[ViaPoint], now_s: float) -> PlanRequest:
        """A continuation through ``via_points`` instead of the ones not yet reached."""
        return self._continue(now_s, via_points, keep=False)

    def accepted(self, trajectory: Trajectory) -> TrajectoryGoal | None:
        """The planner's continuation (or first plan): the goal to send (``goal_id`` to
        be set by the caller), and the path's state updated. None for the first plan (a
        plain goal: the caller sends it without ``replace``)."""
        assert self._asked is not None, "no plan was asked for"
        splice, pending, numbered = self._asked
        self._asked = None
        first = self.running is None
        self.running, self.pending, self.numbered = trajectory, pending, numbered
        if first:
            self.offset = 0.0
            return None
        tau = splice - self.offset
        self.offset = splice
        return TrajectoryGoal(goal_id="", trajectory=trajectory, replace=True, splice_at=tau)

    # -- internals ---------------------------------------------------------------------------

    def _continue(self, now_s: float, new: list[ViaPoint], *, keep: bool) -> PlanRequest:
        if self.running is None:
            raise StreamError("no running path to append to: start() it first")
        splice = now_s
        traj = JointTrajectory(self.running)
        sample = traj.sample(splice - self.offset)
        left = [vp for vp in self.pending if vp.time > splice + GAP_S] if keep else []
        points = left + list(new)
        self._check(splice + GAP_S, points)
        here = self._state_point(sample.q)
        shifted = [dataclasses.replace(vp, time=vp.time - splice) for vp in points]
        numbered = self.numbered + len(new)
        self._asked = (splice, points, numbered)
        motion = ViaPointContinuation(
            path=Path(via_points=[here, *shifted], source=SOURCE),
            velocity=[float(v) for v in sample.qd],
            first_index=numbered - len(points) + 1,
            interpolation=self.interpolation,
        )
        return PlanRequest(motion, start=[float(v) for v in sample.q])

    def _check(self, after_s: float, points: list[ViaPoint]) -> None:
        last = after_s
        for i, vp in enumerate(points):
            if vp.type != 0:
                raise StreamError(f"streamed via point {i}: give it absolute (type 0)")
            if not vp.time > last:
                raise StreamError(
                    f"streamed via point {i} at {vp.time:g} s: not after {last:g} s (the one "
                    f"before it, or the splice plus {GAP_S:g} s)"
                )
            last = vp.time

    def _state_point(self, q: np.ndarray) -> ViaPoint:
        """Via point 0, standing for the reference's state (its pose; the planner puts the
        start there, and the continuation's velocity in joint space)."""
        T = fk(q, self.arm)
        return ViaPoint(
            xyz=[float(v) for v in T[:3, 3]],
            velocity=[0.0, 0.0, 0.0],
            ypr=[float(v) for v in matrix_to_ypr(T[:3, :3])],
            angular_velocity=[0.0, 0.0, 0.0],
            time=0.0,
            type=0,
        )
