"""Sequencer core: task files, whole-task validation, and the step state machine.

The planner is the real ``PlannerCore``; the controller's and the bridge's answers are
scripted here (their messages, as the schemas define them).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path as FilePath

import pytest

from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.kinematics import fk
from schemas.base import Message
from schemas.commands import ArmCommand, ArmCommandReply, EStop
from schemas.control import (
    CancelGoal,
    ControllerFeedback,
    GoalAck,
    GoalResult,
    GripperGoal,
    ResultStatus,
    TrajectoryGoal,
)
from schemas.guardian import GuardianReport
from schemas.planning import PlanRequest, PlanResume, ViaPointPath
from schemas.sequencing import DEFAULT_POSE_DURATION_S, Task, TaskControl, TaskEvent, TaskStep
from schemas.state import BridgeState, JointState
from services.planner.core import PlannerCore
from services.sequencer.actions import Action, Publish, Query
from services.sequencer.core import SequencerCore
from services.sequencer.poses import pose_path
from services.sequencer.taskfile import TaskFileError, parse_task_text, task_from_args
from services.sequencer.validate import Validator
from tests.sequencer_fakes import CAUSES

ROOT = FilePath(__file__).resolve().parent.parent
SQUARE = str(ROOT / "paths" / "thesis_square.txt")
CIRCLE = str(ROOT / "paths" / "thesis_circle.txt")
UNFOLDED = [math.radians(v) for v in UNFOLDED_Q_DEG]
NS = 1_000_000_000
FAR = "[3000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2.0, 0]"  # 3 m away: unreachable


def joint_state(q: list[float], seq: int = 1) -> JointState:
    return JointState(stamp_ns=seq, seq=seq, position=q, gripper=0.0, valid=True,
                      mode="joint", encoder=[0] * 7, applied_velocity=[0.0] * 6,
                      applied_gripper_velocity=0.0, applied_kind="none",
                      applied_seq=-1)  # fmt: skip


def bridge_state(phase: str, seq: int = 1, detail: str = "") -> BridgeState:
    return BridgeState(stamp_ns=seq, seq=seq, phase=phase, estop=phase == "estopped", cycles=seq,
                       period_ms=60.0, jitter_ms=0.0, reply_latency_ms=0.1,
                       reply_latency_max_ms=0.1, missed_windows=0, stale_commands=0, resyncs=0,
                       dropped_frames=0, duplicate_frames=0, garbled_frames=0, buffered_syncs=0,
                       bad_payloads=0, detail=detail)  # fmt: skip


def validate(task: Task, start: list[float] | None = UNFOLDED) -> Validator:
    planner = PlannerCore()
    v = Validator(task, start, DEFAULT_ARM)
    while (request := v.next_request()) is not None:
        v.on_reply(planner.plan(request))
    return v


# -- task files -------------------------------------------------------------------------------


def test_thesis_form_alternates_paths_and_openings() -> None:
    task = task_from_args([SQUARE, "40", CIRCLE, "0"])
    assert [s.kind for s in task.steps] == ["move", "gripper", "move", "gripper"]
    assert task.steps[1].opening == pytest.approx(0.040)
    assert task.steps[0].path is not None and len(task.steps[0].path.via_points) == 17


def test_thesis_form_reports_every_problem(tmp_path: FilePath) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text("0 0 0 0 0 0 0 0 0 0 0 0 0 0\n1 2 3\n")
    with pytest.raises(TaskFileError) as info:
        task_from_args([SQUARE, "120", str(bad), "-5", str(tmp_path / "missing.txt")])
    errors = info.value.errors
    assert len(errors) == 4
    assert errors[0].startswith("argument 2 (120): step 2: gripper opening 120 mm")
    assert f"{bad}:2" in errors[1] and "expected 14 columns" in errors[1]
    assert "argument 4 (-5)" in errors[2]
    assert "missing.txt" in errors[3] and "cannot read" in errors[3]


def test_toml_task_file(tmp_path: FilePath) -> None:
    (tmp_path / "sq.txt").write_text(FilePath(SQUARE).read_text())
    text = """
name = "pick"
mode = "thesis"

[[step]]
fold_out = true

[[step]]
move = "sq.txt"
interpolation = "quintic"
speed_scaling = true

