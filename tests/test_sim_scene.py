"""The simulator knows the scene: a body that meets an object stops there with "motor
blocked", and its truth records the contact and the smallest true clearance."""

from __future__ import annotations

import math

import msgpack
import pytest

from manus.protocol import WARN_MOTOR_BLOCKED, MessageClass
from schemas.state import SimTruth
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.scripted import ScriptedPc, joint_move


def ready(**overrides: object) -> tuple[SimCore, ScriptedPc]:
    core = SimCore(SimConfig().with_overrides(start_pose="unfolded", **overrides))
    pc = ScriptedPc(core)
    pc.enter_joint_mode()
    return core, pc


def test_the_forearm_stops_at_the_table_with_motor_blocked() -> None:
    core, pc = ready()
    start = core.truth()
    assert start.clearance is not None and start.clearance > 0.05
    assert start.contacts == 0 and start.contact == ""
    pc.run_cycles(120, joint_move(0, -10))  # joint 2 tips the arm forward and down
    truth = core.truth()
    assert truth.clearance_pair == "forearm/table"
    assert truth.clearance is not None and 0.0 <= truth.clearance < 0.005
    assert truth.min_clearance is not None and truth.min_clearance >= 0.0
    assert truth.contacts > 0 and truth.contact == "forearm/table"
    last = [c.status for c in pc.cycles[-3:]]
    assert [(s.msg_class, s.msg_code) for s in last] == [
        (MessageClass.WARNING, WARN_MOTOR_BLOCKED)
    ] * 3
    q2 = truth.q_true[1]
    pc.run_cycles(10, joint_move(0, 10))  # backing away is allowed
    after = core.truth()
    assert after.q_true[1] < q2 - math.radians(1.0)
    assert after.clearance is not None and after.clearance > truth.clearance
    pc.run_cycles(5, joint_move(0, 10))
    assert core.truth().contacts == after.contacts  # nothing touched once away


def test_without_a_scene_the_truth_has_no_clearance() -> None:
    core, pc = ready(scene="none")
    pc.run_cycles(60, joint_move(0, -10))
    truth = core.truth()
    assert truth.clearance is None and truth.min_clearance is None and truth.contacts == 0
    assert math.degrees(truth.q_true[1]) > 60.0  # went through where the table was


def test_old_truth_recordings_still_decode() -> None:
    old = {
        "stamp_ns": 5,
        "seq": 1,
        "q_true": [0.0] * 6,
        "q_reported": [0.0] * 6,
        "gripper": 0.0,
        "xyz": [0.0] * 3,
        "ypr": [0.0] * 3,
    }
    truth = SimTruth.decode(msgpack.packb(old))
    assert truth.clearance is None and truth.contacts == 0 and truth.contact == ""
    assert SimTruth.decode(truth.encode()) == truth


def test_a_bad_scene_setting_is_refused() -> None:
    with pytest.raises(Exception, match="cannot read the scene file"):
        SimCore(SimConfig().with_overrides(scene="/nonexistent/scene.yaml"))
