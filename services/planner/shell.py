"""The planner's live shell: a Zenoh queryable around :class:`PlannerCore`.

Its wiring map (:data:`services.planner.wiring.WIRING`): answers ``planner/plan``
(PlanRequest -> PlanReply) and ``planner/scene`` (SceneUpdate -> SceneReply: the scene
replaced at run time) and follows the joint states for the default start configuration
(valid states only). Planning runs outside the node lock on the newest joint state (one
attribute, replaced whole by each update), so a long plan never delays joint-state
updates; concurrent plans take turns only for their collision check (the collision
model's Pinocchio data is shared: :attr:`PlannerCore.checking`). ``compute_ms`` is the
time the answer took.
"""

from __future__ import annotations

import dataclasses
import logging

import zenoh

from manus.node import Node
from manus.session import ZenohSettings
from schemas.base import Message
from schemas.endpoints import Endpoint
from schemas.planning import PlanReply
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.wiring import WIRING

log = logging.getLogger("manus.planner")


class PlannerShell:
    """The planner on the bus (liveliness token ``<prefix>/alive/planner``).

    Args:
        settings: how to reach the bus (its prefix roots the keys).
        config: planner settings.
        session: an open session to share (not closed by :meth:`close`).
    """

    def __init__(
        self,
        settings: ZenohSettings,
        config: PlannerConfig | None = None,
        *,
        session: zenoh.Session | None = None,
    ) -> None:
        self.core = PlannerCore(config)
        self.node = Node("planner", settings, session=session, liveliness=False)
        self.plans = 0
        self.refusals = 0
        WIRING.attach(self.node, self.core, on_reply=self._answered)
        self.node.announce()  # alive once it listens and answers

    def _answered(
        self, endpoint: Endpoint, request: Message, reply: Message, took: float
    ) -> Message:
        if not isinstance(reply, PlanReply):
            return reply
        with self.node.lock:
            self.plans += 1
            self.refusals += not reply.ok
        if reply.error is not None:
            log.info("refused a plan (%s): %s", reply.error.reason, reply.error.message)
        return dataclasses.replace(reply, compute_ms=took * 1e3)

    def close(self) -> None:
        """Leave the bus."""
        self.node.close()

    def __enter__(self) -> PlannerShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