[[step]]
move = [
  [0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0.0, 2],
  [0, 50, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2.0, 2],
]

[[step]]
gripper = 40

[[step]]
wait = 1.5

[[step]]
pose = "home"
duration = 3

[[step]]
fold_in = true
"""
    task = parse_task_text(text, source="t.toml", base=tmp_path)
    assert task.name == "pick" and task.mode == "thesis"
    kinds = [s.kind for s in task.steps]
    assert kinds == ["fold_out", "move", "move", "gripper", "wait", "pose", "fold_in"]
    assert task.steps[1].interpolation == "quintic" and task.steps[1].speed_scaling
    inline = task.steps[2].path
    assert inline is not None and [v.line for v in inline.via_points] == [15, 16]
    assert task.steps[5].pose == "home" and task.steps[5].duration == 3.0
    assert task.steps[0].where == "t.toml:6"
    assert task.steps[3].where == "t.toml:20"


def test_toml_reports_every_problem_with_its_line() -> None:
    text = f"""[[step]]
gripper = 95

[[step]]
move = "nowhere.txt"

[[step]]
pose = "upside_down"

[[step]]
wait = 1
speed = 3

[[step]]
move = [
  {FAR},
  [0, 50, 0],
]
interpolation = "linear"
"""
    with pytest.raises(TaskFileError) as info:
        parse_task_text(text, source="t.toml")
    errors = info.value.errors
    assert errors[0] == "t.toml:2: step 1 (gripper): gripper opening 95 mm is outside 0..90 mm"
    assert errors[1].startswith("t.toml:5: step 2 (move): ") and "nowhere.txt" in errors[1]
    assert errors[2].startswith("t.toml:8: step 3 (pose): unknown pose 'upside_down'")
    assert errors[3].startswith("t.toml:12: step 4 (wait): unknown key 'speed'")
    assert any(e.startswith("t.toml:19: step 5 (move): interpolation 'linear'") for e in errors)
    assert any("t.toml:17: via point 1" in e and "expected 14 columns" in e for e in errors)
    assert len(errors) == 6


def test_toml_syntax_error_names_the_line() -> None:
    with pytest.raises(TaskFileError, match=r"t.toml: not valid TOML: .*line 2"):
        parse_task_text("[[step]]\ngripper = = 4\n", source="t.toml")


# -- validation -------------------------------------------------------------------------------


def far_task() -> Task:
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
move = "{CIRCLE}"
[[step]]
fold_out = true
[[step]]
pose = "home"
"""
    return parse_task_text(text, source="far.toml")


def test_unreachable_step_3_rejects_the_task_and_names_the_rest() -> None:
    v = validate(far_task())
    errors = v.errors
    assert errors[0].startswith("far.toml:6: step 3 (move): planner refused (unreachable)")
    assert "far.toml line 8" in errors[0]  # the planner names the via point's line
    assert errors[1].startswith("far.toml:11: step 4 (move): not planned: its start is unknown")
    assert "step 3 could not be planned" in errors[1]
    assert len(errors) == 2  # step 6 plans again from the unfolded pose after the fold
    assert set(v.plans) == {0, 5}


def test_validation_plans_each_move_from_where_the_last_left_the_arm() -> None:
    task = task_from_args([SQUARE, "40", CIRCLE])
    planner = PlannerCore()
    v = Validator(task, UNFOLDED, DEFAULT_ARM)
    starts = []
    while (request := v.next_request()) is not None:
        starts.append(request.start)
        v.on_reply(planner.plan(request))
    assert v.errors == []
    assert starts[0] == UNFOLDED
    assert starts[1] == v.plans[0].positions[-1]


