"""The table of endpoints: every key of the stack, declared once.

An :class:`Endpoint` is a key suffix (under the prefix, default ``manus``) with what it
carries and who owns it. It *is* its suffix (a ``str`` subclass), so it is used wherever a
suffix is: ``Keys(prefix)(JOINTS)`` is ``manus/state/joints``, a core returns
``(FEEDBACK, message)``, a recording's channel is named by it. Everything else that lists
keys is derived from :data:`TABLE`: :class:`schemas.keys.Keys` and its channel types (the
recorder's JSON Schemas), the schema export (``manus schemas``,
``schemas/supervisor.schema.json``), the replay's per-service outputs and queryables, the
access-control policy check, the services' wiring maps and the key table of
docs/architecture.md (:func:`markdown_table`).

Kinds (:class:`Kind`):

- ``publication``: a stream of one message type, published by its owner (``estop``: by
  anyone; the bridge latches it).
- ``queryable``: request -> reply, answered by its owner. Queries are invisible to
  subscribers, so every answer is mirrored on ``trace/<suffix>/request`` and
  ``trace/<suffix>/reply`` (:meth:`Endpoint.trace`; ``manus.node.Node.queryable``).
- ``liveliness``: a token root: ``alive/<service>`` (the service runs),
  ``where/<service>/<host>/<pid>`` (where each of its processes runs) and
  ``disabled/<service>/<why>`` (it is off on purpose, and why); no payload.
- ``recording``: a channel of recordings only, never published on the bus
  (``liveliness``: the recorder's log of token changes).

Audience (:class:`Audience`): ``supervisor`` endpoints are the public API (documented in
``schemas/supervisor.schema.json``); ``internal`` ones are between the stack's services.

Adding an endpoint is one :class:`Endpoint` here (and, for its owner's core, one line of
the service's wiring map, ``services/<name>/wiring.py``). A key suffix is spelled as a
string literal only here.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from enum import StrEnum
from typing import Any, Generic, TypeVar

from manus.errors import SchemaError
from schemas import (
    collision,
    commands,
    control,
    flight,
    follow,
    guardian,
    health,
    jog,
    liveliness,
    objects,
    planning,
    playback,
    sequencing,
    simfault,
    state,
    target,
)
from schemas.base import Message

M = TypeVar("M", bound=Message)
R = TypeVar("R", bound=Message)


class Kind(StrEnum):
    """How an endpoint travels (see the module docstring)."""

    PUBLICATION = "publication"
    QUERYABLE = "queryable"
    LIVELINESS = "liveliness"
    RECORDING = "recording"


class Audience(StrEnum):
    """Who uses an endpoint."""

    INTERNAL = "internal"
    """between the stack's own services"""
    SUPERVISOR = "supervisor"
    """the public API: supervisors, user interfaces, other systems"""


class Service(StrEnum):
    """The stack's services, each one process (``manus <command>``) and liveliness name."""

    SIMULATOR = "simulator"
    CAN_BRIDGE = "can_bridge"
    PLANNER = "planner"
    CONTROLLER = "controller"
    SEQUENCER = "sequencer"
    RECORDER = "recorder"
    GUARDIAN = "guardian"


ANYONE = "anyone"
"""Owner of an endpoint every identity may publish on (``estop``)."""
EACH_SERVICE = "each service"
"""Owner of the liveliness roots: each service holds its own tokens under them."""

TRACE_ROOT = "trace"
"""Root of the query mirrors: ``trace/<queryable>/request|reply``."""
TRACE_PARTS = ("request", "reply")


def trace_suffix(queryable: str, part: str) -> str:
    """``trace/<queryable>/<part>``: the suffix of a query mirror (``part``: request or
    reply).

    Raises:
        SchemaError: ``part`` is neither request nor reply.
    """
    if part not in TRACE_PARTS:
        raise SchemaError(f"trace part {part!r} is not one of {list(TRACE_PARTS)}")
    return f"{TRACE_ROOT}/{queryable}/{part}"


