"""Controller goals, feedback and results (in the manner of a ROS 2 action).

A goal is submitted by a query and acknowledged at once (accepted or refused with a
reason); while it runs the controller publishes feedback every cycle; when it ends it
publishes exactly one result. A new trajectory goal preempts the running one, or, with
``replace``, splices into it while the arm moves (continuous position and velocity).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from schemas.base import Message, field
from schemas.collision import ClearanceReport
from schemas.planning import Trajectory


class ControlMode(StrEnum):
    """The control law a trajectory goal runs (``services.controller.laws``)."""

    DEFAULT = "default"
    """delay-compensated dead-beat law with Cartesian-aware rounding"""
    THESIS = "thesis"
    """the 2005 thesis's loop, per-segment timing (for comparison)"""


class ResultStatus(StrEnum):
    """How a goal ended (``GoalResult.status``)."""

    SUCCEEDED = "succeeded"
    ABORTED = "aborted"
    CANCELLED = "cancelled"
    PREEMPTED = "preempted"


class EndCause(StrEnum):
    """Why a goal (or a jog) ended, beside how (``GoalResult.cause``, ``JogState.cause``).

    A client decides on these, never on the words of ``reason``.
    """

    REACHED = "reached"
    """succeeded: the goal's end was reached within its tolerances"""
    CANCEL_REQUEST = "cancel_request"
    """cancelled by a ``CancelGoal``"""
    NEW_GOAL = "new_goal"
    """preempted: a newer goal of the same kind replaced it (spliced or not)"""
    USER_TOOK_OVER = "user_took_over"
    """preempted: a jog took the arm (the sequencer pauses its task, it does not fail)"""
    ARM_ERROR = "arm_error"
    """aborted: the arm reports an error"""
    BRIDGE_PHASE = "bridge_phase"
    """aborted: the bridge left ``running`` (stop, e-stop, arm error, fold, shutdown)"""
    STATES_INTERRUPTED = "states_interrupted"
    """aborted: the joint states stopped for longer than ``max_outage_ms``"""
    STATE_UNUSABLE = "state_unusable"
    """aborted: a joint state not valid or not in joint mode"""
    HEARTBEAT_LOST = "heartbeat_lost"
    """aborted: the supervisor's heartbeat is older than ``heartbeat_timeout``"""
    TOKEN_GONE = "token_gone"
    """aborted: the liveliness token of the heartbeats' sender went"""
    COLLISION = "collision"
    """aborted: the collision guard stopped the goal's command"""
    TOLERANCE = "tolerance"
    """aborted: a path, goal or position tolerance was broken"""
    TIMEOUT = "timeout"
    """aborted: a gripper goal not reached within its ``timeout``"""
    RELEASED = "released"
    """a jog: the controls were released (a zero command)"""
    DEADMAN = "deadman"
    """a jog: no new command within ``jog_timeout``"""
    BAD_COMMAND = "bad_command"
    """a jog: a command that cannot be executed (values, units, caps, or not decodable)"""
    NOT_READY = "not_ready"
    """a jog: a command while nothing may move (no joint state, arm error, bridge phase)"""
    TARGET_LOST = "target_lost"
    """a follow goal: no new target frame within ``lost_after``, or the tracker lost it"""
    TARGET_JUMP = "target_jump"
    """a follow goal: the target moved faster than a person can, or its body left the
    bound about its place in the scene"""
    OUT_OF_REACH = "out_of_reach"
    """a follow goal: the standoff point is beyond the arm's reach or a joint limit"""
    KEEP_OUT = "keep_out"
    """a follow goal: the standoff point is in a keep-out zone or outside the workspace"""
    SINGULARITY = "singularity"
    """a follow goal: the way to the standoff point is behind the wrist or elbow
    singularity"""


class Refusal(StrEnum):
    """Why a request was refused (``GoalAck.refusal``; empty when accepted)."""

    NONE = ""
    """accepted"""
    INVALID = "invalid"
    """the request's own fields (the reason names the field, value and limit)"""
    NOT_READY = "not_ready"
    """nothing may move now: no joint state, an arm error, the bridge not ``running``"""
    BUSY = "busy"
    """another command source holds the arm (``GoalAck.held_by`` names it)"""
    START_MISMATCH = "start_mismatch"
    """the trajectory's first knot is further than ``start_tolerance`` from the arm"""
    UNKNOWN_GOAL = "unknown_goal"
    """a cancel of a goal that is not active"""
    NO_GOAL = "no_goal"
    """a speed scale while no trajectory goal is running"""


class CommandSourceKind(StrEnum):
    """What drives the arm in the controller (one at a time; docs/architecture.md,
    Command sources)."""

    GOAL = "goal"
    """trajectory and gripper goals (``controller/goal``, ``controller/gripper``)"""
    JOG = "jog"
    """live control (the ``jog`` stream)"""
    FOLLOW = "follow"
    """following a moving target (``controller/follow``, ``target/pose``)"""


