"""The simulator's 60 ms cycle, reply window and latching, driven through raw frames only."""

from __future__ import annotations

import pytest

from manus.protocol import (
    ZERO_JOINT_MOVE,
    Frame,
    FrameId,
    empty_frame,
    move_frame,
)
from services.simulator.config import SimConfig
from services.simulator.core import MS, SimCore, SimError
from services.simulator.faults import FaultConfig, FrameFault
from services.simulator.scripted import ScriptedPc, joint_move


def test_cycle_order_and_period() -> None:
    core = SimCore()
    frames = core.advance(1200 * MS)
    assert [f.id for f in frames] == [0x350, 0x360, 0x37F] * 20
    for i, f in enumerate(frames):
        assert f.t_ns == (i + 1) * 20 * MS
    for f in frames:
        if f.id == FrameId.SYNC:
            assert f.remote and f.dlc == 0 and f.data == b""
        else:
            assert not f.remote and f.dlc == 8


def test_next_event_steps_by_20_ms_and_advance_returns_only_due_frames() -> None:
    core = SimCore()
    assert core.next_event_ns() == 20 * MS
    assert core.advance(19 * MS) == []
    assert core.next_event_ns() == 20 * MS
    (f,) = core.advance(20 * MS)
    assert (f.id, f.t_ns) == (0x350, 20 * MS)
    assert core.next_event_ns() == 40 * MS


def test_time_must_not_go_backwards() -> None:
    core = SimCore()
    core.advance(100 * MS)
    with pytest.raises(SimError, match="already 100000000 ns"):
        core.advance(99 * MS)
    with pytest.raises(SimError, match="before the current time"):
        core.receive(move_frame(ZERO_JOINT_MOVE, 50 * MS))


def _joint_ready() -> tuple[SimCore, ScriptedPc]:
    core = SimCore()
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    return core, pc


def test_a_latched_command_repeats_until_replaced() -> None:
    core, pc = _joint_ready()
    pc.run_cycles(1, joint_move(5))
    pc.run_cycles(2)  # let the first-motion delay and the transient pass
    before = core.encoder_counts()[0]
    pc.run_cycles(10)  # no reply at all: the arm keeps going
    moved = core.encoder_counts()[0] - before
    gain = core.model.gains[0]
    assert moved == pytest.approx(10 * 3 * 5 * gain, abs=1.5)  # counts of 0.1 deg
    pc.run_cycles(1, move_frame(ZERO_JOINT_MOVE))
    pc.run_cycles(2)
    still = core.encoder_counts()[0]
    pc.run_cycles(5)
    assert core.encoder_counts()[0] == still


def test_only_the_first_reply_of_a_window_counts() -> None:
    core, pc = _joint_ready()
    pc.run_cycles(1)
    sync = pc.last_sync_ns()
    core.receive(joint_move(4).at(sync + 2 * MS))
    core.receive(move_frame(ZERO_JOINT_MOVE, sync + 3 * MS))
    pc.run_cycles(6)
    assert core.counters.extra_replies == 1
    assert core.active is not None and core.active.axes[0] == 4


@pytest.mark.parametrize(
    ("offset_ms", "latched"), [(0.0, True), (19.999, True), (20.0, False), (-5.0, False)]
)
def test_the_reply_window_is_the_20_ms_after_the_sync(offset_ms: float, latched: bool) -> None:
    core, pc = _joint_ready()
    pc.run_cycles(1)
    sync = pc.last_sync_ns()
    if offset_ms < 0:
        pc.run(sync + 40 * MS)  # a frame between 0x350 and 0x360 of the next cycle
        at = sync + 60 * MS + round(offset_ms * MS)
        pc.run(at)
    else:
        at = sync + round(offset_ms * MS)
        pc.run(at)
    core.receive(joint_move(3).at(at))
    pc.run(at + 100 * MS)
    assert (core.active is not None and core.active.axes[0] == 3) is latched
    assert core.counters.outside_window == (0 if latched else 1)


