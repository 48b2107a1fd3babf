"""Faults on the arm's frames: the bridge never acts on a half-updated cycle, stops the arm,
counts the fault and resynchronises (every fault kind of services.simulator.faults)."""

from __future__ import annotations

import pytest

from manus.protocol import (
    Frame,
    FrameId,
    MessageClass,
    StatusFrame,
    encode_status,
    sync_frame,
)
from schemas.state import BridgeState, JointState
from services.can_bridge.core import BridgeCore
from services.simulator.config import SimConfig
from services.simulator.faults import FrameFault, Silence
from tests.bridge_scenarios import MS, VelocityController, check_safety, moves, phases, running

ZERO = (0,) * 8
KINDS = ("drop", "duplicate", "delay", "corrupt")
COUNTER = {
    "drop": "dropped_frames",
    "duplicate": "duplicate_frames",
    "delay": "late_frames",  # 30 ms: after the next frame of its cycle, out of order
    "corrupt": "garbled_frames",
}


@pytest.mark.parametrize("frame_id", [FrameId.STATUS, FrameId.POSITION, FrameId.SYNC])
@pytest.mark.parametrize("kind", KINDS)
def test_single_frame_fault_resyncs(kind: str, frame_id: FrameId) -> None:
    def fault(t0_ms: float) -> FrameFault:
        corrupt = "dlc" if kind == "corrupt" else "bits"
        return FrameFault(kind, start_ms=t0_ms + 100, count=1, ids=(frame_id,), corrupt=corrupt)

    ls = running(SimConfig(start_pose="unfolded", seed=1))
    ctl = VelocityController((10.0, 0, 0, 0, 0, 0))
    ls.subscribe("state/joints", ctl)
    ls.run_for(0.5)
    t0 = ls.t_ns
    ls.sim.add_fault(fault(t0 / 1e6))
    ls.run_for(1.2)
    h = ls.bridge.health
    assert getattr(h, COUNTER[kind]) >= 1
    assert h.resyncs == 1
    assert phases(ls, t0 + 1) == ["running", "resync", "running"]
    # The arm got zeros from the first sync after the fault until two clean cycles passed.
    sent = moves(ls, t0)
    zeros = [t for t, incs in sent if incs == ZERO]
    assert len(zeros) >= 2 and all(t >= t0 + 100 * MS for t in zeros)
    assert sent[-1][1] == (0, 2, 0, 0, 0, 0, 0, 0)  # commands reach the arm again
    # No joint state for a cycle whose 0x350 or 0x360 was hit (the sync comes after it).
    stamps = {m.stamp_ns for t, _, m in ls.messages if isinstance(m, JointState) and t > t0}
    cycles = {t for t in range(t0 + 40 * MS, ls.t_ns - 20 * MS, 60 * MS)}
    missing = cycles - stamps
    if frame_id != FrameId.SYNC or kind == "delay":
        assert missing, "a cycle with a bad frame published a joint state"
    check_safety(ls)


def test_silence_is_reported_and_resynced() -> None:
    ls = running()
    ls.subscribe("state/joints", VelocityController((10.0, 0, 0, 0, 0, 0)))
    ls.run_for(0.3)
    t0 = ls.t_ns
    ls.sim.add_fault(Silence(start_ms=t0 / 1e6 + 50, duration_ms=500))
    ls.run_for(0.4)
    assert ls.bridge.phase == "resync"
    assert ls.bridge.detail.startswith("no frames from the arm for ")
    ls.run_for(0.8)
    assert phases(ls, t0) == ["running", "resync", "running"]
    assert ls.bridge.health.dropped_frames >= 20  # ~25 frames in 500 ms
    assert moves(ls)[-1][1][1] == 2
    check_safety(ls)


def test_random_drops_never_reach_the_arm_as_commands() -> None:
    ls = running(SimConfig(start_pose="unfolded", seed=4))
    ls.subscribe("state/joints", VelocityController((0, 5.0, 0, 0, -10.0, 0)))
    ls.sim.add_fault(FrameFault("drop", rate=0.1, start_ms=ls.t_ns / 1e6, duration_ms=3000))
    ls.sim.add_fault(FrameFault("duplicate", rate=0.05, start_ms=ls.t_ns / 1e6))
    ls.run_for(4.0)
    h = ls.bridge.health
    assert h.dropped_frames > 5 and h.duplicate_frames > 2 and h.resyncs > 3
    check_safety(ls)


