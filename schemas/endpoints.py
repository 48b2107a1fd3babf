"""The table of endpoints: every key of the stack, declared once.

Each key is one :class:`~schemas.endpoint.Endpoint` (what an endpoint is, its kinds and
audiences: :mod:`schemas.endpoint`), collected in :data:`TABLE` (a
:class:`~schemas.endpoint_table.Table`). The types those modules define are re-exported
here, so that ``ep.Kind``, ``ep.Service``, ``ep.TABLE`` and the endpoints are all read as
``from schemas import endpoints as ep``. Everything else that lists keys is derived from
:data:`TABLE`: :class:`schemas.keys.Keys` and its channel types (the
recorder's JSON Schemas), the schema export (``manus schemas``,
``schemas/supervisor.schema.json``), the replay's per-service outputs and queryables, the
access-control policy check, the services' wiring maps and the key table of
docs/architecture.md (:func:`~schemas.endpoint_table.markdown_table`).

Adding an endpoint is one :class:`Endpoint` here, or in a block module of its own that
this one re-exports (:mod:`schemas.object_endpoints`), and, for its owner's core, one
line of the service's wiring map (``services/<name>/wiring.py``). A key suffix is spelled
as a string literal only in its declaration.
"""

from __future__ import annotations

# ruff: noqa: PLC0414 - the `X as X` imports below re-export (mypy strict): ep.Kind etc.
from schemas import (
    collision,
    commands,
    control,
    flight,
    guardian,
    health,
    jog,
    liveliness,
    planning,
    playback,
    sequencing,
    simfault,
    state,
)
from schemas.endpoint import ANYONE as ANYONE
from schemas.endpoint import EACH_SERVICE as EACH_SERVICE
from schemas.endpoint import TRACE_PARTS as TRACE_PARTS
from schemas.endpoint import TRACE_ROOT as TRACE_ROOT
from schemas.endpoint import Audience as Audience
from schemas.endpoint import Endpoint as Endpoint
from schemas.endpoint import Kind as Kind
from schemas.endpoint import Queryable as Queryable
from schemas.endpoint import Service as Service
from schemas.endpoint import Topic as Topic
from schemas.endpoint import publication as _pub
from schemas.endpoint import queryable as _query
from schemas.endpoint import trace_suffix as trace_suffix
from schemas.endpoint_table import Table as Table
from schemas.endpoint_table import markdown_table as markdown_table
from schemas.follow_endpoints import FOLLOW as FOLLOW
from schemas.follow_endpoints import FOLLOW_ENDPOINTS as FOLLOW_ENDPOINTS
from schemas.follow_endpoints import FOLLOW_STATE as FOLLOW_STATE
from schemas.follow_endpoints import TARGET as TARGET
from schemas.follow_endpoints import TARGET_TAKEN as TARGET_TAKEN
from schemas.object_endpoints import ATTACH as ATTACH
from schemas.object_endpoints import OBJECT_ENDPOINTS as OBJECT_ENDPOINTS
from schemas.object_endpoints import OBJECTS as OBJECTS
from schemas.object_endpoints import PERCEPTION as PERCEPTION

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
QUERY_TAKEN = _pub(
    "controller/query_taken",
    _CTRL,
    control.QueryTaken,
    "each query as the controller took it: after which joint state (exact replays)",
)
JOG_STATE = _pub(
    "controller/jog_state",
    _CTRL,
    jog.JogState,
    "the jog as the controller runs it: its state and stop cause, the limits holding it "
    "back, level and caps, refusals, pose",
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
        QUERY_TAKEN,
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
