"""Motion of the simulated arm: delay, transient, encoder map, stale encoders, truth vs report."""

from __future__ import annotations

import math

import numpy as np
import pytest

from manus.joint_map import encoder_to_dh
from manus.protocol import FrameId, MoveCommand, move_frame
from services.simulator.config import SimConfig
from services.simulator.core import MS, SimCore
from services.simulator.scripted import ScriptedPc, joint_move

TAU_S = 0.020


def _ready(config: SimConfig | None = None) -> tuple[SimCore, ScriptedPc]:
    core = SimCore(config)
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    return core, pc


def _lag_position(u: float, t_s: float) -> float:
    """Distance covered after t_s from rest toward speed u through the first-order lag."""
    return u * t_s - u * TAU_S * (1.0 - math.exp(-t_s / TAU_S))


def test_first_motion_waits_60_ms_then_follows_the_transient_exactly() -> None:
    core, pc = _ready()
    e0 = float(core.state.motor_deg[1])
    pc.run_cycles(1, joint_move(0, 5))
    t_active = pc.last_sync_ns() + 20 * MS
    pc.run(t_active + 60 * MS)
    assert float(core.state.motor_deg[1]) == e0
    u = 5 * 5.0 * float(core.model.gains[1])  # deg/s
    for k in range(1, 7):
        pc.run(t_active + (60 + 20 * k) * MS)
        assert float(core.state.motor_deg[1]) - e0 == pytest.approx(
            _lag_position(u, 0.02 * k), abs=1e-9
        )
        # ~95 % of the speed 60 ms after the motion started (docs/protocol.md, Thesis step response)
        if k == 3:
            assert 0.95 * u <= float(core.state.speed_deg_s[1]) < u
    # The encoder reports the motor angle quantised to 0.1 deg at each snapshot.
    report = next(c for c in pc.cycles if c.t_ns == t_active + 120 * MS)
    expected = round((e0 + _lag_position(u, 0.06)) * 10)
    assert report.fields[1] == expected


def test_later_speed_changes_start_at_once() -> None:
    core, pc = _ready()
    pc.run_cycles(1, joint_move(0, 5))
    pc.run_cycles(4)
    pc.run_cycles(1, joint_move(0, 10))
    t_active = pc.last_sync_ns() + 20 * MS
    pc.run(t_active)
    v_before = float(core.state.speed_deg_s[1])
    pc.run(t_active + 20 * MS)
    u10 = 50.0 * float(core.model.gains[1])
    expected = u10 + (v_before - u10) * math.exp(-1.0)
    assert float(core.state.speed_deg_s[1]) == pytest.approx(expected, rel=1e-12)


def test_speed_gain_errors_are_seeded_and_bounded() -> None:
    gains = [SimCore(SimConfig(seed=s)).model.gains for s in range(20)]
    for g in gains:
        assert np.all(np.abs(g - 1.0) <= 0.015)
    assert not np.allclose(gains[0], gains[1])
    assert np.array_equal(SimCore(SimConfig(seed=3)).model.gains, gains[3])


def test_a_joint_2_command_moves_motor_2_only_while_dh_q3_changes() -> None:
    core, pc = _ready()
    before = pc.cycles[-1].fields
    q0 = np.array(core.truth().q_true)
    pc.run_cycles(1, joint_move(0, 8))
    pc.run_cycles(6, joint_move(0, 8))
    pc.run_cycles(3, joint_move())
    after = pc.cycles[-1].fields
    assert after[0] == before[0] and after[2] == before[2]
    de2 = (after[1] - before[1]) * 0.1
    assert de2 > 5.0
    dq = np.degrees(np.array(core.truth().q_true) - q0)
    # q2 = -e2 and q3 = e3 - e2 + 90 (docs/protocol.md, Encoder map): both DH angles move by -de2.
    assert dq[1] == pytest.approx(-de2, abs=0.1)
    assert dq[2] == pytest.approx(-de2, abs=0.1)
    assert np.allclose(dq[[0, 3, 4, 5]], 0.0)


def test_to_move_dh_joint_3_alone_the_pc_commands_motor_3() -> None:
    core, pc = _ready()
    q0 = np.array(core.truth().q_true)
    pc.run_cycles(5, joint_move(0, 0, 6))
    pc.run_cycles(3, joint_move())
    dq = np.degrees(np.array(core.truth().q_true) - q0)
    assert dq[2] > 3.0
    assert np.allclose(dq[[0, 1, 3, 4, 5]], 0.0)


def test_reported_dh_angles_follow_the_joint_map() -> None:
    core, pc = _ready(SimConfig(start_pose="unfolded"))
    pc.run_cycles(6, joint_move(3, -4, 5, 2, -1, 7))
    counts = np.array(core.encoder_counts()[:6])
    truth = core.truth()
    expected = encoder_to_dh(np.radians(counts * 0.1))
    assert np.allclose(truth.q_reported, expected, atol=1e-12)


