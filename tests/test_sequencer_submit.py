"""The sequencer's submission path in its core (refuse, validate with planner queries,
answer, start), the step table, and the submission over Zenoh with a slow planner."""

from __future__ import annotations

import itertools
import threading
import time
from collections.abc import Iterator
from pathlib import Path as FilePath

import pytest
from hypothesis import given
from hypothesis import strategies as st

from manus.node import Node
from manus.session import ZenohSettings
from manus_stack.task_lockstep import TaskLockStep
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmCommand, EStop
from schemas.control import CancelGoal, GripperGoal, TrajectoryGoal
from schemas.planning import PlanReply, PlanRequest
from schemas.sequencing import (
    StepKind,
    SubmitReply,
    Task,
    TaskControl,
    TaskEvent,
    TaskState,
    TaskStep,
)
from services.planner.core import PlannerCore
from services.sequencer.actions import Action, Publish, Query, Reply
from services.sequencer.client import TaskClient
from services.sequencer.core import SequencerCore
from services.sequencer.shell import SequencerShell
from services.sequencer.steps import STEP_TYPES
from services.sequencer.taskfile import parse_task_text, task_from_args
from services.sequencer.wait_step import WaitStep
from tests.conftest import eventually
from tests.sequencer_fakes import FakeBridge, FakeController
from tests.test_sequencer_core import SQUARE, UNFOLDED, bridge_state, far_task, joint_state
from tests.test_sequencer_core import Rig as CoreRig

ROOT = FilePath(__file__).resolve().parent.parent
NS = 1_000_000_000


def ready_core() -> SequencerCore:
    core = SequencerCore()
    for name in ("planner", "controller", "can_bridge"):
        core.on_liveliness(name, True, 0)
    core.on_bridge_state(bridge_state("running"), 0)
    core.on_joint_state(joint_state(UNFOLDED), 0)
    return core


def replies(actions: list[Action]) -> list[Reply]:
    return [a for a in actions if isinstance(a, Reply)]


def queries(actions: list[Action]) -> list[Query]:
    return [a for a in actions if isinstance(a, Query)]


def events(actions: list[Action]) -> list[str]:
    return [
        a.message.event
        for a in actions
        if isinstance(a, Publish) and not isinstance(a, Reply) and isinstance(a.message, TaskEvent)
    ]


def test_a_task_is_validated_by_planner_queries_then_answered_and_started() -> None:
    core, planner = ready_core(), PlannerCore()
    task = task_from_args([SQUARE, "40", SQUARE])
    out = core.submit(task, 10, "a")
    (ask,) = out  # one plan at a time
    assert isinstance(ask, Query) and ask.suffix == ep.PLAN and ask.reply_type is PlanReply
    assert isinstance(ask.request, PlanRequest) and ask.request.start == UNFOLDED
    status = core.status()
    assert (status.state, status.task_id, status.total) == (TaskState.VALIDATING, "a", 3)
    assert not core.busy and core.validating == "a"

    second = core.submit(task, 11, "b")  # one validation at a time
    assert [r.submission for r in replies(second)] == ["b"] and not queries(second)
    assert replies(second)[0].reply.errors == [
        "busy: task a is being validated; submit again once it is accepted or refused"
    ]
    pause, _ = core.control(TaskControl(action="pause"), 12)
    assert not pause.ok and pause.state == TaskState.VALIDATING

    out = core.on_reply(ask.token, planner.plan(ask.request), "", 20)
    (ask2,) = out
    assert isinstance(ask2, Query) and isinstance(ask2.request, PlanRequest)
    assert ask2.request.start != UNFOLDED  # from where the first move leaves the arm
    out = core.on_reply(ask2.token, planner.plan(ask2.request), "", 30)
    (reply,) = replies(out)
    assert reply.submission == "a" and reply.suffix == ep.SUBMIT
    assert reply.reply == SubmitReply(accepted=True, task_id="a")
    assert out[-1] is reply  # after the task's first actions, as the shell did
    assert events(out) == ["accepted", "step_started"]
    assert core.state == TaskState.RUNNING and core.task_id == "a" and core.validating == ""
    plan = queries(out)[-1]  # the first move planned again from the newest joint state
    assert isinstance(plan.request, PlanRequest) and plan.request.start == UNFOLDED


def test_refused_at_once_without_a_query() -> None:
    core = SequencerCore()
    out = core.submit(task_from_args([SQUARE]), 0, "x")
    (reply,) = out
    assert isinstance(reply, Reply) and reply.submission == "x"
    assert reply.reply.errors == [
        "required service(s) not running: can_bridge, controller, planner"
    ]
    assert core.status().state == TaskState.NONE


