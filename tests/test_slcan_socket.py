"""The simulator's slcan adapter on 127.0.0.1: python-can's slcan client over ``socket://``,
one client at a time, clients that come and go."""

from __future__ import annotations

import logging
import os
import socket
import time
from collections.abc import Callable, Iterator

import can
import pytest

from manus.can_sharing import claim_channel, same_channel, second_reader_refusal
from manus.canbus import from_can, open_bus, settles_at_once, to_can
from manus.errors import ConfigError
from manus.protocol import Frame, FrameId, empty_frame, sync_frame
from services.simulator.main import SIM_INTERFACE, open_sim_bus
from services.simulator.nodes import slcan_node
from services.simulator.slcan_socket import SlcanSocketBus


def _client(bus: SlcanSocketBus) -> can.BusABC:
    return open_bus("slcan", bus.device, 250_000, sleep_after_open=0, timeout=0.005)


def _until(cond: Callable[[], bool], bus: SlcanSocketBus, timeout: float = 3.0) -> None:
    """Poll the server (it accepts and reads only in ``recv``) until ``cond`` holds."""
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "condition not reached"
        bus.recv(0.01)


def _take(server: SlcanSocketBus, count: int, timeout: float = 3.0) -> list[can.Message]:
    """The next ``count`` frames the server receives (fewer if the time runs out)."""
    got: list[can.Message] = []
    end = time.monotonic() + timeout
    while len(got) < count and time.monotonic() < end:
        msg = server.recv(0.01)
        if msg is not None:
            got.append(msg)
    return got


def _recv_at(client: can.BusABC, timeout: float = 3.0) -> can.Message | None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg = client.recv(0.01)
        if msg is not None:
            return msg
    return None


@pytest.fixture
def server() -> Iterator[SlcanSocketBus]:
    bus = SlcanSocketBus()
    try:
        yield bus
    finally:
        bus.shutdown()


def test_the_channel_is_a_socket_url_on_loopback(server: SlcanSocketBus) -> None:
    assert server.device == f"socket://127.0.0.1:{server.port}" and server.port > 0
    assert settles_at_once(server.device)
    assert not claim_channel("slcan", server.device, "test").path  # no device file to lock


def test_frames_both_ways_with_python_can_slcan(
    server: SlcanSocketBus, caplog: pytest.LogCaptureFixture
) -> None:
    server.send(to_can(sync_frame()))  # nobody has the channel open: dropped
    assert server.dropped_tx == 1
    with caplog.at_level(logging.WARNING, logger="manus.sim.slcan"):
        client = open_bus("slcan", server.device, 500_000, sleep_after_open=0, timeout=0.005)
        try:
            _until(lambda: server.is_open, server)
            assert "client set 500000 bit/s" in caplog.text
            out = [sync_frame(), Frame(FrameId.STATUS, bytes(range(8))), empty_frame(FrameId.STOP)]
            for f in out:
                server.send(to_can(f))
            got = [_recv_at(client) for _ in out]
            assert [from_can(m, 0) if m else None for m in got] == out
            back = [empty_frame(FrameId.FOLD_IN), sync_frame()]
            for f in back:
                client.send(to_can(f))
            assert [from_can(m, 0) for m in _take(server, len(back))] == back
        finally:
            client.shutdown()
    _until(lambda: not server.connected, server)  # "C", then the connection closes
    assert not server.is_open and server.bad_lines == 0


def test_the_client_sends_without_nagle(server: SlcanSocketBus) -> None:
    client = _client(server)
    try:
        with socket.socket(fileno=os.dup(client.fileno())) as sock:
            assert sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) != 0
    finally:
        client.shutdown()


def test_a_second_client_is_refused_and_a_later_one_served(server: SlcanSocketBus) -> None:
    first = _client(server)
    try:
        _until(lambda: server.is_open, server)
        second = socket.create_connection(("127.0.0.1", server.port), timeout=2.0)
        try:
            _until(lambda: server.refused == 1, server)
            assert second.recv(16) == b""  # closed at once: it reads nothing of the bus
        finally:
            second.close()
        server.send(to_can(sync_frame()))
        msg = _recv_at(first)
        assert msg is not None and msg.arbitration_id == FrameId.SYNC
    finally:
        first.shutdown()
    _until(lambda: not server.connected, server)
    before = server.dropped_tx
    server.send(to_can(sync_frame()))  # between clients: dropped and counted
    assert server.dropped_tx == before + 1
    again = _client(server)  # a bridge restarted
    try:
        _until(lambda: server.is_open, server)
        server.send(to_can(sync_frame()))
        msg = _recv_at(again)
        assert msg is not None and msg.arbitration_id == FrameId.SYNC
    finally:
        again.shutdown()


def test_a_client_that_vanishes_closes_the_channel(server: SlcanSocketBus) -> None:
    raw = socket.create_connection(("127.0.0.1", server.port), timeout=2.0)
    raw.sendall(b"O\rt37F0\rt3")  # opened, one frame, half a line, then gone (no "C")
    assert [m.arbitration_id for m in _take(server, 1)] == [0x37F]
    raw.close()
    _until(lambda: not server.connected, server)
    assert not server.is_open
    raw = socket.create_connection(("127.0.0.1", server.port), timeout=2.0)
    try:
        raw.sendall(b"O\rt3700\r")  # the half line before is not joined to this one
        assert [m.arbitration_id for m in _take(server, 1)] == [0x370]
        assert server.bad_lines == 0
    finally:
        raw.close()


def test_the_nodes_ports_follow_a_given_port() -> None:
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    base = probe.getsockname()[1]
    probe.close()
    nodes = [slcan_node("tcp", str(base), i, 250_000) for i in range(2)]
    try:
        assert [n.device for n in nodes] == [f"socket://127.0.0.1:{base + i}" for i in range(2)]
    finally:
        for n in nodes:
            n.shutdown()
    with pytest.raises(ValueError, match="unknown slcan link"):
        slcan_node("udp", None, 0, 250_000)


def test_one_socket_node_is_one_channel_for_the_guardian() -> None:
    bridge = "socket://127.0.0.1:40001"
    assert same_channel(bridge, "socket://localhost:40001")
    assert not same_channel(bridge, "socket://127.0.0.1:40002")
    assert second_reader_refusal("slcan", bridge, "slcan", bridge)
    assert not second_reader_refusal("slcan", "socket://127.0.0.1:40002", "slcan", bridge)


def test_manus_sim_names_a_port_it_cannot_have(server: SlcanSocketBus) -> None:
    with pytest.raises(ConfigError, match="no slcan adapter on tcp 'x'"):
        open_sim_bus(SIM_INTERFACE, "x", 250_000)
    with pytest.raises(ConfigError, match=f"no slcan adapter on tcp '{server.port}'"):
        open_sim_bus(SIM_INTERFACE, str(server.port), 250_000, nodes=2)  # the port is taken
