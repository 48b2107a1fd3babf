"""Live control in lock-step (simulator + bridge + controller cores), judged on the
simulator's truth: straight lines, the deadman, the release, bad commands, levels, and
the stops that a trajectory obeys (e-stop, arm error, bridge phases); goals refused
while jogging, a trajectory preempted by a jog, a task paused by one; byte-for-byte replay.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

from manus.protocol import FrameId, decode_move
from manus.wiring import BAD_PAYLOAD
from manus_stack.jog_lockstep import JogArm, line_drift
from manus_stack.regression import check_controller
from manus_stack.task_lockstep import TaskLockStep
from schemas import endpoints as ep
from schemas.commands import ArmCommand, EStop, JointVelocityCommand
from schemas.control import CommandSourceKind, EndCause, GoalResult, Refusal, TrajectoryGoal
from schemas.jog import USER_TOOK_OVER, JogLevel, JogRunState, JogTaken, LimitKind
from schemas.keys import Keys
from schemas.planning import Trajectory
from schemas.sequencing import Task, TaskStep
from schemas.state import ArmStatus
from services.controller.core import ControllerCore
from services.controller.jog import JogSource
from services.controller.wiring import WIRING as CONTROLLER
from services.recorder.writer import RecordingWriter
from services.sequencer.taskfile import task_from_args
from services.simulator.config import SimConfig
from services.simulator.faults import InjectedMessage
from tests.controller_plant import steps

PATHS = Path(__file__).resolve().parents[1] / "paths"
CYCLE_NS = 60_000_000
X = [1.0, 0.0, 0.0]


def _arm(level: int | None = None) -> JogArm:
    arm = JogArm()
    arm.start()
    if level is not None:
        assert arm.query(ep.JOG_LEVEL, JogLevel(level=level)).accepted
    arm.run(0.3)
    return arm


def _zero_frames(arm: JogArm, since_ns: int) -> list[tuple[int, bool]]:
    """(send time, all zero) of every joint move the bridge sent from ``since_ns``."""
    return [
        (f.t_ns, decode_move(f.id, f.data).is_zero)
        for f in arm.ls.bridge_frames
        if f.id == FrameId.JOINT and f.t_ns >= since_ns
    ]


def _hold(arm: JogArm, seconds: float) -> None:
    """Keep sending a zero command (a released joystick) for ``seconds``."""
    arm.stream(seconds)


@pytest.mark.parametrize("level", [1, 5])
def test_a_pure_x_twist_is_a_straight_line_on_the_truth(level: int) -> None:
    arm = _arm(level)
    first = len(arm.samples)
    x0 = arm.samples[-1].xyz[0]
    arm.stream(20.0, until=lambda s: s.xyz[0] - x0 >= 0.1, units="unitless", linear=X)
    drift, along, turned = line_drift(arm.samples[first:], np.array(X))
    assert along >= 0.1
    assert drift <= 0.001, drift  # the target, on the simulator's truth
    assert turned <= 0.5, turned
    state = arm.states()[-1]
    assert state.active and state.level == level and state.kind == "twist"
    # the speed follows the level: 30 mm/s at level 1, 150 mm/s at level 5
    moving = [s for s in arm.samples[first:] if s.speed > 1.0]
    seconds = (moving[-1].t_ns - moving[0].t_ns) / 1e9
    assert 0.1 / seconds == pytest.approx(0.15 * level / 5, rel=0.25)


def test_deadman_stops_the_arm_within_two_cycles_and_nothing_resumes_without_a_release() -> None:
    arm = _arm(5)
    arm.stream(0.6, units="unitless", linear=X)
    assert not arm.samples[-1].at_rest
    last_sent = arm.sent[-1][0]
    expiry = last_sent + arm.core.config.jog.timeout_ns
    arm.run(1.0)  # the sender is gone
    first_zero = next(t for t, zero in _zero_frames(arm, last_sent) if zero)
    acting = first_zero + 20_000_000  # latched at the sync, active 20 ms later
    assert acting - expiry <= 2 * CYCLE_NS, (acting - expiry) / 1e6
    # on the truth: the motors slow down from then on, through the drives' lag (tau 20 ms:
    # from 50 deg/s to under 0.5 deg/s in 92 ms), and stay at rest
    rest = arm.rest_from(last_sent)
    assert rest is not None
    assert rest - acting <= 100_000_000, (rest - acting) / 1e6
    after = [s.speed for s in arm.samples if s.t_ns >= acting + 5_000_000]
    assert all(b <= a + 1e-9 for a, b in itertools.pairwise(after))
    assert all(zero for t, zero in _zero_frames(arm, first_zero))
    state = arm.states()[-1]
    assert not state.active and state.deadman_stops == 1
    assert (state.state, state.cause) == (JogRunState.STOPPED, EndCause.DEADMAN)
    assert state.reason.startswith("stopped: deadman") and state.refused == 0
    # the sender comes back still deflected: nothing moves until it releases, and the
    # state says so (each command held back is shown; the stop counts one refusal)
    seen = len(arm.states())
    arm.stream(0.5, units="unitless", linear=X)
    assert all(s.at_rest for s in arm.samples[-80:])
    held = arm.states()[seen:]
    assert len(held) >= 5
    assert {(h.state, h.cause, h.reason, h.refused) for h in held} == {
        (JogRunState.STOPPED, EndCause.DEADMAN, state.reason, 1)
    }
    _hold(arm, 0.2)
    released = arm.states()[-1]
    assert (released.state, released.cause) == (JogRunState.IDLE, EndCause.RELEASED)
    arm.stream(0.4, units="unitless", linear=X)
    assert not arm.samples[-1].at_rest


@pytest.mark.parametrize(("hz", "stops"), [(10.0, False), (7.0, True)])
def test_a_10_hz_stream_with_jitter_keeps_jogging_and_a_7_hz_one_trips_the_deadman(
    hz: float, stops: bool
) -> None:
    """Commands are dated on the joint states' 60 ms grid, so every gap up to two cycles
    (120 ms) passes whatever its phase: 10 Hz with +-20 ms of jitter jogs on; 7 Hz
    (143 ms gaps) leaves a joint state 180 ms after the newest command's and stops."""
    arm = _arm(1)  # 30 mm/s: 3 s stay inside the workspace
    rng = np.random.default_rng(7)
    end = arm.ls.t_ns + 3_000_000_000
    while arm.ls.t_ns < end:
        arm.send(units="unitless", linear=X)
        arm.run(1.0 / hz + float(rng.uniform(-0.02, 0.02)))
    assert (arm.core.source(JogSource).deadman_stops > 0) == stops, arm.core.source(
        JogSource
    ).reason
    assert arm.samples[-1].at_rest == stops


