"""Every key expression of the stack, defined once, rooted at a configurable prefix.

One arm per prefix (default ``manus``). :class:`Keys` builds the concrete key
expressions; :data:`CHANNELS` says which message type travels on each, which the
recorder uses to give every MCAP channel its JSON Schema and the docs use to list them.

| key (after the prefix) | kind       | type                          | publisher  |
|------------------------|------------|-------------------------------|------------|
| state/joints           | pub        | JointState                    | can_bridge |
| state/status           | pub        | ArmStatus                     | can_bridge |
| state/bridge           | pub        | BridgeState                   | can_bridge |
| can/rx, can/tx         | pub        | CanFrame                      | can_bridge |
| cmd/joint_velocity     | pub        | JointVelocityCommand          | controller |
| estop                  | pub        | EStop                         | anyone     |
| heartbeat              | pub        | Heartbeat (deadman)           | sequencer  |
| bridge/command         | queryable  | ArmCommand -> ArmCommandReply | can_bridge |
| planner/plan           | queryable  | PlanRequest -> PlanReply      | planner    |
| controller/goal        | queryable  | TrajectoryGoal -> GoalAck     | controller |
| controller/gripper     | queryable  | GripperGoal -> GoalAck        | controller |
| controller/cancel      | queryable  | CancelGoal -> GoalAck         | controller |
| controller/speed_scale | queryable  | SpeedScale -> GoalAck         | controller |
| controller/feedback    | pub        | ControllerFeedback            | controller |
| controller/result      | pub        | GoalResult                    | controller |
| sequencer/...          | (see schemas.sequencing)                   | sequencer  |
| sim/truth              | pub        | SimTruth                      | simulator  |
| alive/<service>        | liveliness | (no payload)                  | each one   |
| where/<service>/<host>/<pid> | liveliness | (no payload): where it runs | each one |
| trace/<q>/request      | pub        | request type of queryable <q> | its server |
| trace/<q>/reply        | pub        | reply type of queryable <q>   | its server |
| liveliness             | recording  | LivelinessChange              | recorder   |
| recorder/trigger       | pub        | FlightTrigger                 | anyone     |
| replay/control         | queryable  | PlaybackControl -> PlaybackStatus | replay |

Queries are invisible to subscribers, so :meth:`manus.node.Node.queryable` mirrors each
decoded request and each reply of queryable ``<q>`` (e.g. ``planner/plan``) on
``trace/<q>/request`` and ``trace/<q>/reply`` (on by default). Both samples carry the
same attachment, the query's receive time [ns] as 8 bytes little-endian, so a reply
pairs with its request. :func:`channel_type` maps these keys to the ``<q>#request`` and
``<q>#reply`` entries of :func:`channel_types`.

``liveliness`` is not a bus key but a recording channel: the recorder writes every change
of the tokens under the prefix there (``schemas.liveliness``); nobody publishes on it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from manus.session import DEFAULT_PREFIX
from schemas.base import Message
from schemas.liveliness import LIVELINESS, LivelinessChange

SERVICES = ("simulator", "can_bridge", "planner", "controller", "sequencer", "recorder")
"""Names used for liveliness tokens (``<prefix>/alive/<name>``)."""


@dataclass(frozen=True)
class Keys:
    """The key expressions of one arm.

    Attributes:
        prefix: root of every key (one arm per prefix).
    """

    prefix: str = DEFAULT_PREFIX

    def __call__(self, suffix: str) -> str:
        """``<prefix>/<suffix>``."""
        return f"{self.prefix}/{suffix}"

    @property
    def all(self) -> str:
        """Every key of this arm (for recorders)."""
        return f"{self.prefix}/**"

    @property
    def joints(self) -> str:
        return self("state/joints")

    @property
    def status(self) -> str:
        return self("state/status")

    @property
    def bridge_state(self) -> str:
        return self("state/bridge")

    @property
    def can_rx(self) -> str:
        return self("can/rx")

    @property
    def can_tx(self) -> str:
        return self("can/tx")

    @property
    def joint_velocity(self) -> str:
        return self("cmd/joint_velocity")

    @property
    def estop(self) -> str:
        return self("estop")

    @property
    def heartbeat(self) -> str:
        """The supervisor's deadman heartbeat (``schemas.control.Heartbeat``)."""
        return self("heartbeat")

    @property
    def bridge_command(self) -> str:
        return self("bridge/command")

    @property
    def plan(self) -> str:
        return self("planner/plan")

    @property
    def goal(self) -> str:
        return self("controller/goal")

    @property
    def gripper_goal(self) -> str:
        return self("controller/gripper")

    @property
    def cancel(self) -> str:
        return self("controller/cancel")

    @property
    def speed_scale(self) -> str:
        return self("controller/speed_scale")

    @property
    def feedback(self) -> str:
        return self("controller/feedback")

    @property
    def result(self) -> str:
        return self("controller/result")

    @property
    def sim_truth(self) -> str:
        return self("sim/truth")

    def alive(self, service: str) -> str:
        """Liveliness token of one service."""
        return self(f"alive/{service}")

    @property
    def alive_all(self) -> str:
        return self("alive/**")

    def where(self, service: str, host: str, pid: int) -> str:
        """Liveliness token saying on which computer (host name) and process a service
        runs; characters a key cannot hold are replaced by ``_``."""
        safe = re.sub(r"[^A-Za-z0-9_.\-]", "_", host) or "unknown"
        return self(f"where/{service}/{safe}/{pid}")

    @property
    def where_all(self) -> str:
        return self("where/**")

    @property
    def liveliness(self) -> str:
        """The recording channel of liveliness changes (``schemas.liveliness``; not a bus
        key: nobody publishes on it)."""
        return self(LIVELINESS)

    def trace(self, suffix: str, part: str) -> str:
        """Mirror of queryable ``suffix`` (e.g. ``planner/plan``); ``part`` is ``request``
        or ``reply``: ``<prefix>/trace/<suffix>/<part>``."""
        if part not in ("request", "reply"):
            raise ValueError(f"trace part {part!r} is not 'request' or 'reply'")
        return self(f"trace/{suffix}/{part}")

    def suffix(self, key: str) -> str:
        """The part of ``key`` after the prefix (``key`` itself if it is not under it)."""
        head = self.prefix + "/"
        return key[len(head) :] if key.startswith(head) else key


