"""The controller's live shell: :class:`ControllerCore` on Zenoh.

Its subscriptions, queryables and publishers are those of its wiring map
(:data:`services.controller.wiring.WIRING`): the bridge's joint states, status and phase
(goals run only while the bridge is ``running``), the supervisor's deadman heartbeat;
goals, gripper goals, cancels and speed scaling, each answered with a GoalAck; commands,
feedback and results out; the jog stream and its level, the jog's state out. A ``jog``
payload that does not decode is handed to the core as a bad jog (it stops the arm), and a
service's ``alive/<service>`` token vanishing too (:meth:`ControllerCore.on_token_gone`:
the goals whose heartbeats it sent stop at once), both through the wiring map.
Everything runs under the node lock, in the Zenoh thread that received it (an ordered
node), so the core sees one message at a time, in arrival order: a goal sent after the
bridge state it depends on is judged after it.
"""

from __future__ import annotations

import logging
from collections import Counter

import zenoh

from manus.node import Node
from manus.session import ZenohSettings
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore, Output
from services.controller.wiring import WIRING

log = logging.getLogger("manus.controller")


class ControllerShell:
    """The controller on the bus (liveliness token ``<prefix>/alive/controller``).

    Args:
        settings: how to reach the bus (its prefix roots the keys).
        config: controller settings.
        session: an open session to share (not closed by :meth:`close`).

    Attributes:
        sent: messages published per key suffix.
    """

    def __init__(
        self,
        settings: ZenohSettings,
        config: ControllerConfig | None = None,
        *,
        session: zenoh.Session | None = None,
    ) -> None:
        self.core = ControllerCore(config)
        # ordered: a goal must not overtake the bridge state that came before it (the
        # sequencer sends its next goal once it saw the bridge `running` after a fold)
        self.node = Node("controller", settings, session=session, liveliness=False, ordered=True)
        self.sent: Counter[str] = Counter()
        self._publish = WIRING.publishers(self.node)  # before any callback can use it
        WIRING.attach(self.node, self.core, self._deliver, publish=self._publish)
        self.node.announce()  # alive once it listens and answers

    def _deliver(self, out: Output) -> None:
        self._publish(out)
        for suffix, _ in out:
            self.sent[suffix] += 1

    def close(self) -> None:
        """Leave the bus."""
        self.node.close()

    def __enter__(self) -> ControllerShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
