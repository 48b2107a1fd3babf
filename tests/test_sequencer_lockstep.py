"""The sequencer core driving the real controller, bridge and simulator cores in lock-step.

No Zenoh, simulated time: the sequencer's queries are answered in-process by the cores
that own them (planner, controller, bridge), at the simulated instant they are sent.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from manus.config import DEFAULT_ARM
from manus.kinematics import fk
from manus_stack.task_lockstep import TaskLockStep
from schemas.commands import ArmCommand, EStop
from schemas.control import GripperGoal, TrajectoryGoal
from schemas.sequencing import Task, TaskStep
from schemas.state import JointState
from services.sequencer.taskfile import task_from_args
from tests.test_sequencer_core import SQUARE

NS = 1_000_000_000


class Rig(TaskLockStep):
    """The lock-step task runner, started, with the test's shorthand."""

    def __init__(self) -> None:
        super().__init__()
        self.start_arm()

    def start(self, task: Task) -> None:
        reply = self.submit(task)
        assert reply.accepted, reply.errors

    def control_ok(self, action: str) -> bool:
        return self.control(action).ok

    def run_while(self) -> None:
        self.run_while_busy(120.0)


def demo_task() -> Task:
    square = task_from_args([SQUARE, "0", "60"]).steps
    return Task(steps=[TaskStep(kind="fold_out"), *square, TaskStep(kind="fold_in")])


def test_demo_task_runs_through_the_real_cores() -> None:
    rig = Rig()
    rig.start(demo_task())
    rig.run_while()
    assert rig.seq.state == "succeeded", rig.seq.reason
    assert rig.names() == ["accepted"] + ["step_started", "step_finished"] * 5 + ["succeeded"]
    square = rig.results()[0]
    assert square.kind == "trajectory" and square.status == "succeeded"
    assert len(square.via_errors) == 17
    assert max(square.via_errors) < 0.010  # the thesis's largest error; ours is far smaller
    grips = [r for r in rig.results() if r.kind == "gripper"]
    assert [r.status for r in grips] == ["succeeded", "succeeded"]
    folds = [r.action for r in rig.requests if isinstance(r, ArmCommand)]
    assert folds == ["fold_out", "fold_in"]
    assert rig.ls.bridge.phase == "running"


def square_only() -> Task:
    return task_from_args([SQUARE, "40"])


def start_square(rig: Rig) -> None:
    # The simulated arm powers up folded: unfold it with a task of its own first.
    rig.start(Task(steps=[TaskStep(kind="fold_out")]))
    rig.run_while()
    assert rig.seq.state == "succeeded", rig.seq.reason
    rig.events.clear()
    rig.start(square_only())


def speed(states: list[tuple[int, JointState]]) -> list[float]:
    """Largest joint speed between consecutive joint states [rad/s]."""
    out = []
    for (t0, a), (t1, b) in itertools.pairwise(states):
        dq = np.abs(np.subtract(b.position, a.position))
        out.append(float(dq.max()) / ((t1 - t0) / NS))
    return out


def test_cancel_mid_path_decelerates_and_stops_the_arm() -> None:
    rig = Rig()
    start_square(rig)
    rig.ls.run_for(6.0)
    moving = speed(rig.joint_states(rig.ls.t_ns - NS))
    assert max(moving) > math.radians(2.0)  # it was moving
    cancel_at = rig.ls.t_ns
    assert rig.control_ok("cancel")
    rig.run_while()
    assert rig.seq.state == "cancelled"
    assert rig.names()[-1] == "cancelled"
    rig.ls.run_for(2.0)
    after = rig.joint_states(cancel_at)
    rest = [s for (t, s) in after if t > rig.ls.t_ns - NS]
    assert all(s.position == rest[0].position for s in rest)  # at rest
    # stopped within a bounded time (the controller's deceleration), not at the path's end
    stop_time = next(t for (t, s) in after if s.position == rest[0].position) - cancel_at
    assert stop_time < 2 * NS
    # ... decelerating: never faster than it was moving, and the goal ended cancelled
    assert max(speed(after)) <= max(moving) + 1e-9
    assert [r.status for r in rig.results() if r.kind == "trajectory"] == ["cancelled"]
    assert not any(isinstance(r, GripperGoal) for r in rig.requests)  # the next step never ran


def test_pause_and_resume_finish_the_path_where_it_would_have_ended() -> None:
    rig = Rig()
    start_square(rig)
    rig.ls.run_for(7.0)
    assert rig.control_ok("pause")
    rig.run_until_event("paused")
    rig.ls.run_for(2.0)
    still = [s.position for (t, s) in rig.joint_states(rig.ls.t_ns - NS // 2)]
    assert all(p == still[0] for p in still)  # paused: the arm holds still
    assert rig.control_ok("resume")
    rig.run_while()
    assert rig.seq.state == "succeeded", rig.seq.reason
    assert rig.names() == [
        "accepted",
        "step_started",
        "paused",
        "resumed",
        "step_finished",
        "step_started",
        "step_finished",
        "succeeded",
    ]
    goals = [r for r in rig.requests if isinstance(r, TrajectoryGoal)]
    assert len(goals) == 2
    first, second = goals
    assert second.trajectory.via_xyz[-1] == pytest.approx(first.trajectory.via_xyz[-1], abs=1e-6)
    final = [s for (t, s) in rig.joint_states()][-1]
    reached = fk(final.position, DEFAULT_ARM)[:3, 3]
    assert np.linalg.norm(reached - np.asarray(first.trajectory.via_xyz[-1])) < 0.005


def test_estop_mid_path_fails_the_task_and_the_next_is_refused() -> None:
    rig = Rig()
    start_square(rig)
    rig.ls.run_for(3.0)
    stop = EStop(stamp_ns=rig.ls.t_ns, seq=1, engaged=True, source="test", reason="hand in the way")
    rig.ls.publish("estop", stop)
    rig.do(rig.seq.on_estop(stop, rig.ls.t_ns), rig.ls.t_ns)
    assert rig.seq.state == "failed"
    assert rig.seq.reason.endswith("e-stop engaged by test: hand in the way")
    rig.ls.run_for(1.0)
    refused = rig.seq.refuse(square_only())
    assert refused is not None and "estopped" in refused.errors[0]


def test_a_wait_step_ends_on_time() -> None:
    """A joint state that arrives as a wait ends must not swallow its end (lock-step
    delivers each joint state before the tick of the same instant)."""
    rig = Rig()
    rig.start(Task(steps=[TaskStep(kind="wait", duration=1.5)]))
    start = rig.ls.t_ns
    rig.run_while_busy(10.0)
    assert rig.seq.state == "succeeded", rig.seq.reason
    assert 1.5 <= (rig.ls.t_ns - start) / NS <= 1.7