class Endpoint(str):
    """One key suffix and what travels on it (a ``str``: the suffix itself).

    Args:
        suffix: the key after the prefix, e.g. ``state/joints``.
        kind: how it travels.
        owner: the service that publishes it or answers it (:data:`ANYONE`,
            :data:`EACH_SERVICE` for the shared ones).
        msg_type: the message type (publications, recording channels), or the request
            type (queryables); None for liveliness roots.
        reply_type: the reply type of a queryable.
        audience: internal or supervisor.
        doc: one line: what it is for.
        params: for a liveliness root, what follows it in a token's key
            (``<service>/<host>/<pid>``).
        clients: for a queryable, the identities besides its owner that may query it
            (the deployed access control, ``manus_stack.policy``); None: every identity.
    """

    kind: Kind
    owner: str
    msg_type: type[Message] | None
    reply_type: type[Message] | None
    audience: Audience
    doc: str
    params: str
    clients: tuple[str, ...] | None

    def __new__(
        cls,
        suffix: str,
        kind: Kind,
        owner: str,
        msg_type: type[Message] | None = None,
        reply_type: type[Message] | None = None,
        *,
        audience: Audience = Audience.INTERNAL,
        doc: str = "",
        params: str = "",
        clients: tuple[str, ...] | None = None,
    ) -> Any:
        if not suffix or suffix.startswith("/") or suffix.endswith("/") or "*" in suffix:
            raise SchemaError(f"endpoint {suffix!r}: a suffix is non-empty, without * or edge /")
        if (kind is Kind.QUERYABLE) != (reply_type is not None):
            raise SchemaError(f"endpoint {suffix!r}: a reply type iff it is a queryable")
        if (kind is Kind.LIVELINESS) != (msg_type is None):
            raise SchemaError(f"endpoint {suffix!r}: a message type unless it is liveliness")
        self = str.__new__(cls, suffix)
        self.kind = kind
        self.owner = owner
        self.msg_type = msg_type
        self.reply_type = reply_type
        self.audience = audience
        self.doc = doc
        self.params = params
        self.clients = clients
        return self

    @property
    def suffix(self) -> str:
        """The key suffix as a plain ``str``."""
        return str.__str__(self)

    @property
    def pattern(self) -> str:
        """The key as documented: the suffix, and the parameters of a token root."""
        return f"{self.suffix}/{self.params}" if self.params else self.suffix

    def trace(self, part: str) -> str:
        """Suffix of this queryable's mirror: ``trace/<suffix>/<part>`` (request, reply).

        Raises:
            SchemaError: not a queryable, or ``part`` is neither request nor reply.
        """
        if self.kind is not Kind.QUERYABLE:
            raise SchemaError(f"{self.suffix}: only a queryable has trace mirrors")
        return trace_suffix(self.suffix, part)

    def __repr__(self) -> str:
        return f"Endpoint({self.suffix!r}, {self.kind.value}, owner {self.owner})"

    def __str__(self) -> str:
        return self.suffix


class Topic(Endpoint, Generic[M]):
    """A publication (or recording channel) carrying messages of type ``M``."""


class Queryable(Endpoint, Generic[M, R]):
    """A queryable: request ``M`` -> reply ``R``."""


def _pub(
    suffix: str, owner: str, msg: type[M], doc: str, audience: Audience = Audience.INTERNAL
) -> Topic[M]:
    return Topic(suffix, Kind.PUBLICATION, owner, msg, audience=audience, doc=doc)  # type: ignore[no-any-return]


def _query(
    suffix: str,
    owner: str,
    request: type[M],
    reply: type[R],
    doc: str,
    audience: Audience = Audience.INTERNAL,
    clients: tuple[str, ...] | None = None,
) -> Queryable[M, R]:
    return Queryable(  # type: ignore[no-any-return]
        suffix,
        Kind.QUERYABLE,
        owner,
        request,
        reply,
        audience=audience,
        doc=doc,
        clients=clients,
    )