def test_validation_static_problems_and_no_planner() -> None:
    task = Task(steps=[
        TaskStep(kind="gripper", opening=0.1, where="w:1"),
        TaskStep(kind="wait", duration=-1.0, where="w:2"),
        TaskStep(kind="pose", pose="home", duration=2.0, where="w:3"),
        TaskStep(kind="pose", pose="home", duration=2.0, where="w:4"),
        TaskStep(kind="move", where="w:5"),
    ])  # fmt: skip
    v = Validator(task, UNFOLDED, DEFAULT_ARM)
    request = v.next_request()
    assert request is not None and isinstance(request.motion, ViaPointPath)
    assert request.motion.speed_scaling  # a pose may stretch
    v.on_reply(None, "planner/plan: no reply within 5 s")
    assert v.next_request() is None
    assert v.errors == [
        "w:1: step 1 (gripper): gripper opening 100 mm is outside 0..90 mm",
        "w:2: step 2 (wait): wait -1 s is outside 0..3600 s",
        "w:3: step 3 (pose): cannot plan: planner/plan: no reply within 5 s",
        "w:4: step 4 (pose): not planned: planner/plan: no reply within 5 s",
        "w:5: step 5 (move): a move step needs a path",
    ]


def test_named_pose_is_the_fk_of_the_pose_and_plans() -> None:
    path = pose_path("folded", 5.0, DEFAULT_ARM)
    assert len(path.via_points) == 2 and path.via_points[1].type == 0
    start = [0.3, *UNFOLDED[1:]]
    motion = ViaPointPath(path=pose_path("home", 4.0, DEFAULT_ARM), speed_scaling=True)
    reply = PlannerCore().plan(PlanRequest(motion, start=start))
    assert reply.ok and reply.trajectory is not None
    end = fk(reply.trajectory.positions[-1], DEFAULT_ARM)[:3, 3]
    assert end == pytest.approx(fk(UNFOLDED, DEFAULT_ARM)[:3, 3], abs=1e-6)


def test_a_pose_step_without_a_duration_takes_the_default() -> None:
    """``duration`` is optional for a pose (the schema's default 0: 4 s), as for a task file."""
    start = [0.3, *UNFOLDED[1:]]
    task = Task(steps=[TaskStep(kind="pose", pose="home")])
    checked = validate(task, start)
    assert checked.errors == []
    plan = checked.plans[0]
    assert plan is not None and plan.times[-1] >= DEFAULT_POSE_DURATION_S


# -- the step state machine -------------------------------------------------------------------


class Rig:
    """Drives a SequencerCore: the planner answers for real, the rest is scripted."""

    def __init__(self) -> None:
        self.core = SequencerCore()
        self.planner = PlannerCore()
        self.now = 0
        self.events: list[TaskEvent] = []
        self.sent: list[Query] = []
        self.auto_ack = True
        for name in ("planner", "controller", "can_bridge"):
            self.core.on_liveliness(name, True, 0)
        self.core.on_bridge_state(bridge_state("running"), 0)
        self.core.on_joint_state(joint_state(UNFOLDED), 0)

    def feed(self, actions: list[Action]) -> None:
        for action in actions:
            if isinstance(action, Publish):
                assert isinstance(action.message, TaskEvent)
                self.events.append(action.message)
                continue
            self.sent.append(action)
            reply = self.answer(action.request)
            if reply is not None:
                self.feed(self.core.on_reply(action.token, reply, "", self.now))

    def answer(self, request: Message) -> Message | None:
        if isinstance(request, PlanRequest):
            return self.planner.plan(request)
        if isinstance(request, TrajectoryGoal | GripperGoal):
            return GoalAck(accepted=True, goal_id=request.goal_id) if self.auto_ack else None
        if isinstance(request, CancelGoal):
            return GoalAck(accepted=True, goal_id=request.goal_id)
        if isinstance(request, ArmCommand):
            phase = {"fold_out": "folding_out", "fold_in": "folding_in", "stop": "stopped",
                     "clear": "running"}[request.action]  # fmt: skip
            return ArmCommandReply(ok=True, phase=phase, message="")
        raise AssertionError(request)

    def start(self, task: Task) -> None:
        v = validate(task, self.core.start_configuration())
        assert v.errors == []
        assert self.core.refuse(task) is None
        self.feed(self.core.start("t1", task, self.now))

    def goals(self) -> list[Message]:
        return [q.request for q in self.sent if isinstance(q.request, TrajectoryGoal | GripperGoal)]

    def result(self, status: str, reason: str = "", cause: str | None = None) -> None:
        goal = self.goals()[-1]
        kind = "gripper" if isinstance(goal, GripperGoal) else "trajectory"
        cause = cause or CAUSES[ResultStatus(status)]
        res = GoalResult(stamp_ns=self.now, seq=1, goal_id=goal.goal_id, kind=kind,  # type: ignore[attr-defined]
                         status=status, cause=cause, reason=reason)  # fmt: skip
        self.feed(self.core.on_result(res, self.now))

    def feedback(self, t: float) -> None:
        goal = self.goals()[-1]
        assert isinstance(goal, TrajectoryGoal)
        z6, z3 = [0.0] * 6, [0.0] * 3
        fb = ControllerFeedback(stamp_ns=self.now, seq=1, goal_id=goal.goal_id, state="tracking",
                                segment=0, t=t, reference=z6, actual=z6, error=z6, command=z6,
                                reference_xyz=z3, actual_xyz=z3, position_error=0.0)  # fmt: skip
        self.feed(self.core.on_feedback(fb, self.now))

    def control(self, action: str) -> bool:
        status, actions = self.core.control(TaskControl(action=action), self.now)
        self.feed(actions)
        return status.ok

    def names(self) -> list[str]:
        return [e.event for e in self.events if e.event != "step_progress"]


