"""The simulator on a real clock: LiveSim on python-can buses, the slcan pty, Zenoh truth.

Only generous protocol-order checks here: no speed or jitter assertions (CI is slow).
The sync period is still checked (20-100 ms for the nominal 60): a real-time test, in
the live chain (marked ``slow``; it failed beside a CPU-bound worker at load 7).
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import can
import pytest
from can.interfaces.slcan import slcanBus

from manus.canbus import from_can, open_bus, to_can
from manus.node import Node
from manus.protocol import (
    GEN_ANGLES_MEASURED,
    ZERO_JOINT_MOVE,
    Frame,
    FrameId,
    MessageClass,
    decode_status,
    empty_frame,
    move_frame,
    sync_frame,
)
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.objects import Perception
from schemas.state import SimTruth
from services.simulator.camera_config import CameraConfig
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.live import LiveSim
from services.simulator.scripted import joint_move
from services.simulator.shell import MessagePublisher, TruthPublisher
from services.simulator.slcan import SlcanPtyBus
from services.simulator.slcan_socket import SlcanSocketBus
from tests.conftest import eventually

pytestmark = pytest.mark.slow

FAST = SimConfig(gripper_ready_ms=60, angles_measured_ms=120)


def _drive(bus: can.BusABC, seconds: float, command: Frame) -> list[Frame]:
    """Act as a minimal PC: after "angles measured", answer syncs (zero twice, then command)."""
    frames: list[Frame] = []
    ready, answered = False, 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        msg = bus.recv(timeout=0.1)
        if msg is None:
            continue
        f = from_can(msg, time.monotonic_ns())
        frames.append(f)
        if f.id == FrameId.STATUS and f.dlc == 8:
            st = decode_status(f.data)
            ready |= (st.msg_class, st.msg_code) == (MessageClass.GENERAL, GEN_ANGLES_MEASURED)
        if f.id == FrameId.SYNC and ready:
            bus.send(to_can(move_frame(ZERO_JOINT_MOVE) if answered < 2 else command))
            answered += 1
    return frames


def _check_order_and_motion(frames: list[Frame], field: int) -> None:
    ids = [f.id for f in frames]
    start = ids.index(FrameId.STATUS)
    cyclic = ids[start : start + (len(ids) - start) // 3 * 3]
    assert cyclic == [0x350, 0x360, 0x37F] * (len(cyclic) // 3)
    syncs = [f.t_ns for f in frames if f.id == FrameId.SYNC]
    periods_ms = [(b - a) / 1e6 for a, b in itertools.pairwise(syncs)]
    assert all(20.0 < p < 100.0 for p in periods_ms)  # nominal 60 ms; generous
    positions = [decode_status(f.data).fields[field] for f in frames if f.id == FrameId.STATUS]
    assert positions[-1] - positions[-5] > 5  # the commanded joint moves


@pytest.fixture
def virtual_pair() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    channel = f"sim-{uuid.uuid4().hex}"
    arm = can.Bus(interface="virtual", channel=channel)
    pc = can.Bus(interface="virtual", channel=channel)
    try:
        yield arm, pc
    finally:
        arm.shutdown()
        pc.shutdown()


def test_live_sim_on_the_virtual_bus(virtual_pair: tuple[can.BusABC, can.BusABC]) -> None:
    arm, pc = virtual_pair
    live = LiveSim(SimCore(FAST), arm)
    live.start()
    try:
        frames = _drive(pc, 1.2, joint_move(10))
    finally:
        live.stop()
    assert not live.running
    _check_order_and_motion(frames, 0)
    assert live.core.counters.replies_latched >= 10
    assert live.stats.frames == live.core.counters.frames_sent
    with live.lock:
        assert live.core.truth().q_true[0] > 0.0


@pytest.fixture
def pty_bus(tmp_path: Path) -> Iterator[SlcanPtyBus]:
    bus = SlcanPtyBus(str(tmp_path / "manus-can"))
    try:
        yield bus
    finally:
        bus.shutdown()


def _pump(bus: can.BusABC, into: list[can.Message], stop: threading.Event) -> None:
    while not stop.is_set():
        msg = bus.recv(timeout=0.02)
        if msg is not None:
            into.append(msg)


def test_slcan_pty_talks_to_python_can_slcan(
    pty_bus: SlcanPtyBus, tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    assert (tmp_path / "manus-can").resolve() == Path(pty_bus.device).resolve()
    pty_bus.send(to_can(sync_frame()))  # nobody has the channel open: dropped
    assert pty_bus.dropped_tx == 1
    received: list[can.Message] = []
    stop = threading.Event()
    pump = threading.Thread(target=_pump, args=(pty_bus, received, stop), daemon=True)
    pump.start()
    with caplog.at_level(logging.WARNING, logger="manus.sim.slcan"):
        client = slcanBus(str(tmp_path / "manus-can"), bitrate=500000, sleep_after_open=0)
    try:
        assert client.get_version(timeout=2.0) == (10, 13)
        deadline = time.monotonic() + 2.0
        while not pty_bus.is_open and time.monotonic() < deadline:
            time.sleep(0.01)
        assert pty_bus.is_open
        assert "client set 500000 bit/s" in caplog.text
        out = [sync_frame(), Frame(FrameId.STATUS, bytes(range(8))), empty_frame(FrameId.STOP)]
        for f in out:
            pty_bus.send(to_can(f))
        got = [client.recv(timeout=2.0) for _ in out]
        assert [from_can(m, 0) if m else None for m in got] == out
        back = [move_frame(ZERO_JOINT_MOVE), empty_frame(FrameId.FOLD_IN), sync_frame()]
        for f in back:
            client.send(to_can(f))
        deadline = time.monotonic() + 2.0
        while len(received) < len(back) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert [from_can(m, 0) for m in received] == back
    finally:
        client.shutdown()
        stop.set()
        pump.join(2.0)
    assert not pty_bus.is_open  # python-can sends "C" on shutdown


def test_live_sim_on_the_slcan_pty(pty_bus: SlcanPtyBus) -> None:
    client = can.Bus(interface="slcan", channel=pty_bus.device, bitrate=250000, sleep_after_open=0)
    live = LiveSim(SimCore(FAST), pty_bus)
    try:
        while not pty_bus.is_open:
            pty_bus.recv(timeout=0.05)  # what `manus sim` does before powering up
        live.start()
        frames = _drive(client, 1.2, joint_move(0, 0, 10))
    finally:
        live.stop()
        client.shutdown()
    _check_order_and_motion(frames, 2)


def test_truth_is_published_once_per_cycle(
    virtual_pair: tuple[can.BusABC, can.BusABC], zenoh_settings: ZenohSettings
) -> None:
    arm, _ = virtual_pair
    got: list[SimTruth] = []
    with (
        Node("test-listener", zenoh_settings) as listener,
        Node("simulator", zenoh_settings) as node,
    ):
        listener.subscribe(node.keys(ep.SIM_TRUTH), SimTruth, lambda m, _rx: got.append(m))
        live = LiveSim(SimCore(FAST), arm, on_snapshot=TruthPublisher(node))
        live.start()
        try:
            time.sleep(0.5)
            assert "simulator" in listener.alive_services()
        finally:
            live.stop()
    assert len(got) >= 4
    assert [m.seq for m in got] == list(range(got[0].seq, got[0].seq + len(got)))
    stamps = [m.stamp_ns for m in got]
    assert all((b - a) == 60_000_000 for a, b in itertools.pairwise(stamps))


def test_the_camera_publishes_on_the_stacks_clock(
    virtual_pair: tuple[can.BusABC, can.BusABC], zenoh_settings: ZenohSettings
) -> None:
    arm, _ = virtual_pair
    got: list[Perception] = []
    config = FAST.with_overrides(objects="default", camera=CameraConfig(period_ms=50.0))
    with (
        Node("test-listener", zenoh_settings) as listener,
        Node("simulator", zenoh_settings) as node,
    ):
        listener.subscribe(node.keys(ep.PERCEPTION), Perception, lambda m, _rx: got.append(m))
        live = LiveSim(SimCore(config), arm)
        live.on_message = MessagePublisher(node, lambda: live.wall_t0_ns)
        before = time.time_ns()
        live.start()
        try:
            eventually(lambda: len(got) >= 3, what="three camera frames")
        finally:
            live.stop()
        after = time.time_ns()
    assert all(before <= m.stamp_ns <= after for m in got)  # the wall clock, not sim time
    assert [m.seq for m in got] == sorted(m.seq for m in got)
    assert {o.id for m in got for o in m.objects} == {"cup", "bottle", "phone"}


def test_live_sim_on_the_slcan_socket() -> None:
    server = SlcanSocketBus()
    client = open_bus("slcan", server.device, 250000, sleep_after_open=0)
    live = LiveSim(SimCore(FAST), server)
    try:
        while not server.is_open:
            server.recv(timeout=0.05)  # what `manus sim` does before powering up
        live.start()
        frames = _drive(client, 1.2, joint_move(0, 10))
    finally:
        live.stop()
        client.shutdown()
        server.shutdown()
    _check_order_and_motion(frames, 1)
