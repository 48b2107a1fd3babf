"""BridgeCore against the real SimCore in lock-step: start-up, replies, commands, safety."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from manus.protocol import FrameId
from manus.quantize import (
    GRIPPER_COUNT_M_S,
    GRIPPER_COUNT_MAX,
    JOINT_COUNT_MAX,
    ErrorFeedbackQuantizer,
    RoundingQuantizer,
    step_rates,
)
from manus_stack.lockstep import LockStep
from schemas.commands import ArmCommand, EStop, JointVelocityCommand
from schemas.state import ArmStatus, BridgeState, JointState
from services.can_bridge.commands import to_move
from services.simulator.config import SimConfig
from services.simulator.faults import FaultConfig, InjectedMessage
from tests.bridge_scenarios import (
    MS,
    UNFOLDED,
    VelocityController,
    check_safety,
    moves,
    phases,
    running,
)


def test_start_up_frame_by_frame() -> None:
    ls = LockStep()  # folded, "gripper ready" at 300 ms, "angles measured" at 600 ms
    motor0 = ls.sim.state.motor_deg.copy()
    ls.run_until_phase("running", timeout_s=3.0)
    ls.run_for(0.3)
    sent = [(f.t_ns // MS, f.id, f.data) for f in ls.bridge_frames]
    z = bytes(8)
    up = bytes([0, 0, 0, 0, 1, 1, 1, 0])
    down = bytes([0, 0, 0, 0, 0xFF, 0xFF, 0xFF, 0])
    # One 0x370 at the first sync; silence until "absolute angles measured" (0x350 at
    # 620 ms); a zero 0x374 enters joint mode; the four start-up moves of joints 4-6,
    # alternating; zeros; then running (zeros: no controller).
    assert sent[:8] == [
        (60, FrameId.STOP, b""),
        (660, FrameId.JOINT, z),
        (720, FrameId.JOINT, up),
        (780, FrameId.JOINT, down),
        (840, FrameId.JOINT, up),
        (900, FrameId.JOINT, down),
        (960, FrameId.JOINT, z),
        (1020, FrameId.JOINT, z),
    ]
    assert phases(ls) == [
        "waiting_power_up",
        "entering_joint_mode",
        "initialising",
        "running",
    ]
    texts = [m.text for m in ls.published("state/status") if isinstance(m, ArmStatus)]
    assert "gripper ready" in texts and "absolute angles measured (ready)" in texts
    states = [m for m in ls.published("state/joints") if isinstance(m, JointState)]
    # Positions are marked valid only once the joint 4-6 encoders report true values.
    first_valid = next(js for js in states if js.valid)
    assert first_valid.stamp_ns == 1000 * MS
    assert not any(js.valid for js in states if js.stamp_ns < 1000 * MS)
    assert states[-1].encoder == list(ls.sim.encoder_counts())
    # Commanded net motion of joints 4-6 is zero; the arm's 60 ms first-motion delay eats
    # the first move, so the motors end one move (0.3 deg) away, within their backlash.
    assert np.allclose(ls.sim.state.motor_deg - motor0, [0, 0, 0, -0.3, -0.3, -0.3], atol=0.02)
    ls.run_for(0.01)  # the last reply reaches the arm
    assert ls.sim.counters.replies_latched == len(ls.bridge_frames)
    check_safety(ls)


def test_joint_state_is_decoded_through_the_joint_map() -> None:
    ls = running(SimConfig(start_pose=(10.0, 30.0, -30.0, 20.0, -60.0, 5.0), start_gripper_mm=40))
    ls.run_for(0.2)
    js = ls.published("state/joints")[-1]
    assert isinstance(js, JointState) and js.valid and js.mode == "joint"
    truth = ls.sim.truth()
    assert np.allclose(js.position, truth.q_reported, atol=1e-9)
    assert js.position == pytest.approx(np.radians([10, 30, -30, 20, -60.3, 4.7]), abs=0.01)
    assert js.gripper == pytest.approx(0.040)


def test_every_reply_is_inside_its_window_and_latched() -> None:
    ls = running(UNFOLDED, reply_latency_ns=5 * MS)
    t0 = ls.t_ns
    ls.subscribe("state/joints", VelocityController((5.0, -5.0, 5.0, 0, 10.0, 0)))
    ls.run_for(3.01)
    syncs = [f.t_ns for f in ls.arm_frames if f.id == FrameId.SYNC and f.t_ns >= t0]
    answered = {f.t_ns for f in ls.bridge_frames}
    assert all(t in answered for t in syncs)
    c = ls.sim.counters
    assert c.outside_window == 0 and c.extra_replies == 0 and c.not_ready == 0
    assert c.replies_latched == len(ls.bridge_frames)
    bs = ls.published("state/bridge")[-1]
    assert isinstance(bs, BridgeState)
    assert bs.missed_windows == 0 and bs.cycles >= 60 and bs.period_ms == pytest.approx(60.0)
    check_safety(ls)


def test_zeros_without_a_controller() -> None:
    ls = running()
    ls.run_for(0.3)  # the last start-up move settles
    q0 = ls.sim.truth().q_true
    t0 = ls.t_ns
    ls.run_for(1.0)
    assert all(incs == (0,) * 8 for _, incs in moves(ls, t0))
    assert np.allclose(ls.sim.truth().q_true, q0, atol=1e-3)
    assert ls.bridge.health.stale_commands >= 16


def test_zeros_when_the_controller_stops_publishing() -> None:
    ls = running()
    ctl = VelocityController((10.0, 0, 0, 0, 0, 0))
    ls.subscribe("state/joints", ctl)
    ls.run_for(0.5)
    ctl.stop_after_ns = ls.t_ns
    t_stop = ls.t_ns
    ls.run_for(0.6)
    after = [incs for t, incs in moves(ls, t_stop)]
    assert after[0][1] == 2 or after[0] == (0,) * 8  # the command for the last state
    assert all(incs == (0,) * 8 for incs in after[1:])
    q = ls.sim.truth().q_true
    ls.run_for(0.5)
    assert ls.sim.truth().q_true == pytest.approx(q, abs=1e-6)  # the arm has stopped
    check_safety(ls)


def test_a_late_controller_is_stale() -> None:
    ls = running()
    ctl = VelocityController((10.0, 0, 0, 0, 0, 0))
    ctl.lag = 1  # answers the state before the newest one
    ls.subscribe("state/joints", ctl)
    t0 = ls.t_ns
    ls.run_for(1.0)
    assert ctl.sent and all(incs == (0,) * 8 for _, incs in moves(ls, t0))


def test_commands_without_ref_seq_time_out() -> None:
    ls = running()
    ctl = VelocityController((10.0, 0, 0, 0, 0, 0), ref_seq_none=True)
    ls.subscribe("state/joints", ctl)
    ls.run_for(0.6)
    assert moves(ls)[-1][1] == (0, 2, 0, 0, 0, 0, 0, 0)
    ctl.stop_after_ns = ls.t_ns
    t_stop = ls.t_ns
    ls.run_for(0.5)
    # The last command stays fresh for 100 ms: at most two more syncs, then zeros.
    after = [incs for _, incs in moves(ls, t_stop)]
    assert sum(1 for incs in after if any(incs)) <= 2
    assert all(incs == (0,) * 8 for incs in after[2:])


@pytest.mark.parametrize(
    ("deg_s", "gripper", "expected"),
    [
        # de1 = dq1, de2 = -dq2, de3 = dq3 - dq2: the joint 2/3 coupling
        # (docs/protocol.md, Encoder map).
        ((5.0, 10.0, -5.0, 0.0, 0.0, 20.0), 0.01, (0, 1, -2, -3, 0, 0, 4, 2)),
        ((0.0, 10.0, 10.0, 0.0, 0.0, 0.0), 0.0, (0, 0, -2, 0, 0, 0, 0, 0)),
        ((-7.6, 0.0, 0.0, 2.4, -12.6, 0.0), -0.2, (0, -2, 0, 0, 0, -3, 0, -15)),
        # Saturation scales every joint by one factor: (20, 0, .., 5) -> (10, 0, .., 2.5).
        ((100.0, 0.0, 0.0, 0.0, 0.0, 25.0), 0.0, (0, 10, 0, 0, 0, 0, 3, 0)),
    ],
)
def test_exact_increments_for_velocity_commands(
    deg_s: tuple[float, ...], gripper: float, expected: tuple[int, ...]
) -> None:
    ls = running()
    ls.subscribe("state/joints", VelocityController(deg_s, gripper_m_s=gripper))
    t0 = ls.t_ns
    ls.run_for(0.3)
    sent = [incs for _, incs in moves(ls, t0)]
    assert sent[-1] == expected
    assert sent.count(expected) >= 4


def test_coupling_on_the_arm_joint_2_alone_keeps_joint_3() -> None:
    ls = running()
    ls.subscribe("state/joints", VelocityController((0.0, 10.0, 0.0, 0, 0, 0)))
    q0 = np.degrees(ls.sim.truth().q_true)
    ls.run_for(1.5)
    dq = np.degrees(ls.sim.truth().q_true) - q0
    assert dq[1] == pytest.approx(15.0, abs=1.5)
    assert abs(dq[2]) < 0.5  # motor 3 turned with motor 2, so DH joint 3 held
    js = ls.published("state/joints")[-1]
    assert isinstance(js, JointState) and moves(ls)[-1][1][2:4] == (-2, -2)
    assert np.degrees(js.applied_velocity[1:3]) == pytest.approx([10.0, 0.0])


@given(
    st.lists(st.integers(-JOINT_COUNT_MAX, JOINT_COUNT_MAX), min_size=6, max_size=6),
    st.integers(-GRIPPER_COUNT_MAX, GRIPPER_COUNT_MAX),
)
def test_velocities_on_the_speed_table_become_exactly_those_steps(
    motors: list[int], grip: int
) -> None:
    """The controller chooses the steps and sends their SI velocities; at the CAN edge the
    bridge's conversion gives back exactly those steps, whatever its quantizer."""
    cmd = JointVelocityCommand(
        stamp_ns=0, seq=0, source="c", ref_seq=0, velocity=step_rates(motors),
        gripper_velocity=grip * GRIPPER_COUNT_M_S,
    )  # fmt: skip
    for quantizer in (RoundingQuantizer(), ErrorFeedbackQuantizer()):
        move = to_move(cmd, quantizer)
        assert (move.lift, move.axes, move.gripper) == (0, tuple(motors), grip)