SUPERVISOR = "supervisor"
"""The identity of a supervisor (user interfaces, other systems) in the deployment."""

_BRIDGE, _CTRL, _SEQ = Service.CAN_BRIDGE, Service.CONTROLLER, Service.SEQUENCER
_SUP = Audience.SUPERVISOR

# -- the arm, through the bridge ------------------------------------------------------------
JOINTS = _pub("state/joints", _BRIDGE, state.JointState, "joint positions, one per 60 ms cycle")
STATUS = _pub("state/status", _BRIDGE, state.ArmStatus, "the arm's status and message")
BRIDGE_STATE = _pub("state/bridge", _BRIDGE, state.BridgeState, "bridge phase and health")
CAN_RX = _pub("can/rx", _BRIDGE, state.CanFrame, "every frame received from the arm")
CAN_TX = _pub("can/tx", _BRIDGE, state.CanFrame, "every frame sent to the arm")
BRIDGE_TOKEN_GONE = _pub(
    "bridge/token_gone",
    _BRIDGE,
    liveliness.TokenGone,
    "each alive/<service> token vanishing as the bridge took it (a fold whose heartbeats "
    "that service sent stops at once; exact replays)",
)
BRIDGE_COMMAND = _query(
    "bridge/command",
    _BRIDGE,
    commands.ArmCommand,
    commands.ArmCommandReply,
    "stop, fold in/out, clear",
)
ESTOP = Topic(
    "estop",
    Kind.PUBLICATION,
    ANYONE,
    commands.EStop,
    audience=_SUP,
    doc="emergency stop: the bridge latches it; the running task fails",
)
SIM_TRUTH = _pub(
    "sim/truth", Service.SIMULATOR, state.SimTruth, "the simulator's true state, once per cycle"
)
SIM_FAULT = _query(
    "sim/fault",
    Service.SIMULATOR,
    simfault.SimFault,
    simfault.SimFaultReply,
    "switch a fault on in the running simulator (soaks, tests; no real arm has it)",
)

# -- planner and controller -------------------------------------------------------------------
PLAN = _query(
    "planner/plan",
    Service.PLANNER,
    planning.PlanRequest,
    planning.PlanReply,
    "via points -> joint trajectory",
)
SCENE = _query(
    "planner/scene",
    Service.PLANNER,
    collision.SceneUpdate,
    collision.SceneReply,
    "replace the scene every plan is checked against (validated whole, versioned)",
    _SUP,
    clients=(SUPERVISOR,),
)
SCENE_STATE = _pub(
    "planner/scene_state",
    Service.PLANNER,
    collision.SceneState,
    "the scene every plan is checked against: when an update replaces it, and every second",
    _SUP,
)
JOINT_VELOCITY = _pub(
    "cmd/joint_velocity", _CTRL, commands.JointVelocityCommand, "the command for the next sync"
)
GOAL = _query(
    "controller/goal", _CTRL, control.TrajectoryGoal, control.GoalAck, "follow a trajectory"
)
GRIPPER_GOAL = _query(
    "controller/gripper", _CTRL, control.GripperGoal, control.GoalAck, "drive the gripper"
)
CANCEL = _query("controller/cancel", _CTRL, control.CancelGoal, control.GoalAck, "cancel goals")
SPEED_SCALE = _query(
    "controller/speed_scale", _CTRL, control.SpeedScale, control.GoalAck, "time scaling"
)
FEEDBACK = _pub(
    "controller/feedback", _CTRL, control.ControllerFeedback, "reference vs actual, per cycle"
)
RESULT = _pub("controller/result", _CTRL, control.GoalResult, "the one result of each goal")

