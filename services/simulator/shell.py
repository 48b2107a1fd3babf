"""The simulator's Zenoh shell: publish the truth once per cycle, the camera and the moving
target's tracker (optional).

The arm itself has no Zenoh; this exposes what a real arm never reports, the true state
(``<prefix>/sim/truth``, :class:`schemas.state.SimTruth`), so recordings and tests can
judge accuracy, what the simulated camera sees (``<prefix>/perception/objects``) and what
the simulated tracker sees (``<prefix>/target/pose``), stamped on the stack's clock, as a
perception node and a face tracker would publish them. The simulator runs the same
without it.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable

from manus.errors import ConfigError
from manus.node import Node
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.base import Message
from schemas.objects import Perception
from schemas.state import SimTruth
from schemas.target import TargetPose

log = logging.getLogger("manus.sim")

SERVICE_NAME = "simulator"
"""Liveliness name (``<prefix>/alive/simulator``)."""


class TruthPublisher:
    """Publishes each cycle's truth with this stream's own sequence number.

    Args:
        node: the simulator's node.
    """

    def __init__(self, node: Node) -> None:
        self.node = node
        self._pub = node.publisher(node.keys(ep.SIM_TRUTH))
        self._seq = 0

    def __call__(self, truth: SimTruth) -> None:
        """Publish ``truth`` (its ``seq`` replaced by this stream's counter)."""
        self._pub.put(dataclasses.replace(truth, seq=self._seq))
        self._seq += 1


class MessagePublisher:
    """Publishes the core's bus messages (the camera's and the tracker's frames), their
    simulated stamps
    moved onto the stack's clock (``wall_t0_ns``: the stack's clock at simulated time 0,
    :attr:`~services.simulator.live.LiveSim.wall_t0_ns`, read as each one goes out).

    Args:
        node: the simulator's node.
        wall_t0_ns: returns the stack's clock at simulated time 0 [ns].
    """

    def __init__(self, node: Node, wall_t0_ns: Callable[[], int]) -> None:
        self.wall_t0_ns = wall_t0_ns
        self._pubs = {e.suffix: node.publisher(node.keys(e)) for e in (ep.PERCEPTION, ep.TARGET)}

    def __call__(self, suffix: str, msg: Message) -> None:
        """Publish ``msg`` on ``suffix``."""
        if isinstance(msg, Perception | TargetPose):
            msg = dataclasses.replace(msg, stamp_ns=self.wall_t0_ns() + msg.stamp_ns)
        self._pubs[suffix].put(msg)


def open_node(settings: ZenohSettings) -> Node | None:
    """The simulator's node, or None (logged) when no Zenoh router can be reached; not
    alive yet (:meth:`Node.announce` once its queryable is declared)."""
    try:
        return Node(SERVICE_NAME, settings, liveliness=False)
    except ConfigError as exc:
        log.warning("running without Zenoh (no truth published): %s", exc)
        return None
