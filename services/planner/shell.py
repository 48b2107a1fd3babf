"""The planner's live shell: a Zenoh queryable around :class:`PlannerCore`.

Answers ``<prefix>/planner/plan`` (PlanRequest -> PlanReply) and ``<prefix>/planner/scene``
(SceneUpdate -> SceneReply: the scene replaced at run time, between two plans) and
follows
``<prefix>/state/joints`` for the default start configuration (valid states only).
Planning runs outside the node lock on a snapshot of the newest joint state, so a long
plan never delays joint-state updates; plans (and scene updates) take turns on their own
lock, because the collision model's Pinocchio data is shared by every check.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time

import zenoh

from manus.node import Node
from manus.session import ZenohSettings
from schemas.collision import SceneReply, SceneUpdate
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
        self._planning = threading.Lock()
        self.node.subscribe(self.node.keys.joints, JointState, self._on_joint_state)
        self.node.queryable(self.node.keys.plan, PlanRequest, self._on_plan, locked=False)
        self.node.queryable(self.node.keys.scene, SceneUpdate, self._on_scene)
        self.node.announce()  # alive once it listens and answers

    def _on_joint_state(self, js: JointState, rx_ns: int) -> None:
        self.core.on_joint_state(js)

    def _on_plan(self, request: PlanRequest) -> PlanReply:
        started = time.perf_counter()
        with self.node.lock:
            latest = self.core.latest
        with self._planning:  # one plan at a time: the collision model's data is shared
            reply = self.core.plan(request, latest)
        elapsed_ms = (time.perf_counter() - started) * 1e3
        with self.node.lock:
            self.plans += 1
            self.refusals += not reply.ok
        if reply.error is not None:
            log.info("refused a plan (%s): %s", reply.error.reason, reply.error.message)
        return dataclasses.replace(reply, compute_ms=elapsed_ms)

    def _on_scene(self, update: SceneUpdate) -> SceneReply:
        with self._planning:  # between plans
            reply = self.core.update_scene(update)
        log.info("scene update %s: %s", "accepted" if reply.accepted else "refused",
                 f"version {reply.version}" if reply.accepted else reply.error)  # fmt: skip
        return reply

    def close(self) -> None:
        """Leave the bus."""
        self.node.close()

    def __enter__(self) -> PlannerShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
