"""A killed sequencer or a cut link stops the arm at once (issue 19): the controller (moves,
gripper goals) and the bridge (folds) stop when the ``alive/<source>`` token of whoever
sends the goal's heartbeats vanishes, judged in lock-step on the simulator's truth as the
chaos soak judges it; a hang (the token stays) is left to the echo deadman; the token
event is a recorded input, so a replay gives the same outputs."""

from __future__ import annotations

from pathlib import Path

import pytest

from manus.protocol import FrameId, decode_move
from manus_stack.chaos import judge
from manus_stack.controlled import ControlledArm
from manus_stack.lockstep import LockStep
from manus_stack.regression import check_controller
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmCommand
from schemas.control import GripperGoal, Heartbeat, TrajectoryGoal
from schemas.liveliness import TokenGone
from schemas.state import JointState
from services.controller.goal_source import GoalSource
from services.recorder.writer import RecordingWriter
from tests.bridge_scenarios import MS, UNFOLDED, VelocityController, check_safety, running
from tests.test_fold_deadman import Mortal, fold_task_rig

PATHS = Path(__file__).resolve().parents[1] / "paths"
CYCLE_NS = judge.CYCLE_NS
TOKEN = "the sequencer's liveliness token went: process died or link cut"


class Echo:
    """Echoes every joint state with a Heartbeat from ``source`` while ``alive``."""

    def __init__(self, ls: LockStep, source: str = "sequencer") -> None:
        self.source = source
        self.alive = True
        self.seq = 0
        ls.subscribe(ep.JOINTS, self)

    def __call__(self, msg: Message, t_ns: int) -> list[tuple[str, Message]]:
        assert isinstance(msg, JointState)
        if not self.alive:
            return []
        self.seq += 1
        hb = Heartbeat(stamp_ns=t_ns, seq=self.seq, source=self.source, ref_seq=msg.seq,
                       ref_stamp_ns=msg.stamp_ns)  # fmt: skip
        return [(ep.HEARTBEAT, hb)]


def _stop_ms(ls: LockStep, seconds: float = 1.0) -> float:
    """Run ``seconds`` from a fault now: when the arm came to rest, as the soak judges it on
    the simulator's truth [ms after the fault] (and it did not move again)."""
    fault = ls.t_ns
    truth = [judge.from_truth(ls.sim.truth())]
    for _ in range(round(seconds * 1e9 / CYCLE_NS)):
        ls.run_for(CYCLE_NS / 1e9)
        truth.append(judge.from_truth(ls.sim.truth()))
    stop = judge.stop_after(truth, fault, ls.t_ns, ls.t_ns)
    assert stop.stop_ns is not None and stop.resumed_ns is None, stop
    return (stop.stop_ns - fault) / MS


def _at_offset(ls: LockStep, offset_ms: int) -> None:
    """Run to ``offset_ms`` after the next joint state."""
    last = [t for t, s, _ in ls.messages if s == ep.JOINTS][-1]
    ls.run_until(last + CYCLE_NS + offset_ms * MS)


def _moving_square(heartbeat_timeout: float = 0.1) -> tuple[ControlledArm, Echo]:
    arm = ControlledArm(UNFOLDED)
    arm.start()
    echo = Echo(arm.ls)
    goal = TrajectoryGoal(goal_id="sq", trajectory=arm.plan(PATHS / "thesis_square.txt"),
                          heartbeat_timeout=heartbeat_timeout)  # fmt: skip
    assert arm.submit(goal).accepted
    arm.ls.run_for(2.0)
    assert arm.results("sq") == []
    return arm, echo


def _joint_frames(ls: LockStep, since_ns: int) -> list[tuple[int, bool]]:
    return [
        (f.t_ns, decode_move(f.id, f.data).is_zero)
        for f in ls.bridge_frames
        if f.id == FrameId.JOINT and f.t_ns >= since_ns
    ]


# -- moves and gripper goals: the controller ------------------------------------------------