def test_validation_errors_refuse_the_task_and_leave_the_last_one_as_it_was() -> None:
    core, planner = ready_core(), PlannerCore()
    task = far_task()
    task = Task(steps=[*task.steps, TaskStep(kind=StepKind.GRIPPER, opening=0.095)])
    out = core.submit(task, 0, "f")
    asked = 0
    while not replies(out):
        (ask,) = out
        assert isinstance(ask, Query) and isinstance(ask.request, PlanRequest)
        asked += 1
        out = core.on_reply(ask.token, planner.plan(ask.request), "", asked)
    (reply,) = out
    assert isinstance(reply, Reply) and not reply.reply.accepted
    assert reply.reply.errors[0].startswith("far.toml:6: step 3 (move): planner refused")
    assert reply.reply.errors[-1] == "step 7 (gripper): gripper opening 95 mm is outside 0..90 mm"
    assert asked == 3  # steps 1, 3 and 6 (step 4 starts where step 3 could not go)
    assert core.status().state == TaskState.NONE and core.task_id == ""


def test_what_changed_while_planning_is_checked_again() -> None:
    core = ready_core()
    (ask,) = core.submit(task_from_args([SQUARE]), 0, "s")
    assert isinstance(ask, Query) and isinstance(ask.request, PlanRequest)
    plan = PlannerCore().plan(ask.request)
    core.on_bridge_state(bridge_state("estopped", 2), 1)
    (reply,) = core.on_reply(ask.token, plan, "", 2)
    assert isinstance(reply, Reply) and not reply.reply.accepted
    assert "the bridge is not running (estopped)" in reply.reply.errors[0]
    assert core.state == TaskState.NONE


def test_a_planner_that_does_not_answer_and_a_withdrawn_submission() -> None:
    core = ready_core()
    task = task_from_args([SQUARE, "0", SQUARE])
    (ask,) = core.submit(task, 0, "p")
    assert isinstance(ask, Query)
    (reply,) = core.on_reply(ask.token, None, "planner/plan: no reply within 5 s", 5 * NS)
    assert isinstance(reply, Reply)
    assert reply.reply.errors == [
        f"{SQUARE}: step 1 (move): cannot plan: planner/plan: no reply within 5 s",
        f"{SQUARE}: step 3 (move): not planned: planner/plan: no reply within 5 s",
    ]

    (ask,) = core.submit(task, 6 * NS, "w")
    assert isinstance(ask, Query) and isinstance(ask.request, PlanRequest)
    assert core.withdraw("other", 7 * NS, "no") == []
    (gone,) = core.withdraw("w", 7 * NS, "validation did not finish within 20 s")
    assert isinstance(gone, Reply) and gone.reply.errors == [
        "validation did not finish within 20 s"
    ]
    late = PlannerCore().plan(ask.request)
    assert core.on_reply(ask.token, late, "", 8 * NS) == []  # ignored
    assert core.validating == "" and core.status().state == TaskState.NONE
    assert isinstance(core.submit(task, 9 * NS, "n")[0], Query)  # the next one is validated


def test_same_submission_same_outputs() -> None:
    def run() -> list[bytes]:
        core, planner = ready_core(), PlannerCore()
        out = core.submit(task_from_args([SQUARE, "40", SQUARE]), 5, "d")
        seen: list[bytes] = []
        while out:
            seen += [a.request.encode() if isinstance(a, Query) else a.message.encode()
                     for a in out]  # fmt: skip
            ask = queries(out)[0] if queries(out) else None
            if ask is None or not isinstance(ask.request, PlanRequest):
                break
            out = core.on_reply(ask.token, planner.plan(ask.request), "", 9)
        return seen

    first = run()
    assert len(first) > 4 and first == run()


def test_the_lockstep_harness_runs_the_cores_submission_path() -> None:
    rig = TaskLockStep()
    rig.start_arm()
    reply = rig.submit(task_from_args([SQUARE]))  # the arm powers up folded
    assert not reply.accepted and "unfold it first" in reply.errors[-1]
    plans = [r for r in rig.requests if isinstance(r, PlanRequest)]
    assert len(plans) == 1  # the validation's plan request went to the planner core
    assert rig.seq.state == TaskState.NONE and not rig.events


def test_a_wait_ends_even_when_a_joint_state_comes_after_its_end_before_the_tick() -> None:
    # A joint state past the wait's end used to clear the step deadline it shared with
    # the timeouts: the wait then never ended.
    core = ready_core()
    core.start("w", Task(steps=[TaskStep(kind=StepKind.WAIT, duration=1.0)]), 0)
    core.on_joint_state(joint_state(UNFOLDED, 2), NS + 1)
    out = core.on_tick(NS + 2)
    assert events(out) == ["step_finished", "succeeded"]


