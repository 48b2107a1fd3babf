"""The CAN guardian: its decision core, and a bridge stopped or killed mid-path in lock-step
(judged on the simulator's true motor speeds)."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from manus.protocol import ZERO_JOINT_MOVE, Frame, FrameId, empty_frame, move_frame, sync_frame
from manus_stack.guardian_lockstep import bridge_fault_trial
from manus_stack.lockstep import LockStep
from schemas.state import BridgeState
from services.guardian.core import Action, GuardianCore

ROOT = Path(__file__).resolve().parent.parent
MS = 1_000_000


def test_an_answered_sync_is_left_alone() -> None:
    core = GuardianCore()
    for k in range(5):
        t = k * 60 * MS
        assert core.on_frame(sync_frame(t)) is None
        assert core.next_deadline_ns() == t + 12 * MS
        assert core.on_frame(move_frame(ZERO_JOINT_MOVE, t + 11 * MS)) is None
        assert core.next_deadline_ns() is None
        assert core.due(t + 19 * MS) == (None, None)
    assert (core.counts.syncs, core.counts.answered, core.counts.stops_sent) == (5, 5, 0)


def test_an_unanswered_sync_gets_a_stop_at_the_deadline_and_every_one_after() -> None:
    core = GuardianCore(deadline_ms=12.0)
    core.on_frame(sync_frame(0))
    assert core.due(11 * MS) == (None, None)
    frame, action = core.due(12 * MS)
    assert frame == empty_frame(FrameId.STOP, 12 * MS)
    assert action is not None and (action.kind, action.sync_ns) == ("stop_sent", 0)
    assert core.engaged
    assert core.due(13 * MS) == (None, None)  # one stop per sync
    core.on_frame(sync_frame(60 * MS))
    assert core.due(72 * MS)[0] is not None
    # the bridge answers again: nothing sent, and it is reported once
    core.on_frame(sync_frame(120 * MS))
    back = core.on_frame(move_frame(ZERO_JOINT_MOVE, 121 * MS))
    assert back is not None and back.kind == "bridge_back"
    assert core.due(140 * MS) == (None, None)
    assert (core.counts.stops_sent, core.engaged) == (2, False)


def test_a_deadline_noticed_after_the_window_sends_nothing() -> None:
    core = GuardianCore()
    core.on_frame(sync_frame(0))
    frame, action = core.due(20 * MS)  # the 0x370 would arrive after the window
    assert frame is None and action is not None and action.kind == "late"
    assert core.counts.late == 1


def test_replies_outside_a_window_and_arm_frames_do_not_count_as_answers() -> None:
    core = GuardianCore()
    core.on_frame(move_frame(ZERO_JOINT_MOVE, 5 * MS))  # no sync yet
    core.on_frame(sync_frame(60 * MS))
    core.on_frame(Frame(FrameId.STATUS, bytes(8), False, 61 * MS))  # the arm's, not a reply
    assert core.due(72 * MS)[0] is not None
    assert core.counts.other_frames == 1


@pytest.mark.parametrize("deadline", [0.0, 20.0, -1.0])
def test_deadline_must_be_inside_the_window(deadline: float) -> None:
    with pytest.raises(ValueError, match=r"deadline_ms must be in \(0, 20\) ms"):
        GuardianCore(deadline)


def test_the_guardian_imports_no_zenoh_nor_other_services() -> None:
    code = (
        "import sys, services.guardian.main; "
        "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('zenoh', 'schemas') "
        "or m.startswith(('services.can_bridge', 'services.controller', 'manus.node', "
        "'manus.session'))); print(bad)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("fault", ["stop", "kill"])
@pytest.mark.parametrize("offset_ms", [0.5, 20.0, 45.0, 59.5])
def test_bridge_fault_mid_path_stops_the_arm_at_the_next_sync(fault: str, offset_ms: float) -> None:
    trial = bridge_fault_trial(fault, offset_ms)
    assert trial.speed_before_deg_s > 1.0  # it was moving
    assert trial.syncs_to_stop == 1  # the first sync after the fault carries the stop
    # at rest (< 0.05 deg/s) once the drives' 20 ms lag has let the speed decay
    assert trial.rest_ms is not None and trial.rest_ms <= 260.0
    assert not trial.resumed_moving  # SIGCONT, or a new bridge: nothing moves by itself
    assert trial.new_goal == "succeeded"  # and the new bridge takes over


def test_without_the_guardian_a_killed_bridge_leaves_the_arm_moving() -> None:
    trial = bridge_fault_trial("kill", 30.0, guardian=False)
    assert trial.rest_ms is None and trial.stops_sent == 0


class EchoNode:
    """Another PC-side node that sends a zero 0x374 5 ms after every sync."""

    def __init__(self) -> None:
        self.due: int | None = None

    def receive(self, frame: Frame) -> None:
        if frame.id == FrameId.SYNC:
            self.due = frame.t_ns + 5 * MS

    def next_event_ns(self) -> int | None:
        return self.due

    def advance(self, t_ns: int) -> list[Frame]:
        self.due = None
        return [move_frame(ZERO_JOINT_MOVE, t_ns)]


def test_the_bridge_counts_other_nodes_frames_and_never_takes_them_for_the_arms() -> None:
    ls = LockStep()
    ls.run_until_phase("running", timeout_s=3.0)
    ls.run_for(0.3)
    garbled, cycles = ls.bridge.health.garbled_frames, ls.bridge.health.cycles
    ls.attach_node(EchoNode())
    ls.run_for(1.2)  # 20 syncs
    ls.run_until(ls.arm_frames[-1].t_ns + 40 * MS)  # every echo in, no sync since
    n = len(ls.node_frames)
    h = ls.bridge.health
    assert n >= 20 and h.other_node_frames == n and h.preempted_replies == 0
    assert h.garbled_frames == garbled and h.resyncs == 0
    assert h.cycles >= cycles + 20
    assert ls.bridge.phase == "running"
    assert ls.sim.counters.extra_replies == n  # the arm took the bridge's, the first
    ls.bridge.on_tick(ls.t_ns)
    reports = [m for m in ls.published("state/bridge") if isinstance(m, BridgeState)]
    assert reports[-1].other_node_frames >= n - 1  # published with the next state


@pytest.mark.slow
def test_the_loop_stops_an_unanswered_arm_on_a_virtual_bus() -> None:
    """The live loop in process: the simulator on python-can's virtual bus, the guardian
    on another bus of the same channel, no bridge: every sync gets the guardian's 0x370,
    inside the window."""
    import threading
    import uuid

    import can

    from services.guardian.loop import LoopStats, run_loop
    from services.simulator.config import SimConfig
    from services.simulator.core import SimCore
    from services.simulator.live import LiveSim

    channel = f"guardian-{uuid.uuid4().hex}"
    arm_bus = can.Bus(interface="virtual", channel=channel)
    pc_bus = can.Bus(interface="virtual", channel=channel)
    sim = LiveSim(SimCore(SimConfig(start_pose="unfolded")), arm_bus)
    core, stop, stats = GuardianCore(), threading.Event(), LoopStats()
    actions: list[Action] = []
    loop = threading.Thread(target=run_loop, args=(pc_bus, core, stop, actions.append),
                            kwargs={"stats": stats}, daemon=True)  # fmt: skip
    try:
        loop.start()
        sim.start()
        time.sleep(1.0)
    finally:
        sim.stop()
        stop.set()
        loop.join(2.0)
        arm_bus.shutdown()
        pc_bus.shutdown()
    counts = sim.core.counters
    assert core.counts.syncs >= 10 and core.counts.answered == 0
    assert core.counts.stops_sent + core.counts.late == core.counts.syncs
    assert counts.replies_latched >= core.counts.stops_sent - 1  # each one in its window
    assert counts.outside_window <= core.counts.late + 1
    assert len(stats.reaction_ms) == core.counts.stops_sent
    assert [a.kind for a in actions].count("stop_sent") == core.counts.stops_sent


def test_a_reply_of_another_node_before_the_bridges_own_is_counted_preempted() -> None:
    """The bridge answers a sync late (15 ms: it sat in a buffer); the guardian's 0x370
    reached the bus at 12 ms, so the arm latched that one: counted, and what the arm
    executes (``applied``) is the stop, not the bridge's reply."""
    ls = LockStep()
    ls.run_until_phase("running", timeout_s=3.0)
    ls.pause_bridge()  # the test hands the bridge its frames itself from here
    n = len(ls.arm_frames)
    while not any(f.remote for f in ls.arm_frames[n:]):
        ls.run_for(0.005)
    sync = next(f for f in ls.arm_frames[n:] if f.remote)
    bridge = ls.bridge
    out = bridge.on_frame(sync, sync.t_ns + 15 * MS)
    assert out.frames, "the bridge answered"
    bridge.on_frame(empty_frame(FrameId.STOP, sync.t_ns + 12 * MS), sync.t_ns + 16 * MS)
    assert (bridge.health.other_node_frames, bridge.health.preempted_replies) == (1, 1)
    assert bridge._applied[1] == "stop"
    assert "preempted" in bridge.detail
