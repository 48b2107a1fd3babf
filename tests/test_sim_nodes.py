"""The simulated bus with several PC-side nodes: CAN broadcast over one slcan link each
(a loopback TCP connection or a pty)."""

from __future__ import annotations

import time
from collections.abc import Iterator

import can
import pytest

from services.simulator.nodes import LINKS, NodeHub


def _recv(bus: can.BusABC, hub: NodeHub | None = None, timeout: float = 2.0) -> can.Message | None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if hub is not None:
            hub.recv(0.0)  # the hub forwards what it reads
        msg = bus.recv(0.01)
        if msg is not None:
            return msg
    return None


@pytest.fixture(params=LINKS)
def hub(request: pytest.FixtureRequest) -> Iterator[tuple[NodeHub, list[can.BusABC]]]:
    hub = NodeHub(3, request.param)
    clients = [
        can.Bus(interface="slcan", channel=dev, bitrate=250_000, sleep_after_open=0, timeout=0.005)
        for dev in hub.devices
    ]
    try:
        end = time.monotonic() + 2.0
        while not all(n.is_open for n in hub.nodes) and time.monotonic() < end:
            hub.recv(0.01)  # the clients' "O" commands
        assert hub.is_open and all(n.is_open for n in hub.nodes)
        yield hub, clients
    finally:
        for c in clients:
            c.shutdown()
        hub.shutdown()


def test_a_frame_of_the_arm_reaches_every_node(hub: tuple[NodeHub, list[can.BusABC]]) -> None:
    bus, clients = hub
    bus.send(can.Message(arbitration_id=0x37F, is_remote_frame=True, is_extended_id=False))
    for c in clients:
        msg = _recv(c)
        assert msg is not None and msg.arbitration_id == 0x37F and msg.is_remote_frame


def test_a_nodes_frame_reaches_the_arm_and_every_other_node_but_itself(
    hub: tuple[NodeHub, list[can.BusABC]],
) -> None:
    bus, clients = hub
    clients[1].send(can.Message(arbitration_id=0x370, data=b"", is_extended_id=False))
    at_arm = None
    end = time.monotonic() + 2.0
    while at_arm is None and time.monotonic() < end:
        at_arm = bus.recv(0.01)
    assert at_arm is not None and at_arm.arbitration_id == 0x370
    assert bus.received == [0, 1, 0]
    for i in (0, 2):
        msg = _recv(clients[i])
        assert msg is not None and msg.arbitration_id == 0x370
    assert _recv(clients[1], timeout=0.2) is None  # no echo of its own frame


def test_a_bus_needs_a_node() -> None:
    with pytest.raises(ValueError, match="at least one node"):
        NodeHub(0)
