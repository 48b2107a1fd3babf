"""The sequencer's supervisor API over Zenoh: the real sequencer and planner shells on a
loopback router; the bridge and the controller are test fakes (tests/sequencer_fakes.py).

Live tests (``slow``): the fake bridge publishes its joint states every 60 ms from a
thread and the sequencer judges them in time, so they run in a live lane at its priority
(tests/scheduling.py); beside CPU-bound pure tests and two CPU hogs a step failed.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path as FilePath

import pytest

from manus.node import Node
from manus.session import ZenohSettings
from schemas.control import GripperGoal, TrajectoryGoal
from schemas.sequencing import Task, TaskEvent, TaskStep
from services.planner.shell import PlannerShell
from services.sequencer.client import TaskClient
from services.sequencer.shell import SequencerShell
from services.sequencer.taskfile import parse_task_text, task_from_args
from tests.conftest import eventually
from tests.sequencer_fakes import FakeBridge, FakeController

pytestmark = pytest.mark.slow

ROOT = FilePath(__file__).resolve().parent.parent
SQUARE = str(ROOT / "paths" / "thesis_square.txt")
FAR = "[3000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2.0, 0]"


class Stack:
    def __init__(self, settings: ZenohSettings) -> None:
        self.planner = PlannerShell(settings)
        self.bridge = FakeBridge(settings)
        self.controller = FakeController(settings, self.bridge)
        self.sequencer = SequencerShell(settings, query_timeout=2.0)
        self.client_node = Node("test_supervisor", settings, liveliness=False)
        self.client = TaskClient(self.client_node)
        eventually(
            lambda: (
                not self.sequencer.core.missing_services()
                and self.sequencer.core.bridge_phase == "running"
                and self.sequencer.core.latest is not None
            )
        )

    def events(self, task_id: str, timeout: float = 20.0) -> list[TaskEvent]:
        got: list[TaskEvent] = []
        final = self.client.follow(task_id, got.append, timeout=timeout)
        assert final is not None, f"task {task_id} did not end: {[e.event for e in got]}"
        return got

    def close(self) -> None:
        for part in (self.client_node, self.sequencer, self.controller, self.bridge, self.planner):
            part.close()


@pytest.fixture
def stack(zenoh_settings: ZenohSettings) -> Iterator[Stack]:
    s = Stack(zenoh_settings)
    try:
        yield s
    finally:
        s.close()


def names(events: list[TaskEvent]) -> list[str]:
    return [e.event for e in events if e.event != "step_progress"]


def test_submit_runs_the_task_and_publishes_events(stack: Stack) -> None:
    task = task_from_args([SQUARE, "40"])
    reply = stack.client.submit(task)
    assert reply.accepted and reply.task_id and reply.errors == []
    events = stack.events(reply.task_id)
    assert names(events) == [
        "accepted",
        "step_started",
        "step_finished",
        "step_started",
        "step_finished",
        "succeeded",
    ]
    progress = [e.progress for e in events if e.event == "step_progress" and e.step == 0]
    assert progress == sorted(progress) and len(progress) >= 3
    assert isinstance(stack.controller.goals[0], TrajectoryGoal)
    assert isinstance(stack.controller.goals[1], GripperGoal)
    status = stack.client.control("status")
    assert status.state == "succeeded" and status.progress == 1.0


def test_unreachable_step_3_is_refused_before_step_1_moves(stack: Stack) -> None:
    text = f"""[[step]]