def test_a_joint_state_reports_the_executed_steps_as_velocities() -> None:
    ls = running()
    ctl = VelocityController((15.0, -5.0, 10.0, 0, 0, 0), gripper_m_s=-0.01)
    ls.subscribe("state/joints", ctl)
    ls.run_for(0.3)
    assert moves(ls)[-1][1] == (0, 3, 1, 3, 0, 0, 0, -2)  # dq2 = -de2, dq3 = de3 - de2
    js = ls.published("state/joints")[-1]
    assert isinstance(js, JointState)
    assert js.applied_kind == "joint" and js.applied_seq == ctl.sent[-2].seq
    assert np.degrees(js.applied_velocity) == pytest.approx([15.0, -5.0, 10.0, 0, 0, 0])
    assert js.applied_gripper_velocity == pytest.approx(-0.01)


def test_undecodable_messages_are_counted_in_the_next_bridge_state() -> None:
    ls = running()
    before = [m for _, _, m in ls.messages if isinstance(m, BridgeState)][-1].bad_payloads
    for _ in range(4):
        ls.bridge.on_bad_payload()  # what the shell does when its node refuses a payload
    t0 = ls.t_ns
    ls.run_for(0.1)
    states = [m for t, _, m in ls.messages if isinstance(m, BridgeState) and t > t0]
    assert states and states[0].bad_payloads == before + 4
    assert all(s.phase == "running" for s in states)  # counted, nothing stops