def test_a_zero_command_stops_at_once() -> None:
    arm = _arm(5)
    arm.stream(0.6, units="unitless", linear=X)
    released = arm.ls.t_ns
    before = len(arm.ls.published(ep.JOINT_VELOCITY))
    arm.send()
    arm.run(0.001)
    corrections = arm.ls.published(ep.JOINT_VELOCITY)[before:]
    assert len(corrections) == 1  # the stop replaces this cycle's command at once
    assert isinstance(corrections[0], JointVelocityCommand)
    assert steps(corrections[0]) == [0] * 8
    arm.run(0.5)
    rest = arm.rest_from(released)  # zeros act within 100 ms, then the lag's 92 ms
    assert rest is not None
    assert rest - released <= 200_000_000, (rest - released) / 1e6
    assert not arm.states()[-1].active


@pytest.mark.parametrize(
    "fields",
    [
        {"units": "unitless", "linear": [1.0, math.nan, 0.0]},
        {"units": "unitless", "linear": [2.0, 0.0, 0.0]},
        {"linear": [0.4, 0.0, 0.0]},
    ],
)
def test_a_bad_command_is_refused_counted_and_the_arm_stops(fields: dict[str, object]) -> None:
    arm = _arm(5)
    arm.stream(0.5, units="unitless", linear=X)
    bad = arm.ls.t_ns
    arm.send(**fields)
    arm.stream(0.5, units="unitless", linear=X)  # the good stream goes on: ignored
    rest = arm.rest_from(bad)
    assert rest is not None
    assert rest - bad <= 200_000_000, (rest - bad) / 1e6
    state = arm.states()[-1]
    assert state.refused == 1 and not state.active
    assert (state.state, state.cause) == (JogRunState.STOPPED, EndCause.BAD_COMMAND)
    assert "refused" in state.reason


