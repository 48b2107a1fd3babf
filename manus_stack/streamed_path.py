"""Streamed via points: via points appended to (or replacing the rest of) a running path,
without stopping (docs/follow.md, Streamed via points).

A client (a supervisor; ``manus bench follow``) keeps a :class:`StreamedPath`. The path
starts as any plan does (:meth:`StreamedPath.start`: a ``PlanRequest`` from the arm at
rest). Each time via points arrive (:meth:`StreamedPath.append`, or
:meth:`StreamedPath.replace` for the ones not yet reached), it asks the planner for a
**continuation**: a plan from the running reference's state at the splice time (its
joint angles as ``start``, and its velocity as the first via point's: the planner's
clamped spline starts with it, so position and velocity are continuous across the
splice), through the via points not yet reached and the new ones, at their times on the
path's one clock. The planner checks the new part as any plan (limits, the collision
sweep), and refuses it the same way (the running path then goes on to its own end). The
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
import math

import numpy as np

from manus.config import ArmConfig
from manus.errors import ManusError
from manus.kinematics import fk, jacobian
from manus.orientation import matrix_to_ypr
from manus.trajectory import JointTrajectory
from schemas.control import TrajectoryGoal
from schemas.planning import Path, PlanRequest, Trajectory, ViaPoint

GAP_S = 0.2
"""A via point closer than this after the splice counts as reached [s]: the continuation
needs room to bend toward the next one."""


class StreamError(ManusError, ValueError):
    """A streamed via point that cannot be taken (the message names it)."""


def _ypr_rates(ypr: tuple[float, float, float], omega: np.ndarray) -> list[float]:
    """(yaw, pitch, roll) rates [rad/s] of the angular velocity ``omega`` [rad/s]."""
    yaw, pitch = ypr[0], ypr[1]
    cy, sy, cp, sp = math.cos(yaw), math.sin(yaw), math.cos(pitch), math.sin(pitch)
    E = np.array([[0.0, -sy, cy * cp], [0.0, cy, sy * cp], [1.0, 0.0, -sp]])
    return [float(v) for v in np.linalg.solve(E, omega)]


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
        self._asked: tuple[float, list[ViaPoint]] | None = None

    def start(self, q: list[float], via_points: list[ViaPoint]) -> PlanRequest:
        """The first plan: from the arm at rest at ``q`` [rad] through ``via_points``
        (absolute; times on the path's clock, the first after 0).

        Raises:
            StreamError: a via point not after the one before it.
        """
        self._check(0.0, via_points)
        rest = self._state_point(np.asarray(q, dtype=float), np.zeros(6))
        self._asked = (0.0, list(via_points))
        return self._request(q, [rest, *via_points])

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
        splice, pending = self._asked
        self._asked = None
        first = self.running is None
        self.running, self.pending = trajectory, pending
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
        here = self._state_point(sample.q, sample.qd)
        shifted = [dataclasses.replace(vp, time=vp.time - splice) for vp in points]
        self._asked = (splice, points)
        return self._request([float(v) for v in sample.q], [here, *shifted])

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

    def _state_point(self, q: np.ndarray, qd: np.ndarray) -> ViaPoint:
        """The via point of the reference's state: its pose, and its velocity."""
        T = fk(q, self.arm)
        twist = jacobian(q, self.arm) @ qd
        ypr = matrix_to_ypr(T[:3, :3])
        return ViaPoint(
            xyz=[float(v) for v in T[:3, 3]],
            velocity=[float(v) for v in twist[:3]],
            ypr=[float(v) for v in ypr],
            angular_velocity=_ypr_rates(ypr, twist[3:]),
            time=0.0,
            type=0,
        )

    def _request(self, q: list[float], points: list[ViaPoint]) -> PlanRequest:
        path = Path(via_points=points, source="streamed via points")
        return PlanRequest(path=path, start=list(q), interpolation=self.interpolation)
