"""Following a moving target through the whole pipeline in lock-step (simulator with its
moving target and tracker, bridge, controller), judged on the simulator's truth: holding
the standoff, the faults and their stops, no resuming by itself, refusals, preemption,
the closer approach, and the guard's person moving with the tracker."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from manus.held import HeldBody
from manus.protocol import FrameId
from manus.validity import ValidityChecker
from manus_stack.follow_lockstep import FollowArm
from manus_stack.regression import check_controller
from schemas import endpoints as ep
from schemas.control import EndCause, Refusal, ResultStatus
from schemas.follow import CLOSE_SPEED_CAP, FollowGoal, FollowPhase
from schemas.jog import JogCommand
from schemas.target import TargetPose, TargetTaken
from services.controller.config import ControllerConfig
from services.controller.follow_config import FollowConfig
from services.recorder.writer import RecordingWriter
from services.simulator.config import SimConfig
from services.simulator.target_config import LostWindow, TargetConfig, TargetMove

START = (51.2, 17.4, -4.2, -51.9, -98.2, -10.3)
"""A cup 250 mm in front of the default user's mouth, its rim (60 mm past the gripper)
toward it (DH [deg])."""
RIM = [0.0, 0.0, 0.06]


def _arm(follow: FollowConfig | None = None, **target: Any) -> FollowArm:
    base: dict[str, Any] = {"enabled": True, "sway_mm": (0.0, 10.0, 0.0), "sway_hz": 0.25}
    cfg = TargetConfig(**(base | target))
    arm = FollowArm(
        SimConfig(start_pose=START, target=cfg), ControllerConfig(follow=follow or FollowConfig())
    )
    arm.start()
    arm.run(0.3)
    return arm


def _zero_acts(arm: FollowArm, after_ns: int) -> int:
    """When the first zero command sent after ``after_ns`` acts on the arm [ns]."""
    zero = next(
        f.t_ns
        for f in arm.ls.bridge_frames
        if f.id == FrameId.JOINT and f.t_ns >= after_ns and not any(f.data)
    )
    return zero + 20_000_000


def test_the_rim_comes_to_the_standoff_and_holds_it_as_the_mouth_sways() -> None:
    arm = _arm()
    assert arm.follow(offset=RIM).accepted
    arm.run(6.0)
    last = arm.samples[-100:]  # the last second
    assert max(s.error for s in last) < 0.004
    assert min(s.rim for s in arm.samples if s.aim is not None) > 0.050  # never in clearance
    assert all(s.person is not None and s.person > 0.050 for s in arm.samples)
    state = arm.states()[-1]
    assert state.state == FollowPhase.HOLDING and state.cause == ""
    assert state.frames > 100 and len(state.aim_xyz) == 3 and len(state.predicted_xyz) == 3
    assert state.body == "head" and len(state.body_xyz) == 3
    assert arm.follow_results() == []


def test_a_lost_target_stops_the_arm_within_two_cycles_and_nothing_resumes() -> None:
    arm = _arm(lost=(LostWindow(at_s=4.0, for_s=1.0),))
    assert arm.follow(offset=RIM).accepted
    arm.run(6.0 - arm.ls.t_ns / 1e9)
    (result,) = arm.follow_results()
    assert result.status == ResultStatus.ABORTED and result.cause == EndCause.TARGET_LOST
    frames = [t for t, k, m in arm.ls.messages if k == ep.TARGET and t < 4.2e9]
    timeout = frames[-1] + round(2e9 / 30)  # the last frame's arrival + two periods
    assert _zero_acts(arm, timeout) - timeout <= 120_000_000
    after = [s for s in arm.samples if s.t_ns > 4.5e9]
    assert max(s.speed for s in after) < 0.5  # at rest, though the target came back at 5 s
    assert arm.states()[-1].state == FollowPhase.ENDED
    assert arm.follow(goal_id="f2", offset=RIM).accepted  # a fresh command resumes
    arm.run(2.0)
    assert arm.samples[-1].error < 0.005


def test_a_tracker_that_says_it_lost_the_target_stops_at_once() -> None:
    arm = _arm(lost=(LostWindow(at_s=3.0, for_s=1.0),), lost_reports="untracked")
    assert arm.follow(offset=RIM).accepted
    arm.run(3.5 - arm.ls.t_ns / 1e9)
    (result,) = arm.follow_results()
    assert result.cause == EndCause.TARGET_LOST and "lost the target" in result.reason
    told = min(
        t
        for t, k, m in arm.ls.messages
        if k == ep.TARGET and isinstance(m, TargetPose) and not m.tracked
    )
    assert _zero_acts(arm, told) - told <= 120_000_000


def test_a_target_that_jumps_stops_the_arm() -> None:
    arm = _arm(body="", moves=(TargetMove(at_s=3.0, by_mm=(0.0, 200.0, 0.0)),))
    assert arm.follow(offset=RIM).accepted
    arm.run(4.0 - arm.ls.t_ns / 1e9)
    (result,) = arm.follow_results()
    assert result.cause == EndCause.TARGET_JUMP and "more than a person can" in result.reason
    arrived = min(
        t for t, k, m in arm.ls.messages
        if k == ep.TARGET and isinstance(m, TargetPose) and m.stamp_ns >= 3e9
    )  # fmt: skip
    assert _zero_acts(arm, arrived) - arrived <= 120_000_000


def test_a_target_out_of_reach_stops_the_arm() -> None:
    far = _arm(body="", moves=(TargetMove(at_s=2.0, by_mm=(700.0, 300.0, 0.0), over_s=3.0),))
    assert far.follow(offset=RIM, standoff=0.0).accepted
    far.run(7.0)
    (result,) = far.follow_results()
    assert result.cause == EndCause.OUT_OF_REACH, result.reason
    assert "out of reach" in result.reason or "stretched" in result.reason
    ended = next(s for s in far.states() if s.state == FollowPhase.ENDED)
    assert max(s.speed for s in far.samples if s.t_ns > ended.stamp_ns + 200_000_000) < 0.5


def test_refusals_name_what_is_wrong() -> None:
    arm = _arm()
    ack = arm.follow(source="nobody")
    assert not ack.accepted and ack.refusal == Refusal.NOT_READY and "'nobody'" in ack.reason
    ack = arm.follow(standoff=0.03)
    assert not ack.accepted and ack.refusal == Refusal.INVALID
    assert "inside the person's clearance 50 mm" in ack.reason and "close" in ack.reason
    ack = arm.follow(max_speed=0.5)
    assert not ack.accepted and "above the controller's cap" in ack.reason
    ack = arm.follow(approach=[0.0, 0.0, 0.0])
    assert not ack.accepted and "no direction" in ack.reason
    ack = arm.query(ep.FOLLOW, FollowGoal(goal_id="x", stop=True))
    assert not ack.accepted and ack.refusal == Refusal.UNKNOWN_GOAL
    assert arm.follow().accepted
    ack = arm.query(ep.GOAL, _trajectory_goal(arm))
    assert not ack.accepted and ack.refusal == Refusal.BUSY and ack.held_by == "follow"


def _trajectory_goal(arm: FollowArm) -> Any:
    from schemas.control import TrajectoryGoal
    from schemas.planning import Trajectory

    js = arm.core.last_js
    assert js is not None
    q = list(js.position)
    traj = Trajectory(times=[0.0, 1.0], positions=[q, q], velocities=[[0.0] * 6] * 2)
    return TrajectoryGoal(goal_id="t1", trajectory=traj)


def test_stopping_a_goal_cancels_it_and_a_jog_takes_over() -> None:
    arm = _arm()
    assert arm.follow(offset=RIM).accepted
    arm.run(1.0)
    assert arm.stop().accepted
    arm.run(0.3)
    (result,) = arm.follow_results()
    assert result.status == ResultStatus.CANCELLED and result.cause == EndCause.CANCEL_REQUEST
    assert arm.follow(goal_id="f2", offset=RIM).accepted
    arm.run(1.0)
    jog = JogCommand(
        stamp_ns=arm.ls.t_ns, seq=1, source="test", kind="twist", units="si", linear=[0.02, 0, 0]
    )
    arm.ls.publish(ep.JOG, jog)
    arm.run(0.2)
    second = arm.follow_results()[-1]
    assert second.status == ResultStatus.PREEMPTED and second.cause == EndCause.USER_TOOK_OVER


def test_the_closer_approach_is_explicit_slow_and_keeps_its_clearance() -> None:
    arm = _arm()
    ack = arm.follow(offset=RIM, close=True, standoff=0.03, close_clearance=0.02)
    assert ack.accepted
    arm.run(12.0)
    held = [s for s in arm.samples if s.aim is not None]
    assert min(s.rim for s in held) > 0.020
    assert held[-1].error < 0.004 and held[-1].rim < 0.040  # closer than the default's 50 mm
    near = [s for s in held if math.dist(s.point, s.target) < 0.1]
    for a, b in zip(near, near[30:], strict=False):  # 0.3 s apart: 5 cycles
        v = (np.array(b.point) - np.array(a.point)) / ((b.t_ns - a.t_ns) / 1e9)
        away = np.array(a.point) - np.array(a.target)
        u = away / np.linalg.norm(away)
        rest = v - max(0.0, float(v @ u)) * u
        assert float(np.linalg.norm(rest)) <= CLOSE_SPEED_CAP


def test_the_guard_keeps_the_person_where_the_tracker_sees_it() -> None:
    arm = _arm(moves=(TargetMove(at_s=1.0, by_mm=(40.0, -30.0, 0.0), over_s=0.5),))
    arm.run(2.5)
    guard = arm.core.guard
    assert guard is not None
    model = guard.guard.model
    head = next(o for o in model.geom.geometryObjects if o.name == "head")
    truth = arm.ls.sim.truth().target
    assert truth is not None
    chair = model.scene.mount @ head.placement.homogeneous  # type: ignore[union-attr]
    assert np.allclose(chair[:3, 3], truth.body_xyz, atol=0.003)
    # the fast check the guard anchors with has it there too (as one built now would)
    js = arm.core.last_js
    assert js is not None
    q = np.array(js.position)
    fast = guard.guard.advance.checker.margins(q)
    assert np.array_equal(fast.free, ValidityChecker(model).margins(q).free)
    # and a guard rebuilt for a held cup keeps it there
    guard.hold([HeldBody("cup", "cup", "cylinder", (0.035, 0.1), (0.0, 0.0, 0.08), (0.0,) * 3)])
    assert np.array_equal(guard.guard.model.moved.poses["head"], model.moved.poses["head"])


def test_every_frame_is_recorded_where_the_controller_took_it() -> None:
    arm = _arm()
    arm.run(1.0)
    taken = [m for m in arm.ls.published(ep.TARGET_TAKEN) if isinstance(m, TargetTaken)]
    frames = arm.ls.published(ep.TARGET)
    assert len(taken) == len(frames) > 20
    assert [t.target for t in taken] == frames
    seqs = [t.after_seq for t in taken]
    assert seqs == sorted(seqs)


@pytest.mark.parametrize("standoff", [0.06, 0.1])
def test_the_standoff_is_measured_along_the_approach_axis(standoff: float) -> None:
    arm = _arm(sway_mm=(0.0, 0.0, 0.0))
    assert arm.follow(offset=RIM, standoff=standoff).accepted
    arm.run(6.0)
    s = arm.samples[-1]
    assert s.error < 0.003
    assert s.point[0] - s.target[0] == pytest.approx(standoff, abs=0.003)  # the face's x


def test_a_follow_session_replays_byte_for_byte(tmp_path: Path) -> None:
    arm = _arm(lost=(LostWindow(at_s=3.0, for_s=0.5),), noise_mm=0.5)
    assert arm.follow(offset=RIM).accepted
    arm.run(3.7 - arm.ls.t_ns / 1e9)
    assert arm.follow(goal_id="f2", offset=RIM).accepted
    arm.run(1.0)
    assert arm.stop().accepted
    arm.run(0.3)
    path = tmp_path / "follow.mcap"
    with RecordingWriter(path) as writer:
        for t_ns, suffix, msg in arm.ls.messages:
            # the tracker's frames logged 3 ms late: after the next joint state sometimes
            writer.write(suffix, msg, t_ns + (3_000_000 if suffix == ep.TARGET else 0))
    result = check_controller(path)
    assert result.ok, result.difference
    assert result.compared > 100
    assert [r.cause for r in arm.follow_results()] == [
        EndCause.TARGET_LOST,
        EndCause.CANCEL_REQUEST,
    ]