def test_a_garbage_payload_stops_the_jog() -> None:
    core = ControllerCore()
    arm = _arm(5)
    arm.stream(0.5, units="unitless", linear=X)
    out = CONTROLLER.feed_bad(arm.core, ep.JOG, BAD_PAYLOAD, 0)
    assert [s for s, _ in out] == [ep.JOG_TAKEN, ep.JOINT_VELOCITY]  # taken, and stopped
    taken = out[0][1]
    assert isinstance(taken, JogTaken) and taken.command is None
    assert taken.error == "the payload does not decode"
    assert not arm.core.source(JogSource).engaged and arm.core.source(JogSource).refused == 1
    assert [s for s, _ in CONTROLLER.feed_bad(core, ep.JOG, "junk", 0)] == [
        ep.JOG_TAKEN
    ]  # idle: only counted
    assert core.source(JogSource).refused == 1


@pytest.mark.parametrize("stop", ["estop", "arm_error", "bridge_stop"])
def test_the_stops_of_a_trajectory_stop_a_jog(stop: str) -> None:
    arm = _arm(5)
    arm.stream(0.5, units="unitless", linear=X)
    t = arm.ls.t_ns
    if stop == "estop":
        arm.ls.publish("estop", EStop(stamp_ns=t, seq=0, engaged=True, source="test"))
    elif stop == "arm_error":
        arm.ls.sim.add_fault(InjectedMessage(msg_class="error", code=4, at_ms=t / 1e6))
    else:
        assert arm.ls.arm_command(ArmCommand(action="stop", source="test")).ok
    arm.stream(0.8, units="unitless", linear=X)
    rest = arm.rest_from(t)
    assert rest is not None
    assert rest - t <= 300_000_000, (rest - t) / 1e6
    assert not arm.core.source(JogSource).engaged
    assert arm.core.source(JogSource).stopped is not None  # until the user releases the controls
    assert (
        arm.core.source(JogSource).refused <= 1
    )  # a joystick held through the stop is one refusal


def test_goals_are_refused_while_jogging_and_a_jog_preempts_a_trajectory() -> None:
    arm = _arm(5)
    arm.stream(0.3, units="unitless", linear=X)
    js = arm.core.last_js
    assert js is not None
    q = list(js.position)
    goal = TrajectoryGoal(
        goal_id="g1",
        trajectory=Trajectory(times=[0.0, 2.0], positions=[q, q], velocities=[[0.0] * 6] * 2),
    )
    ack = arm.submit(goal)
    assert not ack.accepted and "jogging" in ack.reason
    assert (ack.refusal, ack.held_by) == (Refusal.BUSY, CommandSourceKind.JOG)
    _hold(arm, 0.3)
    js = arm.core.last_js
    assert js is not None
    q = list(js.position)
    q2 = [*q[:5], q[5] + 0.3]
    moving = TrajectoryGoal(
        goal_id="g2",
        trajectory=Trajectory(times=[0.0, 3.0], positions=[q, q2], velocities=[[0.0] * 6] * 2),
    )
    assert arm.submit(moving).accepted
    arm.run(0.5)
    arm.send(units="unitless", linear=[0.0, 0.5, 0.0])
    arm.run(0.1)
    result = arm.results("g2")
    assert len(result) == 1 and result[0].status == "preempted"
    assert result[0].cause == EndCause.USER_TOOK_OVER
    assert result[0].reason.startswith(USER_TOOK_OVER)