class GoalKind(StrEnum):
    """What a goal drives."""

    TRAJECTORY = "trajectory"
    GRIPPER = "gripper"
    FOLLOW = "follow"


class TrackState(StrEnum):
    """What the controller does with the active goal (``ControllerFeedback.state``)."""

    IDLE = "idle"
    TRACKING = "tracking"
    SETTLING = "settling"
    DECELERATING = "decelerating"
    HOLDING = "holding"


CONTROL_MODES = tuple(ControlMode)
RESULT_STATUSES = tuple(ResultStatus)
GOAL_KINDS = tuple(GoalKind)


def _heartbeat_timeout() -> Any:
    """The deadman field of every goal the controller runs (manus/deadman.py)."""
    return field(
        "deadman: abort (zeros) when the newest Heartbeat refers to a joint state older than "
        "this, judged on joint-state stamps (0: no heartbeat needed)",
        unit="s",
        default=0.0,
        minimum=0.0,
        maximum=10.0,
    )


@dataclass(frozen=True)
class TrajectoryGoal(Message):
    """Follow a joint trajectory."""

    TYPE_NAME = "manus/TrajectoryGoal/1"

    goal_id: str = field("caller-chosen unique id")
    trajectory: Trajectory = field("what to follow")
    mode: str = field("control law", default="default", choices=ControlMode)
    path_tolerance: list[float] = field(
        "largest allowed |reference - actual| per joint while moving (0: unchecked)",
        unit="rad",
        default_factory=list,
    )
    goal_tolerance: list[float] = field(
        "largest allowed |final - actual| per joint at the end (0: unchecked)",
        unit="rad",
        default_factory=list,
    )
    goal_time_tolerance: float = field(
        "time allowed after the trajectory's end to get within tolerance", unit="s", default=5.0
    )
    position_tolerance: float = field(
        "gripper position error at the end under which the goal succeeds", unit="m", default=0.002
    )
    start_tolerance: float = field(
        "largest allowed |first knot - measured| per joint at the start", unit="rad", default=0.05
    )
    replace: bool = field(
        "splice into the running trajectory at the next cycle instead of preempting it",
        default=False,
    )
    splice_at: float = field(
        "with replace: the running trajectory's time that this one's time 0 stands for, so "
        "that its knots keep the running one's clock (a continuation planned from the running "
        "reference at that time: streamed via points); -1: the moment of the splice",
        unit="s",
        default=-1.0,
    )
    speed_scale: float = field(
        "initial speed scaling (1: as planned)", default=1.0, minimum=0.05, maximum=1.0
    )
    heartbeat_timeout: float = _heartbeat_timeout()


@dataclass(frozen=True)
class Heartbeat(Message):
    """The supervisor's deadman signal (key ``heartbeat``), one per joint state it receives
    while a task runs.

    It echoes the newest joint state the sender has seen, so the controller (arm
    computer) judges its age on the bridge's own stamps: a heartbeat proves that the link
    carried that joint state to the sender and the heartbeat back. No clock of the sender
    is compared with the arm's.
    """

    TYPE_NAME = "manus/Heartbeat/1"

    stamp_ns: int = field("sender's clock when sent (informative only)", unit="ns")
    seq: int = field("sequence number of the sender", minimum=0)
    source: str = field("who sends it (e.g. 'sequencer')")
    ref_seq: int = field("seq of the newest JointState the sender has received")
    ref_stamp_ns: int = field("stamp of that JointState (the bridge's clock)", unit="ns")
    task_id: str = field("the task running ('' when none)", default="")


@dataclass(frozen=True)
class GripperGoal(Message):
    """Drive the gripper to an opening."""

    TYPE_NAME = "manus/GripperGoal/1"

    goal_id: str = field("caller-chosen unique id")
    opening: float = field("target opening", unit="m", minimum=0.0, maximum=0.09)
    tolerance: float = field("done when within this of the target", unit="m", default=0.001)
    timeout: float = field("abort if not reached within this time", unit="s", default=10.0)
    heartbeat_timeout: float = _heartbeat_timeout()


@dataclass(frozen=True)
class CancelGoal(Message):
    """Cancel a goal (decelerate to rest within the arm's limits)."""

    TYPE_NAME = "manus/CancelGoal/1"

    goal_id: str = field("goal to cancel; empty: every active goal", default="")


@dataclass(frozen=True)
class SpeedScale(Message):
    """Change the speed of the running trajectory (time scaling) from the next cycle."""

    TYPE_NAME = "manus/SpeedScale/1"

    scale: float = field("1: as planned; smaller: slower", minimum=0.05, maximum=1.0)


