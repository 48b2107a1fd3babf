"""The planner's live shell: a Zenoh queryable around :class:`PlannerCore`.

Answers ``<prefix>/planner/plan`` (PlanRequest -> PlanReply) and follows
``<prefix>/state/joints`` for the default start configuration (valid states only).
Planning runs outside the node lock on a snapshot of the newest joint state, so a long
plan never delays joint-state updates and concurrent queries do not wait for each
other (the core does not mutate anything while planning).
"""

from __future__ import annotations

import dataclasses
import logging
import time

import zenoh

from manus.node import Node
from manus.session import ZenohSettings
from schemas.planning import PlanReply, PlanRequest
from schemas.state import JointState
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore

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
        self.node.subscribe(self.node.keys.joints, JointState, self._on_joint_state)
        self.node.queryable(self.node.keys.plan, PlanRequest, self._on_plan, locked=False)
        self.node.announce()  # alive once it listens and answers

    def _on_joint_state(self, js: JointState, rx_ns: int) -> None:
        self.core.on_joint_state(js)

    def _on_plan(self, request: PlanRequest) -> PlanReply:
        started = time.perf_counter()
        with self.node.lock:
            latest = self.core.latest
        reply = self.core.plan(request, latest)
        elapsed_ms = (time.perf_counter() - started) * 1e3
        with self.node.lock:
            self.plans += 1
            self.refusals += not reply.ok
        if reply.error is not None:
            log.info("refused a plan (%s): %s", reply.error.reason, reply.error.message)
        return dataclasses.replace(reply, compute_ms=elapsed_ms)

    def close(self) -> None:
        """Leave the bus."""
        self.node.close()

    def __enter__(self) -> PlannerShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
