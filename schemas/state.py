"""What the arm and the bridge report: joint state, arm status, bridge health, raw frames.

All published by ``can_bridge`` (``SimTruth`` by the simulator). SI units; stamps are
integer nanoseconds of the publishing process's clock (the CAN receive time for
arm data), and every stream has its own sequence number.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field
from schemas.objects import ObjectContact, ObjectTruth
from schemas.target import TargetTruth


class ArmMode(StrEnum):
    """The arm's active mode (low nibble of status byte 0, docs/protocol.md)."""

    NONE = "none"
    CARTESIAN = "cartesian"
    JOINT = "joint"
    FOLD_OUT = "fold_out"
    FOLD_IN = "fold_in"
    UNKNOWN = "unknown"


class MessageClass(StrEnum):
    """Class of the arm's message (bits 7-6 of status byte 0)."""

    NONE = "none"
    WARNING = "warning"
    GENERAL = "general"
    ERROR = "error"


class BridgePhase(StrEnum):
    """What the bridge is doing (``BridgeState.phase``)."""

    OPENING = "opening"
    """bus being opened"""
    WAITING_POWER_UP = "waiting_power_up"
    """waiting for 'gripper ready' / 'absolute angles measured'"""
    ENTERING_JOINT_MODE = "entering_joint_mode"
    """zero 0x374 sent, waiting for joint mode and valid positions"""
    INITIALISING = "initialising"
    """the four small joint 4-6 moves of the start-up (docs/protocol.md)"""
    RUNNING = "running"
    """normal cycle: commands from the controller reach the arm"""
    RESYNC = "resync"
    """frames lost or out of order: zeros until two clean cycles"""
    FOLDING_IN = "folding_in"
    """0x376 held until the arm reports it folded"""
    FOLDING_OUT = "folding_out"
    """0x375 held until the arm reports it unfolded"""
    STOPPED = "stopped"
    """0x370 sent, waiting for a command"""
    ESTOPPED = "estopped"
    """e-stop latched: zeros then 0x370, until cleared"""
    ARM_ERROR = "arm_error"
    """the arm reported an error: stopped until cleared"""
    SHUTDOWN = "shutdown"
    """zeros and 0x370 sent, bus closed"""


class AppliedKind(StrEnum):
    """Kind of the frame the bridge sent at the previous sync."""

    NONE = "none"
    JOINT = "joint"
    CARTESIAN = "cartesian"
    STOP = "stop"
    FOLD_IN = "fold_in"
    FOLD_OUT = "fold_out"


MODES = tuple(ArmMode)
MESSAGE_CLASSES = tuple(MessageClass)
BRIDGE_PHASES = tuple(BridgePhase)
APPLIED_KINDS = tuple(AppliedKind)
STOPPING_PHASES = frozenset(
    {
        BridgePhase.STOPPED,
        BridgePhase.ESTOPPED,
        BridgePhase.ARM_ERROR,
        BridgePhase.FOLDING_IN,
        BridgePhase.FOLDING_OUT,
        BridgePhase.SHUTDOWN,
    }
)
"""Bridge phases in which no goal can run (the arm is stopped or folding)."""
ON_ITS_WAY_PHASES = frozenset(
    {
        BridgePhase.OPENING,
        BridgePhase.WAITING_POWER_UP,
        BridgePhase.ENTERING_JOINT_MODE,
        BridgePhase.INITIALISING,
        BridgePhase.RESYNC,
        BridgePhase.FOLDING_IN,
        BridgePhase.FOLDING_OUT,
    }
)
"""Bridge phases that lead to ``running`` by themselves: the start-up, a resync, a fold
in progress. From the others but ``running`` (stopped, estopped, arm_error, shutdown)
only a command (``clear``, an e-stop's release) or a new bridge brings it back:
``manus up`` and the sequencer wait a bounded time for the former and refuse at once in
the latter."""