def test_estop_zeros_then_stop_latched_until_released() -> None:
    ls = running()
    ls.subscribe("state/joints", VelocityController((0, 0, 0, 0, 0, 20.0)))
    ls.run_for(0.5)
    ls.publish("estop", EStop(stamp_ns=ls.t_ns, seq=0, engaged=True, source="op", reason="x"))
    t_e = ls.t_ns
    ls.run_for(0.5)
    after = [(f.id, f.data) for f in ls.bridge_frames if f.t_ns > t_e]
    assert after[0] == (FrameId.JOINT, bytes(8))
    assert all(fid == FrameId.STOP for fid, _ in after[1:])
    assert ls.bridge.phase == "estopped" and "e-stop engaged by op: x" in ls.bridge.detail
    q = ls.sim.truth().q_true
    assert not ls.arm_command(ArmCommand(action="clear", source="t")).ok
    assert not ls.arm_command(ArmCommand(action="fold_in", source="t")).ok
    ls.run_for(0.5)
    assert ls.sim.truth().q_true == pytest.approx(q, abs=1e-6)
    ls.publish("estop", EStop(stamp_ns=ls.t_ns, seq=1, engaged=False, source="op"))
    ls.run_until_phase("running", timeout_s=1.0)
    assert phases(ls, t_e + 1) == ["estopped", "entering_joint_mode", "running"]
    check_safety(ls)


