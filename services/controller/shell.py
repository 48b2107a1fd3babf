"""The controller's live shell: :class:`ControllerCore` on Zenoh.

Subscribes ``<prefix>/state/joints``, ``<prefix>/state/status`` and
``<prefix>/state/bridge`` (goals run only while the bridge is ``running``) and
``<prefix>/heartbeat`` (the supervisor's deadman, for goals with ``heartbeat_timeout``) and
``<prefix>/jog`` (live control: a payload that does not decode stops the jog); answers the
queryables ``controller/goal`` (TrajectoryGoal), ``controller/gripper`` (GripperGoal),
``controller/cancel`` (CancelGoal), ``controller/speed_scale`` (SpeedScale) and
``controller/jog_level`` (JogLevel), each with a GoalAck; publishes what the core returns
on ``cmd/joint_velocity``, ``controller/feedback``, ``controller/result`` and
``controller/jog_state``. Everything runs under the node lock,
so the core sees one message at a time, in arrival order.
"""

from __future__ import annotations

import logging
from collections import Counter

import zenoh

from manus.node import Node, Publisher
from manus.session import ZenohSettings
from schemas.base import Message
from schemas.control import CancelGoal, GripperGoal, Heartbeat, SpeedScale, TrajectoryGoal
from schemas.jog import JogCommand, JogLevel
from schemas.state import ArmStatus, BridgeState, JointState
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore, Output
from services.controller.jog import BAD_JOG_PAYLOAD

log = logging.getLogger("manus.controller")

PUBLISHED = (
    "cmd/joint_velocity",
    "controller/feedback",
    "controller/result",
    "controller/jog_state",
)
"""Key suffixes the controller publishes on."""


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
        self.node = Node("controller", settings, session=session, liveliness=False)
        self.sent: Counter[str] = Counter()
        keys = self.node.keys
        self._pubs: dict[str, Publisher] = {s: self.node.publisher(keys(s)) for s in PUBLISHED}
        self.node.subscribe(keys.joints, JointState, self._on_joint_state)
        self.node.subscribe(keys.status, ArmStatus, self._on_status)
        self.node.subscribe(keys.bridge_state, BridgeState, self._on_bridge)
        self.node.subscribe(keys.heartbeat, Heartbeat, self._on_heartbeat)
        self.node.subscribe(keys.jog, JogCommand, self._on_jog)
        self.node.on_bad_payload = self._on_bad_payload
        self.node.queryable(keys.goal, TrajectoryGoal, self._on_goal)
        self.node.queryable(keys.gripper_goal, GripperGoal, self.core.submit_gripper)
        self.node.queryable(keys.cancel, CancelGoal, self.core.cancel)
        self.node.queryable(keys.speed_scale, SpeedScale, self.core.set_speed_scale)
        self.node.queryable(keys.jog_level, JogLevel, self.core.set_jog_level)
        self.node.announce()  # alive once it listens and answers

    def _publish(self, out: Output) -> None:
        for suffix, msg in out:
            self._pubs[suffix].put(msg)
            self.sent[suffix] += 1

    def _on_joint_state(self, js: JointState, rx_ns: int) -> None:
        self._publish(self.core.on_joint_state(js))

    def _on_status(self, st: ArmStatus, rx_ns: int) -> None:
        self._publish(self.core.on_status(st))

    def _on_bridge(self, bs: BridgeState, rx_ns: int) -> None:
        self._publish(self.core.on_bridge_state(bs))

    def _on_heartbeat(self, hb: Heartbeat, rx_ns: int) -> None:
        self._publish(self.core.on_heartbeat(hb))

    def _on_jog(self, cmd: JogCommand, rx_ns: int) -> None:
        self._publish(self.core.on_jog(cmd))

    def _on_bad_payload(self, key: str) -> None:
        if key == self.node.keys.jog:
            with self.node.lock:
                self._publish(self.core.on_bad_jog(BAD_JOG_PAYLOAD))

    def _on_goal(self, goal: TrajectoryGoal) -> Message:
        ack = self.core.submit(goal)
        if not ack.accepted:
            log.info("refused goal %s: %s", goal.goal_id, ack.reason)
        return ack

    def close(self) -> None:
        """Leave the bus."""
        self.node.close()

    def __enter__(self) -> ControllerShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