# -- live control (schemas/jog.py) -----------------------------------------------------------
JOG = _pub(
    "jog",
    SUPERVISOR,
    jog.JogCommand,
    "live control at 10-50 Hz: twist, joint or gripper speeds; the controller's deadman "
    "(jog_timeout, 150 ms) stops the arm when it stops coming; a running task pauses",
    _SUP,
)
JOG_LEVEL = _query(
    "controller/jog_level",
    _CTRL,
    jog.JogLevel,
    control.GoalAck,
    "set the jog speed level (1..5)",
    _SUP,
)
JOG_TAKEN = _pub(
    "controller/jog_taken",
    _CTRL,
    jog.JogTaken,
    "each jog command as the controller took it: after which joint state (exact replays)",
)
TOKEN_GONE = _pub(
    "controller/token_gone",
    _CTRL,
    liveliness.TokenGone,
    "each alive/<service> token vanishing as the controller took it: after which joint "
    "state (goals whose heartbeats that service sent stop at once; exact replays)",
)
JOG_STATE = _pub(
    "controller/jog_state",
    _CTRL,
    jog.JogState,
    "the jog as the controller runs it: level, slow-down and stop reasons, refusals, pose",
    _SUP,
)

# -- the sequencer: the supervisor's API -----------------------------------------------------
HEARTBEAT = _pub(
    "heartbeat", _SEQ, control.Heartbeat, "deadman: echo of each joint state while a task runs"
)
SUBMIT = _query(
    "sequencer/submit",
    _SEQ,
    sequencing.Task,
    sequencing.SubmitReply,
    "validate a whole task and start it; reply: id or every error. Held while the bridge "
    "is still starting (at most the sequencer's bridge_wait_s, 30 s by default); refused "
    "at once when it is stopped (stopped, estopped, arm_error: phase and detail)",
    _SUP,
    clients=(SUPERVISOR,),
)
TASK_CONTROL = _query(
    "sequencer/control",
    _SEQ,
    sequencing.TaskControl,
    sequencing.TaskStatus,
    "cancel, pause, resume (or status of) the task",
    _SUP,
    clients=(SUPERVISOR,),
)
TASK_STATUS = _query(
    "sequencer/status",
    _SEQ,
    sequencing.TaskControl,
    sequencing.TaskStatus,
    "where the current task stands (action: status)",
    _SUP,
)
HISTORY = _query(
    "sequencer/history",
    _SEQ,
    sequencing.HistoryRequest,
    sequencing.TaskHistory,
    "the most recent tasks and how each ended, newest first",
    _SUP,
)
EVENTS = _pub(
    "sequencer/events",
    _SEQ,
    sequencing.TaskEvent,
    "accepted, step_started/progress/finished/failed, paused, resumed, cancelled, "
    "succeeded, failed",
    _SUP,
)

# -- the CAN guardian ---------------------------------------------------------------------------
GUARDIAN_REPORT = _pub(
    "guardian/report",
    Service.GUARDIAN,
    guardian.GuardianReport,
    "what the CAN guardian did (a 0x370 for an unanswered sync, the bridge back), counts",
)

# -- presence and recordings -----------------------------------------------------------------
ALIVE = Endpoint(
    "alive",
    Kind.LIVELINESS,
    EACH_SERVICE,
    audience=_SUP,
    doc="one token per running service",
    params="<service>",
)
WHERE = Endpoint(
    "where",
    Kind.LIVELINESS,
    EACH_SERVICE,
    audience=_SUP,
    doc="on which computer (host name) and process each service runs",
    params="<service>/<host>/<pid>",
)
DISABLED = Endpoint(
    "disabled",
    Kind.LIVELINESS,
    EACH_SERVICE,
    audience=_SUP,
    doc="a service deliberately not running in this deployment, and why (a word: "
    "disabled/guardian/single_reader_channel)",
    params="<service>/<why>",
)
HEALTH = Endpoint(
    "health",
    Kind.QUERYABLE,
    EACH_SERVICE,
    health.HealthRequest,
    health.NodeHealth,
    doc="each service's node: the bad input it counted (payloads that did not decode, per "
    "key; handler errors); any request payload",
    params="<service>",
)
LIVELINESS = Topic(
    liveliness.LIVELINESS,
    Kind.RECORDING,
    Service.RECORDER,
    liveliness.LivelinessChange,
    doc="recordings only: every liveliness token change the recorder saw",
)