def channel_types() -> dict[str, type[Message]]:
    """Key suffix -> message type of every published (non-query) channel, and of the
    recorder's ``liveliness`` channel.

    Queryables are listed with their request type under ``<suffix>#request`` and their
    reply type under ``<suffix>#reply`` so that recorders can store both; on the bus they
    travel as ``trace/<suffix>/request|reply`` (:func:`channel_type` maps the keys).
    """
    from schemas import commands, control, flight, planning, playback, sequencing, state

    table: dict[str, type[Message]] = {
        "state/joints": state.JointState,
        "state/status": state.ArmStatus,
        "state/bridge": state.BridgeState,
        "can/rx": state.CanFrame,
        "can/tx": state.CanFrame,
        "sim/truth": state.SimTruth,
        "cmd/joint_velocity": commands.JointVelocityCommand,
        "estop": commands.EStop,
        "heartbeat": control.Heartbeat,
        "bridge/command#request": commands.ArmCommand,
        "bridge/command#reply": commands.ArmCommandReply,
        "planner/plan#request": planning.PlanRequest,
        "planner/plan#reply": planning.PlanReply,
        "controller/goal#request": control.TrajectoryGoal,
        "controller/goal#reply": control.GoalAck,
        "controller/gripper#request": control.GripperGoal,
        "controller/gripper#reply": control.GoalAck,
        "controller/cancel#request": control.CancelGoal,
        "controller/cancel#reply": control.GoalAck,
        "controller/speed_scale#request": control.SpeedScale,
        "controller/speed_scale#reply": control.GoalAck,
        "controller/feedback": control.ControllerFeedback,
        "controller/result": control.GoalResult,
        LIVELINESS: LivelinessChange,
        flight.TRIGGER: flight.FlightTrigger,
        f"{playback.CONTROL}#request": playback.PlaybackControl,
        f"{playback.CONTROL}#reply": playback.PlaybackStatus,
    }
    table.update(sequencing.CHANNELS)
    return table


TRACE_ROOT = "trace/"
"""Key suffixes under this root mirror queries (see the module docstring)."""


def channel_name(suffix: str) -> str:
    """The :func:`channel_types` name of a key suffix: ``trace/<q>/request`` ->
    ``<q>#request`` (likewise ``reply``); any other suffix is its own name."""
    if suffix.startswith(TRACE_ROOT):
        head, _, part = suffix[len(TRACE_ROOT) :].rpartition("/")
        if head and part in ("request", "reply"):
            return f"{head}#{part}"
    return suffix


def channel_type(suffix: str) -> type[Message] | None:
    """Message type carried on key ``<prefix>/<suffix>`` (trace keys included); None when
    the key is not in the table."""
    if not _TABLE:  # built on first use: channel_types() imports every schema module
        _TABLE.update(channel_types())
    return _TABLE.get(channel_name(suffix))


_TABLE: dict[str, type[Message]] = {}