def test_joints_4_to_6_report_stale_values_until_240_ms_after_their_first_command() -> None:
    _core, pc = _ready()
    stale = (1793, -368, 826)  # docs/protocol.md, Thesis stale encoders [0.1 deg]
    assert pc.cycles[-1].fields[3:] == stale
    pc.run_cycles(6, joint_move(2))  # joint 1 alone does not end it
    assert pc.cycles[-1].fields[3:] == stale
    pc.run_cycles(1, joint_move(0, 0, 0, 1, 1, 1))
    t0 = pc.last_sync_ns() + 20 * MS
    pc.run(t0 + 300 * MS, joint_move())
    by_time = {c.t_ns - t0: c.fields[3:] for c in pc.cycles if c.t_ns >= t0}
    for dt in (0, 60, 120, 180):
        assert by_time[dt * MS] == stale
    real = by_time[240 * MS]
    assert real != stale
    assert real == pytest.approx((-900, -900, 0), abs=5)  # the folded pose's motors


def test_belt_backlash_true_angle_lags_the_motor_through_the_dead_band() -> None:
    core, pc = _ready()
    pc.run_cycles(4, joint_move(0, 0, 0, 2))
    pc.run_cycles(3, joint_move())
    st = core.state
    assert st.output_deg[3] - st.motor_deg[3] == pytest.approx(-0.15, abs=1e-9)  # half of 0.3
    q4_before = core.truth().q_true[3]
    # One cycle of the slowest reverse speed: the motor travels about 0.3 deg back, which
    # the dead band swallows.
    pc.run_cycles(1, joint_move(0, 0, 0, -1))
    pc.run_cycles(3, joint_move())
    travel = float(core.state.motor_deg[3] - st.motor_deg[3])
    assert travel == pytest.approx(-0.3, abs=0.01)
    dq4 = math.degrees(core.truth().q_true[3] - q4_before)
    assert abs(dq4) < 0.01  # the motor moved ~0.3 deg, the joint (almost) not at all
    # Going on in reverse, the joint follows with the slack on the other side.
    pc.run_cycles(3, joint_move(0, 0, 0, -2))
    pc.run_cycles(3, joint_move())
    st = core.state
    assert st.output_deg[3] - st.motor_deg[3] == pytest.approx(0.15, abs=1e-9)
    report = pc.cycles[-1].fields[3]
    assert report == round(float(st.motor_deg[3]) * 10)  # the encoder sees the motor


def test_joint_1_true_angle_has_a_scale_error() -> None:
    core, pc = _ready(SimConfig(start_pose="unfolded"))
    pc.run_cycles(20, joint_move(10))
    pc.run_cycles(3, joint_move())
    e1 = float(core.state.motor_deg[0])
    assert e1 > 50.0
    q1_true = math.degrees(core.truth().q_true[0])
    assert q1_true == pytest.approx((e1 - 0.075) * 1.003, abs=1e-9)


def test_gripper_moves_within_0_to_90_mm() -> None:
    core, pc = _ready()
    pc.run_cycles(40, joint_move(gripper=15))  # 75 mm/s for 2.4 s
    assert pc.cycles[-1].position is not None and pc.cycles[-1].position.gripper == 900
    assert core.truth().gripper == pytest.approx(0.090)
    pc.run_cycles(40, joint_move(gripper=-15))
    assert pc.cycles[-1].position is not None and pc.cycles[-1].position.gripper == 0


def test_cartesian_mode_moves_the_gripper_along_x_and_reports_xyz() -> None:
    core, pc = _ready(SimConfig(start_pose="unfolded"))
    zero = move_frame(MoveCommand(FrameId.CARTESIAN, 0, (0, 0, 0, 0, 0, 0), 0))
    pc.run_cycles(2, zero)
    last = pc.cycles[-1]
    assert last.status.mode == 1
    x, y, z = last.fields[:3]
    assert (x * 0.022, y * 0.022, z * 0.022) == pytest.approx((207.85, 105.0, 200.0), abs=0.05)
    xyz0 = np.array(core.truth().xyz)
    ypr0 = np.array(core.truth().ypr)
    plus_x = move_frame(MoveCommand(FrameId.CARTESIAN, 0, (100, 0, 0, 0, 0, 0), 0))
    pc.run_cycles(10, plus_x)  # 2.2 mm per 20 ms
    pc.run_cycles(3, zero)
    d = (np.array(core.truth().xyz) - xyz0) * 1000.0
    assert d[0] > 40.0
    assert abs(d[1]) < 0.05 * d[0] and abs(d[2]) < 0.05 * d[0]
    assert np.allclose(np.array(core.truth().ypr), ypr0, atol=math.radians(1.0))
    reported = np.array(pc.cycles[-1].fields[:3]) * 0.022
    assert reported == pytest.approx(np.array(core.truth().xyz) * 1000.0, abs=0.6)