def test_runs_every_kind_of_step_in_order() -> None:
    rig = Rig()
    task = Task(steps=[
        TaskStep(kind="fold_out"), TaskStep(kind="move", path=square_task().steps[0].path),
        TaskStep(kind="gripper", opening=0.04), TaskStep(kind="wait", duration=1.0),
        TaskStep(kind="fold_in"),
    ])  # fmt: skip
    rig.start(task)
    assert rig.core.state == "running"
    # the fold completes when the bridge has shown the fold and is running again
    rig.feed(rig.core.on_bridge_state(bridge_state("running", 2), 1))
    assert rig.core.step == 0
    rig.feed(rig.core.on_bridge_state(bridge_state("folding_out", 3), 2))
    rig.feed(rig.core.on_bridge_state(bridge_state("running", 4, "fold_out complete"), 3))
    assert rig.core.step == 1
    plan = rig.sent[-2].request
    assert isinstance(plan, PlanRequest) and plan.start == UNFOLDED
    rig.feedback(9.6)
    assert rig.events[-1].event == "step_progress" and rig.events[-1].progress == pytest.approx(0.5)
    rig.result("succeeded")
    gripper = rig.goals()[-1]
    assert isinstance(gripper, GripperGoal) and gripper.opening == pytest.approx(0.04)
    rig.result("succeeded")
    assert rig.core.step == 3
    rig.now = NS // 2
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.step == 3 and rig.events[-1].progress == pytest.approx(0.5)
    rig.now = NS + 1
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.step == 4
    rig.feed(rig.core.on_bridge_state(bridge_state("folding_in", 5), rig.now))
    rig.feed(rig.core.on_bridge_state(bridge_state("running", 6), rig.now))
    assert rig.core.state == "succeeded"
    assert rig.names() == ["accepted"] + ["step_started", "step_finished"] * 5 + ["succeeded"]
    assert rig.core.status().progress == 1.0


def square_task() -> Task:
    return task_from_args([SQUARE, "40"])


def test_controller_abort_fails_the_task_with_its_reason() -> None:
    rig = Rig()
    rig.start(square_task())
    rig.result("aborted", "path tolerance of joint 2 exceeded: 0.2 rad > 0.1 rad")
    assert rig.core.state == "failed"
    assert rig.events[-1].event == "failed"
    assert rig.events[-1].reason.endswith(
        "step 1 (move): controller: goal aborted: path tolerance of joint 2 exceeded: "
        "0.2 rad > 0.1 rad"
    )
    assert rig.names()[-2:] == ["step_failed", "failed"]
    assert len(rig.goals()) == 1  # nothing after the failure


def test_refused_goal_and_estop_and_lost_service_fail() -> None:
    rig = Rig()
    rig.auto_ack = False
    rig.start(square_task())
    token = rig.sent[-1].token
    rig.feed(rig.core.on_reply(token, GoalAck(accepted=False, goal_id="x", reason="busy"), "", 0))
    assert rig.core.state == "failed" and "controller refused the goal: busy" in rig.core.reason

    rig = Rig()
    rig.start(square_task())
    rig.feed(rig.core.on_estop(EStop(stamp_ns=1, seq=1, engaged=True, source="supervisor",
                                     reason="person too close"), 1))  # fmt: skip
    assert rig.core.reason.endswith("e-stop engaged by supervisor: person too close")
    assert isinstance(rig.sent[-1].request, CancelGoal)  # the goal does not outlive the task

    rig = Rig()
    rig.start(square_task())
    rig.feed(rig.core.on_liveliness("controller", False, 1))
    assert rig.core.reason.endswith("controller is gone (its liveliness token vanished)")
    assert rig.core.refuse(square_task()) is not None