def test_the_documented_task_runs_in_lockstep_to_the_end() -> None:
    page = (ROOT / "docs" / "sequencer.md").read_text(encoding="utf-8")
    text = page.split("```toml\n", 1)[1].split("```", 1)[0]
    task = parse_task_text(text, source="docs/sequencer.md", base=ROOT)
    assert StepKind.WAIT in [s.kind for s in task.steps]
    rig = TaskLockStep()
    rig.start_arm()
    reply = rig.submit(task)
    assert reply.accepted, reply.errors
    rig.run_while_busy(200.0)
    assert rig.seq.state == TaskState.SUCCEEDED, rig.seq.reason
    assert rig.names() == ["accepted"] + ["step_started", "step_finished"] * 7 + ["succeeded"]


def test_the_core_runs_steps_through_the_table(monkeypatch: pytest.MonkeyPatch) -> None:
    assert set(STEP_TYPES) == set(StepKind)
    begun: list[float] = []

    class CountedWait(WaitStep):
        @classmethod
        def problems(cls, spec: TaskStep) -> list[str]:
            return ["counted"] if spec.duration == 7.0 else []

        def begin(self) -> list[Action]:
            begun.append(self.spec.duration)
            return super().begin()

    monkeypatch.setitem(STEP_TYPES, StepKind.WAIT, CountedWait)
    core = ready_core()
    (reply,) = core.submit(Task(steps=[TaskStep(kind=StepKind.WAIT, duration=7.0)]), 0, "c")
    assert isinstance(reply, Reply) and reply.reply.errors == ["step 1 (wait): counted"]
    out = core.submit(Task(steps=[TaskStep(kind=StepKind.WAIT, duration=0.5)]), 0, "d")
    assert replies(out)[0].reply.accepted and begun == [0.5]


# -- over Zenoh ----------------------------------------------------------------------------


class SlowPlanner:
    """A planner that takes ``delay`` [s] to answer (the real planner core behind it)."""

    def __init__(self, settings: ZenohSettings, delay: float) -> None:
        self.node = Node("planner", settings)
        self.core = PlannerCore()
        self.delay = delay
        self.node.queryable(self.node.keys(ep.PLAN), PlanRequest, self._plan, locked=False)

    def _plan(self, request: PlanRequest) -> PlanReply:
        time.sleep(self.delay)
        return self.core.plan(request)

    def close(self) -> None:
        self.node.close()


@pytest.fixture
def slow_stack(zenoh_settings: ZenohSettings) -> Iterator[tuple[SequencerShell, TaskClient]]:
    planner = SlowPlanner(zenoh_settings, 0.5)
    bridge = FakeBridge(zenoh_settings)
    controller = FakeController(zenoh_settings, bridge)
    sequencer = SequencerShell(zenoh_settings, query_timeout=3.0)
    node = Node("test_supervisor", zenoh_settings, liveliness=False)
    try:
        core = sequencer.core
        eventually(lambda: not core.missing_services() and core.latest is not None
                   and core.bridge_phase == "running")  # fmt: skip
        yield sequencer, TaskClient(node)
    finally:
        for part in (node, sequencer, controller, bridge, planner):
            part.close()


def test_status_answers_while_a_submission_validates_over_zenoh(
    slow_stack: tuple[SequencerShell, TaskClient],
) -> None:
    sequencer, client = slow_stack
    got: list[SubmitReply] = []
    first = threading.Thread(target=lambda: got.append(client.submit(task_from_args([SQUARE]))))
    first.start()
    try:
        # the submit handler waits for the core's answer without holding the node lock
        eventually(lambda: client.control("status").state == TaskState.VALIDATING, timeout=5.0)
        assert not got
        # Zenoh hands a queryable one query at a time: this one waits for the first's
        # answer, then finds its task running (the core refuses a submission made while
        # another validates too: test_a_task_is_validated_by_planner_queries_...)
        second = client.submit(task_from_args([SQUARE]))
    finally:
        first.join(timeout=10.0)
    assert len(got) == 1 and got[0].accepted, got
    assert not second.accepted and second.errors[0].startswith("busy: task ")
    assert (sequencer.submitted, sequencer.refused) == (1, 1)
    status = client.control("status")
    assert status.task_id == got[0].task_id and status.state == TaskState.RUNNING


# -- any order of inputs ---------------------------------------------------------------------

OPS = ("pause", "resume", "cancel", "tick", "long_tick", "joints", "feedback", "succeeded",
       "cancelled", "aborted", "fold_done", "running", "arm_error", "estop")  # fmt: skip
FINAL = {"succeeded", "failed", "cancelled"}


