"""ControllerCore with synthetic joint states (tests/controller_plant.py): every goal rule."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from manus.config import DEFAULT_ARM
from manus.deadman import RecentStates
from manus.errors import ConfigError
from manus.quantize import COUNT_RAD_S
from schemas import endpoints as ep
from schemas.commands import JointVelocityCommand
from schemas.control import CancelGoal, GripperGoal, Heartbeat, SpeedScale, TrajectoryGoal
from schemas.state import ArmStatus, BridgeState, JointState
from services.controller.backlash import PlayModel
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore
from services.controller.goal_source import GoalSource
from services.controller.reference import Reference
from tests.controller_plant import MS, Q0, Plant, ask, feed, line_trajectory, steps


def _plant(**config: object) -> Plant:
    plant = Plant(ControllerCore(ControllerConfig(**config)))  # type: ignore[arg-type]
    plant.run(3)
    return plant


def _goal(
    goal_id: str = "g", delta: tuple[float, ...] = (10, -8, 6, 5, 5, 5), **kw: object
) -> TrajectoryGoal:
    plant_q = kw.pop("q0", Q0)
    duration = float(kw.pop("duration", 3.0))  # type: ignore[arg-type]
    traj = line_trajectory(np.asarray(plant_q), delta, duration)
    return TrajectoryGoal(goal_id=goal_id, trajectory=traj, **kw)  # type: ignore[arg-type]


def test_idle_answers_every_state_with_zeros() -> None:
    plant = _plant()
    assert len(plant.commands) == 3
    for js, cmd in zip(plant.states, plant.commands, strict=True):
        assert cmd.ref_seq == js.seq
        assert steps(cmd) == [0] * 8
        assert cmd.velocity == [0.0] * 6
    assert plant.feedback == [] and plant.results == []


@pytest.mark.parametrize("mode", ["default", "thesis"])
def test_goal_succeeds_with_one_result_and_via_errors(mode: str) -> None:
    plant = _plant()
    goal = _goal(mode=mode)
    assert ask(plant.core, ep.GOAL, goal).accepted
    result = plant.run_until_result("g")
    assert result.status == "succeeded", result.reason
    assert len(result.via_errors) == len(goal.trajectory.times) == len(result.via_stamps)
    assert result.via_stamps == sorted(result.via_stamps)
    assert max(result.via_errors) < 0.01
    assert result.kind == "trajectory" and result.duration >= 3.0
    plant.run(5)
    assert [r.goal_id for r in plant.results] == ["g"]
    assert steps(plant.commands[-1]) == [0] * 8
    assert np.max(np.abs(plant.q - np.asarray(goal.trajectory.positions[-1]))) < math.radians(0.3)


def test_default_mode_tracks_closer_than_thesis() -> None:
    errors = {}
    for mode in ("default", "thesis"):
        plant = _plant()
        ask(plant.core, ep.GOAL, _goal(mode=mode, delta=(20, -15, 12, 10, 10, 10), duration=4.0))
        errors[mode] = float(np.mean(plant.run_until_result("g").via_errors[1:]))
    assert errors["default"] < errors["thesis"]


def test_start_state_check_refuses_a_far_first_knot() -> None:
    plant = _plant()
    q = Q0.copy()
    q[2] += 0.2
    ack = ask(plant.core, ep.GOAL, _goal(q0=q))
    assert not ack.accepted
    assert "joint 3" in ack.reason and "start_tolerance 0.0500 rad" in ack.reason
    plant.run(2)
    assert plant.results == []


def test_refused_without_joint_state_and_bad_fields() -> None:
    core = ControllerCore()
    ack = ask(core, ep.GOAL, _goal())
    assert not ack.accepted and "no valid joint state" in ack.reason
    plant = _plant()
    bad = ask(plant.core, ep.GOAL, _goal(path_tolerance=[0.1, 0.1]))
    assert not bad.accepted and "`path_tolerance` has 2 values" in bad.reason
    empty = ask(plant.core, ep.GOAL, _goal(goal_id=""))
    assert not empty.accepted and "goal_id" in empty.reason


def test_path_tolerance_abort_names_joint_error_and_tolerance() -> None:
    plant = _plant()
    plant.stuck = {0}  # joint 1's motor does not move
    ask(plant.core, ep.GOAL, _goal(path_tolerance=[0.02] * 6))
    result = plant.run_until_result("g")
    assert result.status == "aborted"
    assert (
        "path tolerance: joint 1 error" in result.reason and "exceeds 0.0200 rad" in result.reason
    )
    plant.run(2)
    assert steps(plant.commands[-1]) == [0] * 8
    assert len(plant.results) == 1


def test_goal_time_tolerance_abort() -> None:
    plant = _plant()
    plant.stuck = {0}
    ask(
        plant.core, ep.GOAL, _goal(goal_time_tolerance=0.5, goal_tolerance=[0.01] * 6, duration=1.0)
    )
    result = plant.run_until_result("g")
    assert result.status == "aborted"
    assert "goal tolerance: joint 1" in result.reason and "goal_time_tolerance" in result.reason
    assert 1.5 <= result.duration <= 2.0


def test_cancel_decelerates_within_the_bound_then_reports() -> None:
    config = ControllerConfig(cancel_decel=math.radians(60.0))
    plant = Plant(ControllerCore(config))
    plant.run(3)
    ask(plant.core, ep.GOAL, _goal(delta=(60, 0, 0, 0, 0, 0), duration=2.0))
    plant.run(14)  # mid-way: near top speed
    before = len(plant.commands)
    assert max(abs(c) for c in steps(plant.commands[-1])) >= 5
    assert ask(plant.core, ep.CANCEL, CancelGoal(goal_id="g")).accepted
    result = plant.run_until_result("g")
    assert result.status == "cancelled"
    counts = np.array([steps(c) for c in plant.commands[before - 1 :]])[:, 1:7]
    step = config.cancel_decel * config.cycle_s / COUNT_RAD_S  # 0.72 counts per cycle
    drops = np.abs(counts[:-1]) - np.abs(counts[1:])
    assert drops.min() >= 0  # never speeds up
    assert drops.max() <= step + 0.5 + 1e-9
    assert not np.any(counts[-1])
    plant.run(3)
    assert len(plant.results) == 1


def test_cancel_unknown_goal_is_refused_and_cancel_all_accepts() -> None:
    plant = _plant()
    assert not ask(plant.core, ep.CANCEL, CancelGoal(goal_id="nope")).accepted
    assert ask(plant.core, ep.CANCEL, CancelGoal()).accepted


def test_reference_splice_is_continuous_in_position_velocity_acceleration() -> None:
    old = Reference(line_trajectory(Q0, (30, 10, -10, 5, 5, 5), 3.0), arm=DEFAULT_ARM)
    tau = 1.3
    at = old.sample(tau).q
    new_msg = line_trajectory(at + np.radians([1, -1, 1, 0, 0, 0]), (-20, 5, 5, 0, 0, 0), 2.0)
    new = old.spliced(new_msg, tau, 0.8)
    a, b = old.sample(tau), new.sample(0.0)
    np.testing.assert_allclose(b.q, a.q, atol=1e-12)
    np.testing.assert_allclose(b.qd, a.qd, atol=1e-12)
    np.testing.assert_allclose(b.qdd, a.qdd, atol=1e-9)
    plain = Reference(new_msg, arm=DEFAULT_ARM)
    for t in (0.8, 1.0, 2.5):
        np.testing.assert_allclose(new.sample(t).q, plain.sample(t).q, atol=1e-12)
    # The cycle's scalar positions are sample().q, inside the blend, after it, before 0.
    for t in (-0.06, 0.0, 0.3, 0.79, 0.8, 1.0, 2.5, 9.0):
        assert new.position(t) == new.sample(t).q.tolist()


def test_replace_while_moving_splices_without_a_jump() -> None:
    plant = _plant()
    ask(plant.core, ep.GOAL, _goal(delta=(30, 0, 0, 0, 0, 0), duration=3.0))
    plant.run(20)
    q_now = np.asarray(plant.states[-1].position)
    replacement = line_trajectory(q_now, (0, 10, 0, 0, 0, 0), 2.0)
    ack = ask(
        plant.core, ep.GOAL, TrajectoryGoal(goal_id="h", trajectory=replacement, replace=True)
    )
    assert ack.accepted
    n = len(plant.feedback)
    result = plant.run_until_result("h")
    assert result.status == "succeeded", result.reason
    first = next(r for r in plant.results if r.goal_id == "g")
    assert first.status == "preempted" and "spliced" in first.reason
    refs = np.array([f.reference for f in plant.feedback[n - 3 : n + 4]])
    # The reference keeps moving joint 1 on through the splice: no jump, no stop.
    moves = np.diff(refs[:, 0])
    assert np.all(moves > 0) and np.max(np.abs(np.diff(moves))) < math.radians(0.5)
    counts = np.array([steps(c) for c in plant.commands])[:, 1:7]
    assert np.max(np.abs(np.diff(counts, axis=0))) <= 3


def test_preempt_gives_each_goal_exactly_one_result() -> None:
    plant = _plant()
    ask(plant.core, ep.GOAL, _goal("a"))
    plant.run(5)
    ask(
        plant.core,
        ep.GOAL,
        _goal("b", q0=np.asarray(plant.states[-1].position), delta=(1, 0, 0, 0, 0, 0)),
    )
    ask(
        plant.core,
        ep.GOAL,
        _goal("c", q0=np.asarray(plant.states[-1].position), delta=(1, 0, 0, 0, 0, 0)),
    )
    plant.run_until_result("c")
    plant.run(3)
    by_id = {r.goal_id: r.status for r in plant.results}
    assert by_id == {"a": "preempted", "b": "preempted", "c": "succeeded"}
    assert len(plant.results) == 3


def test_arm_error_stops_and_aborts_with_the_arms_message() -> None:
    plant = _plant()
    ask(plant.core, ep.GOAL, _goal())
    ask(plant.core, ep.GRIPPER_GOAL, GripperGoal(goal_id="grip", opening=0.06))
    plant.run(10)
    st = ArmStatus(
        stamp_ns=plant.t_ns,
        seq=1,
        mode="joint",
        mode_code=4,
        msg_class="error",
        msg_code=4,
        text="absolute encoder error",
    )
    out = plant.core.on_status(st)
    plant.collect(out)
    statuses = {r.goal_id: (r.status, r.reason) for r in plant.results}
    assert statuses["g"] == ("aborted", "arm error: absolute encoder error")
    assert statuses["grip"][0] == "aborted"
    plant.run(2)
    assert all(steps(c) == [0] * 8 for c in plant.commands[-2:])
    refused = ask(plant.core, ep.GOAL, _goal("h", q0=np.asarray(plant.states[-1].position)))
    assert not refused.accepted and "absolute encoder error" in refused.reason
    ok = dataclasses.replace(st, msg_class="none", msg_code=0, text="")
    plant.core.on_status(ok)
    assert ask(plant.core, ep.GOAL, _goal("h", q0=np.asarray(plant.states[-1].position))).accepted


@pytest.mark.parametrize("kind", ["seq", "stamp"])
def test_short_joint_state_gap_stops_for_a_cycle_then_resumes(kind: str) -> None:
    plant = _plant()
    ask(plant.core, ep.GOAL, _goal())
    plant.run(10)
    assert any(steps(plant.commands[-1]))
    running = plant.core.source(GoalSource).run
    tau_before = running.tau if running else 0.0
    if kind == "seq":
        plant.cycle(seq_step=2)  # the next state skips a seq
    else:
        plant.cycle(skip=True)  # a whole cycle without a joint state
    plant.cycle()
    cmd = plant.commands[-1]
    assert steps(cmd) == [0] * 8 and cmd.ref_seq == plant.states[-1].seq
    run = plant.core.source(GoalSource).run
    waited = tau_before + (0.06 if kind == "seq" else 0.0)  # nothing added over the gap
    assert run is not None and run.tau == pytest.approx(waited)
    result = plant.run_until_result("g")
    assert result.status == "succeeded", result.reason


def test_long_joint_state_outage_aborts_with_zeros() -> None:
    plant = _plant()
    ask(plant.core, ep.GOAL, _goal())
    ask(plant.core, ep.GRIPPER_GOAL, GripperGoal(goal_id="grip", opening=0.06))
    plant.run(10)
    for _ in range(6):
        plant.cycle(skip=True)
    plant.cycle()
    assert steps(plant.commands[-1]) == [0] * 8
    reasons = {r.goal_id: (r.status, r.reason) for r in plant.results}
    assert reasons["g"][0] == "aborted" and "joint states interrupted" in reasons["g"][1]
    assert "max_outage_ms 300 ms" in reasons["g"][1]
    assert reasons["grip"][0] == "aborted"


def test_a_late_joint_state_is_no_lost_heartbeat() -> None:
    """A joint state 210 ms after the one before it (a late arm cycle: a gap) whose
    predecessor was echoed in time keeps the goal; once the echoes stop, the goal aborts
    at the same state as it would without the late one: the first whose predecessor
    went unechoed."""

    def cycle(plant: Plant, late_ms: int = 0, echo: bool = True) -> None:
        plant.t_ns += late_ms * MS
        plant.cycle()
        js = plant.states[-1]
        if echo:
            hb = Heartbeat(stamp_ns=js.stamp_ns, seq=js.seq, source="test", ref_seq=js.seq,
                           ref_stamp_ns=js.stamp_ns)  # fmt: skip
            feed(plant.core, ep.HEARTBEAT, hb)

    for late in (0, 150):
        plant = _plant()
        assert ask(plant.core, ep.GOAL, _goal(heartbeat_timeout=0.1)).accepted
        for _ in range(10):
            cycle(plant)
        cycle(plant, late_ms=150)
        assert steps(plant.commands[-1]) == [0] * 8  # the gap's zeros
        for _ in range(5):
            cycle(plant)
        assert plant.results == []
        cycle(plant, late_ms=late, echo=False)  # the link is cut: no echo from here on
        assert plant.results == []
        cycle(plant, echo=False)
        assert [r.status for r in plant.results] == ["aborted"]
        assert plant.results[0].reason.startswith("lost the supervisor's heartbeat")
        assert steps(plant.commands[-1]) == [0] * 8


def test_an_echo_gets_a_full_cycle_after_a_late_joint_state() -> None:
    """A joint state 29 ms late and the next one on time, 31 ms after it, whose echo
    comes 41 ms after its stamp, after the next state (seen in a soak, on a bridge just
    restarted): no lost heartbeat, the late state credits the echo before it with its
    lateness. A supervisor that hangs after that is caught where it always is: at the
    second state after the last echo. The credit never reaches past the newest states."""

    def state(plant: Plant, shift_ms: int = 0) -> JointState:
        plant.t_ns += shift_ms * MS
        plant.cycle()
        return plant.states[-1]

    def echo(plant: Plant, js: JointState) -> None:
        hb = Heartbeat(stamp_ns=js.stamp_ns, seq=js.seq, source="test", ref_seq=js.seq,
                       ref_stamp_ns=js.stamp_ns)  # fmt: skip
        feed(plant.core, ep.HEARTBEAT, hb)

    plant = _plant()
    assert ask(plant.core, ep.GOAL, _goal(heartbeat_timeout=0.1)).accepted
    for _ in range(10):
        echo(plant, state(plant))
    late = state(plant, 29)
    after = state(plant, -29)  # back on the grid: 31 ms after the late one
    assert plant.results == [], plant.results[0].reason  # was: aborted, echo 122 ms old
    echo(plant, late)
    echo(plant, after)
    state(plant)  # the supervisor hangs: no echo from here on
    assert plant.results == []
    state(plant)
    assert [r.status for r in plant.results] == ["aborted"]
    assert plant.results[0].reason.startswith("lost the supervisor's heartbeat")

    recent = RecentStates(60 * MS, keep=3)
    for stamp in (0, 60, 149, 180):
        recent.add(stamp * MS)
    assert recent.credit(60 * MS) == 89 * MS  # the state after it came 29 ms late
    assert recent.credit(149 * MS) == 149 * MS  # the state after it came early
    assert recent.credit(0) == 0  # no longer among the newest: no credit
    assert recent.credit(180 * MS) == 180 * MS  # nothing after it yet


def test_old_or_duplicate_state_is_not_answered() -> None:
    plant = _plant()
    assert plant.core.on_joint_state(plant.states[-1]) == []


def test_invalid_state_gets_zeros() -> None:
    plant = _plant()
    js = dataclasses.replace(plant.joint_state(), valid=False)
    out = plant.core.on_joint_state(js)
    assert out[0][0] == "cmd/joint_velocity"
    cmd = out[0][1]
    assert isinstance(cmd, JointVelocityCommand) and steps(cmd) == [0] * 8


@pytest.mark.parametrize("target", [0.06, 0.005])
def test_gripper_opens_and_closes_beside_an_arm_goal(target: float) -> None:
    plant = _plant()
    assert ask(plant.core, ep.GOAL, _goal()).accepted
    assert ask(plant.core, ep.GRIPPER_GOAL, GripperGoal(goal_id="grip", opening=target)).accepted
    result = plant.run_until_result("grip")
    assert result.status == "succeeded", result.reason
    assert result.kind == "gripper"
    assert abs(plant.gripper - target) <= 0.001 + 1e-4
    assert plant.run_until_result("g").status == "succeeded"
    assert any(f.gripper_goal_id == "grip" for f in plant.feedback)


def test_gripper_timeout_aborts() -> None:
    plant = _plant()
    ask(plant.core, ep.GRIPPER_GOAL, GripperGoal(goal_id="grip", opening=0.09, timeout=0.3))
    result = plant.run_until_result("grip")
    assert result.status == "aborted" and "timeout 0.3 s" in result.reason


def test_speed_scale_slows_the_goal() -> None:
    durations = []
    for scale in (1.0, 0.5):
        plant = _plant()
        ask(plant.core, ep.GOAL, _goal())
        plant.run(2)
        ack = ask(plant.core, ep.SPEED_SCALE, SpeedScale(scale=scale))
        assert ack.accepted and ack.goal_id == "g"
        durations.append(plant.run_until_result("g").duration)
    assert durations[1] > 1.7 * durations[0]
    assert not ask(ControllerCore(), ep.SPEED_SCALE, SpeedScale(scale=0.5)).accepted


def test_same_inputs_same_outputs() -> None:
    logs = []
    for _ in range(2):
        plant = _plant()
        ask(plant.core, ep.GOAL, _goal())
        ask(plant.core, ep.GRIPPER_GOAL, GripperGoal(goal_id="grip", opening=0.03))
        plant.run_until_result("g")
        logs.append([m.encode() for m in (*plant.commands, *plant.feedback, *plant.results)])
    assert logs[0] == logs[1]


def test_config_validation_names_the_field() -> None:
    with pytest.raises(ConfigError, match="thesis_gain"):
        ControllerConfig(thesis_gain=-1.0)
    with pytest.raises(ConfigError, match="default_quantizer"):
        ControllerConfig(default_quantizer="magic")
    assert ControllerConfig().cycle_ns == 60 * MS


def test_goals_run_only_while_the_bridge_is_running() -> None:
    plant = _plant()
    bs = BridgeState(
        stamp_ns=plant.t_ns,
        seq=0,
        phase="running",
        estop=False,
        cycles=10,
        period_ms=60.0,
        jitter_ms=0.0,
        reply_latency_ms=1.0,
        reply_latency_max_ms=1.0,
        missed_windows=0,
        stale_commands=0,
        resyncs=0,
        dropped_frames=0,
        duplicate_frames=0,
        garbled_frames=0,
        buffered_syncs=0,
        bad_payloads=0,
        detail="",
    )
    assert plant.core.on_bridge_state(bs) == []
    ask(plant.core, ep.GOAL, _goal())
    plant.run(5)
    plant.collect(
        plant.core.on_bridge_state(dataclasses.replace(bs, phase="estopped", detail="e-stop"))
    )
    result = plant.results[-1]
    assert result.status == "aborted" and result.reason == "bridge phase estopped: e-stop"
    ack = ask(plant.core, ep.GOAL, _goal("h", q0=np.asarray(plant.states[-1].position)))
    assert not ack.accepted and "'estopped'" in ack.reason
    plant.core.on_bridge_state(bs)
    assert ask(plant.core, ep.GOAL, _goal("h", q0=np.asarray(plant.states[-1].position))).accepted


def test_play_model_aims_the_belt_output() -> None:
    play = PlayModel(np.radians([0.0, 0.0, 0.0, 0.3, 0.3, 0.3]), math.radians(0.02))
    motor = np.zeros(6)
    play.update(motor)
    half = math.radians(0.15)
    up = play.motor_target(np.full(6, math.radians(1.0)), motor)
    np.testing.assert_allclose(up[3:], math.radians(1.0) + half)
    np.testing.assert_allclose(up[:3], math.radians(1.0))
    moved = np.full(6, math.radians(1.0) + half)
    play.update(moved)
    np.testing.assert_allclose(play.output[3:], math.radians(1.0))  # type: ignore[index]
    hold = play.motor_target(np.full(6, math.radians(1.0)), moved)
    np.testing.assert_allclose(hold[3:], moved[3:])  # output already there: motor stays
    down = play.motor_target(np.full(6, math.radians(0.5)), moved)
    np.testing.assert_allclose(down[3:], math.radians(0.5) - half)
