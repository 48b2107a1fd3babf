"""The lock-step harness: simulator + bridge cores + a subscriber on one simulated clock."""

from __future__ import annotations

import math

import numpy as np
import pytest

from manus.protocol import FrameId
from manus_stack.lockstep import LockStep
from schemas.base import Message
from schemas.commands import ArmCommand, EStop, JointVelocityCommand
from schemas.state import BridgeState, JointState
from services.simulator.config import SimConfig

UNFOLDED = SimConfig(start_pose="unfolded")


class Joint1Controller:
    """Answers every valid joint state with joint 1 at ``deg_s`` (records what it saw)."""

    def __init__(self, deg_s: float) -> None:
        self.deg_s = deg_s
        self.seen: list[tuple[int, JointState]] = []
        self.seq = 0

    def __call__(self, msg: Message, t_ns: int) -> list[tuple[str, Message]]:
        assert isinstance(msg, JointState)
        self.seen.append((t_ns, msg))
        if not msg.valid:
            return []
        self.seq += 1
        cmd = JointVelocityCommand(
            stamp_ns=msg.stamp_ns,
            seq=self.seq,
            source="test",
            ref_seq=msg.seq,
            velocity=[math.radians(self.deg_s), 0, 0, 0, 0, 0],
            gripper_velocity=0.0,
        )
        return [("cmd/joint_velocity", cmd)]


def test_start_up_reaches_running_and_records_messages() -> None:
    ls = LockStep(UNFOLDED)
    ls.run_until_phase("running", timeout_s=3.0)
    phases = [m.phase for m in ls.published("state/bridge") if isinstance(m, BridgeState)]
    order = ["waiting_power_up", "entering_joint_mode", "initialising", "running"]
    assert [p for i, p in enumerate(phases) if i == 0 or phases[i - 1] != p] == order
    assert all(t <= ls.t_ns for t, _, _ in ls.messages)
    assert [t for t, _, _ in ls.messages] == sorted(t for t, _, _ in ls.messages)


def test_subscriber_commands_move_the_simulated_arm() -> None:
    ls = LockStep(UNFOLDED, bus_latency_ns=300_000)
    ctl = Joint1Controller(10.0)
    ls.subscribe("state/joints", ctl)
    ls.run_until_phase("running", timeout_s=3.0)
    q0 = np.degrees(ls.sim.truth().q_true)
    ls.run_for(2.0)
    q1 = np.degrees(ls.sim.truth().q_true)
    # 10 deg/s = 2 counts exactly; gain error <= 1.5 %, first-motion delay 60 ms, lag.
    assert q1[0] - q0[0] == pytest.approx(20.0, abs=1.5)
    assert np.allclose(q1[1:], q0[1:], atol=0.5)
    # Subscribers get each state bus_latency_ns after its publication.
    published = {m.seq: t for t, _, m in ls.messages if isinstance(m, JointState)}
    assert all(t - published[js.seq] == 300_000 for t, js in ctl.seen)
    # The bridge sent the controller's increments (motor 1 = +2) at the syncs.
    moves = [f for f in ls.bridge_frames if f.id == FrameId.JOINT and f.data[1] == 2]
    assert len(moves) >= 30


def test_estop_publication_reaches_the_bridge() -> None:
    ls = LockStep(UNFOLDED)
    ls.run_until_phase("running", timeout_s=3.0)
    ls.publish("estop", EStop(stamp_ns=ls.t_ns, seq=0, engaged=True, source="test"))
    ls.run_for(0.2)
    assert ls.bridge.phase == "estopped"
    reply = ls.arm_command(ArmCommand(action="clear", source="test"))
    assert not reply.ok and "e-stop" in reply.message


def test_same_inputs_same_messages() -> None:
    def run() -> list[tuple[int, str, bytes]]:
        ls = LockStep(UNFOLDED)
        ls.subscribe("state/joints", Joint1Controller(-7.0))
        ls.run_for(2.0)
        return [(t, s, m.encode()) for t, s, m in ls.messages]

    assert run() == run()


def test_run_until_phase_names_what_it_saw() -> None:
    ls = LockStep(SimConfig(angles_measured_ms=5000, gripper_ready_ms=100))
    with pytest.raises(TimeoutError, match=r"'running' not reached .* 'waiting_power_up'"):
        ls.run_until_phase("running", timeout_s=0.5)


def test_time_only_moves_forward() -> None:
    ls = LockStep()
    ls.run_for(0.1)
    with pytest.raises(ValueError, match="time is already"):
        ls.run_until(0)