FLIGHT_TRIGGER = Topic(
    "recorder/trigger",
    Kind.PUBLICATION,
    ANYONE,
    flight.FlightTrigger,
    audience=_SUP,
    doc="ask the flight recorder (manus record --ring) to write what it holds now",
)
PLAYBACK_CONTROL = _query(
    "replay/control",
    Service.RECORDER,
    playback.PlaybackControl,
    playback.PlaybackStatus,
    "pause, resume, step, seek, rate or status of a running manus replay",
    _SUP,
)

# -- objects: perception and the world model (docs/objects.md) -------------------------------
PERCEPTION = _pub(
    "perception/objects",
    Service.SIMULATOR,
    objects.Perception,
    "one camera frame's objects (added or moved) and the ones known gone; the simulated "
    "camera's, until a perception node of its own takes this key (and its ownership)",
)
OBJECTS = _pub(
    "planner/objects",
    Service.PLANNER,
    objects.WorldUpdate,
    "the world model's objects as versioned diffs, and the whole set every second",
    _SUP,
)
OBJECT_ENDPOINTS = (PERCEPTION, OBJECTS)
"""The objects' endpoints (a block of their own in :data:`TABLE`)."""
# -- following a moving target (docs/follow.md) -----------------------------------------------
TARGET = _pub(
    "target/pose",
    Service.SIMULATOR,
    target.TargetPose,
    "a tracker's target at 5-30 Hz (the user's mouth; the pose of the head it moves with): "
    "the simulated tracker's, until a tracker node of its own takes this key (and its "
    "ownership)",
    _SUP,
)
FOLLOW = _query(
    "controller/follow",
    _CTRL,
    follow.FollowGoal,
    control.GoalAck,
    "follow a tracker's target to a standoff and hold it there, or stop following",
    _SUP,
)
FOLLOW_STATE = _pub(
    "controller/follow_state",
    _CTRL,
    follow.FollowState,
    "the follow goal every cycle while it runs (target, predicted target, standoff point, "
    "tracked point), once when it ends",
    _SUP,
)
TARGET_TAKEN = _pub(
    "controller/target_taken",
    _CTRL,
    target.TargetTaken,
    "each target frame as the controller took it: after which joint state (exact replays)",
)
FOLLOW_ENDPOINTS = (TARGET, FOLLOW, FOLLOW_STATE, TARGET_TAKEN)
"""The endpoints of following a target (a block of their own in :data:`TABLE`)."""


