"""The simulator's Zenoh shell: publish the truth once per cycle (optional).

The arm itself has no Zenoh; this only exposes what a real arm never reports, the true
state (``<prefix>/sim/truth``, :class:`schemas.state.SimTruth`), so recordings and tests
can judge accuracy. The simulator runs the same without it.
"""

from __future__ import annotations

import dataclasses
import logging

from manus.errors import ConfigError
from manus.node import Node
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.state import SimTruth

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


def open_node(settings: ZenohSettings) -> Node | None:
    """The simulator's node, or None (logged) when no Zenoh router can be reached; not
    alive yet (:meth:`Node.announce` once its queryable is declared)."""
    try:
        return Node(SERVICE_NAME, settings, liveliness=False)
    except ConfigError as exc:
        log.warning("running without Zenoh (no truth published): %s", exc)
        return None