@dataclass(frozen=True)
class GoalAck(Message):
    """Immediate answer to a goal, cancel or speed request."""

    TYPE_NAME = "manus/GoalAck/1"

    accepted: bool = field("accepted")
    goal_id: str = field("the goal concerned")
    reason: str = field("why it was refused, in words", default="")
    refusal: str = field(
        "why it was refused, the kind a client decides on ('' when accepted)",
        default=Refusal.NONE,
        choices=Refusal,
    )
    held_by: str = field(
        "refusal `busy`: the command source that holds the arm ('' otherwise)",
        default="",
        choices=("", *CommandSourceKind),
    )


@dataclass(frozen=True)
class QueryTaken(Message):
    """A query as the controller took it (key ``controller/query_taken``), published at
    once: which queryable, after which joint state. A goal starts at the joint state after
    it came, and the mirrored request (``trace/<q>/request``) and the joint states come
    from two publishers, so a recorder may log them in the other order than the controller
    took them; this record says where it took it, and the regression check (``manus replay
    --check controller``) feeds the request there."""

    TYPE_NAME = "manus/QueryTaken/1"

    query: str = field("the queryable's key suffix (controller/goal, controller/gripper, ...)")
    after_seq: int = field("seq of the newest joint state when it came (-1: none yet)")


@dataclass(frozen=True)
class ControllerFeedback(Message):
    """One cycle of the controller: reference vs actual."""

    TYPE_NAME = "manus/ControllerFeedback/1"

    stamp_ns: int = field("stamp of the joint state this cycle answers", unit="ns")
    seq: int = field("sequence number", minimum=0)
    goal_id: str = field("active trajectory goal ('' when idle)")
    state: str = field("what the controller does with the goal", choices=TrackState)
    segment: int = field("index of the knot interval being tracked (-1: none)")
    t: float = field("trajectory time", unit="s")
    reference: list[float] = field("reference joint angles", unit="rad", length=6)
    actual: list[float] = field("measured joint angles", unit="rad", length=6)
    error: list[float] = field("reference - actual", unit="rad", length=6)
    command: list[float] = field(
        "commanded joint velocities (after quantization)", unit="rad/s", length=6
    )
    reference_xyz: list[float] = field("gripper position of the reference", unit="m", length=3)
    actual_xyz: list[float] = field("gripper position of the measurement", unit="m", length=3)
    position_error: float = field("|reference_xyz - actual_xyz|", unit="m")
    gripper_goal_id: str = field("active gripper goal ('' when none)", default="")
    gripper_target: float = field("gripper target opening", unit="m", default=0.0)
    gripper: float = field("measured gripper opening", unit="m", default=0.0)
    speed_scale: float = field("current speed scaling", default=1.0)
    guard: str = field(
        "what the collision guard did to this cycle's command and why ('': nothing)",
        default="",
    )


@dataclass(frozen=True)
class GoalResult(Message):
    """The one result of a goal."""

    TYPE_NAME = "manus/GoalResult/2"

    stamp_ns: int = field(
        "the bridge's clock, not a wall clock: the stamp of the ArmStatus or BridgeState "
        "that ended the goal, else of the newest JointState when the result left (a result "
        "leaves with the controller's next publication: at the joint state where the goal "
        "ended; for a goal ended by a query, at the next joint state)",
        unit="ns",
    )
    seq: int = field("sequence number", minimum=0)
    goal_id: str = field("the goal")
    kind: str = field("trajectory, gripper or follow", choices=GoalKind)
    status: str = field("how it ended", choices=ResultStatus)
    cause: str = field("why it ended: the kind a client decides on", choices=EndCause)
    reason: str = field("why it ended that way, in words")
    via_errors: list[float] = field(
        "gripper position error at each knot time, measured (FK of the encoders)",
        unit="m",
        default_factory=list,
    )
    via_stamps: list[int] = field(
        "time of each via error's measurement (snapshot clock: JointState stamp minus the "
        "snapshot age)",
        unit="ns",
        default_factory=list,
    )
    final_error: float = field(
        "how far from its end the goal ended: a trajectory's gripper from its last via "
        "point (measured while it settles at the end, and where the collision guard stopped "
        "it; 0 when it ended before either), a gripper goal's opening from its target",
        unit="m",
        default=0.0,
    )
    duration: float = field("time from start to end", unit="s", default=0.0)
    clearance: ClearanceReport | None = field(
        "smallest clearance the collision guard computed while the goal ran (None: none)",
        default=None,
    )

    @property
    def path_via_errors(self) -> list[float]:
        """``via_errors`` without the first knot's [m]: the first via point is the arm's
        own pose when the path was planned (docs/protocol.md, Thesis via-point format), so
        its error says nothing about tracking. Means and maxima of a path are taken over
        these."""
        return self.via_errors[1:]