@pytest.mark.parametrize("seed", range(6))
def test_bit_flips_are_caught_or_within_the_plausible_step(seed: int) -> None:
    ls = running(SimConfig(start_pose="unfolded", seed=seed))
    ls.run_for(0.3)
    t0 = ls.t_ns
    truth = list(ls.sim.encoder_counts())
    ls.sim.add_fault(FrameFault("corrupt", start_ms=t0 / 1e6, count=2, ids=(0x350, 0x360)))
    ls.run_for(0.6)
    step = ls.bridge.config.max_field_step
    for t, _, m in ls.messages:
        if isinstance(m, JointState) and t > t0:
            assert all(abs(a - b) <= step for a, b in zip(m.encoder, truth, strict=True))


def test_bit_flip_beyond_the_step_is_garbled() -> None:
    ls = running(SimConfig(start_pose="unfolded", seed=5))
    t0 = ls.t_ns
    ls.sim.add_fault(FrameFault("corrupt", start_ms=t0 / 1e6 + 100, count=1, ids=(0x360,)))
    ls.run_for(0.6)
    assert ls.bridge.health.garbled_frames == 1
    assert phases(ls, t0 + 1) == ["running", "resync", "running"]


# -- frame level: buffered syncs, unknown ids, shutdown ---------------------------------------


def _status(t_ns: int) -> Frame:
    data = encode_status(StatusFrame(0, MessageClass.NONE, 0, (0, 0, 0)))
    return Frame(FrameId.STATUS, data, False, t_ns)


def test_buffered_syncs_are_never_answered() -> None:
    core = BridgeCore()
    core.start(0)
    # A burst of old cycles read at once when the bus opens (stamped when they arrived).
    now = 500 * MS
    sent = []
    for k in range(5):
        t = 60 * MS * k
        for f in (_status(t + 20 * MS), Frame(FrameId.POSITION, bytes(8), False, t + 40 * MS)):
            sent += core.on_frame(f, now).frames
        sent += core.on_frame(sync_frame(t + 60 * MS), now).frames
    assert sent == []
    assert core.health.buffered_syncs == 5
    # The current sync is answered (one 0x370 before the power-up messages).
    out = core.on_frame(sync_frame(now), now + 1 * MS)
    assert [f.id for f in out.frames] == [FrameId.STOP]
    state = [m for s, m in out.messages if s == "state/bridge"][-1]
    assert isinstance(state, BridgeState) and state.buffered_syncs == 5


def test_second_sync_in_one_window_is_not_answered() -> None:
    core = BridgeCore()
    core.start(0)
    assert core.on_frame(sync_frame(60 * MS), 60 * MS).frames
    assert not core.on_frame(sync_frame(60 * MS + 500_000), 60 * MS + 500_000).frames
    assert core.health.duplicate_frames == 1


def test_unknown_ids_are_counted_without_breaking_the_cycle() -> None:
    ls = running()
    t0 = ls.t_ns
    out = ls.bridge.on_frame(Frame(0x123, b"\x01", False, t0 + 5 * MS), t0 + 5 * MS)
    assert out.frames == [] and ls.bridge.health.garbled_frames == 1
    assert ls.bridge.phase == "running"


def test_shutdown_sends_zeros_then_stop_at_the_next_syncs() -> None:
    ls = running()
    ls.subscribe("state/joints", VelocityController((10.0, 0, 0, 0, 0, 0)))
    ls.run_for(0.3)
    t0 = ls.t_ns
    ls.bridge.begin_shutdown(t0)
    ls.run_for(0.3)
    after = [(f.id, f.data) for f in ls.bridge_frames if f.t_ns > t0]
    assert after == [(FrameId.JOINT, bytes(8)), (FrameId.STOP, b"")]
    assert ls.bridge.finished and ls.bridge.phase == "shutdown"


def test_forced_shutdown_sends_what_is_left_at_once() -> None:
    core = BridgeCore()
    core.start(0)
    out = core.force_shutdown(5 * MS)
    assert [(f.id, f.t_ns) for f in out.frames] == [(FrameId.JOINT, 5 * MS), (FrameId.STOP, 5 * MS)]
    assert core.finished and core.force_shutdown(6 * MS).frames == []
