"""A task submitted while the bridge is still starting waits for it, a bounded time
(``services/sequencer/bridge_wait.py``), in the sequencer's core: held, then validated
and started once the bridge runs; refused at once by a stopped bridge; refused at the
end of ``bridge_wait_s`` with the phase reached."""

from __future__ import annotations

import dataclasses

import pytest

from manus.errors import ConfigError
from schemas.planning import PlanRequest
from schemas.sequencing import Task, TaskState
from services.planner.core import PlannerCore
from services.sequencer.actions import Action, Query, Reply
from services.sequencer.config import SequencerConfig
from services.sequencer.core import SequencerCore
from tests.test_sequencer_core import UNFOLDED, bridge_state, joint_state, square_task

NS = 1_000_000_000


class Starting:
    """A core whose services are up and whose bridge is starting (waiting_power_up)."""

    def __init__(self, wait_s: float = 30.0) -> None:
        self.core = SequencerCore(SequencerConfig(bridge_wait_s=wait_s))
        self.seq = 0
        for name in ("planner", "controller", "can_bridge"):
            self.core.on_liveliness(name, True, 0)
        self.bridge("waiting_power_up", 0, "bus open: waiting for the arm")

    def bridge(self, phase: str, t_ns: int, detail: str = "") -> list[Action]:
        self.seq += 1
        return self.core.on_bridge_state(bridge_state(phase, self.seq, detail), t_ns)

    def joints(self, t_ns: int, valid: bool = True) -> list[Action]:
        self.seq += 1
        js = dataclasses.replace(joint_state(UNFOLDED, self.seq), valid=valid)
        return self.core.on_joint_state(js, t_ns)


def _replies(actions: list[Action]) -> list[Reply]:
    return [a for a in actions if isinstance(a, Reply)]


def _validate(core: SequencerCore, actions: list[Action], t_ns: int) -> list[Action]:
    """Answer the plan queries among ``actions`` with the real planner, to the end."""
    planner = PlannerCore()
    out: list[Action] = []
    queue = list(actions)
    while queue:
        action = queue.pop(0)
        if isinstance(action, Query) and isinstance(action.request, PlanRequest):
            queue += core.on_reply(action.token, planner.plan(action.request), "", t_ns)
        else:
            out.append(action)
    return out


def test_a_task_waits_for_a_starting_bridge_and_starts_once_it_runs() -> None:
    rig = Starting()
    core = rig.core
    assert core.submit(square_task(), 1 * NS, "a") == []  # held, not refused
    status = core.status()
    assert status.state == TaskState.VALIDATING and status.task_id == "a"
    assert status.message == "waiting for the bridge to run (phase waiting_power_up), at most 30 s"
    (other,) = core.submit(square_task(), 1 * NS, "b")
    assert isinstance(other, Reply) and other.submission == "b"
    assert other.reply.errors == [
        "busy: task a waits for the bridge to run; submit again once it is accepted or refused"
    ]
    for phase in ("entering_joint_mode", "initialising"):
        assert rig.bridge(phase, 2 * NS) == []
        assert rig.joints(2 * NS, valid=False) == []  # start-up states: not valid
        assert core.on_tick(3 * NS) == []
    assert rig.bridge("running", 4 * NS, "initialised: commands reach the arm") == []
    first = rig.joints(4 * NS)  # running and a valid joint state: validated now
    assert [type(a) for a in first] == [Query]
    (answer,) = _replies(_validate(core, first, 4 * NS))
    assert answer.submission == "a" and answer.reply.accepted
    assert core.state == TaskState.RUNNING and core.task_id == "a"


def test_a_bridge_that_stops_starting_refuses_the_held_task_at_once() -> None:
    rig = Starting()
    assert rig.core.submit(square_task(), 1 * NS, "a") == []
    assert rig.bridge("entering_joint_mode", 2 * NS) == []
    (refused,) = _replies(rig.bridge("arm_error", 3 * NS, "arm error 4: absolute encoder error"))
    assert refused.submission == "a" and not refused.reply.accepted
    assert refused.reply.errors == [
        "the bridge is not running (arm_error: arm error 4: absolute encoder error); a task "
        "starts only in phase running"
    ]
    assert rig.core.validating == "" and rig.core.status().state == TaskState.NONE