def test_refuses_when_busy_missing_services_or_bridge_not_running() -> None:
    rig = Rig()
    rig.start(square_task())
    refused = rig.core.refuse(square_task())
    assert refused is not None and "busy: task t1 is running" in refused.errors[0]
    core = SequencerCore()
    core.on_liveliness("planner", True, 0)
    refused = core.refuse(square_task())
    assert refused is not None
    assert refused.errors == ["required service(s) not running: can_bridge, controller"]
    core.on_liveliness("controller", True, 0)
    core.on_liveliness("can_bridge", True, 0)
    core.on_bridge_state(bridge_state("estopped"), 0)
    refused = core.refuse(square_task())
    assert refused is not None and "the bridge is not running (estopped)" in refused.errors[0]


def test_cancel_mid_path_cancels_the_goal_and_ends_the_task() -> None:
    rig = Rig()
    rig.start(square_task())
    goal = rig.goals()[-1]
    rig.feedback(4.0)
    assert rig.control("cancel")
    cancel = rig.sent[-1].request
    assert isinstance(cancel, CancelGoal) and cancel.goal_id == goal.goal_id  # type: ignore[attr-defined]
    assert rig.core.state == "running"  # until the controller confirms the arm is at rest
    rig.result("cancelled", "cancelled: decelerated to rest")
    assert rig.core.state == "cancelled"
    assert rig.names()[-1] == "cancelled"
    assert len(rig.goals()) == 1
    assert not rig.control("resume")


def test_cancel_without_confirmation_asks_the_bridge_to_stop() -> None:
    rig = Rig()
    rig.start(square_task())
    assert rig.control("cancel")
    rig.now = 4 * NS
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.state == "cancelled" and "did not confirm the cancel" in rig.core.reason
    stop = [q.request for q in rig.sent if isinstance(q.request, ArmCommand)]
    assert stop == [ArmCommand(action="stop", source="sequencer")]


def test_pause_and_resume_replan_the_rest_from_where_the_arm_stopped() -> None:
    rig = Rig()
    rig.start(square_task())
    asked = [q.request for q in rig.sent if isinstance(q.request, PlanRequest)]
    first = rig.goals()[-1]
    assert isinstance(first, TrajectoryGoal)
    rig.feedback(5.0)
    assert rig.control("pause")
    assert isinstance(rig.sent[-1].request, CancelGoal)
    assert not rig.control("pause")  # already pausing
    rig.result("cancelled", "cancelled")
    assert rig.core.state == "paused" and rig.names()[-1] == "paused"
    stopped_at = [0.1, *UNFOLDED[1:]]
    rig.core.on_joint_state(joint_state(stopped_at, 2), rig.now)
    assert rig.control("resume")
    plan = rig.sent[-2].request
    # The same motion again, for the planner that made it: the plan and how far it got.
    assert isinstance(plan, PlanRequest) and plan.start == stopped_at
    assert plan.motion == asked[-1].motion
    assert plan.resume == PlanResume(trajectory=first.trajectory, reached=5.0)
    remaining = [i for i, t in enumerate(first.trajectory.times) if t > 5.0]
    second = rig.goals()[-1]
    assert isinstance(second, TrajectoryGoal) and second.goal_id != first.goal_id
    assert second.trajectory.via_indices == [-1, *remaining]
    assert second.trajectory.knot_kinds == ["start", *["via_point"] * len(remaining)]
    rig.feedback(second.trajectory.times[-1] / 2)
    assert rig.core.status().progress > 0.25
    rig.result("succeeded")
    rig.result("succeeded")  # the gripper
    assert rig.core.state == "succeeded"
    assert rig.names() == ["accepted", "step_started", "paused", "resumed", "step_finished",
                           "step_started", "step_finished", "succeeded"]  # fmt: skip