def test_the_command_becomes_active_at_the_tick_after_the_window() -> None:
    core, pc = _joint_ready()
    pc.run_cycles(1)
    pc.run_cycles(1, joint_move(gripper=15))
    sync = pc.last_sync_ns()
    pc.run(sync + 19 * MS)
    assert core.active is not None and core.active.gripper == 0
    pc.run(sync + 20 * MS)
    assert core.active is not None and core.active.gripper == 15


def test_acknowledgement_frames_are_accepted_and_ignored() -> None:
    core, pc = _joint_ready()
    pc.run_cycles(1)
    sync = pc.last_sync_ns()
    core.receive(Frame(FrameId.STATUS, b"", False, sync + 1 * MS))
    core.receive(Frame(FrameId.POSITION, b"", False, sync + 2 * MS))
    core.receive(joint_move(2).at(sync + 3 * MS))
    pc.run_cycles(1)
    assert core.counters.ack_frames == 2
    assert core.active is not None and core.active.axes[0] == 2


def test_malformed_and_unknown_frames_are_counted_not_latched() -> None:
    core, pc = _joint_ready()
    pc.run_cycles(1)
    sync = pc.last_sync_ns()
    core.receive(Frame(FrameId.JOINT, b"\x00" * 7, False, sync + 1 * MS))  # short 0x374
    core.receive(Frame(FrameId.STOP, b"\x01", False, sync + 2 * MS))  # 0x370 with data
    core.receive(Frame(0x123, b"\x00", False, sync + 3 * MS))
    core.receive(Frame(FrameId.JOINT, b"", True, sync + 4 * MS, 8))  # remote
    core.receive(joint_move(1).at(sync + 5 * MS))
    pc.run_cycles(1)
    assert core.counters.bad_frames == 3
    assert core.counters.unknown_frames == 1
    assert core.active is not None and core.active.axes[0] == 1


def test_stop_latches_zero_and_keeps_the_mode() -> None:
    core, pc = _joint_ready()
    pc.run_cycles(1, joint_move(10))
    pc.run_cycles(3)
    pc.run_cycles(1, empty_frame(FrameId.STOP))
    pc.run_cycles(2)
    held = core.encoder_counts()
    pc.run_cycles(3)
    assert core.encoder_counts() == held
    assert pc.cycles[-1].status.mode == 4


def _run_scenario(seed: int) -> list[Frame]:
    faults = FaultConfig(frames=(FrameFault("drop", rate=0.1), FrameFault("corrupt", rate=0.05)))
    core = SimCore(SimConfig(seed=seed, faults=faults))
    pc = ScriptedPc(core)
    pc.run(700 * MS)
    pc.run_cycles(2, move_frame(ZERO_JOINT_MOVE))
    pc.run_cycles(20, joint_move(3, -2, 1, 4, -5, 6, gripper=7))
    return pc.frames


def test_same_seed_same_frames_bit_for_bit() -> None:
    a, b = _run_scenario(7), _run_scenario(7)
    assert a == b
    assert a != _run_scenario(8)


def test_both_frames_of_a_cycle_come_from_one_snapshot() -> None:
    core, pc = _joint_ready()
    pc.run_cycles(1, joint_move(0, 0, 0, 10, 0, 0))
    pc.run_cycles(6)  # past the stale-encoder period; joint 4 moves 1 deg per 20 ms
    snapshot_t = pc.last_sync_ns() + 20 * MS
    pc.run(snapshot_t)
    at_snapshot = core.encoder_counts()
    pc.run(snapshot_t + 20 * MS)
    assert core.encoder_counts()[3] != at_snapshot[3]
    last = pc.cycles[-1]
    assert last.t_ns == snapshot_t and last.position is not None
    assert last.position.fields == at_snapshot[3:6]
    assert last.status.fields == at_snapshot[:3]
