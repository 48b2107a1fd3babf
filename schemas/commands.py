"""What the stack tells the bridge: velocity commands, e-stop, arm commands."""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field
from schemas.state import BridgePhase


class ArmAction(StrEnum):
    """What an :class:`ArmCommand` asks the bridge."""

    STOP = "stop"
    """0x370 now, then stay stopped"""
    FOLD_IN = "fold_in"
    """0x376 held until the arm reports it folded"""
    FOLD_OUT = "fold_out"
    """0x375 held until the arm reports it unfolded"""
    CLEAR = "clear"
    """leave stopped, e-stop or arm error (the arm back in joint mode)"""


ARM_ACTIONS = tuple(ArmAction)


@dataclass(frozen=True)
class JointVelocityCommand(Message):
    """Joint and gripper velocities for the next sync (the arm applies them for 60 ms).

    The bridge sends the newest command at each 0x37F only if it is fresh: it answers the
    current joint state (``ref_seq`` equal to the newest ``JointState.seq``, or at most
    ``command_max_age_cycles`` older), or, with ``ref_seq`` = -1, it arrived within the
    bridge's command timeout. Otherwise the arm gets zeros.

    The arm runs each motor at one of 21 speeds (multiples of 5 deg/s up to 50 deg/s, the
    joint map coupling joints 2 and 3: ``manus.quantize``) and the gripper at multiples of
    5 mm/s; the bridge turns the velocities into those steps at the CAN edge. A velocity
    on them (the controller chooses one, its rounding decides how) is sent exactly; any
    other is scaled into the range by one factor and rounded by the bridge's quantizer.
    """

    TYPE_NAME = "manus/JointVelocityCommand/2"

    stamp_ns: int = field(
        "time the command was computed (the stamp of the state it answers)", unit="ns"
    )
    seq: int = field("sequence number", minimum=0)
    source: str = field("who sent it (e.g. 'controller')")
    ref_seq: int = field("seq of the JointState this command answers (-1: none)", minimum=-1)
    velocity: list[float] = field("DH joint velocities", unit="rad/s", length=6)
    gripper_velocity: float = field("gripper opening velocity (positive opens)", unit="m/s")


@dataclass(frozen=True)
class EStop(Message):
    """Emergency stop. ``engaged`` latches it in the bridge; only ``engaged=false`` clears it."""

    TYPE_NAME = "manus/EStop/1"

    stamp_ns: int = field("time it was sent", unit="ns")
    seq: int = field("sequence number", minimum=0)
    engaged: bool = field("true: stop now and stay stopped; false: clear a latched e-stop")
    source: str = field("who sent it")
    reason: str = field("why", default="")


@dataclass(frozen=True)
class ArmCommand(Message):
    """A request to the bridge: stop (0x370), fold in / out (held until done), clear error."""

    TYPE_NAME = "manus/ArmCommand/1"

    action: str = field("what to do", choices=ArmAction)
    source: str = field("who asks", default="")
    heartbeat_timeout: float = field(
        "a fold's deadman: the fold frame goes out only while the newest Heartbeat "
        "refers to a joint state no older than this (judged on joint-state stamps) and "
        "the controller answers the joint states; otherwise the fold stops "
        "(0: no deadman; ignored by stop and clear)",
        unit="s",
        default=0.0,
        minimum=0.0,
        maximum=10.0,
    )


@dataclass(frozen=True)
class ArmCommandReply(Message):
    """The bridge's answer to an ArmCommand."""

    TYPE_NAME = "manus/ArmCommandReply/1"

    ok: bool = field("accepted")
    phase: str = field("bridge phase after the request", choices=BridgePhase)
    message: str = field("why it was refused, or what happens now")