move = "{SQUARE}"
[[step]]
gripper = 40
[[step]]
move = [
  [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0.0, 2],
  {FAR},
]
[[step]]
gripper = 0
"""
    reply = stack.client.submit(parse_task_text(text, source="far.toml"))
    assert not reply.accepted and reply.task_id == ""
    assert len(reply.errors) == 1
    assert reply.errors[0].startswith("far.toml:6: step 3 (move): planner refused (unreachable)")
    assert stack.controller.goals == []  # nothing moved
    assert stack.client.control("status").state == "none"


def test_refused_goal_fails_the_task_with_the_controllers_reason(stack: Stack) -> None:
    stack.controller.refuse = "another goal is active"
    reply = stack.client.submit(task_from_args([SQUARE]))
    events = stack.events(reply.task_id)
    assert names(events)[-2:] == ["step_failed", "failed"]
    assert events[-1].reason.endswith("controller refused the goal: another goal is active")


def test_cancel_mid_path_stops_the_goal(stack: Stack) -> None:
    stack.controller.speedup = 1.0  # real time: 19 s, cancelled long before
    reply = stack.client.submit(task_from_args([SQUARE, "40"]))
    eventually(lambda: stack.sequencer.core._phase == "active")
    time.sleep(0.3)
    status = stack.client.control("cancel", reply.task_id)
    assert status.ok
    events = stack.events(reply.task_id)
    assert names(events)[-1] == "cancelled"
    goal = stack.controller.goals[0]
    assert stack.controller.cancels == [goal.goal_id]
    assert len(stack.controller.goals) == 1  # the gripper step never ran


def test_pause_and_resume_over_zenoh(stack: Stack) -> None:
    stack.controller.speedup = 4.0
    reply = stack.client.submit(task_from_args([SQUARE]))
    eventually(lambda: stack.sequencer.core._phase == "active")
    time.sleep(1.0)
    assert stack.client.control("pause", reply.task_id).ok
    eventually(lambda: stack.client.control("status").state == "paused")
    first = stack.controller.goals[0]
    assert isinstance(first, TrajectoryGoal)
    assert stack.controller.cancels == [first.goal_id]
    assert stack.client.control("resume", reply.task_id).ok
    events = stack.events(reply.task_id)
    assert names(events) == [
        "accepted",
        "step_started",
        "paused",
        "resumed",
        "step_finished",
        "succeeded",
    ]
    second = stack.controller.goals[1]
    assert isinstance(second, TrajectoryGoal)
    # the rest of the path: fewer via points than the whole square, ending at its end
    assert len(second.trajectory.times) < len(first.trajectory.times)
    assert second.trajectory.via_xyz[-1] == pytest.approx(first.trajectory.via_xyz[-1], abs=1e-6)


def test_fold_steps_wait_for_the_bridge(stack: Stack) -> None:
    task = Task(steps=[TaskStep(kind="fold_out"), TaskStep(kind="fold_in")])
    reply = stack.client.submit(task)
    events = stack.events(reply.task_id)
    assert names(events)[-1] == "succeeded"
    assert stack.bridge.commands == ["fold_out", "fold_in"]


def test_missing_services_are_named(zenoh_settings: ZenohSettings) -> None:
    with (
        PlannerShell(zenoh_settings),
        SequencerShell(zenoh_settings) as sequencer,
        Node("test_supervisor", zenoh_settings, liveliness=False) as node,
    ):
        eventually(lambda: "planner" in sequencer.core.alive)
        reply = TaskClient(node).submit(task_from_args([SQUARE]))
        assert not reply.accepted
        assert reply.errors == ["required service(s) not running: can_bridge, controller"]


def test_example_supervisor_in_another_process(stack: Stack, router_endpoint: str) -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.run(
        [
            sys.executable,
            str(ROOT / "examples" / "supervisor.py"),
            "--connect",
            router_endpoint,
            "--prefix",
            "test",
            "--pause-after",
            "0.5",
            "--resume-after",
            "0.3",
            SQUARE,
            "40",
        ],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
    )
    out = proc.stdout
    assert proc.returncode == 0, out + proc.stderr
    assert "alive: can_bridge, controller, planner, sequencer" in out
    assert "accepted: task" in out
    assert "pause -> " in out and "resume -> running ok=True" in out
    assert out.strip().endswith("event: succeeded step -1/2")

    bad = subprocess.run(
        [
            sys.executable,
            str(ROOT / "examples" / "supervisor.py"),
            "--connect",
            router_endpoint,
            "--prefix",
            "test",
            SQUARE,
            "120",
        ],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
    )
    assert bad.returncode == 2
    assert "step 2 (gripper): gripper opening 120 mm is outside 0..90 mm" in bad.stdout


def test_manus_run_with_an_in_process_sequencer(
    zenoh_settings: ZenohSettings, router_endpoint: str
) -> None:
    with (
        PlannerShell(zenoh_settings),
        FakeBridge(zenoh_settings) as bridge,
        FakeController(zenoh_settings, bridge, speedup=20.0),
    ):
        env = dict(os.environ, MANUS_ZENOH_CONNECT=router_endpoint, MANUS_PREFIX="test")
        cmd = [
            sys.executable,
            "-m",
            "manus_stack.cli",
            "run",
            SQUARE,
            "40",
            "--plain",
            "--fold-out",
            "--fold-in",
        ]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60, env=env)
        assert proc.returncode == 0, proc.stdout + proc.stderr
        assert "no sequencer is running: running one in this process" in proc.stderr
        lines = proc.stdout.splitlines()
        assert lines[0].startswith("task ") and lines[0].endswith("(4 steps)")
        assert any(line.startswith("step 3/4 gripper 40 mm: step_finished") for line in lines)
        assert lines[-1].endswith(": succeeded")

        refused = subprocess.run(
            [*cmd[:4], "95", SQUARE + ".missing"],
            capture_output=True,
            text=True,
            timeout=60,
            env=env,
        )
        assert refused.returncode == 2
        assert "argument 1 (95): step 1: gripper opening 95 mm" in refused.stderr
        assert "cannot read the file" in refused.stderr


def test_ctrl_c_in_manus_run_cancels_the_task(stack: Stack, router_endpoint: str) -> None:
    stack.controller.speedup = 1.0  # the square takes 19 s: interrupted long before
    env = dict(os.environ, MANUS_ZENOH_CONNECT=router_endpoint, MANUS_PREFIX="test")
    cmd = [sys.executable, "-m", "manus_stack.cli", "run", SQUARE, "40", "--plain"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        eventually(lambda: stack.sequencer.core._phase == "active", timeout=20.0)
        os.kill(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 130, out + err
    assert "interrupted: cancelling task" in err
    assert "cancelled" in out.splitlines()[-1]
    assert stack.client.control("status").state == "cancelled"
    assert stack.controller.cancels == [stack.controller.goals[0].goal_id]


def test_history_lists_the_recent_tasks_newest_first(
    stack: Stack, router_endpoint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """``sequencer/history`` (a supervisor query added through the endpoint table, the
    sequencer's wiring map and one core method) over Zenoh and ``manus task history``."""
    assert stack.client.history().tasks == []
    stack.controller.refuse = "another goal is active"
    failed = stack.client.submit(task_from_args([SQUARE], name="first"))
    failed_events = stack.events(failed.task_id)
    stack.controller.refuse = ""
    done = stack.client.submit(task_from_args([SQUARE, "40"], name="second"))
    done_events = stack.events(done.task_id)
    tasks = stack.client.history().tasks
    # each record keeps its task's final event exactly as it was published
    assert [t.final for t in tasks] == [done_events[-1], failed_events[-1]]
    assert [e.event for e in (done_events[-1], failed_events[-1])] == ["succeeded", "failed"]
    assert [(t.task_id, t.name, t.state) for t in tasks] == [
        (done.task_id, "second", "succeeded"),
        (failed.task_id, "first", "failed"),
    ]
    assert tasks[1].reason.endswith("controller refused the goal: another goal is active")
    assert tasks[0].steps == 2 and 0 < tasks[0].started_ns <= tasks[0].ended_ns
    assert [t.task_id for t in stack.client.history(limit=1).tasks] == [done.task_id]
    from manus_stack.cli import main

    prefix = stack.client_node.settings.prefix
    args = ["task", "history", "--limit", "5", "--connect", router_endpoint, "--prefix", prefix]
    assert main(args) == 0
    printed = json.loads(capsys.readouterr().out)
    assert [t["task_id"] for t in printed["tasks"]] == [done.task_id, failed.task_id]
