"""Several PC-side nodes on the simulated bus: CAN broadcast over one slcan pty per node.

On a real CAN bus every frame reaches every other node: the bridge and the guardian
(``manus guardian``) both see the arm's frames and each other's, and the arm sees both.
A pseudo-terminal links two parties only, so :class:`NodeHub` holds one
:class:`~services.simulator.slcan.SlcanPtyBus` per node and acts as the arm's one bus:
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

from services.simulator.slcan import SlcanPtyBus


class NodeHub(can.BusABC):
    """The arm's bus with ``count`` PC-side slcan nodes (see the module docstring).

    Args:
        count: number of nodes (>= 1).
        channel: optional symlink path for node 0 (node i > 0: ``<channel>.<i>``).
        bitrate: the bus bitrate [bit/s].

    Attributes:
        nodes: the nodes' pty buses, node 0 first.
        received: frames received from each node.
    """

    def __init__(
        self, count: int, channel: str | None = None, bitrate: int = 250_000, **kwargs: Any
    ) -> None:
        if count < 1:
            raise ValueError(f"a bus needs at least one node, got {count}")
        self.nodes = [
            SlcanPtyBus(f"{channel}.{i}" if channel and i else channel or None, bitrate=bitrate)
            for i in range(count)
        ]
        self.received = [0] * count
        self._ready: deque[tuple[int, can.Message]] = deque()
        super().__init__(channel=self.nodes[0].device, **kwargs)
        self.channel_info = "slcan hub: " + ", ".join(n.device for n in self.nodes)

    @property
    def devices(self) -> list[str]:
        """The pty device of each node, node 0 first."""
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
        select.select([n.fileno() for n in self.nodes], [], [], timeout)

    def shutdown(self) -> None:
        """Close every node (idempotent)."""
        if self._is_shutdown:
            return
        super().shutdown()
        for node in self.nodes:
            node.shutdown()
