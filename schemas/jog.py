"""Live control (jog): the user drives the arm with a stream of speed commands.

A supervisor, a keypad or a joystick publishes :class:`JogCommand` on ``jog`` at its own
rate (10-50 Hz); the controller turns the newest one into joint speeds every cycle
(``services/controller/jog.py``). No new command for the controller's ``jog_timeout``
(the deadman), a zero command or a bad one stops the arm. The speed level (1..5 by
default, like the arm's own controller) is set with :class:`JogLevel` on the queryable
``controller/jog_level`` and shown in :class:`JogState` (``controller/jog_state``), which
also says why the jog is slowed or stopped.

Values are SI (m/s, rad/s) with ``units = "si"``, or unitless deflections in -1..1 (a
joystick's) with ``units = "unitless"``, scaled by the speed level's share of the caps.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field


class JogKind(StrEnum):
    """What a jog command's values mean."""

    TWIST = "twist"
    """gripper linear + angular velocity"""
    JOINTS = "joints"
    """DH joint velocities"""
    STOP = "stop"
    """stop at once"""


class JogFrame(StrEnum):
    """The axes a twist is expressed in."""

    BASE = "base"
    GRIPPER = "gripper"
    """the gripper frame's axes, moving with it"""


class JogUnits(StrEnum):
    """How a jog command's speeds are given."""

    SI = "si"
    """m/s, rad/s"""
    UNITLESS = "unitless"
    """-1..1, a joystick's deflection, scaled by the speed level"""


USER_TOOK_OVER = "user took over"
"""Start of the reason of a goal the controller ends because a jog command arrived (the
sequencer pauses its task on it instead of failing)."""
JOGGING = "the user is jogging"
"""Start of the controller's refusal of a goal submitted while a jog moves the arm."""


@dataclass(frozen=True)
class JogCommand(Message):
    """One speed command of the live control stream (key ``jog``).

    A ``twist`` moves the gripper frame's origin at ``linear`` and turns it at
    ``angular`` (both in ``frame``'s axes); ``joints`` moves each DH joint at its speed;
    ``gripper`` opens (+) or closes (-) the gripper with either kind. ``drink`` holds the
    cup level (the gripper's pitch and roll relative to gravity are kept, only yaw turns);
    ``pour`` then tilts the cup about its rim (the controller's ``rim_offset`` in the
    gripper frame) instead of about the wrist. All zeros, or ``kind = "stop"``, stops at
    once.
    """

    TYPE_NAME = "manus/JogCommand/1"

    stamp_ns: int = field("sender's clock when sent (informative only)", unit="ns")
    seq: int = field("sequence number of the sender", minimum=0)
    source: str = field("who sends it (e.g. 'teleop', 'joystick')")
    kind: str = field("what the values mean", choices=JogKind)
    units: str = field("SI speeds or unitless deflections in -1..1", choices=JogUnits)
    frame: str = field("axes of a twist", default=JogFrame.BASE, choices=JogFrame)
    linear: list[float] = field(
        "twist: gripper origin velocity x, y, z",
        unit="m/s or -1..1",
        default_factory=lambda: [0.0] * 3,
        length=3,
    )
    angular: list[float] = field(
        "twist: angular velocity about x, y, z",
        unit="rad/s or -1..1",
        default_factory=lambda: [0.0] * 3,
        length=3,
    )
    joints: list[float] = field(
        "joints: DH joint velocities q1..q6",
        unit="rad/s or -1..1",
        default_factory=lambda: [0.0] * 6,
        length=6,
    )
    gripper: float = field(
        "gripper opening velocity (positive opens)", unit="m/s or -1..1", default=0.0
    )
    drink: bool = field("drink mode: keep the cup level (twist only)", default=False)
    pour: float = field(
        "drink mode: tilt about the cup's rim (positive pours forward, about the gripper's y axis)",
        unit="rad/s or -1..1",
        default=0.0,
    )


@dataclass(frozen=True)
class JogLevel(Message):
    """Set the jog speed level (queryable ``controller/jog_level``, answered by a GoalAck)."""

    TYPE_NAME = "manus/JogLevel/1"

    level: int = field("speed level: 1 (slowest) .. the controller's number of levels", minimum=1)


@dataclass(frozen=True)
class JogTaken(Message):
    """A jog command as the controller took it (key ``controller/jog_taken``), published
    at once: after which joint state it came. The command stream and the joint states come
    from two publishers, so a recorder may log a command and a joint state that arrived
    together in the other order than the controller saw them; this record says where the
    controller saw it, and the regression check (``manus replay --check controller``)
    feeds the command there."""

    TYPE_NAME = "manus/JogTaken/1"

    after_seq: int = field("seq of the newest joint state when it came (-1: none yet)")
    command: JogCommand | None = field("the command (None: a payload that did not decode)")
    error: str = field("why the payload did not decode ('' when it did)", default="")


@dataclass(frozen=True)
class JogState(Message):
    """The jog as the controller runs it (key ``controller/jog_state``): every cycle while
    a jog runs, once when it stops, and at the cycle after a level change or a refusal."""

    TYPE_NAME = "manus/JogState/1"

    stamp_ns: int = field("stamp of the joint state this answers", unit="ns")
    seq: int = field("sequence number", minimum=0)
    active: bool = field("a jog command is being executed")
    kind: str = field("kind of the command executed ('' when none)")
    frame: str = field("frame of the twist executed ('' when none)")
    drink: bool = field("drink mode")
    level: int = field("speed level in use", minimum=1)
    levels: int = field("number of speed levels", minimum=1)
    scale: float = field("slow-down factor applied (1: none, 0: stopped at a limit)")
    reason: str = field("why the jog is slowed, stopped or refused ('' when none)")
    command_seq: int = field("seq of the newest command accepted (-1: none)")
    refused: int = field("jog commands refused so far (bad values, not allowed now)", minimum=0)
    deadman_stops: int = field("stops for want of a new command within jog_timeout", minimum=0)
    actual_xyz: list[float] = field("gripper position of the measurement", unit="m", length=3)
    actual_ypr: list[float] = field(
        "gripper (yaw, pitch, roll) of the measurement", unit="rad", length=3
    )