def test_pause_during_a_fold_takes_effect_after_it_and_a_wait_keeps_its_time() -> None:
    rig = Rig()
    rig.start(Task(steps=[TaskStep(kind="fold_out"), TaskStep(kind="wait", duration=2.0)]))
    assert rig.control("pause")
    assert rig.core.state == "running"
    rig.feed(rig.core.on_bridge_state(bridge_state("folding_out", 2), 0))
    rig.feed(rig.core.on_bridge_state(bridge_state("running", 3), 0))
    assert rig.core.state == "paused" and rig.core.step == 1
    rig.now = 10 * NS
    assert rig.control("resume")
    rig.now = 11 * NS
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.control("pause")
    assert rig.core.state == "paused"
    rig.now = 100 * NS
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.state == "paused"
    assert rig.control("resume")
    rig.now += NS - 1
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.state == "running"
    rig.now += 2
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.state == "succeeded"


def test_fold_failure_and_cancel_during_a_fold() -> None:
    rig = Rig()
    rig.start(Task(steps=[TaskStep(kind="fold_out")]))
    rig.feed(rig.core.on_bridge_state(bridge_state("folding_out", 2), 0))
    rig.feed(rig.core.on_bridge_state(bridge_state("arm_error", 3, "error 0x02: joint 2"), 0))
    assert rig.core.state == "failed"
    assert rig.core.reason.endswith("can_bridge: phase arm_error: error 0x02: joint 2")

    rig = Rig()
    rig.start(Task(steps=[TaskStep(kind="fold_in")]))
    assert rig.control("cancel")
    actions = [q.request for q in rig.sent if isinstance(q.request, ArmCommand)]
    assert [a.action for a in actions] == ["fold_in", "stop", "clear"]
    assert rig.core.state == "cancelled"


def test_same_inputs_same_outputs() -> None:
    def run() -> list[TaskEvent]:
        rig = Rig()
        rig.start(square_task())
        rig.feedback(3.0)
        rig.control("pause")
        rig.result("cancelled")
        rig.control("resume")
        rig.result("succeeded")
        rig.result("succeeded")
        return rig.events

    assert run() == run()


def test_the_documented_task_file_parses_and_validates() -> None:
    page = (ROOT / "docs" / "sequencer.md").read_text(encoding="utf-8")
    text = page.split("```toml\n", 1)[1].split("```", 1)[0]
    task = parse_task_text(text, source="docs/sequencer.md", base=ROOT)
    assert [s.kind for s in task.steps] == [
        "fold_out", "move", "move", "gripper", "wait", "pose", "fold_in",
    ]  # fmt: skip
    assert validate(task).errors == []


def test_a_path_from_the_folded_arm_says_to_unfold_it_first() -> None:
    folded = [math.radians(v) for v in (0.0, -90.0, -90.0, 0.0, -90.0, 0.0)]
    errors = validate(task_from_args([SQUARE]), start=folded).errors
    assert errors[0].startswith(f"{SQUARE}: step 1 (move): planner refused")
    assert errors[1].endswith("the arm is folded there: unfold it first (a fold_out step; "
                              "`manus run --fold-out ...` for the thesis form)")  # fmt: skip
    unfolded_first = Task(steps=[TaskStep(kind="fold_out"), *task_from_args([SQUARE]).steps])
    assert validate(unfolded_first, start=folded).errors == []


def test_a_bridge_state_published_late_does_not_end_a_fold() -> None:
    """The bridge publishes from two threads: its loop's 'running' (seq 4) may reach the bus
    after the 'folding_out' its fold request made (seq 5). Taken as the fold's end, the
    next step started while the arm was still folding (the chaos soak: 'bridge phase
    folding_out' right after the fold step)."""
    rig = Rig()
    rig.start(Task(steps=[TaskStep(kind="fold_out"), TaskStep(kind="gripper", opening=0.04)]))
    rig.feed(rig.core.on_bridge_state(bridge_state("folding_out", 5), 1))
    rig.feed(rig.core.on_bridge_state(bridge_state("running", 4), 2))  # late
    assert rig.core.step == 0 and rig.core.bridge_phase == "folding_out"
    rig.feed(rig.core.on_bridge_state(bridge_state("running", 6, "fold_out complete"), 3))
    assert rig.core.step == 1
    # a restarted bridge counts from 0 again, with newer stamps: taken
    restarted = dataclasses.replace(bridge_state("stopped", 0), stamp_ns=10)
    rig.core.on_bridge_state(restarted, 4)
    assert rig.core.bridge_phase == "stopped"