def test_stop_then_clear() -> None:
    ls = running()
    ls.subscribe("state/joints", VelocityController((10.0, 0, 0, 0, 0, 0)))
    ls.run_for(0.3)
    reply = ls.arm_command(ArmCommand(action="stop", source="seq"))
    assert reply.ok and reply.phase == "stopped"
    t_s = ls.t_ns
    ls.run_for(0.5)
    assert {f.id for f in ls.bridge_frames if f.t_ns > t_s} == {FrameId.STOP}
    reply = ls.arm_command(ArmCommand(action="clear", source="seq"))
    assert reply.ok
    ls.run_until_phase("running", timeout_s=1.0)
    ls.run_for(0.3)
    assert moves(ls)[-1][1][1] == 2


def test_arm_error_stops_until_clear() -> None:
    faults = FaultConfig(messages=(InjectedMessage("error", 4, at_ms=1500.0),))
    ls = running(SimConfig(start_pose="unfolded", faults=faults))
    ls.subscribe("state/joints", VelocityController((10.0, 0, 0, 0, 0, 0)))
    ls.run_until_phase("arm_error", timeout_s=2.0)
    assert ls.bridge.detail == "arm error 4: absolute encoder error"
    t_err = ls.t_ns
    ls.run_for(0.5)
    assert {f.id for f in ls.bridge_frames if f.t_ns > t_err} == {FrameId.STOP}
    statuses = [m for m in ls.published("state/status") if isinstance(m, ArmStatus)]
    assert any(s.msg_class == "error" and s.text == "absolute encoder error" for s in statuses)
    assert not ls.arm_command(ArmCommand(action="fold_out")).ok
    assert ls.arm_command(ArmCommand(action="clear", source="op")).ok
    ls.run_until_phase("running", timeout_s=1.0)
    ls.run_for(0.3)
    assert moves(ls)[-1][1][1] == 2
    check_safety(ls)