@pytest.mark.parametrize("offset_ms", [5, 25, 45])
def test_a_move_stops_at_once_when_its_heartbeat_senders_token_goes(offset_ms: int) -> None:
    arm, echo = _moving_square()
    _at_offset(arm.ls, offset_ms)
    echo.alive = False  # SIGKILL: the heartbeats stop and the token goes at once
    fault = arm.ls.t_ns
    arm.ls.token_gone("sequencer")
    result = arm.results("sq")
    assert len(result) == 1 and result[0].status == "aborted"
    assert result[0].reason.startswith(TOKEN), result[0].reason
    # the very next sync gets zeros (the zero command replaced the one sent for it)
    stop_ms = _stop_ms(arm.ls)
    frames = _joint_frames(arm.ls, fault)
    assert frames[0][1] and all(zero for _, zero in frames), frames[:3]
    assert stop_ms <= judge.STOP_LIMIT_NS / MS, stop_ms
    record = arm.ls.published(ep.TOKEN_GONE)[-1]
    assert isinstance(record, TokenGone) and record.stopped == result[0].reason
    echo.alive = True  # back (a new sequencer): nothing resumes by itself
    arm.ls.run_for(1.0)
    assert (
        all(zero for _, zero in _joint_frames(arm.ls, fault))
        and arm.core.source(GoalSource).run is None
    )
    check_safety(arm.ls)


def test_only_the_token_of_whoever_sends_the_heartbeats_counts() -> None:
    """A client that is not the sequencer (a test, a supervisor of its own) sends a goal and
    its heartbeats: the sequencer's token going, or another service's, stops nothing."""
    arm, echo = _moving_square()
    echo.source = "my-supervisor"  # has no token at all
    arm.ls.run_for(0.2)
    arm.ls.token_gone("sequencer")
    arm.ls.token_gone("planner")
    arm.ls.run_for(0.5)
    assert arm.results("sq") == []
    assert [m.stopped for m in arm.ls.published(ep.TOKEN_GONE)] == ["", ""]  # type: ignore[attr-defined]
    # a goal without a deadman is tied to nobody
    arm2 = ControlledArm(UNFOLDED)
    arm2.start()
    Echo(arm2.ls)
    assert arm2.submit(TrajectoryGoal(goal_id="free",
                       trajectory=arm2.plan(PATHS / "thesis_square.txt"))).accepted  # fmt: skip
    arm2.ls.run_for(0.5)
    arm2.ls.token_gone("sequencer")
    arm2.ls.run_for(0.3)
    assert arm2.results("free") == []


def test_a_goal_with_no_heartbeat_of_its_own_yet_is_left_to_the_echo_deadman() -> None:
    """Tied only once a heartbeat echoes the goal's first joint state or a later one: a
    goal started while its sender's heartbeats have not come (or no token is seen) runs
    on the echo's age, which stops it without any token."""
    arm = ControlledArm(UNFOLDED)
    arm.start()
    echo = Echo(arm.ls)
    arm.ls.run_for(0.3)
    echo.alive = False  # heartbeats stopped before the goal: none is the goal's
    goal = TrajectoryGoal(goal_id="sq", trajectory=arm.plan(PATHS / "thesis_square.txt"),
                          heartbeat_timeout=0.1)  # fmt: skip
    assert arm.submit(goal).accepted
    arm.ls.run_for(0.07)
    assert arm.core.source(GoalSource).run is not None
    arm.ls.token_gone("sequencer")
    assert arm.results("sq") == []
    result = arm.run_until_result("sq", timeout_s=1.0)
    assert result.reason.startswith("lost the supervisor's heartbeat"), result.reason


def test_a_gripper_goal_stops_at_once_too() -> None:
    arm = ControlledArm(UNFOLDED)
    arm.start()
    echo = Echo(arm.ls)
    assert arm.query(ep.GRIPPER_GOAL, GripperGoal(goal_id="g", opening=0.08,
                                                  heartbeat_timeout=0.1)).accepted  # fmt: skip
    arm.ls.run_for(0.3)
    assert arm.results("g") == []
    echo.alive = False
    fault = arm.ls.t_ns
    arm.ls.token_gone("sequencer")
    [result] = arm.results("g")
    assert result.status == "aborted" and result.reason.startswith(TOKEN), result.reason
    arm.ls.run_for(0.3)
    grips = [decode_move(f.id, f.data).gripper for f in arm.ls.bridge_frames
             if f.id == FrameId.JOINT and f.t_ns >= fault]  # fmt: skip
    assert grips and set(grips) == {0}


