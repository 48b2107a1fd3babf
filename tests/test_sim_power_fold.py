"""Power-up messages and undefined positions; fold in / fold out procedures."""

from __future__ import annotations

import numpy as np
import pytest

from manus.config import FOLDED_Q_DEG, UNFOLDED_Q_DEG
from manus.protocol import (
    GEN_ANGLES_MEASURED,
    GEN_FOLDED,
    GEN_GRIPPER_READY,
    GEN_UNFOLDED,
    ZERO_JOINT_MOVE,
    FrameId,
    MessageClass,
    empty_frame,
    move_frame,
)
from services.simulator.arm import dh_to_motor_deg
from services.simulator.config import SimConfig
from services.simulator.core import MS, SimCore
from services.simulator.scripted import Cycle, ScriptedPc, joint_move


def _generals(cycles: list[Cycle]) -> list[tuple[int, int]]:
    return [
        (c.t_ns // MS, c.status.msg_code)
        for c in cycles
        if c.status.msg_class == MessageClass.GENERAL
    ]


def test_power_up_messages_in_order_with_mode_none() -> None:
    pc = ScriptedPc(SimCore())
    pc.run(1000 * MS)
    assert _generals(pc.cycles) == [(320, GEN_GRIPPER_READY), (620, GEN_ANGLES_MEASURED)]
    assert all(c.status.mode == 0 for c in pc.cycles)


def test_power_up_times_are_configurable() -> None:
    pc = ScriptedPc(SimCore(SimConfig(gripper_ready_ms=100, angles_measured_ms=150)))
    pc.run(400 * MS)
    assert _generals(pc.cycles) == [(140, GEN_GRIPPER_READY), (200, GEN_ANGLES_MEASURED)]


def test_positions_are_garbage_until_a_move_mode_is_active() -> None:
    pc = ScriptedPc(SimCore(SimConfig(seed=1)))
    pc.wait_ready()
    noisy = {c.fields for c in pc.cycles}
    assert len(noisy) == len(pc.cycles)  # seeded noise, different every cycle
    pc.run_cycles(2, move_frame(ZERO_JOINT_MOVE))
    assert pc.cycles[-1].status.mode == 4
    assert pc.cycles[-1].fields[:3] == (0, 900, -900)  # the folded pose's motors
    maxed = ScriptedPc(SimCore(SimConfig(garbage="max")))
    maxed.run(300 * MS)
    assert {c.fields for c in maxed.cycles} == {(0x7FFF,) * 6}


def test_no_motion_command_is_obeyed_before_angles_are_measured() -> None:
    core = SimCore()
    pc = ScriptedPc(core)
    pc.run(590 * MS, joint_move(5))  # syncs at 60, 120, ... 540 ms
    assert core.counters.not_ready == 9
    assert core.mode == 0 and core.active is None
    pc.run(1200 * MS, joint_move(5))
    assert core.mode == 4 and core.counters.replies_latched > 0


def _fold(core: SimCore, pc: ScriptedPc, kind: FrameId, limit_s: float) -> None:
    done_code = GEN_FOLDED if kind == FrameId.FOLD_IN else GEN_UNFOLDED
    end = core.time_ns + round(limit_s * 1e9)
    while core.time_ns < end:
        pc.run_cycles(1, empty_frame(kind))
        if (MessageClass.GENERAL, done_code) == (
            pc.cycles[-1].status.msg_class,
            pc.cycles[-1].status.msg_code,
        ):
            return
    raise AssertionError(f"{kind.name} did not complete in {limit_s} s")


def test_fold_out_runs_in_mode_5_and_ends_with_arm_unfolded() -> None:
    core = SimCore()
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    start = core.state.motor_deg.copy()
    target = dh_to_motor_deg(np.array(UNFOLDED_Q_DEG))
    t0 = core.time_ns
    _fold(core, pc, FrameId.FOLD_OUT, 12.0)
    took_s = (core.time_ns - t0) / 1e9
    # The longest way is motor 2 (120 deg) at 15 deg/s: 8 s, plus delay and cycle slack.
    assert 8.0 <= took_s <= 8.5
    assert np.allclose(core.state.motor_deg, target, atol=1e-9)
    modes = {c.status.mode for c in pc.cycles if c.t_ns > t0 + 60 * MS}
    assert modes == {5}
    unfolded = [c for c in pc.cycles if c.status.msg_class == MessageClass.GENERAL]
    assert [c.status.msg_code for c in unfolded][-1] == GEN_UNFOLDED
    # Every joint arrives together: halfway in time, every motor is halfway.
    half = pc.cycles[len(pc.cycles) - round(took_s / 0.06 / 2)]
    progress = (np.array(half.fields[:3]) * 0.1 - start[:3]) / (target[:3] - start[:3] + 1e-12)
    moving = np.abs(target[:3] - start[:3]) > 1.0
    assert np.allclose(progress[moving], progress[moving][0], atol=0.02)
    # Keeping on sending 0x375 after the end changes nothing and repeats no message.
    pc.run_cycles(5, empty_frame(FrameId.FOLD_OUT))
    assert all(c.status.msg_class == MessageClass.NONE for c in pc.cycles[-5:])


def test_fold_in_from_unfolded_reports_arm_folded_and_mode_6() -> None:
    core = SimCore(SimConfig(start_pose="unfolded"))
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    _fold(core, pc, FrameId.FOLD_IN, 12.0)
    assert pc.cycles[-1].status.mode == 6
    assert pc.cycles[-1].status.msg_code == GEN_FOLDED
    assert np.allclose(core.state.motor_deg, dh_to_motor_deg(np.array(FOLDED_Q_DEG)))


def test_a_fold_pauses_when_a_sync_goes_unanswered_and_resumes() -> None:
    core = SimCore()
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    pc.run_cycles(20, empty_frame(FrameId.FOLD_OUT))
    pc.run_cycles(3)  # no reply: the fold pauses (the motors coast to rest)
    paused = core.encoder_counts()
    pc.run_cycles(10)
    assert core.encoder_counts() == paused
    assert pc.cycles[-1].status.mode == 5
    _fold(core, pc, FrameId.FOLD_OUT, 12.0)
    assert np.allclose(core.state.motor_deg, dh_to_motor_deg(np.array(UNFOLDED_Q_DEG)))


def test_a_stop_or_a_move_abandons_the_fold() -> None:
    core = SimCore()
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    pc.run_cycles(10, empty_frame(FrameId.FOLD_IN))  # already folded: completes at once
    assert (MessageClass.GENERAL, GEN_FOLDED) in [
        (c.status.msg_class, c.status.msg_code) for c in pc.cycles[-10:]
    ]
    pc.run_cycles(10, empty_frame(FrameId.FOLD_OUT))
    pc.run_cycles(1, empty_frame(FrameId.STOP))
    pc.run_cycles(3)
    stopped = core.encoder_counts()
    assert core.fold is None and pc.cycles[-1].status.mode == 5
    pc.run_cycles(5)
    assert core.encoder_counts() == stopped
    pc.run_cycles(1, move_frame(ZERO_JOINT_MOVE))
    pc.run_cycles(1)
    assert pc.cycles[-1].status.mode == 4


@pytest.mark.parametrize("pose", ["folded", "unfolded", (10.0, 20.0, -20.0, 5.0, -45.0, 30.0)])
def test_start_pose_is_configurable(pose: str | tuple[float, ...]) -> None:
    core = SimCore(SimConfig(start_pose=pose))
    named = {"folded": FOLDED_Q_DEG, "unfolded": UNFOLDED_Q_DEG}
    expected = named[pose] if isinstance(pose, str) else pose
    assert np.allclose(np.degrees(core.truth().q_true), expected)
