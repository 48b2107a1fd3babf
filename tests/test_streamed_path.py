"""Streamed via points: a continuation starts from the running reference's state (its
position and velocity) and keeps the path's clock; appended one by one while moving, the
arm never stops and passes the via points as well as the path planned whole."""

from __future__ import annotations

import numpy as np
import pytest

from manus.config import DEFAULT_ARM
from manus.kinematics import fk
from manus.trajectory import JointTrajectory
from manus_stack.bench.follow_stream import STEP_S, Run, _plan, via_points
from manus_stack.streamed_path import StreamedPath, StreamError
from schemas.control import TrajectoryGoal
from schemas.planning import ViaPointContinuation
from services.planner.core import PlannerCore


def test_a_continuation_starts_on_the_running_reference_and_keeps_its_clock() -> None:
    points = via_points()
    stream = StreamedPath(DEFAULT_ARM)
    q0 = [0.0, 0.5236, -0.5236, 0.0, -1.0472, 0.0]
    first = _plan(stream.start(q0, points[:2]))
    assert stream.accepted(first) is None  # the first plan: a plain goal
    request = stream.append(points[2:3], now_s=2.0)
    running = JointTrajectory(first).sample(2.0)
    assert request.start == pytest.approx(running.q.tolist())
    motion = request.motion
    assert isinstance(motion, ViaPointContinuation)
    assert motion.velocity == pytest.approx(running.qd.tolist())  # in joint space
    assert [vp.time for vp in motion.path.via_points] == pytest.approx(
        [0.0, points[1].time - 2.0, points[2].time - 2.0]  # via point 0 was reached
    )
    reply = PlannerCore().plan(request)
    assert reply.trajectory is not None
    # Knots labelled: the start, then the streamed path's via points 2 and 3.
    assert reply.trajectory.knot_kinds == ["start", "via_point", "via_point"]
    assert reply.trajectory.via_indices == [-1, 2, 3]
    assert reply.trajectory.time_scale == 1.0
    goal = stream.accepted(reply.trajectory)
    assert goal is not None and goal.replace and goal.splice_at == pytest.approx(2.0)
    cont = JointTrajectory(reply.trajectory).sample(0.0)
    assert np.allclose(cont.q, running.q) and np.allclose(cont.qd, running.qd, atol=1e-9)
    assert stream.offset == 2.0
    end = JointTrajectory(reply.trajectory).sample(points[2].time - 2.0)
    assert np.allclose(fk(end.q, DEFAULT_ARM)[:3, 3], points[2].xyz, atol=1e-6)


def test_replacing_drops_the_via_points_not_reached_and_bad_times_are_refused() -> None:
    points = via_points()
    stream = StreamedPath(DEFAULT_ARM)
    q0 = [0.0, 0.5236, -0.5236, 0.0, -1.0472, 0.0]
    stream.accepted(_plan(stream.start(q0, points[:3])))
    request = stream.replace(points[4:5], now_s=1.0)
    motion = request.motion
    assert isinstance(motion, ViaPointContinuation)
    assert len(motion.path.via_points) == 2  # the state, then only the new one
    assert motion.first_index == 4  # numbered after the three of the start
    with pytest.raises(StreamError, match="not after"):
        stream.append(points[0:1], now_s=2.0)  # due before the splice
    with pytest.raises(StreamError, match="start"):
        StreamedPath(DEFAULT_ARM).append(points[:1], now_s=0.0)


def test_via_points_streamed_while_moving_never_stop_the_arm() -> None:
    run = Run()
    js = run.arm.core.last_js
    assert js is not None
    stream = StreamedPath(DEFAULT_ARM)
    points = via_points()[:5]
    traj = _plan(stream.start(list(js.position), points[:1]))
    stream.accepted(traj)
    run.send(TrajectoryGoal(goal_id="", trajectory=traj))
    for vp in points[1:]:
        run.run(max(0.0, vp.time - STEP_S - 0.75 - (run.path_time() if run.t0_ns else 0.0)))
        reply = PlannerCore().plan(stream.append([vp], run.path_time()))
        assert reply.trajectory is not None, reply.error
        goal = stream.accepted(reply.trajectory)
        assert goal is not None
        run.send(goal)
    run.run(points[-1].time - run.path_time() + 1.0)
    errors = run.errors(points)
    assert max(errors) < 0.003
    assert run.t0_ns is not None
    moving = [np.abs(qd).max() for t, _, qd in run.truth
              if run.t0_ns + 0.5e9 < t < run.t0_ns + points[-1].time * 1e9 - 0.5e9]  # fmt: skip
    assert min(moving) > np.radians(1.0)  # never at rest on the way
    results = run.arm.results()
    assert [r.cause for r in results[:-1]] == ["new_goal"] * (len(points) - 1)
    assert results[-1].status == "succeeded"