def test_a_jog_pauses_the_running_task_and_resume_finishes_it() -> None:
    rig = TaskLockStep(SimConfig(start_pose="unfolded"))
    rig.start_arm()
    assert rig.submit(task_from_args([str(PATHS / "thesis_square.txt")])).accepted
    rig.run_until_event("step_started")
    rig.ls.run_for(2.0)
    seq = 0
    for _ in range(10):  # the user pushes the joystick for half a second
        seq += 1
        cmd = JogArm.make_command(seq, rig.ls.t_ns, units="unitless", linear=[0.0, 0.0, 0.5])
        rig.ls.publish(ep.JOG, cmd)
        rig.ls.run_for(0.05)
    paused = [e for e in rig.events if e.event == "paused"]
    assert len(paused) == 1 and paused[0].reason == USER_TOOK_OVER
    assert rig.seq.state == "paused"
    seq += 1
    rig.ls.publish(ep.JOG, JogArm.make_command(seq, rig.ls.t_ns))
    rig.ls.run_for(1.0)
    assert rig.seq.state == "paused"  # resuming is explicit
    assert rig.control("resume").ok
    rig.run_while_busy(120.0)
    assert rig.seq.state == "succeeded", rig.seq.reason
    results = [r for r in rig.results() if isinstance(r, GoalResult)]
    assert any(r.reason.startswith(USER_TOOK_OVER) for r in results)


def test_a_jog_session_replays_byte_for_byte(tmp_path: Path) -> None:
    arm = _arm(4)
    arm.stream(0.5, units="unitless", linear=X)
    arm.stream(0.4, frame="gripper", units="unitless", linear=[0.0, 0.5, 0.0])
    arm.stream(0.4, units="unitless", drink=True, angular=[0.0, 0.0, 0.5], pour=0.4)
    arm.stream(0.3, kind="joints", units="unitless", joints=[0.0, 0.0, 0.0, 0.0, 0.0, 0.4])
    arm.send(linear=[0.5, 0.0, 0.0])  # above the cap: refused
    _hold(arm, 0.2)
    arm.query(ep.JOG_LEVEL, JogLevel(level=2))
    arm.stream(0.3, units="unitless", linear=X, gripper=0.5)
    # a garbage payload on jog, as the live shell hands it over (recorded as it travelled)
    garbage_ns: int | None = arm.ls.t_ns
    for suffix, msg in CONTROLLER.feed_bad(arm.core, ep.JOG, BAD_PAYLOAD, 0):
        arm.ls.publish(suffix, msg)
    _hold(arm, 0.2)
    arm.stream(0.3, units="unitless", linear=X)
    arm.run(0.5)  # deadman
    path = tmp_path / "jog.mcap"
    with RecordingWriter(path) as writer:
        for t_ns, suffix, msg in arm.ls.messages:
            if garbage_ns is not None and t_ns >= garbage_ns:
                writer.write_payload(Keys()(ep.JOG), b"\xc1 not msgpack", garbage_ns)
                garbage_ns = None
            writer.write(suffix, msg, t_ns)
    result = check_controller(path)
    assert result.ok, result.difference
    assert result.compared > 100
    assert arm.core.source(JogSource).refused == 2


