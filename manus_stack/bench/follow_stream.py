"""Streamed via points against the same path planned whole, on the simulator's truth.

The path: 10 via points on a 100 mm circle in front of the user (the gripper's
orientation held), 1.5 s apart, after the arm's start. **Whole**: planned at once from
the arm at rest, run to its end. **Streamed**: planned with the first via point only;
then each next one is appended (:class:`manus_stack.streamed_path.StreamedPath`, the
planner core, a ``replace`` goal with ``splice_at``) while the arm moves, 0.75 s before
the newest one is due. Each via point's true error: the distance of the simulator's true
gripper to it at its time on the path's clock (the first goal's trajectory time 0 found
from the controller's feedback). Figures: the mean and max of both, their difference
(target: the mean within 0.2 mm), the continuations refused, and the largest true joint
speed change across a splice against the largest anywhere (velocity continuity).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from manus_stack.controlled import ControlledArm
from manus_stack.streamed_path import StreamedPath
from schemas import endpoints as ep
from schemas.control import ControllerFeedback, TrajectoryGoal
from schemas.planning import PlanRequest, Trajectory, ViaPoint
from services.planner.core import PlannerCore
from services.simulator.config import SimConfig

STEP_S = 1.5
"""Time between via points [s]."""
COUNT = 10
RADIUS_M = 0.10
CYCLE_S = 0.06


def via_points() -> list[ViaPoint]:
    """The path's via points (base frame; times on its clock)."""
    q = np.radians(UNFOLDED_Q_DEG)
    T = fk(q, DEFAULT_ARM)
    ypr = [float(v) for v in matrix_to_ypr(T[:3, :3])]
    centre = T[:3, 3] + np.array([0.0, RADIUS_M, 0.0])
    out = []
    for k in range(1, COUNT + 1):
        a = -math.pi / 2 + 2 * math.pi * k / COUNT
        xyz = centre + RADIUS_M * np.array([0.0, math.cos(a), math.sin(a)])
        out.append(
            ViaPoint(xyz=[float(v) for v in xyz], velocity=[0.0] * 3, ypr=ypr,
                     angular_velocity=[0.0] * 3, time=STEP_S * k, type=0)
        )  # fmt: skip
    return out


def _plan(request: PlanRequest) -> Trajectory:
    reply = PlannerCore().plan(request)
    if reply.trajectory is None:
        raise RuntimeError(f"the planner refused: {reply.error}")
    return reply.trajectory


class Run:
    """An arm, its goals and its clock (the first goal's trajectory time 0 [ns])."""

    def __init__(self) -> None:
        self.arm = ControlledArm(SimConfig(start_pose="unfolded"))
        self.arm.start()
        self.arm.ls.run_for(0.3)
        self.t0_ns: int | None = None
        self.truth: list[tuple[int, np.ndarray, np.ndarray]] = []
        self._n = 0

    def send(self, goal: TrajectoryGoal) -> None:
        self._n += 1
        ack = self.arm.submit(TrajectoryGoal(**{**_fields(goal), "goal_id": f"s{self._n}"}))
        assert ack.accepted, ack.reason

    def run(self, seconds: float) -> None:
        end = self.arm.ls.t_ns + round(seconds * 1e9)
        while self.arm.ls.t_ns < end:
            self.arm.ls.run_for(0.01)
            truth = self.arm.ls.sim.truth()
            self.truth.append((truth.stamp_ns, np.array(truth.xyz), np.array(truth.qd_true)))
            if self.t0_ns is None:
                fbs = [m for m in self.arm.ls.published(ep.FEEDBACK)
                       if isinstance(m, ControllerFeedback) and m.goal_id == "s1"]  # fmt: skip
                if fbs:
                    self.t0_ns = fbs[0].stamp_ns - 20_000_000 - round(fbs[0].t * 1e9)

    def path_time(self) -> float:
        """Where the path's clock is now [s]."""
        assert self.t0_ns is not None
        return (self.arm.ls.t_ns - self.t0_ns) / 1e9

    def errors(self, points: list[ViaPoint]) -> list[float]:
        """The true error at each via point's time [m]."""
        assert self.t0_ns is not None
        times = np.array([t for t, _, _ in self.truth])
        out = []
        for vp in points:
            k = int(np.argmin(np.abs(times - (self.t0_ns + vp.time * 1e9))))
            out.append(float(np.linalg.norm(self.truth[k][1] - np.array(vp.xyz))))
        return out


def _fields(goal: TrajectoryGoal) -> dict[str, Any]:
    return {f: getattr(goal, f) for f in goal.__dataclass_fields__}


def whole() -> list[float]:
    """The path planned at once: each via point's true error [m]."""
    run = Run()
    js = run.arm.core.last_js
    assert js is not None
    stream = StreamedPath(DEFAULT_ARM)
    points = via_points()
    traj = _plan(stream.start(list(js.position), points))
    run.send(TrajectoryGoal(goal_id="", trajectory=traj))
    run.run(STEP_S * COUNT + 1.5)
    return run.errors(points)


def streamed() -> dict[str, Any]:
    """The path streamed one via point at a time (module docstring)."""
    run = Run()
    js = run.arm.core.last_js
    assert js is not None
    stream = StreamedPath(DEFAULT_ARM)
    points = via_points()
    traj = _plan(stream.start(list(js.position), points[:1]))
    stream.accepted(traj)
    run.send(TrajectoryGoal(goal_id="", trajectory=traj))
    refused = 0
    splices: list[float] = []
    for vp in points[1:]:
        run.run(max(0.0, (vp.time - STEP_S - 0.75) - (run.path_time() if run.t0_ns else 0.0)))
        request = stream.append([vp], run.path_time())
        reply = PlannerCore().plan(request)
        if reply.trajectory is None:
            refused += 1
            continue
        goal = stream.accepted(reply.trajectory)
        assert goal is not None
        splices.append(run.arm.ls.t_ns / 1e9)
        run.send(goal)
    run.run(points[-1].time - run.path_time() + 1.5)
    return {"errors": run.errors(points), "refused": refused, "splices": splices, "run": run}


def jumps(run: Run, splices: list[float]) -> tuple[float, float]:
    """The largest change of a true joint speed between samples near a splice, and
    anywhere [deg/s]."""
    qd = np.array([s for _, _, s in run.truth])
    times = np.array([t for t, _, _ in run.truth]) / 1e9
    change = np.degrees(np.abs(np.diff(qd, axis=0)).max(axis=1))
    near = [c for c, t in zip(change, times[1:], strict=True)
            if any(0.0 <= t - s <= 3 * CYCLE_S for s in splices)]  # fmt: skip
    return max(near, default=0.0), float(change.max())


def figures() -> dict[str, Any]:
    """The comparison (module docstring)."""
    plain = whole()
    out = streamed()
    near, anywhere = jumps(out["run"], out["splices"])
    mean_w, mean_s = float(np.mean(plain)), float(np.mean(out["errors"]))
    return {
        "via_points": COUNT,
        "whole_mean_mm": round(mean_w * 1e3, 3),
        "whole_max_mm": round(max(plain) * 1e3, 3),
        "streamed_mean_mm": round(mean_s * 1e3, 3),
        "streamed_max_mm": round(max(out["errors"]) * 1e3, 3),
        "mean_difference_mm": round((mean_s - mean_w) * 1e3, 3),
        "continuations_refused": out["refused"],
        "speed_step_at_splices_deg_s": round(near, 2),
        "speed_step_anywhere_deg_s": round(anywhere, 2),
    }
