"""The sequencer core driving the real controller, bridge and simulator cores in lock-step.

No Zenoh, simulated time: the sequencer's queries are answered in-process by the cores
that own them (planner, controller, bridge), at the simulated instant they are sent.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from manus.kinematics import fk
from manus_stack.lockstep import LockStep
from schemas.base import Message
from schemas.commands import ArmCommand, EStop
from schemas.control import CancelGoal, GoalResult, GripperGoal, TrajectoryGoal
from schemas.planning import PlanRequest
from schemas.sequencing import Task, TaskControl, TaskEvent, TaskStep
from schemas.state import JointState
from services.controller.core import ControllerCore
from services.planner.core import PlannerCore
from services.sequencer.core import Action, Publish, SequencerCore
from services.sequencer.taskfile import task_from_args
from services.sequencer.validate import Validator
from tests.test_sequencer_core import SQUARE

NS = 1_000_000_000


class Rig:
    """Simulator + bridge (LockStep) + controller + planner + sequencer cores."""

    def __init__(self) -> None:
        self.ls = LockStep()
        self.controller = ControllerCore()
        self.planner = PlannerCore()
        self.seq = SequencerCore()
        self.events: list[TaskEvent] = []
        self.requests: list[Message] = []
        ls, ctl, seq = self.ls, self.controller, self.seq
        ls.subscribe("state/joints", lambda m, t: ctl.on_joint_state(m))  # type: ignore[arg-type]
        ls.subscribe("state/status", lambda m, t: ctl.on_status(m))  # type: ignore[arg-type]
        ls.subscribe(
            "state/joints",
            lambda m, t: self.do(
                seq.on_joint_state(m, t)  # type: ignore[arg-type]
                + seq.on_tick(t),
                t,
            ),
        )
        ls.subscribe("state/bridge", lambda m, t: self.do(seq.on_bridge_state(m, t), t))  # type: ignore[arg-type]
        ls.subscribe("controller/feedback", lambda m, t: self.do(seq.on_feedback(m, t), t))  # type: ignore[arg-type]
        ls.subscribe("controller/result", lambda m, t: self.do(seq.on_result(m, t), t))  # type: ignore[arg-type]
        for name in ("planner", "controller", "can_bridge"):
            seq.on_liveliness(name, True, 0)
        ls.run_until_phase("running", 20.0)
        ls.run_for(0.5)

    def answer(self, request: Message) -> Message:
        self.requests.append(request)
        if isinstance(request, PlanRequest):
            return self.planner.plan(request)
        if isinstance(request, TrajectoryGoal):
            return self.controller.submit(request)
        if isinstance(request, GripperGoal):
            return self.controller.submit_gripper(request)
        if isinstance(request, CancelGoal):
            return self.controller.cancel(request)
        assert isinstance(request, ArmCommand)
        return self.ls.arm_command(request)

    def do(self, actions: list[Action], t: int) -> list[tuple[str, Message]]:
        out: list[tuple[str, Message]] = []
        for action in actions:
            if isinstance(action, Publish):
                assert isinstance(action.message, TaskEvent)
                self.events.append(action.message)
                out.append((action.suffix, action.message))
                continue
            reply = self.answer(action.request)
            out += self.do(self.seq.on_reply(action.token, reply, "", t), t)
        return out

    def start(self, task: Task) -> None:
        v = Validator(task, self.seq.start_configuration())
        while (request := v.next_request()) is not None:
            v.on_reply(self.planner.plan(request))
        assert v.errors == []
        assert self.seq.refuse(task) is None
        self.do(self.seq.start("t", task, self.ls.t_ns), self.ls.t_ns)

    def control(self, action: str) -> bool:
        status, actions = self.seq.control(TaskControl(action=action), self.ls.t_ns)
        self.do(actions, self.ls.t_ns)
        return status.ok

    def run_while(self, busy: bool = True, limit_s: float = 120.0) -> None:
        end = self.ls.t_ns + round(limit_s * NS)
        while self.seq.busy == busy and self.ls.t_ns < end:
            self.ls.run_for(0.1)

    def run_until_event(self, name: str, limit_s: float = 60.0) -> None:
        end = self.ls.t_ns + round(limit_s * NS)
        while not any(e.event == name for e in self.events):
            assert self.ls.t_ns < end, f"no {name} event within {limit_s} s"
            self.ls.run_for(0.06)

    def names(self) -> list[str]:
        return [e.event for e in self.events if e.event != "step_progress"]

    def joint_states(self, since_ns: int = 0) -> list[tuple[int, JointState]]:
        return [
            (t, m)
            for t, s, m in self.ls.messages
            if s == "state/joints" and t >= since_ns and isinstance(m, JointState)
        ]

    def results(self) -> list[GoalResult]:
        return [m for m in self.ls.published("controller/result") if isinstance(m, GoalResult)]


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
    assert rig.control("cancel")
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
    assert rig.control("pause")
    rig.run_until_event("paused")
    rig.ls.run_for(2.0)
    still = [s.position for (t, s) in rig.joint_states(rig.ls.t_ns - NS // 2)]
    assert all(p == still[0] for p in still)  # paused: the arm holds still
    assert rig.control("resume")
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
    reached = fk(final.position)[:3, 3]
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