def test_a_stopped_bridge_refuses_at_once_and_a_slow_one_at_the_end_of_the_wait() -> None:
    rig = Starting(wait_s=5.0)
    rig.bridge("estopped", 1 * NS, "e-stop engaged by pad")
    (refused,) = _replies(rig.core.submit(square_task(), 1 * NS, "a"))
    assert "the bridge is not running (estopped: e-stop engaged by pad)" in refused.reply.errors[0]
    rig.bridge("waiting_power_up", 2 * NS, "e-stop released by pad: waiting for the arm")
    assert rig.core.submit(square_task(), 2 * NS, "b") == []
    assert rig.core.on_tick(6 * NS) == []  # 4 s: still waiting
    (late,) = _replies(rig.core.on_tick(7 * NS))
    assert late.submission == "b" and late.reply.errors == [
        "the bridge did not get ready within 5 s (bridge_wait_s; waited 5.0 s, phase "
        "waiting_power_up: e-stop released by pad: waiting for the arm); a task starts only "
        "in phase running, with a valid joint state"
    ]
    assert rig.core.submit(square_task(), 8 * NS, "c") == []  # held: the wait is free again
    assert rig.core.validating == "c"


def test_running_without_a_joint_state_yet_holds_too_and_a_held_task_can_be_withdrawn() -> None:
    rig = Starting()
    rig.bridge("running", 1 * NS)
    assert rig.core.submit(square_task(), 1 * NS, "a") == []  # no valid joint state yet
    (gone,) = rig.core.withdraw("a", 2 * NS, "the sequencer is shutting down")
    assert isinstance(gone, Reply) and gone.reply.errors == ["the sequencer is shutting down"]
    assert rig.core.validating == ""
    assert rig.joints(3 * NS) == []  # nothing held any more


def test_without_a_wait_a_starting_bridge_refuses_at_once_as_before() -> None:
    rig = Starting(wait_s=0.0)
    (refused,) = _replies(rig.core.submit(square_task(), 1 * NS, "a"))
    assert refused.reply.errors[0].startswith(
        "the bridge is not running (waiting_power_up: bus open: waiting for the arm)"
    )
    with pytest.raises(ConfigError, match=r"bridge_wait_s = -1.0 s is outside 0..3600 s"):
        SequencerConfig(bridge_wait_s=-1.0)


def test_services_not_seen_yet_are_waited_for_and_the_task_starts_once_they_are_up() -> None:
    # `manus up` starts them together; a loaded sequencer may hear their tokens late
    core = SequencerCore(SequencerConfig(bridge_wait_s=30.0))
    core.on_liveliness("can_bridge", True, 0)
    core.on_bridge_state(bridge_state("running", 1, "initialised"), 0)
    core.on_joint_state(joint_state(UNFOLDED, 2), 0)
    assert core.submit(square_task(), 1 * NS, "a") == []  # held, not refused
    assert core.status().message == "waiting for controller, planner to start, at most 30 s"
    assert core.on_liveliness("planner", True, 2 * NS) == []
    first = core.on_liveliness("controller", True, 3 * NS)
    assert [type(a) for a in first] == [Query]  # every one up: validated now
    (accepted,) = _replies(_validate(core, first, 3 * NS))
    assert accepted.reply.accepted and accepted.submission == "a"


def test_services_that_never_come_are_named_at_the_end_of_the_wait() -> None:
    core = SequencerCore(SequencerConfig(bridge_wait_s=5.0))
    core.on_bridge_state(bridge_state("running", 1, "initialised"), 0)
    core.on_joint_state(joint_state(UNFOLDED, 2), 0)
    assert core.submit(square_task(), 0, "a") == []
    assert _replies(core.on_tick(4 * NS)) == []
    (late,) = _replies(core.on_tick(6 * NS))
    assert late.reply.errors == [
        "required service(s) not running: can_bridge, controller, planner (not up within "
        "5 s of the submission, bridge_wait_s; waited 6.0 s)"
    ]


def test_a_service_seen_up_and_gone_is_not_waited_for() -> None:
    rig = Starting()
    rig.bridge("running", 1 * NS, "initialised")
    rig.joints(1 * NS)
    rig.core.on_liveliness("planner", False, 1 * NS)
    (refused,) = _replies(rig.core.submit(square_task(), 2 * NS, "a"))
    assert refused.reply.errors == ["required service(s) not running: planner"]


@pytest.mark.parametrize("wait_s", [0.0, 30.0])
def test_missing_services_without_a_running_bridge_refuse_at_once(wait_s: float) -> None:
    core = SequencerCore(SequencerConfig(bridge_wait_s=wait_s))
    (refused,) = _replies(core.submit(Task(steps=square_task().steps), 0, "a"))
    assert refused.reply.errors == [
        "required service(s) not running: can_bridge, controller, planner"
    ]
