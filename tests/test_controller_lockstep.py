"""The controller in lock-step with the real simulator and bridge cores (ControlledArm).

Scenarios on the simulated clock: tolerance abort, cancel deceleration, replacement while
moving, start-state refusal, arm error, gripper, stale joint states, and a replay of the
recorded messages into a fresh core, compared bit for bit.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from manus_stack.controlled import ControlledArm, controller_input
from schemas.commands import JointVelocityCommand
from schemas.control import (
    CancelGoal,
    ControllerFeedback,
    GripperGoal,
    SpeedScale,
    TrajectoryGoal,
)
from schemas.planning import Trajectory
from schemas.state import JointState
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore
from services.simulator.config import SimConfig
from services.simulator.faults import InjectedMessage, Silence, StuckJoint
from tests.controller_plant import steps

PATHS = Path(__file__).resolve().parent.parent / "paths"


def _arm(config: ControllerConfig | None = None) -> tuple[ControlledArm, JointState]:
    arm = ControlledArm(SimConfig(start_pose="unfolded"), config)
    return arm, arm.start()


def _move(js: JointState, delta_deg: tuple[float, ...], duration: float) -> Trajectory:
    """Smooth joint move from the measured angles (rest at both ends), 5 knots."""
    q0 = np.asarray(js.position, dtype=float)
    d = np.radians(np.asarray(delta_deg, dtype=float))
    ts = np.linspace(0.0, duration, 5)
    s = ts / duration
    return Trajectory(
        times=[float(t) for t in ts],
        positions=[[float(v) for v in q0 + d * (3 * x**2 - 2 * x**3)] for x in s],
        velocities=[[float(v) for v in d * (6 * x - 6 * x**2) / duration] for x in s],
    )


def _commands(arm: ControlledArm) -> list[JointVelocityCommand]:
    return [
        m for m in arm.ls.published("cmd/joint_velocity") if isinstance(m, JointVelocityCommand)
    ]


def _now_ms(arm: ControlledArm) -> float:
    return arm.ls.t_ns / 1e6


def test_square_in_default_mode_succeeds_with_small_via_errors() -> None:
    arm, _ = _arm()
    trajectory = arm.plan(PATHS / "thesis_square.txt")
    assert arm.submit(TrajectoryGoal(goal_id="sq", trajectory=trajectory)).accepted
    result = arm.run_until_result("sq", timeout_s=30.0)
    assert result.status == "succeeded", result.reason
    assert len(result.via_errors) == len(trajectory.times)
    assert max(result.via_errors) < 0.005  # figures: manus bench track
    assert arm.ls.bridge.phase == "running"


def test_path_tolerance_abort_on_a_stuck_joint() -> None:
    arm, js = _arm()
    goal = TrajectoryGoal(
        goal_id="stuck", trajectory=_move(js, (15, 0, 0, 0, 0, 0), 2.0), path_tolerance=[0.03] * 6
    )
    arm.ls.sim.add_fault(StuckJoint(joint=1, at_ms=_now_ms(arm)))
    assert arm.submit(goal).accepted
    result = arm.run_until_result("stuck", timeout_s=5.0)
    assert result.status == "aborted"
    assert (
        "path tolerance: joint 1 error" in result.reason and "exceeds 0.0300 rad" in result.reason
    )
    arm.ls.run_for(0.2)
    assert all(steps(c) == [0] * 8 for c in _commands(arm)[-2:])


def test_cancel_decelerates_at_the_bound_and_comes_to_rest() -> None:
    config = ControllerConfig(cancel_decel=math.radians(60.0))
    arm, js = _arm(config)
    arm.submit(TrajectoryGoal(goal_id="c", trajectory=_move(js, (40, 0, 0, 0, 0, 0), 2.0)))
    arm.ls.run_for(1.0)
    before = len(_commands(arm))
    assert max(abs(c) for c in steps(_commands(arm)[-1])) >= 4
    assert arm.query("controller/cancel", CancelGoal(goal_id="c")).accepted
    result = arm.run_until_result("c", timeout_s=2.0)
    assert result.status == "cancelled"
    counts = np.array([steps(c) for c in _commands(arm)[before - 1 :]])[:, 1:7]
    step = config.cancel_decel * config.cycle_s / math.radians(5.0)
    drops = np.abs(counts[:-1]) - np.abs(counts[1:])
    assert drops.min() >= 0 and drops.max() <= step + 0.5 + 1e-9
    arm.ls.run_for(0.3)
    speed = np.asarray(arm.ls.sim.state.speed_deg_s)
    assert np.max(np.abs(speed)) < 0.1


def test_replacement_while_moving_is_continuous() -> None:
    arm, js = _arm()
    arm.submit(TrajectoryGoal(goal_id="a", trajectory=_move(js, (30, 0, 0, 0, 0, 0), 3.0)))
    arm.ls.run_for(1.2)
    now = arm.core.last_js
    assert now is not None
    fb_before = len(arm.ls.published("controller/feedback"))
    new = _move(now, (0, 8, 0, 0, 0, 0), 2.0)
    assert arm.submit(TrajectoryGoal(goal_id="b", trajectory=new, replace=True)).accepted
    result = arm.run_until_result("b", timeout_s=10.0)
    assert result.status == "succeeded", result.reason
    first = arm.results("a")[0]
    assert first.status == "preempted" and "spliced" in first.reason
    feedback = [
        m for m in arm.ls.published("controller/feedback") if isinstance(m, ControllerFeedback)
    ]
    refs = np.array([f.reference for f in feedback[fb_before - 4 : fb_before + 5]])
    # Joint 1 keeps its speed through the splice (continuous position and velocity):
    # the per-cycle steps of the reference change smoothly.
    steps = np.diff(refs[:, 0])
    assert np.all(steps > 0)
    assert np.max(np.abs(np.diff(steps))) < math.radians(0.3)
    # ... and the arm follows it through the splice without a jump in the error.
    errors = np.array([f.error for f in feedback[fb_before - 4 : fb_before + 10]])
    assert np.max(np.abs(errors)) < math.radians(1.0)


def test_start_state_refusal() -> None:
    arm, js = _arm()
    far = _move(js, (5, 0, 0, 0, 0, 0), 1.0)
    shifted = [[v + (0.1 if j == 4 else 0.0) for j, v in enumerate(row)] for row in far.positions]
    goal = TrajectoryGoal(goal_id="far", trajectory=Trajectory(far.times, shifted, far.velocities))
    ack = arm.submit(goal)
    assert not ack.accepted and "joint 5" in ack.reason and "start_tolerance" in ack.reason
    arm.ls.run_for(0.3)
    assert arm.results() == []


def test_arm_error_stops_and_aborts_with_the_arms_message() -> None:
    arm, js = _arm()
    arm.submit(TrajectoryGoal(goal_id="e", trajectory=_move(js, (20, 0, 0, 0, 0, 0), 2.0)))
    arm.ls.sim.add_fault(InjectedMessage(msg_class="error", code=4, at_ms=_now_ms(arm) + 500))
    result = arm.run_until_result("e", timeout_s=3.0)
    assert result.status == "aborted" and result.reason.startswith("arm error: ")
    assert "encoder" in result.reason
    n = len(_commands(arm))
    arm.ls.run_for(0.3)
    assert all(steps(c) == [0] * 8 for c in _commands(arm)[n:])
    later = arm.core.last_js
    assert later is not None
    assert arm.ls.bridge.phase == "arm_error"
    refused = arm.submit(
        TrajectoryGoal(goal_id="f", trajectory=_move(later, (1, 0, 0, 0, 0, 0), 1.0))
    )
    assert not refused.accepted and "arm_error" in refused.reason


@pytest.mark.parametrize("opening", [0.04, 0.0])
def test_gripper_open_close(opening: float) -> None:
    arm, _ = _arm()
    goal = GripperGoal(goal_id="grip", opening=opening)
    assert arm.query("controller/gripper", goal).accepted
    result = arm.run_until_result("grip", timeout_s=5.0)
    assert result.status == "succeeded", result.reason
    arm.ls.run_for(0.2)
    true_mm = arm.ls.sim.truth().gripper * 1000.0
    assert abs(true_mm - opening * 1000.0) <= 1.2


def test_gripper_and_arm_goals_run_together() -> None:
    arm, js = _arm()
    arm.submit(TrajectoryGoal(goal_id="arm", trajectory=_move(js, (10, 0, 0, 0, 0, 0), 1.5)))
    arm.query("controller/gripper", GripperGoal(goal_id="grip", opening=0.03))
    arm.run_until_result("arm", timeout_s=5.0)
    arm.run_until_result("grip", timeout_s=5.0)
    assert {r.goal_id: r.status for r in arm.results()} == {"arm": "succeeded", "grip": "succeeded"}


def test_stale_joint_state_gives_zeros_and_a_long_outage_stops() -> None:
    arm, js = _arm()
    arm.submit(TrajectoryGoal(goal_id="s", trajectory=_move(js, (20, 0, 0, 0, 0, 0), 2.0)))
    arm.ls.run_for(0.8)
    assert any(steps(_commands(arm)[-1]))
    n = len(_commands(arm))
    # The arm falls silent for two cycles: the first state after it is answered with zeros
    # and the trajectory's time waits; the goal then finishes.
    arm.ls.sim.add_fault(Silence(start_ms=_now_ms(arm), duration_ms=100.0))
    result = arm.run_until_result("s", timeout_s=6.0)
    assert result.status == "succeeded", result.reason
    after_gap = [c for c in _commands(arm)[n:] if c.ref_seq >= 0]
    assert steps(after_gap[0]) == [0] * 8
    assert result.duration > 2.0
    # A silence of half a second aborts the next goal and stops the arm.
    now = arm.core.last_js
    assert now is not None
    arm.submit(TrajectoryGoal(goal_id="t", trajectory=_move(now, (-20, 0, 0, 0, 0, 0), 2.0)))
    arm.ls.run_for(0.6)
    arm.ls.sim.add_fault(Silence(start_ms=_now_ms(arm), duration_ms=500.0))
    aborted = arm.run_until_result("t", timeout_s=3.0)
    assert aborted.status == "aborted" and "interrupted" in aborted.reason
    last = next(
        c for c in reversed(_commands(arm)) if c.ref_seq == result_seq(arm, aborted.stamp_ns)
    )
    assert steps(last) == [0] * 8
    arm.ls.run_for(0.5)
    assert np.max(np.abs(arm.ls.sim.state.speed_deg_s)) < 0.1


def result_seq(arm: ControlledArm, stamp_ns: int) -> int:
    """Seq of the joint state stamped ``stamp_ns``."""
    for m in arm.ls.published("state/joints"):
        if isinstance(m, JointState) and m.stamp_ns == stamp_ns:
            return m.seq
    raise AssertionError(f"no joint state stamped {stamp_ns}")


def test_replay_of_the_recorded_messages_gives_the_same_commands_bit_for_bit() -> None:
    arm, js = _arm()
    arm.submit(TrajectoryGoal(goal_id="r1", trajectory=_move(js, (12, -5, 5, 5, 0, 0), 1.5)))
    arm.query("controller/gripper", GripperGoal(goal_id="g1", opening=0.02))
    arm.ls.run_for(0.6)
    arm.query("controller/speed_scale", SpeedScale(scale=0.6))
    arm.run_until_result("r1", timeout_s=10.0)
    now = arm.core.last_js
    assert now is not None
    arm.submit(
        TrajectoryGoal(goal_id="r2", trajectory=_move(now, (-8, 0, 0, 0, 0, 0), 1.0), mode="thesis")
    )
    arm.ls.run_for(0.5)
    arm.query("controller/cancel", CancelGoal())
    arm.ls.run_for(0.5)
    recorded = [
        (s, m.encode())
        for _, s, m in arm.ls.messages
        if s.startswith(("cmd/", "controller/", "trace/controller/"))
    ]
    fresh = ControllerCore()
    replayed: list[tuple[str, bytes]] = []
    for _, suffix, msg in arm.ls.messages:
        if suffix.startswith("trace/controller/") and suffix.endswith("/reply"):
            continue  # the replay produces its own replies
        if suffix.startswith("trace/controller/"):
            replayed.append((suffix, msg.encode()))
        for out_suffix, out in controller_input(fresh, suffix, msg):
            replayed.append((out_suffix, out.encode()))
    recorded_outputs = [r for r in recorded if not r[0].endswith("/request")]
    replayed_outputs = [r for r in replayed if not r[0].endswith("/request")]
    assert len(recorded_outputs) > 100
    assert replayed_outputs == recorded_outputs