@pytest.mark.parametrize(
    ("action", "start", "pose"),
    [("fold_in", "unfolded", "folded_q_deg"), ("fold_out", "folded", "unfolded_q_deg")],
)
def test_folding(action: str, start: str, pose: str) -> None:
    cfg = SimConfig(start_pose=start)
    ls = running(cfg)
    ls.subscribe("state/joints", VelocityController((10.0, 0, 0, 0, 0, 0)))
    reply = ls.arm_command(ArmCommand(action=action, source="seq"))
    assert reply.ok and reply.phase == f"folding_{action[5:]}"
    t_f = ls.t_ns
    ls.run_until_phase("running", timeout_s=30.0)
    assert ls.bridge.detail == f"{action} complete"
    fold_id = FrameId.FOLD_IN if action == "fold_in" else FrameId.FOLD_OUT
    ids = [f.id for f in ls.bridge_frames if f.t_ns > t_f]
    n = ids.count(fold_id)
    # The fold frame on every sync until the arm reports completion, then 0x370, then
    # zeros until joint mode.
    assert ids[:n] == [fold_id] * n and n > 10
    assert ids[n] == FrameId.STOP and ids[n + 1] == FrameId.JOINT
    assert np.allclose(np.degrees(ls.sim.truth().q_reported), getattr(cfg, pose), atol=0.2)
    assert phases(ls, t_f + 1) == [f"folding_{action[5:]}", "running"]
    # Commands reach the arm again.
    ls.run_for(0.3)
    assert moves(ls)[-1][1][1] == 2


def test_fold_interrupted_by_estop_ends_estopped() -> None:
    ls = running()
    assert ls.arm_command(ArmCommand(action="fold_in")).ok
    ls.run_for(1.0)
    ls.publish("estop", EStop(stamp_ns=ls.t_ns, seq=0, engaged=True, source="op"))
    ls.run_for(0.3)
    assert ls.bridge.phase == "estopped"
    assert ls.bridge_frames[-1].id == FrameId.STOP


def test_fold_timeout_ends_in_arm_error() -> None:
    from services.can_bridge.config import BridgeConfig

    ls = LockStep(UNFOLDED, BridgeConfig(fold_timeout_s=1.0))
    ls.run_until_phase("running", timeout_s=3.0)
    assert ls.arm_command(ArmCommand(action="fold_in")).ok
    ls.run_until_phase("arm_error", timeout_s=2.0)
    assert ls.bridge.detail == "fold_in not complete after 1 s"


def test_bridge_state_reports_phase_every_cycle() -> None:
    ls = running()
    t0 = ls.t_ns
    ls.run_for(0.6)
    states = [m for t, s, m in ls.messages if isinstance(m, BridgeState) and t > t0]
    assert len(states) >= 10
    assert [s.seq for s in states] == list(range(states[0].seq, states[0].seq + len(states)))
    assert all(s.phase == "running" and not s.estop for s in states)
    assert math.isclose(states[-1].period_ms, 60.0)


def test_a_restarted_bridge_stops_the_arm_first_and_skips_the_power_up_wait() -> None:
    from services.can_bridge.core import BridgeCore

    ls = running()
    ls.subscribe("state/joints", VelocityController((10.0, 0, 0, 0, 0, 0)))
    ls.run_for(0.5)
    assert moves(ls)[-1][1][1] == 2  # the arm is moving
    ls.bridge = BridgeCore()  # the old process died; its last command stays latched
    t0 = ls.t_ns
    ls.bridge.start(t0)
    ls.run_for(0.2)
    after = [f for f in ls.bridge_frames if f.t_ns > t0]
    assert after[0].id == FrameId.STOP  # the first sync stops the leftover motion
    q = ls.sim.truth().q_true
    ls.run_until_phase("running", timeout_s=2.0)  # joint mode reported: no power-up wait
    assert phases(ls, t0)[-3:] == ["entering_joint_mode", "initialising", "running"]
    assert abs(ls.sim.truth().q_true[0] - q[0]) < 0.01


def test_power_up_timeout_when_the_messages_never_come() -> None:
    from services.can_bridge.config import BridgeConfig

    sim = SimConfig(start_pose="unfolded", gripper_ready_ms=900, angles_measured_ms=1000)
    ls = LockStep(sim, BridgeConfig(power_up_timeout_ms=300))
    ls.run_until_phase("entering_joint_mode", timeout_s=1.0)
    assert ls.t_ns < 600 * MS
    assert "no 'absolute angles measured' within 300 ms" in ls.bridge.detail
    ls.run_until_phase("running", timeout_s=2.0)  # zeros are obeyed once the arm is ready
    check_safety(ls)