def test_the_token_event_replays_exactly_where_the_controller_took_it(tmp_path: Path) -> None:
    """A token is no sample: the controller's TokenGone record says after which joint state
    it came, and the regression check feeds it there even when the recorder logged it
    after the next joint state."""
    arm, echo = _moving_square()
    _at_offset(arm.ls, 30)
    echo.alive = False
    arm.ls.token_gone("sequencer")
    arm.ls.run_for(0.5)
    states = sorted(t for t, s, _ in arm.ls.messages if s == ep.JOINTS)
    path = tmp_path / "token.mcap"
    with RecordingWriter(path) as writer:
        for t_ns, suffix, msg in sorted(
            (
                (next(x for x in states if x > t) + MS if s == ep.TOKEN_GONE else t, s, m)
                for t, s, m in arm.ls.messages
            ),
            key=lambda item: item[0],
        ):
            writer.write(suffix, msg, t_ns)
    result = check_controller(path)
    assert result.ok, result.difference
    assert result.compared > 50


# -- folds: the bridge ------------------------------------------------------------------------


def _folding() -> tuple[LockStep, Echo]:
    ls = running(UNFOLDED)
    ls.subscribe(ep.JOINTS, VelocityController((0.0,) * 6))
    echo = Echo(ls)
    ls.run_for(0.2)
    fold = ArmCommand(action="fold_in", source="sequencer", heartbeat_timeout=0.15)
    assert ls.arm_command(fold).ok
    ls.run_for(1.0)
    assert ls.bridge.phase == "folding_in"
    return ls, echo


@pytest.mark.parametrize("offset_ms", [5, 25, 45])
def test_a_fold_stops_at_once_when_its_heartbeat_senders_token_goes(offset_ms: int) -> None:
    ls, echo = _folding()
    _at_offset(ls, offset_ms)
    echo.alive = False
    fault = ls.t_ns
    ls.token_gone("sequencer")
    assert ls.bridge.phase == "stopped"
    assert ls.bridge.detail == f"fold_in stopped: {TOKEN} (it sent the heartbeats)"
    stop_ms = _stop_ms(ls)
    sent = [f for f in ls.bridge_frames if f.t_ns >= fault]
    assert sent[0].id == FrameId.STOP, sent[0]  # 0x370 at the very next sync
    assert stop_ms <= judge.STOP_LIMIT_NS / MS, stop_ms
    echo.alive = True  # nothing resumes by itself
    ls.run_for(1.0)
    assert {f.id for f in ls.bridge_frames if f.t_ns >= fault} == {FrameId.STOP}
    check_safety(ls)


def test_a_fold_of_another_heartbeat_sender_or_a_hang_goes_on() -> None:
    ls, echo = _folding()
    ls.token_gone("planner")  # not its heartbeats' sender
    echo.source = "my-supervisor"
    ls.run_for(0.2)
    ls.token_gone("sequencer")  # its heartbeats come from a client without a token now
    ls.run_for(0.3)
    assert ls.bridge.phase == "folding_in"
    records = ls.published(ep.BRIDGE_TOKEN_GONE)
    assert [(r.service, r.stopped) for r in records] == [  # type: ignore[attr-defined]
        ("planner", ""),
        ("sequencer", ""),
    ]


def test_a_killed_sequencer_in_a_task_stops_the_fold_within_the_soaks_limit() -> None:
    """Through the sequencer core: its fold step asks for the deadman, its heartbeats carry
    source 'sequencer'; killed (heartbeats stop, the token goes), the fold is at rest
    within the soak's 180 ms (before: the 0.15 s echo deadman, 216-239 ms live)."""
    rig = fold_task_rig()
    assert isinstance(rig.seq, Mortal)
    rig.seq.running = False
    rig.ls.token_gone("sequencer")
    assert _stop_ms(rig.ls) <= judge.STOP_LIMIT_NS / MS
    assert rig.ls.bridge.phase == "stopped" and TOKEN in rig.ls.bridge.detail


@pytest.mark.parametrize("gone", [True, False])
def test_the_bridge_drops_the_command_of_a_controller_whose_token_went(gone: bool) -> None:
    """A router restart cuts the controller off after its command for the coming sync
    arrived: without its token that command is dropped, zeros at that very sync (before:
    the arm moved one more cycle on it)."""
    ls = running(UNFOLDED)
    controller = VelocityController((10.0, 0, 0, 0, 0, 0))
    ls.subscribe(ep.JOINTS, controller)
    ls.run_for(1.0)
    _at_offset(ls, 15)  # the command for the coming sync is in
    cut = ls.t_ns
    controller.stop_after_ns = cut
    if gone:
        ls.token_gone("controller")
        assert ls.published(ep.BRIDGE_TOKEN_GONE)[-1].stopped.startswith(  # type: ignore[attr-defined]
            "the controller's liveliness token went"
        )
    ls.run_for(0.3)
    first = _joint_frames(ls, cut)[0]
    assert first[1] is gone, first
