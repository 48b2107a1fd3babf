"""Several PC-side nodes on the simulated bus: CAN broadcast over one slcan link per node.

On a real CAN bus every frame reaches every other node: the bridge and the guardian
(``manus guardian``) both see the arm's frames and each other's, and the arm sees both.
An slcan link (a TCP connection, a pseudo-terminal) joins two parties only, so
:class:`NodeHub` holds one :class:`~services.simulator.slcan.SlcanDevice` per node (a
:class:`~services.simulator.slcan_socket.SlcanSocketBus` or a
:class:`~services.simulator.slcan.SlcanPtyBus`, :func:`slcan_node`) and acts as the arm's
one bus:
a frame the arm sends goes to every node; a frame a node sends reaches the arm (through
:meth:`NodeHub.recv`) and is passed on to every other node at once. Which of two replies
in one window counts is the arm's business, as on a real bus: the first one received
(:class:`services.simulator.core.SimCore` counts the others ``extra_replies``).

python-can's ``virtual`` interface already has these semantics (every bus on a channel
receives what the others send), so in-process peers need no hub.
"""

from __future__ import annotations

import select
from collections import deque
from typing import Any

import can

from services.simulator.slcan import SlcanDevice, SlcanPtyBus
from services.simulator.slcan_socket import SlcanSocketBus

LINKS = ("tcp", "pty")
"""How a PC-side node reaches the simulator's slcan adapter: a TCP connection on
127.0.0.1 (the default: docs/simulator.md, Links) or a pseudo-terminal."""


def slcan_node(link: str, channel: str | None, index: int, bitrate: int) -> SlcanDevice:
    """Node ``index``'s slcan adapter on ``link``.

    Args:
        link: ``tcp`` or ``pty`` (:data:`LINKS`).
        channel: ``tcp``: node 0's port (node i: port + i; empty: ports the system
            chooses); ``pty``: a symlink path for node 0 (node i: ``<channel>.<i>``;
            empty: no link).
        index: the node's index (0: the bridge's).
        bitrate: the bus bitrate [bit/s].

    Raises:
        ValueError: an unknown link or a port that is no number.
    """
    if link == "tcp":
        port = int(channel) if channel else 0
        return SlcanSocketBus(port + index if port else 0, bitrate=bitrate)
    if link == "pty":
        return SlcanPtyBus(f"{channel}.{index}" if channel and index else channel or None, bitrate)
    raise ValueError(f"unknown slcan link {link!r}: one of {', '.join(LINKS)}")


class NodeHub(can.BusABC):
    """The arm's bus with ``count`` PC-side slcan nodes (see the module docstring).

    Args:
        count: number of nodes (>= 1).
        link: ``tcp`` or ``pty`` (:func:`slcan_node`).
        channel: node 0's port (tcp) or symlink path (pty); see :func:`slcan_node`.
        bitrate: the bus bitrate [bit/s].

    Attributes:
        nodes: the nodes' slcan adapters, node 0 first.
        received: frames received from each node.
    """

    def __init__(
        self,
        count: int,
        link: str = "tcp",
        channel: str | None = None,
        bitrate: int = 250_000,
        **kwargs: Any,
    ) -> None:
        if count < 1:
            raise ValueError(f"a bus needs at least one node, got {count}")
        self.nodes: list[SlcanDevice] = []
        try:
            for i in range(count):
                self.nodes.append(slcan_node(link, channel, i, bitrate))
        except (OSError, ValueError):
            for node in self.nodes:
                node.shutdown()
            raise
        self.received = [0] * count
        self._ready: deque[tuple[int, can.Message]] = deque()
        super().__init__(channel=self.nodes[0].device, **kwargs)
        self.channel_info = "slcan hub: " + ", ".join(n.device for n in self.nodes)

    @property
    def devices(self) -> list[str]:
        """The channel each node's client opens (a pty path, a ``socket://`` URL), node 0
        first."""
        return [n.device for n in self.nodes]

    @property
    def is_open(self) -> bool:
        """Node 0's client (the bridge) has opened the channel."""
        return self.nodes[0].is_open

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """A frame from the arm: to every node."""
        for node in self.nodes:
            node.send(msg, timeout)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if not self._ready:
            self._collect(0.0)
        if not self._ready:
            self._wait(timeout)
            self._collect(0.0)
        if not self._ready:
            return None, False
        index, msg = self._ready.popleft()
        self.received[index] += 1
        for i, node in enumerate(self.nodes):
            if i != index:
                node.send(msg)
        return msg, False

    def _collect(self, timeout: float) -> None:
        for i, node in enumerate(self.nodes):
            msg = node.recv(timeout)
            while msg is not None:
                self._ready.append((i, msg))
                msg = node.recv(0.0)

    def _wait(self, timeout: float | None) -> None:
        select.select([fd for n in self.nodes for fd in n.wait_fds()], [], [], timeout)

    def shutdown(self) -> None:
        """Close every node (idempotent)."""
        if self._is_shutdown:
            return
        super().shutdown()
        for node in self.nodes:
            node.shutdown()