class Table:
    """The endpoints, by suffix, in declaration order (:data:`TABLE`)."""

    def __init__(self, endpoints: tuple[Endpoint, ...]) -> None:
        self._by_suffix: dict[str, Endpoint] = {}
        self.version = 0
        """Bumped on every change (caches derived from the table compare it)."""
        for endpoint in endpoints:
            self.add(endpoint)

    def add(self, endpoint: Endpoint) -> None:
        """Declare one more endpoint.

        Raises:
            SchemaError: its suffix is taken, or lies under another endpoint's (or the
                trace root).
        """
        suffix = endpoint.suffix
        if suffix in self._by_suffix:
            raise SchemaError(f"endpoint {suffix!r} is declared twice")
        root = suffix.split("/")[0]
        if root == TRACE_ROOT:
            raise SchemaError(f"endpoint {suffix!r}: {TRACE_ROOT}/ holds the query mirrors")
        for other in self._by_suffix.values():
            if other.kind is Kind.LIVELINESS and root == other.suffix:
                raise SchemaError(f"endpoint {suffix!r} lies under the token root {other!r}")
        self._by_suffix[suffix] = endpoint
        self.version += 1

    def remove(self, endpoint: Endpoint) -> None:
        """Withdraw an endpoint (tests that declare a throwaway one)."""
        del self._by_suffix[endpoint.suffix]
        self.version += 1

    @contextlib.contextmanager
    def extended(self, *endpoints: Endpoint) -> Iterator[None]:
        """Declare ``endpoints`` for the duration of a ``with`` block."""
        for endpoint in endpoints:
            self.add(endpoint)
        try:
            yield
        finally:
            for endpoint in endpoints:
                self.remove(endpoint)

    def __iter__(self) -> Iterator[Endpoint]:
        return iter(list(self._by_suffix.values()))

    def __contains__(self, suffix: object) -> bool:
        return suffix in self._by_suffix

    def get(self, suffix: str) -> Endpoint | None:
        """The endpoint of ``suffix`` (None: not declared)."""
        return self._by_suffix.get(suffix)

    def of_kind(self, *kinds: Kind) -> list[Endpoint]:
        """The endpoints of these kinds, in declaration order."""
        return [e for e in self if e.kind in kinds]

    def owned_by(self, owner: str, *kinds: Kind) -> list[Endpoint]:
        """What ``owner`` publishes or answers (of ``kinds``; all kinds when none given)."""
        return [e for e in self if e.owner == owner and (not kinds or e.kind in kinds)]

    def outputs(self, service: str) -> tuple[Endpoint, ...]:
        """What ``service`` publishes (its publications; not the trace mirrors)."""
        return tuple(self.owned_by(service, Kind.PUBLICATION))

    def queryables(self, service: str) -> tuple[Endpoint, ...]:
        """The queryables ``service`` answers."""
        return tuple(self.owned_by(service, Kind.QUERYABLE))


TABLE = Table(
    (
        JOINTS,
        STATUS,
        BRIDGE_STATE,
        CAN_RX,
        CAN_TX,
        BRIDGE_TOKEN_GONE,
        BRIDGE_COMMAND,
        ESTOP,
        SIM_TRUTH,
        PLAN,
        SCENE,
        SCENE_STATE,
        JOINT_VELOCITY,
        GOAL,
        GRIPPER_GOAL,
        CANCEL,
        SPEED_SCALE,
        FEEDBACK,
        RESULT,
        JOG,
        JOG_LEVEL,
        JOG_TAKEN,
        TOKEN_GONE,
        JOG_STATE,
        HEARTBEAT,
        SUBMIT,
        TASK_CONTROL,
        TASK_STATUS,
        HISTORY,
        EVENTS,
        GUARDIAN_REPORT,
        ALIVE,
        WHERE,
        DISABLED,
        HEALTH,
        LIVELINESS,
        FLIGHT_TRIGGER,
        PLAYBACK_CONTROL,
        *OBJECT_ENDPOINTS,
        *FOLLOW_ENDPOINTS,
    )
)
"""Every endpoint of the stack."""


def markdown_table(table: Table = TABLE) -> str:
    """The key table of docs/architecture.md (kept equal by a test)."""
    rows = [
        "| key (after the prefix) | kind | type | owner | audience |",
        "|---|---|---|---|---|",
    ]
    for e in table:
        if e.kind is Kind.QUERYABLE:
            assert e.msg_type is not None and e.reply_type is not None
            what = f"{e.msg_type.__name__} -> {e.reply_type.__name__}"
        elif e.msg_type is not None:
            what = e.msg_type.__name__
        else:
            what = "(token, no payload)"
        rows.append(f"| `{e.pattern}` | {e.kind.value} | {what} | {e.owner} | {e.audience.value} |")
    return "\n".join(rows) + "\n"
