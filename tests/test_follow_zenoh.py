"""Following on the bus: the simulator publishes its tracker's frames on the stack's clock,
the live controller shell takes them (each recorded where it took it) and answers
``controller/follow``; ``manus track`` builds its goal from its options and says why a
goal is refused."""

from __future__ import annotations

import subprocess
import sys
import time

import can
import pytest

from manus.node import Node
from manus.session import ZenohSettings
from manus_stack.cli import build_parser
from manus_stack.commands.track import goal_of
from schemas import endpoints as ep
from schemas.control import GoalAck, Refusal
from schemas.follow import FollowGoal
from schemas.target import TargetPose, TargetTaken
from services.controller.follow_source import FollowSource
from services.controller.shell import ControllerShell
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.live import LiveSim
from services.simulator.shell import MessagePublisher
from services.simulator.target_config import TargetConfig
from tests.conftest import eventually


def test_the_simulator_publishes_its_tracker_on_the_stack_clock(
    zenoh_settings: ZenohSettings,
) -> None:
    core = SimCore(SimConfig(target=TargetConfig(enabled=True, rate_hz=20.0)))
    got: list[tuple[TargetPose, int]] = []
    bus = can.Bus(interface="virtual", channel="follow-test", receive_own_messages=False)
    with (
        Node("sim-test", zenoh_settings, liveliness=False) as node,
        Node("listener", zenoh_settings, liveliness=False) as listener,
    ):
        listener.subscribe(
            listener.keys(ep.TARGET), TargetPose, lambda m, rx: got.append((m, rx)), locked=False
        )
        live: LiveSim | None = None

        def wall_t0() -> int:
            return live.wall_t0_ns if live is not None else 0

        live = LiveSim(core, bus, on_message=MessagePublisher(node, wall_t0))
        live.start()
        try:
            eventually(lambda: len(got) >= 5, 10.0, "five frames")
        finally:
            live.stop()
            bus.shutdown()
    for msg, rx in got:
        assert msg.source == "mouth" and msg.body == "head"
        assert 0 < rx - msg.stamp_ns < 2_000_000_000  # a capture on the stack's clock, past


def test_the_controller_takes_frames_and_answers_follow_goals(
    zenoh_settings: ZenohSettings,
) -> None:
    frame = TargetPose(
        stamp_ns=time.time_ns(), seq=0, source="mouth", xyz=[0.08, 0.0, 1.19], ypr=[0.0] * 3
    )
    with ControllerShell(zenoh_settings) as controller, Node("t", zenoh_settings) as node:
        node.publisher(node.keys(ep.TARGET)).put(frame)
        follow = controller.core.source(FollowSource)
        eventually(lambda: "mouth" in follow.tracks, 10.0, "the frame taken")
        assert controller.sent[ep.TARGET_TAKEN] == 1
        ack = node.query(node.keys(ep.FOLLOW), FollowGoal(goal_id="g", source="mouth"), GoalAck)
        assert not ack.accepted and ack.refusal == Refusal.NOT_READY
        assert "no valid joint state" in ack.reason
        ack = node.query(node.keys(ep.FOLLOW), FollowGoal(goal_id="g", stop=True), GoalAck)
        assert not ack.accepted and ack.refusal == Refusal.UNKNOWN_GOAL
    assert isinstance(TargetTaken(after_seq=-1, target=frame), TargetTaken)


def test_manus_track_builds_its_goal_from_its_options() -> None:
    args = build_parser("track").parse_args(
        ["track", "mouth", "--standoff-mm", "80", "--offset-mm", "0", "0", "60", "--close",
         "--close-clearance-mm", "25", "--max-speed-mm-s", "50", "--goal-id", "g1"]
    )  # fmt: skip
    goal = goal_of(args)
    assert goal.goal_id == "g1" and goal.source == "mouth"
    assert goal.standoff == pytest.approx(0.08) and goal.offset == pytest.approx([0, 0, 0.06])
    assert goal.close and goal.close_clearance == pytest.approx(0.025)
    assert goal.max_speed == pytest.approx(0.05)


@pytest.mark.slow
def test_manus_track_says_why_a_goal_is_refused(
    zenoh_settings: ZenohSettings, router_endpoint: str
) -> None:
    with ControllerShell(zenoh_settings):
        done = subprocess.run(
            [sys.executable, "-m", "manus_stack.cli", "track", "mouth", "--connect",
             router_endpoint, "--prefix", zenoh_settings.prefix],
            capture_output=True, text=True, timeout=60, check=False,
        )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert "refused (not_ready): no valid joint state" in done.stderr