@dataclass(frozen=True)
class JointState(Message):
    """Joint positions of the arm, one per 60 ms cycle, published as soon as 0x360 is in."""

    TYPE_NAME = "manus/JointState/2"

    stamp_ns: int = field("CAN receive time of the cycle's 0x360 frame", unit="ns")
    seq: int = field("cycle sequence number of this stream", minimum=0)
    position: list[float] = field("DH joint angles q1..q6", unit="rad", length=6)
    gripper: float = field("gripper opening", unit="m")
    valid: bool = field("positions are meaningful (a move mode is active, the bridge is running)")
    mode: str = field("active mode of the arm", choices=ArmMode)
    encoder: list[int] = field(
        "the raw position fields as received (diagnostics): joints 1..6 [0.1 deg, motor "
        "angles] and gripper [0.1 mm]",
        length=7,
    )
    applied_velocity: list[float] = field(
        "DH joint velocities the arm executes from this snapshot on, sent at the previous "
        "sync (zeros unless applied_kind is joint)",
        unit="rad/s",
        length=6,
    )
    applied_gripper_velocity: float = field(
        "gripper opening velocity it executes likewise (positive opens)", unit="m/s"
    )
    applied_kind: str = field("kind of the frame sent at the previous sync", choices=AppliedKind)
    applied_seq: int = field(
        "seq of the velocity command that was sent at the previous sync (-1: none, zeros)"
    )


@dataclass(frozen=True)
class ArmStatus(Message):
    """The arm's status byte and message of one cycle (docs/protocol.md, Status byte),
    decoded."""

    TYPE_NAME = "manus/ArmStatus/1"

    stamp_ns: int = field("CAN receive time of the 0x350 frame", unit="ns")
    seq: int = field("sequence number", minimum=0)
    mode: str = field("active mode", choices=ArmMode)
    mode_code: int = field("raw low nibble of status byte 0", minimum=0, maximum=15)
    msg_class: str = field("message class (bits 7-6 of status byte 0)", choices=MessageClass)
    msg_code: int = field("message code (byte 1)", minimum=0, maximum=255)
    text: str = field("meaning of the message, empty when there is none")


@dataclass(frozen=True)
class BridgeState(Message):
    """Phase and timing health of the bridge, published every cycle and on every change."""

    TYPE_NAME = "manus/BridgeState/1"

    stamp_ns: int = field("time of the event that caused this report", unit="ns")
    seq: int = field("sequence number", minimum=0)
    phase: str = field("what the bridge is doing", choices=BridgePhase)
    estop: bool = field("e-stop latched")
    cycles: int = field("complete cycles seen since start", minimum=0)
    period_ms: float = field("last sync-to-sync period", unit="ms")
    jitter_ms: float = field("largest |period - 60 ms| since start", unit="ms")
    reply_latency_ms: float = field("last time from 0x37F receipt to reply sent", unit="ms")
    reply_latency_max_ms: float = field("largest reply latency since start", unit="ms")
    missed_windows: int = field("syncs not answered within the 20 ms window", minimum=0)
    stale_commands: int = field(
        "syncs answered with zeros because no fresh command was in", minimum=0
    )
    resyncs: int = field("times the bridge lost the cycle and resynchronised", minimum=0)
    dropped_frames: int = field("frames missing from a cycle", minimum=0)
    duplicate_frames: int = field("frames seen twice in a cycle", minimum=0)
    garbled_frames: int = field("frames with a wrong length or unknown id", minimum=0)
    buffered_syncs: int = field("old syncs found in a buffer and not answered", minimum=0)
    bad_payloads: int = field(
        "bus messages to the bridge that failed to decode, and commands it refused (a count "
        "out of range), counted as they come",
        minimum=0,
    )
    detail: str = field("last notable event, in words")
    late_frames: int = field(
        "frames that arrived out of order: after a later frame of their cycle, or after "
        "their cycle had ended",
        default=0,
        minimum=0,
    )
    other_node_frames: int = field(
        "frames of another PC-side node seen on the bus (replies to the arm such as the "
        "guardian's 0x370): counted, never taken for the arm's or the bridge's own",
        default=0,
        minimum=0,
    )
    preempted_replies: int = field(
        "replies of the bridge that reached the bus after another node's reply to the same "
        "sync (the arm latched the other one, e.g. the guardian's stop)",
        default=0,
        minimum=0,
    )
    buffered_states: int = field(
        "0x360 frames found in a buffer (processed more than sync_max_age_ms after they "
        "arrived, e.g. after a SIGSTOP): no joint state published from them",
        default=0,
        minimum=0,
    )


