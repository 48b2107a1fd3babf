"""The deadman heartbeat in lock-step: a cut link between the computers stops the arm.

The link is cut by dropping every message that would cross it: joint states, bridge
states, feedback and results no longer reach the sequencer (base computer) and its
heartbeats no longer reach the controller (arm computer). Bridge and controller share
the arm computer, so without the heartbeat the controller would keep the arm moving.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import pytest

from manus.deadman import late_states
from manus.errors import ConfigError
from manus.protocol import FrameId, decode_move
from manus_stack.controlled import ControlledArm, controller_input
from manus_stack.task_lockstep import TaskLockStep
from schemas import endpoints as ep
from schemas.base import Message
from schemas.control import CancelGoal, GoalResult, GripperGoal, Heartbeat, TrajectoryGoal
from schemas.state import BridgeState, JointState
from services.controller.command_source import CommandSource
from services.controller.core import ControllerCore, Output
from services.sequencer.actions import HEARTBEAT_SUFFIX, Action, Publish, Query
from services.sequencer.config import SequencerConfig
from services.sequencer.core import SequencerCore
from services.sequencer.taskfile import task_from_args
from services.simulator.config import SimConfig
from tests.test_sequencer_core import SQUARE, UNFOLDED, joint_state, square_task
from tests.test_sequencer_core import Rig as SeqRig

S = TypeVar("S", bound=CommandSource)

PATHS = Path(__file__).resolve().parents[1] / "paths"

NS = 1_000_000_000
CYCLE_NS = 60_000_000
STOPS: list[tuple[int, float, float]] = []
"""(cut offset in the cycle [ms], cut -> first zero 0x374 [ms], cut -> arm at rest [ms])."""


@dataclass
class Link:
    """The network between the two computers."""

    up: bool = True


class ArmSideController(ControllerCore):
    """The controller on the arm computer: heartbeats reach it only over the link."""

    def __init__(self, link: Link) -> None:
        super().__init__()
        self.link = link

    def take(self, kind: type[S], handle: Callable[[S, Any], Output], msg: Any) -> Output:
        if isinstance(msg, Heartbeat) and not self.link.up:
            return []
        return super().take(kind, handle, msg)


class BaseSideSequencer(SequencerCore):
    """The sequencer on the base computer: the arm's messages reach it only over the link
    (its clock ticks on regardless)."""

    def __init__(self, link: Link, config: SequencerConfig | None = None) -> None:
        super().__init__(config)
        self.link = link

    def on_joint_state(self, js: JointState, now_ns: int) -> list[Action]:
        return super().on_joint_state(js, now_ns) if self.link.up else []

    def on_bridge_state(self, bs: BridgeState, now_ns: int) -> list[Action]:
        return super().on_bridge_state(bs, now_ns) if self.link.up else []

    def on_result(self, res: GoalResult, now_ns: int) -> list[Action]:
        return super().on_result(res, now_ns) if self.link.up else []


class Rig(TaskLockStep):
    """Task lock-step with a link that can be cut."""

    def __init__(self, config: SequencerConfig | None = None) -> None:
        super().__init__(SimConfig(start_pose="unfolded"))
        self.link = Link()
        self.controller = ArmSideController(self.link)
        self.seq = BaseSideSequencer(self.link, config)
        for name in self.seq.config.required_services:
            self.seq.on_liveliness(name, True, 0)
        self.start_arm()

    def joint_frames(self, since_ns: int) -> list[tuple[int, bool]]:
        """(send time [ns], all zero) of every 0x374 the bridge sent from ``since_ns``."""
        return [
            (f.t_ns, decode_move(f.id, f.data).is_zero)
            for f in self.ls.bridge_frames
            if f.id == FrameId.JOINT and f.t_ns >= since_ns
        ]


def _echoing(arm: ControlledArm) -> Link:
    """A supervisor that echoes every joint state in a Heartbeat while its link is up."""
    link = Link()
    beats = iter(range(1, 1_000_000))

    def supervisor(msg: Message, t_ns: int) -> list[tuple[str, Message]]:
        assert isinstance(msg, JointState)
        if not link.up:
            return []
        hb = Heartbeat(stamp_ns=t_ns, seq=next(beats), source="test", ref_seq=msg.seq,
                       ref_stamp_ns=msg.stamp_ns)  # fmt: skip
        return [("heartbeat", hb)]

    arm.ls.subscribe("state/joints", supervisor)
    return link


@pytest.mark.parametrize("offset_ms", [5, 25, 45])
def test_cut_link_stops_the_arm_on_the_deadman_and_nothing_resumes(offset_ms: int) -> None:
    rig = Rig()
    assert rig.submit(task_from_args([SQUARE])).accepted
    rig.run_until_event("step_started")
    rig.ls.run_for(2.0)  # mid-path: the arm moves
    moving = rig.joint_frames(rig.ls.t_ns - CYCLE_NS * 3)
    assert moving and not all(zero for _, zero in moving)
    goals = [r for r in rig.requests if isinstance(r, TrajectoryGoal)]
    timeout = goals[-1].heartbeat_timeout
    assert timeout == pytest.approx(SequencerConfig().heartbeat_timeout_s)

    # cut the link at an instant `offset_ms` into a cycle of joint states
    last_js = rig.joint_states()[-1][0]
    rig.ls.run_until(last_js + offset_ms * 1_000_000)
    cut = rig.ls.t_ns
    rig.link.up = False
    truth: list[tuple[int, np.ndarray]] = []
    for _ in range(50):  # 1 s in 20 ms ticks, the simulator's truth at each
        rig.ls.run_for(0.02)
        truth.append((rig.ls.t_ns, np.asarray(rig.ls.sim.truth().q_true)))

    frames = rig.joint_frames(cut)
    first_zero = next(t for t, zero in frames if zero)
    stop_ms = (first_zero - cut) / 1e6
    # the last heartbeat the controller got echoes a state at most one cycle before the
    # cut; the states within the timeout of it move, the next is answered with zeros, sent
    # 20 ms after it (0.15 s: 3 cycles + the reply delay)
    assert stop_ms <= (late_states(timeout, CYCLE_NS) + 1) * 60 + 20, stop_ms
    assert all(zero for t, zero in frames if t >= first_zero), "moved again after the stop"
    # the simulator's truth: the arm's speed decays (drive lag, tau 20 ms) from the cycle
    # the zeros act in: under 0.05 deg/s within 3 cycles of the zeros' send time
    speed = [
        (t1, float(np.max(np.abs(q1 - q0))) / 0.02)
        for (_, q0), (t1, q1) in itertools.pairwise(truth)
    ]
    at_rest = next(
        t for t, v in speed if all(v2 < math.radians(0.05) for t2, v2 in speed if t2 >= t)
    )
    STOPS.append((offset_ms, stop_ms, (at_rest - cut) / 1e6))
    assert at_rest - first_zero <= 3 * CYCLE_NS, (at_rest - first_zero) / 1e6

    aborted = [r for r in rig.results() if r.status == "aborted"]
    assert len(aborted) == 1
    assert aborted[0].reason.startswith("lost the supervisor's heartbeat")
    # the sequencer (its own clock) sees the arm fall silent and fails the task
    assert rig.seq.state == "failed"
    assert "no joint states from the arm" in rig.seq.reason
    assert rig.names()[-1] == "failed"

    # the link returns: nothing resumes by itself ...
    rig.link.up = True
    back = rig.ls.t_ns
    rig.ls.run_for(2.0)
    assert all(zero for _, zero in rig.joint_frames(back))
    assert rig.seq.state == "failed"
    # ... and a new task runs normally
    assert rig.submit(task_from_args([SQUARE])).accepted
    rig.run_while_busy(60.0)
    assert rig.seq.state == "succeeded", rig.seq.reason


def test_deadman_abort_replays_bit_for_bit() -> None:
    """Heartbeats are controller inputs like any message: replaying the recorded inputs
    through a fresh core gives the same commands and the same abort, bit for bit."""
    arm = ControlledArm(SimConfig(start_pose="unfolded"))
    arm.start()
    link = _echoing(arm)
    trajectory = arm.plan(PATHS / "thesis_square.txt")
    goal = TrajectoryGoal(goal_id="sq", trajectory=trajectory, heartbeat_timeout=0.1)
    assert arm.submit(goal).accepted
    arm.ls.run_for(3.0)
    assert arm.results("sq") == []  # heartbeats keep it running
    link.up = False
    result = arm.run_until_result("sq", timeout_s=2.0)
    assert result.status == "aborted"
    assert result.reason.startswith("lost the supervisor's heartbeat"), result.reason
    arm.ls.run_for(1.0)

    outputs = ("cmd/joint_velocity", "controller/feedback", "controller/result")
    recorded = [(s, m.encode()) for _, s, m in arm.ls.messages if s in outputs]
    core = ControllerCore()
    replayed: list[tuple[str, bytes]] = []
    for _, suffix, msg in arm.ls.messages:
        replayed += [
            (s, m.encode()) for s, m in controller_input(core, suffix, msg) if s in outputs
        ]
    assert replayed == recorded


def test_no_timeout_keeps_the_old_behaviour_without_heartbeats() -> None:
    arm = ControlledArm(SimConfig(start_pose="unfolded"))
    js = arm.start()
    trajectory = arm.plan(PATHS / "thesis_square.txt")
    assert TrajectoryGoal(goal_id="a", trajectory=trajectory).heartbeat_timeout == 0.0
    assert arm.submit(TrajectoryGoal(goal_id="a", trajectory=trajectory)).accepted
    arm.ls.run_for(1.0)
    assert arm.results("a") == []
    assert arm.core.last_js is not None and arm.core.last_js.seq > js.seq
    # with a deadman and no supervisor at all, the goal stops after its timeout
    assert arm.submit(TrajectoryGoal(goal_id="b", trajectory=arm.plan(PATHS / "thesis_square.txt"),
                                     heartbeat_timeout=0.2)).accepted  # fmt: skip
    result = arm.run_until_result("b", timeout_s=1.0)
    assert result.status == "aborted" and "heartbeat_timeout 200 ms" in result.reason


def test_sequencer_core_heartbeats_only_while_a_task_runs() -> None:
    rig = SeqRig()
    assert rig.core.on_joint_state(joint_state(UNFOLDED, seq=2), 0) == []  # idle: none
    rig.start(square_task())
    out = rig.core.on_joint_state(joint_state(UNFOLDED, seq=3), 10)
    beats = [a.message for a in out if isinstance(a, Publish) and a.suffix == HEARTBEAT_SUFFIX]
    assert len(beats) == 1 and isinstance(beats[0], Heartbeat)
    assert (beats[0].ref_seq, beats[0].ref_stamp_ns, beats[0].task_id) == (3, 3, "t1")
    goal = rig.goals()[-1]
    assert isinstance(goal, TrajectoryGoal)
    assert goal.heartbeat_timeout == pytest.approx(SequencerConfig().heartbeat_timeout_s)


def test_sequencer_core_fails_the_task_when_the_arm_falls_silent() -> None:
    rig = SeqRig()
    rig.start(square_task())
    rig.core.on_joint_state(joint_state(UNFOLDED, seq=3), 0)
    assert rig.core.on_tick(400_000_000) == []
    actions = rig.core.on_tick(600_000_000)
    assert rig.core.state == "failed"
    assert "no joint states from the arm for 600 ms" in rig.core.reason
    assert any(isinstance(a, Query) and isinstance(a.request, CancelGoal) for a in actions)


def test_sequencer_config_checks_its_deadman_settings() -> None:
    with pytest.raises(ConfigError, match="heartbeat_timeout_s = -1"):
        SequencerConfig(heartbeat_timeout_s=-1.0)
    with pytest.raises(ConfigError, match=r"link_timeout_s = 0\.01"):
        SequencerConfig(link_timeout_s=0.01)


def test_a_gripper_goal_has_the_deadman_too() -> None:
    """A gripper goal with ``heartbeat_timeout`` stops (zeros, aborted) when the supervisor's
    heartbeats stop, judged on the stamps like a trajectory's; without it, it goes on."""
    arm = ControlledArm(SimConfig(start_pose="unfolded"))
    arm.start()
    link = _echoing(arm)
    goal = GripperGoal(goal_id="g", opening=0.08, heartbeat_timeout=0.1)
    assert arm.query(ep.GRIPPER_GOAL, goal).accepted
    arm.ls.run_for(0.3)
    assert arm.results("g") == []  # heartbeats keep it going
    link.up = False
    cut = arm.ls.t_ns
    result = arm.run_until_result("g", timeout_s=1.0)
    assert result.status == "aborted"
    assert result.reason.startswith("lost the supervisor's heartbeat"), result.reason
    grips = [decode_move(f.id, f.data).gripper for f in arm.ls.bridge_frames
             if f.id == FrameId.JOINT and f.t_ns >= cut]  # fmt: skip
    assert grips[:2] != [0, 0] and grips[3:] == [0] * len(grips[3:])  # zeros after 2 cycles
    # no deadman asked: the old behaviour, the goal goes on without heartbeats
    assert arm.query(ep.GRIPPER_GOAL, GripperGoal(goal_id="h", opening=0.085)).accepted
    arm.ls.run_for(0.5)
    assert arm.results("h") == []