def test_a_fold_stopped_by_its_deadman_fails_the_task_with_the_bridge_detail() -> None:
    rig = Rig()
    rig.start(Task(steps=[TaskStep(kind="fold_in")]))
    fold = next(q.request for q in rig.sent if isinstance(q.request, ArmCommand))
    assert isinstance(fold, ArmCommand) and fold.heartbeat_timeout == pytest.approx(0.15)
    rig.feed(rig.core.on_bridge_state(bridge_state("folding_in", 2), 0))
    detail = "fold_in stopped: no command from the controller answering the newest joint state"
    rig.feed(rig.core.on_bridge_state(bridge_state("stopped", 3, detail), 0))
    assert rig.core.state == "failed"
    assert rig.core.reason.endswith(f"can_bridge: phase stopped: {detail}")


def _guardian(engaged: bool, seq: int = 0) -> GuardianReport:
    return GuardianReport(stamp_ns=0, seq=seq, action="stop_sent" if engaged else "counts",
                          sync_age_ms=12.0 if engaged else 0.0, syncs=100, answered=90,
                          stops_sent=10, late=0, engaged=engaged)  # fmt: skip


@pytest.mark.parametrize(
    ("reports", "named"),
    [
        ("engaged", "can_bridge stopped answering the arm"),
        ("counts", "can_bridge publishes none, though the arm computer is heard"),
        ("none", "the link to it is down"),
        ("before", "the link to it is down"),  # heard just before the cut: proves nothing
    ],
)
def test_joint_states_stopping_names_the_bridge_when_the_arm_computer_is_heard(
    reports: str, named: str
) -> None:
    rig = Rig()
    rig.start(square_task())
    last = rig.now
    if reports == "before":
        rig.feed(rig.core.on_guardian_report(_guardian(False), last + 50_000_000))
    for k in range(1, 10):
        rig.now = last + k * 60_000_000
        if reports in ("engaged", "counts") and (reports == "engaged" or k == 5):
            rig.feed(rig.core.on_guardian_report(_guardian(reports == "engaged", k), rig.now))
        rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.state == "failed"
    assert "no joint states from the arm for 540 ms" in rig.core.reason
    assert named in rig.core.reason, rig.core.reason


@pytest.mark.parametrize("back", ["states", "result", "silent"])
def test_a_sequencer_that_did_not_run_does_not_blame_the_bridge(back: str) -> None:
    """The sequencer frozen 1.5 s mid-move (SIGSTOP, or starved of the CPU): its first
    tick after it is no proof that the joint states stopped. The chaos soak saw it blame
    the bridge on waking, before it read the controller's result naming the heartbeat.
    Back, it judges the link from its return: the joint states that come on (nothing
    fails), the controller's result (its reason), or none for 540 ms (the link, then)."""
    rig = Rig()
    rig.start(square_task())
    assert rig.core.state == "running" and rig.goals()
    rig.feed(rig.core.on_tick(rig.now))  # it ticks while it runs
    rig.now += 1_500_000_000  # no tick, nothing read: the process did not run
    rig.feed(rig.core.on_tick(rig.now))
    assert rig.core.state == "running", rig.core.reason
    if back == "result":
        rig.result("aborted", "lost the supervisor's heartbeat", "heartbeat_lost")
        assert rig.core.state == "failed" and "heartbeat" in rig.core.reason, rig.core.reason
        return
    back_at = rig.now
    for k in range(1, 10):
        rig.now = back_at + k * 60_000_000
        if back == "states":
            rig.core.on_joint_state(joint_state(UNFOLDED, k), rig.now)
        rig.feed(rig.core.on_tick(rig.now))
    if back == "states":
        assert rig.core.state == "running", rig.core.reason
    else:
        assert rig.core.state == "failed"
        assert "no joint states from the arm for 540 ms" in rig.core.reason, rig.core.reason
        assert "the link to it is down" in rig.core.reason
