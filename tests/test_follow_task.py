"""A task's follow step: written in a task file, run by the sequencer core through the real
controller, bridge and simulator cores (lock-step): it holds for its time, or until the
supervisor's ``done``, and fails with the goal's fault."""

from __future__ import annotations

from pathlib import Path

import pytest

from manus_stack.task_lockstep import TaskLockStep
from schemas.follow import FollowGoal
from schemas.sequencing import StepKind, Task, TaskStep
from services.sequencer.taskfile import TaskFileError, load_task_file
from services.simulator.config import SimConfig
from services.simulator.target_config import LostWindow, TargetConfig

START = (51.2, 17.4, -4.2, -51.9, -98.2, -10.3)
RIM = [0.0, 0.0, 0.06]


def _rig(**target: object) -> TaskLockStep:
    cfg = TargetConfig(enabled=True, sway_mm=(0.0, 10.0, 0.0), **target)  # type: ignore[arg-type]
    rig = TaskLockStep(SimConfig(start_pose=START, target=cfg))
    rig.start_arm()
    rig.ls.run_for(0.5)
    return rig


def _follow(hold_s: float = 0.0) -> Task:
    goal = FollowGoal(goal_id="", source="mouth", offset=RIM)
    return Task(steps=[TaskStep(kind=StepKind.FOLLOW, follow=goal, duration=hold_s)])


def test_a_follow_step_holds_for_its_time() -> None:
    rig = _rig()
    assert rig.submit(_follow(hold_s=2.0)).accepted
    rig.run_while_busy(30.0)
    assert rig.seq.state == "succeeded", rig.seq.reason
    (result,) = [r for r in rig.results() if r.kind == "follow"]
    assert result.cause == "cancel_request"
    assert result.duration > 2.0  # the approach, then two seconds held


def test_a_follow_step_pauses_resumes_and_holds_until_the_supervisor_says_done() -> None:
    rig = _rig()
    assert rig.submit(_follow()).accepted
    rig.ls.run_for(6.0)
    assert rig.seq.state == "running"
    assert rig.control("pause").ok
    rig.ls.run_for(1.0)
    assert rig.seq.state == "paused"
    assert [r.cause for r in rig.results() if r.kind == "follow"] == ["cancel_request"]
    assert rig.control("resume").ok
    rig.ls.run_for(4.0)
    status = rig.control("done")
    assert status.ok, status.message
    rig.run_while_busy(10.0)
    assert rig.seq.state == "succeeded", rig.seq.reason


def test_done_is_refused_for_other_steps() -> None:
    rig = _rig()
    task = Task(steps=[TaskStep(kind=StepKind.WAIT, duration=5.0)])
    assert rig.submit(task).accepted
    rig.ls.run_for(1.0)
    status = rig.control("done")
    assert not status.ok and "not a follow step" in status.message


def test_a_lost_target_fails_the_step() -> None:
    rig = _rig(lost=(LostWindow(at_s=4.0, for_s=1.0),))
    assert rig.submit(_follow(hold_s=20.0)).accepted
    rig.run_while_busy(30.0)
    assert rig.seq.state == "failed"
    assert "target_lost" in rig.seq.reason or "no new frame" in rig.seq.reason


def test_a_task_file_writes_a_follow_step(tmp_path: Path) -> None:
    path = tmp_path / "drink.toml"
    path.write_text(
        '[[step]]\nfollow = "mouth"\noffset_mm = [0, 0, 60]\nstandoff_mm = 70\nhold_s = 5\n'
        "[[step]]\nwait = 1\n"
    )
    task = load_task_file(path)
    step = task.steps[0]
    assert step.kind == StepKind.FOLLOW and step.duration == 5.0
    assert step.follow is not None and step.follow.offset == pytest.approx([0.0, 0.0, 0.06])
    assert step.follow.standoff == pytest.approx(0.07) and step.follow.source == "mouth"
    path.write_text('[[step]]\nfollow = ""\nhold_s = -1\nclose = "yes"\n')
    with pytest.raises(TaskFileError) as err:
        load_task_file(path)
    text = "\n".join(err.value.errors)
    assert "drink.toml:2: step 1 (follow): follow takes the tracker's name" in text
    assert "hold_s must be" in text and "close must be true or false" in text