def test_a_joint_jog_toward_the_wrist_singularity_stops_before_it_on_the_truth() -> None:
    arm = _arm(5)
    start_q5 = math.degrees(arm.ls.sim.truth().q_true[4])
    assert start_q5 < -40.0  # the unfolded wrist: q5 = -60 deg
    arm.stream(4.0, kind="joints", units="unitless", joints=[0.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    q5 = [math.degrees(s.q[4]) for s in arm.samples]
    stop = arm.core.config.jog.wrist_stop_deg
    assert max(q5) < 0.0  # never across: no wrist flip
    assert -stop - 1.0 < q5[-1] < -stop + 0.5, q5[-1]  # stopped near the stop
    assert arm.samples[-1].at_rest
    wrist = [(s, lim) for s in arm.states() for lim in s.limits if lim.object == "wrist"]
    assert all(lim.kind == LimitKind.SINGULARITY for _, lim in wrist)
    assert any(0.0 < lim.scale < 1.0 for _, lim in wrist)  # slowed first
    last = arm.states()[-1]
    assert [(lim.object, lim.scale) for lim in last.limits] == [("wrist", 0.0)]
    assert last.scale == 0.0 and last.limits[0].angle == pytest.approx(math.radians(stop), abs=0.02)
    assert last.reason.startswith("stopped by the wrist singularity")
    assert last.state == JogRunState.RUNNING  # held there, still jogging: backing out is allowed
    arm.stream(0.6, kind="joints", units="unitless", joints=[0.0, 0.0, 0.0, 0.0, -1.0, 0.0])
    assert math.degrees(arm.ls.sim.truth().q_true[4]) < q5[-1] - 5.0


def test_reaching_out_stops_before_a_joint_limit_and_holds_still() -> None:
    arm = _arm(5)
    arm.stream(4.0, units="unitless", linear=X)  # forward, the gripper's pitch kept: q5 falls
    state = arm.states()[-1]
    assert state.state == JogRunState.RUNNING and state.scale == 0.0
    assert [(lim.kind, lim.object, lim.scale) for lim in state.limits] == [
        (LimitKind.JOINT_LIMIT, "joint 5", 0.0)
    ]
    assert state.reason.startswith("stopped by the limit of joint 5"), state.reason
    lower = math.degrees(arm.core.config.arm.lower[4])
    q5 = [math.degrees(s.q[4]) for s in arm.samples]
    assert min(q5) > lower + arm.core.config.jog.limit_stop_deg - 0.5  # (the belt's play)
    assert all(s.at_rest for s in arm.samples[-100:])  # held without a limit cycle
    complaints = [m for m in arm.ls.published(ep.STATUS) if isinstance(m, ArmStatus)]
    assert not [m for m in complaints if m.msg_class in ("warning", "error")]


def test_drink_mode_keeps_the_cup_level_and_pours_about_the_rim_on_the_truth() -> None:
    arm = _arm(3)
    first = len(arm.samples)
    arm.stream(1.5, units="unitless", drink=True, linear=[0.5, -0.5, 0.3], angular=[0.0, 0.0, 1.0])
    seg = arm.samples[first:]
    up0 = seg[0].R.T @ np.array([0.0, 0.0, 1.0])
    tilt = max(math.degrees(math.acos(min(1.0, float(up0 @ (s.R.T @ np.array([0, 0, 1.0]))))))
               for s in seg)  # fmt: skip
    turned = math.degrees(math.acos((np.trace(seg[0].R.T @ seg[-1].R) - 1.0) / 2.0))
    assert tilt <= 0.5, tilt  # the cup stays level ...
    assert turned > 10.0  # ... while it turns about the vertical
    _hold(arm, 0.3)
    rim = np.asarray(arm.core.config.jog.rim_offset)
    before = arm.samples[-1]
    arm.stream(1.0, units="unitless", drink=True, pour=1.0)
    _hold(arm, 0.3)
    after = arm.samples[-1]
    tilted = math.degrees(math.acos((np.trace(before.R.T @ after.R) - 1.0) / 2.0))
    moved = np.linalg.norm((after.R @ rim + after.xyz) - (before.R @ rim + before.xyz))
    assert tilted > 8.0, tilted
    assert moved < 0.002, moved  # the rim point stays (within the belts' play)


def _push(rig: TaskLockStep, seconds: float, seq: int) -> int:
    """The user pushes the stick (+z, unitless) for ``seconds`` at 20 Hz."""
    for _ in range(round(seconds / 0.05)):
        seq += 1
        cmd = JogArm.make_command(seq, rig.ls.t_ns, units="unitless", linear=[0.0, 0.0, 0.5])
        rig.ls.publish(ep.JOG, cmd)
        rig.ls.run_for(0.05)
    return seq


def test_a_jog_during_a_wait_pauses_the_task_and_keeps_the_wait() -> None:
    rig = TaskLockStep(SimConfig(start_pose="unfolded"))
    rig.start_arm()
    task = Task(steps=[TaskStep(kind="wait", duration=3.0), TaskStep(kind="gripper", opening=0.03)])
    assert rig.submit(task).accepted
    rig.ls.run_for(1.0)
    seq = _push(rig, 0.3, 0)
    paused = [e for e in rig.events if e.event == "paused"]
    assert len(paused) == 1 and paused[0].reason == USER_TOOK_OVER and paused[0].step == 0
    rig.ls.publish(ep.JOG, JogArm.make_command(seq + 1, rig.ls.t_ns))  # released
    rig.ls.run_for(5.0)
    assert rig.seq.state == "paused"
    t_resume = rig.ls.t_ns
    assert rig.control("resume").ok
    rig.run_while_busy(30.0)
    assert rig.seq.state == "succeeded", rig.seq.reason
    finished = next(e for e in rig.events if e.event == "step_finished" and e.step == 0)
    assert 1.5 < (finished.stamp_ns - t_resume) / 1e9 < 2.2  # the rest of the wait


def test_a_goal_refused_because_the_user_jogs_pauses_the_task() -> None:
    rig = TaskLockStep(SimConfig(start_pose="unfolded"))
    rig.start_arm()
    seq = _push(rig, 0.2, 0)  # the user already jogs when the task starts
    assert rig.submit(Task(steps=[TaskStep(kind="gripper", opening=0.03)])).accepted
    rig.ls.run_for(0.2)
    paused = [e for e in rig.events if e.event == "paused"]
    assert len(paused) == 1 and paused[0].reason == USER_TOOK_OVER
    rig.ls.publish(ep.JOG, JogArm.make_command(seq + 1, rig.ls.t_ns))
    rig.ls.run_for(0.3)
    assert rig.control("resume").ok
    rig.run_while_busy(30.0)
    assert rig.seq.state == "succeeded", rig.seq.reason


def test_a_recording_whose_jog_and_joint_states_crossed_still_replays_exactly(
    tmp_path: Path,
) -> None:
    """Live, the recorder may log a jog command after a joint state that reached the
    controller after it (two publishers): the controller's JogTaken says where it was taken."""
    arm = _arm(4)
    arm.stream(0.6, units="unitless", linear=X)
    arm.send(linear=[0.5, 0.0, 0.0])  # refused
    _hold(arm, 0.2)
    arm.stream(0.4, units="unitless", linear=[0.0, 0.5, 0.0])
    arm.run(0.4)
    states = sorted(t for t, s, _ in arm.ls.messages if s == ep.JOINTS)

    def late(t_ns: int) -> int:  # just after the next joint state: the crossing
        nxt = next((s for s in states if s > t_ns), t_ns)
        return nxt + 1_000_000

    path = tmp_path / "crossed.mcap"
    crossed = 0
    with RecordingWriter(path) as writer:
        for t_ns, suffix, msg in sorted(
            ((late(t) if s in (ep.JOG, ep.JOG_TAKEN) else t, s, m) for t, s, m in arm.ls.messages),
            key=lambda item: item[0],
        ):
            crossed += suffix == ep.JOG
            writer.write(suffix, msg, t_ns)
    assert crossed > 10
    result = check_controller(path)
    assert result.ok, result.difference
