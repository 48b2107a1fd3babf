"""Warnings: joint limits, the stretched elbow, the work area, clamped increments, priority."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from manus.config import DEFAULT_ARM
from manus.protocol import (
    GEN_GRIPPER_READY,
    WARN_MOTOR_BLOCKED,
    WARN_STRETCHED,
    WARN_WRONG_AREA,
    Frame,
    FrameId,
    MessageClass,
    MoveCommand,
    message_text,
    move_frame,
)
from services.simulator.config import SimConfig
from services.simulator.core import MS, SimCore
from services.simulator.faults import FaultConfig, InjectedMessage
from services.simulator.replies import WARN_CLAMPED
from services.simulator.scripted import Cycle, ScriptedPc, joint_move


def _ready(**overrides: object) -> tuple[SimCore, ScriptedPc]:
    core = SimCore(SimConfig().with_overrides(**overrides))
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    return core, pc


def _warnings(cycles: list[Cycle]) -> list[int]:
    return [c.status.msg_code for c in cycles if c.status.msg_class == MessageClass.WARNING]


def _cartesian(x: int = 0, y: int = 0, z: int = 0, *, strict: bool = True) -> Frame:
    return move_frame(MoveCommand(FrameId.CARTESIAN, 0, (x, y, z, 0, 0, 0), 0), strict=strict)


def test_a_joint_stops_at_its_limit_with_motor_blocked_while_pushed() -> None:
    core, pc = _ready(start_pose=(0.0, 30.0, -30.0, 0.0, 110.0, 0.0))
    pc.run_cycles(14, joint_move(0, 0, 0, 0, 10))
    assert pc.cycles[-1].fields[4] == 1200  # joint 5 at +120 deg
    assert core.state.motor_deg[4] == pytest.approx(120.0, abs=1e-9)
    assert _warnings(pc.cycles[-5:]) == [WARN_MOTOR_BLOCKED] * 5
    pc.run_cycles(4, joint_move())
    assert _warnings(pc.cycles[-2:]) == []
    pc.run_cycles(3, joint_move(0, 0, 0, 0, -2))  # away from the limit: allowed
    assert pc.cycles[-1].fields[4] < 1200
    assert _warnings(pc.cycles[-2:]) == []


def test_the_arm_refuses_to_straighten_the_elbow_inside_the_margin() -> None:
    core, pc = _ready(start_pose=(0.0, 0.0, 100.0, 0.0, -60.0, 0.0))
    pc.run_cycles(14, joint_move(0, 0, -5))  # q3 decreases toward 90 deg (straight)
    q3 = math.degrees(core.truth().q_true[2])
    assert 93.0 <= q3 < 93.6
    assert _warnings(pc.cycles[-4:]) == [WARN_STRETCHED] * 4
    assert message_text(MessageClass.WARNING, WARN_STRETCHED) == "arm folded or fully stretched"
    pc.run_cycles(4, joint_move(0, 0, 5))  # bending back is allowed
    assert math.degrees(core.truth().q_true[2]) > q3 + 1.0
    assert _warnings(pc.cycles[-2:]) == []


def test_the_gripper_may_not_go_below_the_floor() -> None:
    core, pc = _ready(start_pose="unfolded", arm=replace(DEFAULT_ARM, work_floor_z=0.150))
    pc.run_cycles(16, _cartesian(z=-100))  # -110 mm/s from z = 200 mm
    z = core.truth().xyz[2] * 1000.0
    assert 150.0 - 1e-6 <= z < 155.0
    assert _warnings(pc.cycles[-3:]) == [WARN_WRONG_AREA] * 3
    pc.run_cycles(4, _cartesian(z=100))
    assert core.truth().xyz[2] * 1000.0 > z + 10.0


def test_the_gripper_may_not_enter_the_cylinder_around_the_base() -> None:
    core, pc = _ready(start_pose="unfolded", arm=replace(DEFAULT_ARM, work_base_radius=0.200))
    pc.run_cycles(16, _cartesian(x=-100))  # toward the base axis from r = 233 mm
    x, y, _ = np.array(core.truth().xyz) * 1000.0
    assert 200.0 - 1e-6 <= math.hypot(x, y) < 205.0
    assert _warnings(pc.cycles[-3:]) == [WARN_WRONG_AREA] * 3


def test_out_of_range_increments_are_clamped_with_warning_7() -> None:
    core, pc = _ready()
    pc.run_cycles(1, joint_move(20, strict=False))
    pc.run_cycles(5)
    assert core.active is not None and core.active.axes[0] == 10
    assert core.counters.clamped == 1
    assert WARN_CLAMPED in _warnings(pc.cycles[-6:])
    assert message_text(MessageClass.WARNING, WARN_CLAMPED) == "unspecified warning 7"
    speed = float(core.state.speed_deg_s[0])
    assert speed == pytest.approx(50.0 * float(core.model.gains[0]), rel=1e-3)
    pc.run_cycles(1, _cartesian(x=-128, strict=False))
    pc.run_cycles(1)
    assert core.active is not None and core.active.axes[0] == -127


def test_error_beats_warning_beats_general_and_generals_wait_their_turn() -> None:
    faults = FaultConfig(
        messages=(
            InjectedMessage("warning", 5, at_ms=300.0, duration_ms=100.0),
            InjectedMessage("error", 4, at_ms=700.0),
            InjectedMessage("warning", 6, at_ms=700.0, duration_ms=60.0),
        )
    )
    pc = ScriptedPc(SimCore(SimConfig(faults=faults)))
    pc.run(900 * MS)
    by_time = {c.t_ns // MS: (c.status.msg_class, c.status.msg_code) for c in pc.cycles}
    assert by_time[320] == (MessageClass.WARNING, 5)
    assert by_time[380] == (MessageClass.WARNING, 5)
    assert by_time[440] == (MessageClass.GENERAL, GEN_GRIPPER_READY)  # delayed, not lost
    assert by_time[740] == (MessageClass.ERROR, 4)