def drive(ops: list[str]) -> tuple[CoreRig, list[bytes]]:
    """Start a task of every kind of step, apply ``ops``, then cancel and let time pass."""
    rig = CoreRig()
    ended: set[str] = set()  # goals whose result the controller published
    folds_done: list[int] = []  # queries sent when the bridge showed a whole fold
    rig.start(Task(steps=[
        TaskStep(kind=StepKind.FOLD_OUT), *task_from_args([SQUARE, "40"]).steps,
        TaskStep(kind=StepKind.WAIT, duration=1.0), TaskStep(kind=StepKind.FOLD_IN),
    ]))  # fmt: skip
    for seq, op in enumerate(ops, start=2):
        if op in ("succeeded", "cancelled", "aborted") and rig.goals():
            ended.add(goal_id(rig.goals()[-1]))
        if op == "fold_done":
            folds_done.append(len(rig.sent))
        apply(rig, op, seq)
        check(rig)
    rig.control("cancel")
    for _ in range(10):  # a cancel ends the task within cancel_timeout_s (3 s)
        rig.now += NS // 2
        rig.feed(rig.core.on_tick(rig.now))
    check(rig)
    assert not rig.core.busy and rig.names()[-1] in FINAL, rig.names()
    # no goal outlives the task: it ended, or the sequencer cancelled it, or had the
    # bridge stop the arm
    requests = [q.request for q in rig.sent]
    cancelled = {r.goal_id for r in requests if isinstance(r, CancelGoal)}
    stopped = any(isinstance(r, ArmCommand) and r.action == "stop" for r in requests)
    for goal in map(goal_id, rig.goals()):
        assert goal in ended | cancelled or stopped, (goal, rig.names())
    # ... nor a fold: it was seen through, or the bridge was told to stop
    for i, r in enumerate(requests):
        if isinstance(r, ArmCommand) and r.action.startswith("fold_"):
            stop_after = any(isinstance(x, ArmCommand) and x.action == "stop"
                             for x in requests[i:])  # fmt: skip
            assert any(n > i for n in folds_done) or stop_after, rig.names()
    return rig, [e.encode() for e in rig.events] + [q.request.encode() for q in rig.sent]


def goal_id(goal: Message) -> str:
    assert isinstance(goal, TrajectoryGoal | GripperGoal)
    return goal.goal_id


def apply(rig: CoreRig, op: str, seq: int) -> None:
    core, goals = rig.core, rig.goals()
    if op in ("pause", "resume", "cancel"):
        rig.control(op)
    elif op in ("tick", "long_tick"):
        rig.now += NS // 10 if op == "tick" else 5 * NS
        rig.feed(core.on_tick(rig.now))
    elif op == "joints":
        out = core.on_joint_state(joint_state(UNFOLDED, seq), rig.now)
        rig.feed([a for a in out if not (isinstance(a, Publish) and a.suffix == ep.HEARTBEAT)])
    elif op == "feedback" and goals and isinstance(goals[-1], TrajectoryGoal):
        rig.feedback(goals[-1].trajectory.times[-1] * (seq % 10) / 10)
    elif op in ("succeeded", "cancelled", "aborted") and goals:
        rig.result(op, "test")
    elif op == "fold_done":  # the bridge shows a fold, then running again
        for phase in ("folding_out", "folding_in", "running"):
            rig.feed(core.on_bridge_state(bridge_state(phase, seq), rig.now))
    elif op in ("running", "arm_error"):
        rig.feed(core.on_bridge_state(bridge_state(op, seq), rig.now))
    elif op == "estop":
        stop = EStop(stamp_ns=rig.now, seq=seq, engaged=True, source="test", reason="")
        rig.feed(core.on_estop(stop, rig.now))


def check(rig: CoreRig) -> None:
    """The events tell one story: accepted first, one final event last, steps in order."""
    names = rig.names()
    assert names[0] == "accepted"
    finals = [i for i, n in enumerate(names) if n in FINAL]
    assert len(finals) <= 1 and (not finals or finals[0] == len(names) - 1), names
    assert rig.core.busy == (not finals)
    steps = [e.step for e in rig.events if e.event == "step_started"]
    assert steps == sorted(steps) and len(set(steps)) >= len(steps) - names.count("resumed")
    paused = [n for n in names if n in ("paused", "resumed")]
    assert all(a != b for a, b in itertools.pairwise(paused)), names
    status = rig.core.status()
    assert 0.0 <= status.progress <= 1.0 and status.state == rig.core.state


@given(st.booleans(), st.lists(st.sampled_from(OPS), max_size=30))
def test_any_order_of_inputs_tells_one_story_and_a_cancel_ends_it(
    unfolded: bool, ops: list[str]
) -> None:
    ops = ["fold_done", *ops] if unfolded else ops  # half of them start past the fold
    _, first = drive(ops)
    _, again = drive(ops)
    assert first == again  # same inputs, same outputs
