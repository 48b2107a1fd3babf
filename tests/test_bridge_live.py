"""The bridge shell live: on python-can ``virtual`` with a LiveSim in this process, and as
``manus bridge`` against ``manus sim`` in separate processes over the slcan pty.

Protocol-level checks only (phases, what was sent, clean shutdown); timing figures are
``manus bench bridge``'s job. Each test runs a few seconds.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TypeVar

import can
import pytest

from manus.node import Node
from manus.protocol import FrameId
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.commands import ArmCommand, ArmCommandReply, EStop
from schemas.state import BridgeState, CanFrame, JointState
from services.can_bridge.shell import BridgeShell
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.live import LiveSim

ROOT = Path(__file__).resolve().parent.parent
FAST = SimConfig(start_pose="unfolded", gripper_ready_ms=60, angles_measured_ms=120)
pytestmark = pytest.mark.slow
M = TypeVar("M")


class Listener:
    """Collects what the bridge publishes."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.lock = threading.Lock()
        self.states: list[BridgeState] = []
        self.joints: list[JointState] = []
        self.tx: list[CanFrame] = []
        keys = node.keys
        node.subscribe(keys(ep.BRIDGE_STATE), BridgeState, self._add(self.states), locked=False)
        node.subscribe(keys(ep.JOINTS), JointState, self._add(self.joints), locked=False)
        node.subscribe(keys(ep.CAN_TX), CanFrame, self._add(self.tx), locked=False)

    def _add(self, into: list[M]) -> Callable[[M, int], None]:
        def add(msg: M, _rx: int) -> None:
            with self.lock:
                into.append(msg)

        return add

    def phase(self) -> str:
        with self.lock:
            return self.states[-1].phase if self.states else ""

    def wait_phase(self, phase: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while self.phase() != phase:
            if time.monotonic() > deadline:
                pytest.fail(f"bridge phase {phase!r} not reached: {self.phase()!r}")
            time.sleep(0.02)

    def tx_since(self, index: int) -> list[CanFrame]:
        with self.lock:
            return list(self.tx[index:])


@pytest.fixture
def virtual_pair() -> Iterator[tuple[can.BusABC, can.BusABC]]:
    channel = f"bridge-{uuid.uuid4().hex}"
    arm = can.Bus(interface="virtual", channel=channel)
    pc = can.Bus(interface="virtual", channel=channel)
    try:
        yield arm, pc
    finally:
        arm.shutdown()
        pc.shutdown()


def test_bridge_shell_on_virtual_with_live_sim(
    virtual_pair: tuple[can.BusABC, can.BusABC], zenoh_settings: ZenohSettings
) -> None:
    arm, pc = virtual_pair
    live = LiveSim(SimCore(FAST), arm)
    with Node("test-listener", zenoh_settings) as node:
        seen = Listener(node)
        shell = BridgeShell(pc, zenoh_settings)
        try:
            shell.start()
            live.start()
            seen.wait_phase("running", timeout=8.0)
            assert "can_bridge" in node.alive_services()
            # No controller: zeros only.
            mark = len(seen.tx_since(0))
            time.sleep(0.4)
            after = seen.tx_since(mark)
            assert after and all(f.id == FrameId.JOINT and f.data == bytes(8) for f in after)
            with seen.lock:
                assert seen.joints and seen.joints[-1].valid
            # E-stop: zeros at the next sync, then 0x370, latched.
            node.publisher(node.keys(ep.ESTOP)).put(
                EStop(stamp_ns=time.time_ns(), seq=0, engaged=True, source="test")
            )
            seen.wait_phase("estopped", timeout=2.0)
            time.sleep(0.3)
            reply = node.query(
                node.keys(ep.BRIDGE_COMMAND), ArmCommand(action="clear"), ArmCommandReply
            )
            assert not reply.ok and reply.phase == "estopped"
            ids = [f.id for f in seen.tx_since(0)]
            assert ids[-1] == FrameId.STOP
            node.publisher(node.keys(ep.ESTOP)).put(
                EStop(stamp_ns=time.time_ns(), seq=1, engaged=False, source="test")
            )
            seen.wait_phase("running", timeout=2.0)
            mark = len(seen.tx_since(0))
        finally:
            shell.stop(timeout=3.0)
            shell.node.close()
            live.stop()
        time.sleep(0.1)  # the last samples reach the listener
        tail = [(f.id, f.data) for f in seen.tx_since(mark)][-2:]
        assert tail == [(FrameId.JOINT, bytes(8)), (FrameId.STOP, b"")]
        assert shell.core.phase == "shutdown" and not shell.running
    with live.lock:
        counters = live.core.counters
        assert counters.replies_latched >= 10 and counters.extra_replies == 0


# -- separate processes over the slcan pty ----------------------------------------------------


def _start(args: list[str], env: dict[str, str]) -> subprocess.Popen[str]:
    cmd = [sys.executable, "-m", "manus_stack.cli", *args]
    return subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )


def _end(proc: subprocess.Popen[str]) -> tuple[int, str]:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        os.kill(proc.pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=5)
    return proc.returncode, err


def _stats(err: str) -> dict[str, object]:
    line = next(x for x in err.splitlines() if x.startswith("stats: "))
    result: dict[str, object] = json.loads(line[7:])
    return result


def test_manus_bridge_process_with_manus_sim_over_slcan(
    tmp_path: Path, router_endpoint: str, zenoh_settings: ZenohSettings
) -> None:
    device_file = tmp_path / "device"
    env = {**os.environ, "MANUS_ZENOH_CONNECT": router_endpoint, "MANUS_PREFIX": "test"}
    sim = _start(["sim", "--device-file", str(device_file), "--no-zenoh", "--seed", "2"], env)
    bridge: subprocess.Popen[str] | None = None
    try:
        with Node("test-listener", zenoh_settings) as node:
            seen = Listener(node)
            bridge = _start(["bridge", "--device-file", str(device_file)], env)
            seen.wait_phase("running", timeout=20.0)
            time.sleep(0.3)
            tx = seen.tx_since(0)
            assert tx[0].id == FrameId.STOP  # the first sync: stop what an earlier run left
            assert [f.id for f in tx[-3:]] == [FrameId.JOINT] * 3
            assert all(f.data == bytes(8) for f in tx[-3:])  # no controller: zeros
            stop = ArmCommand(action="stop")
            reply = node.query(node.keys(ep.BRIDGE_COMMAND), stop, ArmCommandReply)
            assert reply.ok and reply.phase == "stopped"
            time.sleep(0.3)
            assert seen.tx_since(0)[-1].id == FrameId.STOP
            code, err = _end(bridge)
            assert code == 0, err
            stats = _stats(err)
            assert stats["phase"] == "shutdown" and int(str(stats["cycles"])) >= 10
            time.sleep(0.1)
            assert [f.id for f in seen.tx_since(0)[-2:]] == [FrameId.JOINT, FrameId.STOP]
    finally:
        if bridge is not None:
            _end(bridge)
        code, err = _end(sim)
    assert code == 0, err
    sim_stats = _stats(err)
    assert int(str(sim_stats["replies_latched"])) >= 10