@dataclass(frozen=True)
class CanFrame(Message):
    """One raw CAN frame as seen on the bus (``can/rx``: from the arm; ``can/tx``: sent)."""

    TYPE_NAME = "manus/CanFrame/1"

    stamp_ns: int = field("receive or send time", unit="ns")
    seq: int = field("sequence number of this stream", minimum=0)
    id: int = field("11-bit identifier", minimum=0, maximum=0x7FF)
    data: bytes = field("payload (empty for remote frames)")
    remote: bool = field("remote transmission request")
    dlc: int = field("data length code", minimum=0, maximum=8)


@dataclass(frozen=True)
class SimTruth(Message):
    """The simulator's true state, which a real arm never reports (for judging accuracy)."""

    TYPE_NAME = "manus/SimTruth/1"

    stamp_ns: int = field("simulated time", unit="ns")
    seq: int = field("sequence number", minimum=0)
    q_true: list[float] = field("true DH joint angles", unit="rad", length=6)
    q_reported: list[float] = field("DH angles the encoders report", unit="rad", length=6)
    gripper: float = field("true gripper opening", unit="m")
    xyz: list[float] = field("true gripper position in the base frame", unit="m", length=3)
    ypr: list[float] = field("true gripper (yaw, pitch, roll)", unit="rad", length=3)
    qd_true: list[float] = field(
        "true DH joint speeds (the drives' speeds through the joint map; empty in recordings "
        "made before it existed)",
        unit="rad/s",
        default_factory=list,
    )
    clearance: float | None = field(
        "smallest true distance between the arm and the scene (objects and the arm itself, "
        "no clearances, no zones) now; None: no scene",
        unit="m",
        default=None,
    )
    clearance_pair: str = field("body/object of `clearance` (e.g. gripper/head)", default="")
    min_clearance: float | None = field(
        "smallest `clearance` at any tick since power-up (None: no scene)", unit="m", default=None
    )
    contacts: int = field(
        "ticks on which a body, or the object the gripper holds, met an object (or the arm "
        "itself) and the arm was stopped",
        default=0,
        minimum=0,
    )
    contact: str = field("body/object of the last contact ('': none yet)", default="")
    objects: list[ObjectTruth] = field(
        "every object of the simulator, where it truly is (docs/objects.md)",
        default_factory=list,
    )
    object_contacts: list[ObjectContact] = field(
        "every pair that touched since power-up: an arm body and a free object, or a held "
        "object and the scene or another object",
        default_factory=list,
    )
    held_clearance: float | None = field(
        "smallest true distance now between a held object and the scene or another object "
        "(None: nothing held)",
        unit="m",
        default=None,
    )
    held_clearance_pair: str = field("object/other of `held_clearance`", default="")
    held_min_person: float | None = field(
        "smallest true distance between a held object and the person at any tick since "
        "power-up (None: nothing held yet)",
        unit="m",
        default=None,
    )
    person_clearance: float | None = field(
        "smallest true distance now between the arm and a person object (no clearance; "
        "None: no person in the scene)",
        unit="m",
        default=None,
    )
    person_pair: str = field("body/object of `person_clearance`", default="")
    min_person_clearance: float | None = field(
        "smallest `person_clearance` at any tick since power-up (None: no person)",
        unit="m",
        default=None,
    )
    target: TargetTruth | None = field(
        "the moving target and the body it moves with, truly (None: no moving target)",
        default=None,
    )
