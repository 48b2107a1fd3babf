"""The Manus transparent-mode CAN protocol: identifiers, units and codecs.

The protocol is docs/protocol.md, The CAN protocol. Pure functions over ``(arbitration_id,
data, is_remote)``; nothing here touches a bus. Both the simulator (the arm's side) and the
bridge (the PC's side) use this module, and ``schemas/manus.dbc`` describes the same frames
for CAN tools.

Multi-byte fields are signed 16-bit big-endian; command bytes are signed 8-bit.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

from manus.errors import ProtocolError

BITRATE = 250_000
"""Bus bitrate [bit/s]."""

CYCLE_S = 0.060
"""The arm's frame cycle [s]."""

TICK_S = 0.020
"""The period of command execution and of the frames within a cycle [s]."""

REPLY_WINDOW_S = 0.020
"""Time after the sync frame within which the PC's one reply must arrive [s]."""


class FrameId(IntEnum):
    """Standard 11-bit identifiers of the protocol."""

    STATUS = 0x350  # arm -> PC: status, message, joints 1-3 (or X, Y, Z)
    POSITION = 0x360  # arm -> PC: joints 4-6 (or yaw, pitch, roll), gripper
    SYNC = 0x37F  # arm -> PC: remote frame, the PC may reply once now
    STOP = 0x370  # PC -> arm: stop / (re)initialise
    CARTESIAN = 0x371  # PC -> arm: Cartesian move increments
    JOINT = 0x374  # PC -> arm: joint move increments
    FOLD_OUT = 0x375  # PC -> arm: fold out (repeat on every sync until done)
    FOLD_IN = 0x376  # PC -> arm: fold in (likewise)


REPLY_IDS = frozenset(
    {FrameId.STOP, FrameId.CARTESIAN, FrameId.JOINT, FrameId.FOLD_OUT, FrameId.FOLD_IN}
)
"""Identifiers of the PC's replies to a sync (the bridge's, the guardian's)."""


JOINT_UNIT_DEG = 0.1
"""Position unit of joint fields and of joint increments [deg]."""

XYZ_UNIT_MM = 0.022
"""Position unit of Cartesian fields and increments [mm]."""

GRIPPER_UNIT_MM = 0.1
"""Gripper opening unit and gripper increment unit [mm] (the project's choice)."""

JOINT_INC_MAX = 10
"""Largest joint increment magnitude [0.1 deg per 20 ms] (50 deg/s)."""

XYZ_INC_MAX = 127
ANGLE_INC_MAX = 10
GRIPPER_INC_MAX = 15
LIFT_INC_MAX = 1


class Mode(IntEnum):
    """Active mode: the low nibble of status byte 0."""

    NONE = 0
    CARTESIAN = 1
    JOINT = 4
    FOLD_OUT = 5
    FOLD_IN = 6


class MessageClass(IntEnum):
    """Message class: bits 7-6 of status byte 0."""

    NONE = 0x00
    WARNING = 0x40
    GENERAL = 0x80
    ERROR = 0xC0


WARNING_TEXT = {
    0: "gripper collision / stuck gripper",
    1: "wrong work area (not allowed to go there)",
    2: "arm folded or fully stretched",
    3: "motor blocked (or weight limit)",
    4: "base motor at maximum rotation",
    5: "moving without input",
    6: "memory buffer full",
}
GENERAL_TEXT = {
    0: "arm folded",
    1: "arm unfolded",
    2: "gripper ready",
    3: "absolute angles measured (ready)",
}
ERROR_TEXT = {
    1: "80C552 I/O error",
    4: "absolute encoder error",
    13: "movement without input",
    15: "movement without input",
}

# Message codes used by name elsewhere.
WARN_GRIPPER_COLLISION = 0
WARN_WRONG_AREA = 1
WARN_STRETCHED = 2
WARN_MOTOR_BLOCKED = 3
WARN_BASE_MAX = 4
GEN_FOLDED = 0
GEN_UNFOLDED = 1
GEN_GRIPPER_READY = 2
GEN_ANGLES_MEASURED = 3


def message_text(msg_class: MessageClass, code: int) -> str:
    """Human-readable meaning of a (class, code) pair (docs/protocol.md, Message codes)."""
    if msg_class == MessageClass.NONE:
        return ""
    table = {
        MessageClass.WARNING: WARNING_TEXT,
        MessageClass.GENERAL: GENERAL_TEXT,
        MessageClass.ERROR: ERROR_TEXT,
    }[msg_class]
    if code in table:
        return table[code]
    kind = msg_class.name.lower()
    return f"unspecified {kind} {code}"


def status_byte(mode: int, msg_class: MessageClass) -> int:
    """Status byte 0 from its two bit fields."""
    return (int(msg_class) & 0xC0) | (int(mode) & 0x0F)


def split_status(byte0: int) -> tuple[int, MessageClass]:
    """(mode nibble, message class) of status byte 0. The mode may be an unknown value."""
    return byte0 & 0x0F, MessageClass(byte0 & 0xC0)


@dataclass(frozen=True)
class StatusFrame:
    """Decoded 0x350.

    Attributes:
        mode: low nibble of byte 0 (see :class:`Mode`; other values are reported as is).
        msg_class: bits 7-6 of byte 0.
        msg_code: byte 1.
        fields: joints 1-3 [0.1 deg] in joint mode, or X, Y, Z [0.022 mm].
    """

    mode: int
    msg_class: MessageClass
    msg_code: int
    fields: tuple[int, int, int]


@dataclass(frozen=True)
class PositionFrame:
    """Decoded 0x360.

    Attributes:
        fields: joints 4-6 [0.1 deg] in joint mode, or yaw, pitch, roll [0.1 deg].
        gripper: gripper opening [0.1 mm].
    """

    fields: tuple[int, int, int]
    gripper: int


def _check(frame_id: int, data: bytes, dlc: int) -> None:
    if len(data) != dlc:
        raise ProtocolError(f"frame 0x{frame_id:03X}: DLC {len(data)}, expected {dlc}")


def encode_status(frame: StatusFrame) -> bytes:
    """Payload of 0x350 (8 bytes)."""
    if not 0 <= frame.msg_code <= 255:
        raise ProtocolError(f"0x350 message code {frame.msg_code} outside 0..255")
    byte0 = status_byte(frame.mode, frame.msg_class)
    return struct.pack(">BBhhh", byte0, frame.msg_code, *_i16(frame.fields, "0x350"))


def decode_status(data: bytes) -> StatusFrame:
    """Decode the payload of 0x350."""
    _check(FrameId.STATUS, data, 8)
    byte0, code, a, b, c = struct.unpack(">BBhhh", data)
    mode, msg_class = split_status(byte0)
    return StatusFrame(mode, msg_class, code, (a, b, c))


def encode_position(frame: PositionFrame) -> bytes:
    """Payload of 0x360 (8 bytes)."""
    return struct.pack(">hhhh", *_i16((*frame.fields, frame.gripper), "0x360"))


def decode_position(data: bytes) -> PositionFrame:
    """Decode the payload of 0x360."""
    _check(FrameId.POSITION, data, 8)
    a, b, c, g = struct.unpack(">hhhh", data)
    return PositionFrame((a, b, c), g)


def _i16(values: tuple[int, ...], where: str) -> tuple[int, ...]:
    out = []
    for v in values:
        iv = int(v)
        if not -32768 <= iv <= 32767:
            raise ProtocolError(f"{where}: field value {iv} does not fit a signed 16-bit field")
        out.append(iv)
    return tuple(out)


@dataclass(frozen=True)
class MoveCommand:
    """A 0x371 or 0x374 move: increments per 20 ms.

    Attributes:
        frame_id: :attr:`FrameId.JOINT` or :attr:`FrameId.CARTESIAN`.
        lift: lift direction (-1, 0, +1).
        axes: joint 1..6 [0.1 deg] or X, Y, Z [0.022 mm], yaw, pitch, roll [0.1 deg].
        gripper: gripper increment [0.1 mm].
    """

    frame_id: FrameId
    lift: int
    axes: tuple[int, int, int, int, int, int]
    gripper: int

    @property
    def is_zero(self) -> bool:
        """True when every increment is zero."""
        return self.lift == 0 and self.gripper == 0 and not any(self.axes)


def move_limits(frame_id: FrameId) -> tuple[int, ...]:
    """Per-byte magnitude limits of a move command: lift, six axes, gripper."""
    if frame_id == FrameId.JOINT:
        return (LIFT_INC_MAX, *([JOINT_INC_MAX] * 6), GRIPPER_INC_MAX)
    if frame_id == FrameId.CARTESIAN:
        return (LIFT_INC_MAX, *([XYZ_INC_MAX] * 3), *([ANGLE_INC_MAX] * 3), GRIPPER_INC_MAX)
    raise ProtocolError(f"0x{int(frame_id):03X} is not a move command")


def encode_move(cmd: MoveCommand, *, strict: bool = True) -> bytes:
    """Payload of a move command (8 signed bytes).

    Args:
        cmd: the command.
        strict: raise on a value beyond its range (else only the int8 range is checked,
            so that tests can send out-of-range values to the simulator).
    """
    values = (cmd.lift, *cmd.axes, cmd.gripper)
    limits = move_limits(cmd.frame_id)
    names = ("lift", "axis 1", "axis 2", "axis 3", "axis 4", "axis 5", "axis 6", "gripper")
    for name, v, lim in zip(names, values, limits, strict=True):
        if not -128 <= v <= 127:
            raise ProtocolError(f"0x{int(cmd.frame_id):03X} {name}: {v} does not fit a signed byte")
        if strict and abs(v) > lim:
            raise ProtocolError(
                f"0x{int(cmd.frame_id):03X} {name}: increment {v} outside -{lim}..{lim}"
            )
    return struct.pack(">8b", *values)


def decode_move(frame_id: int, data: bytes) -> MoveCommand:
    """Decode a 0x371/0x374 payload (values are not clamped here)."""
    fid = FrameId(frame_id)
    if fid not in (FrameId.JOINT, FrameId.CARTESIAN):
        raise ProtocolError(f"0x{frame_id:03X} is not a move command")
    _check(frame_id, data, 8)
    lift, a1, a2, a3, a4, a5, a6, grip = struct.unpack(">8b", data)
    return MoveCommand(fid, lift, (a1, a2, a3, a4, a5, a6), grip)


ZERO_JOINT_MOVE = MoveCommand(FrameId.JOINT, 0, (0, 0, 0, 0, 0, 0), 0)
"""The zero 0x374: enters joint mode and holds the arm still."""


@dataclass(frozen=True)
class Frame:
    """A CAN frame as the cores see it: no bus object, time inside.

    Attributes:
        id: 11-bit identifier.
        data: payload (empty for remote frames and DLC-0 frames).
        remote: remote transmission request (the 0x37F sync).
        t_ns: when it was sent (by the simulator) or received (by the bridge) [ns].
        dlc: data length code; for remote frames the requested length (0 here).
    """

    id: int
    data: bytes = b""
    remote: bool = False
    t_ns: int = 0
    dlc: int = -1

    def __post_init__(self) -> None:
        # Normalise so that equal frames compare equal: plain int id, explicit DLC.
        object.__setattr__(self, "id", int(self.id))
        if self.dlc < 0:
            object.__setattr__(self, "dlc", len(self.data))

    @property
    def length(self) -> int:
        """The data length code."""
        return self.dlc

    def at(self, t_ns: int) -> Frame:
        """The same frame stamped ``t_ns``."""
        return Frame(self.id, self.data, self.remote, t_ns, self.dlc)


def sync_frame(t_ns: int = 0) -> Frame:
    """The arm's 0x37F remote frame."""
    return Frame(FrameId.SYNC, b"", True, t_ns, 0)


def move_frame(cmd: MoveCommand, t_ns: int = 0, *, strict: bool = True) -> Frame:
    """A 0x371/0x374 frame carrying ``cmd``."""
    return Frame(cmd.frame_id, encode_move(cmd, strict=strict), False, t_ns)


def empty_frame(frame_id: FrameId, t_ns: int = 0) -> Frame:
    """A DLC-0 data frame: 0x370 stop, 0x375 fold out, 0x376 fold in."""
    return Frame(frame_id, b"", False, t_ns, 0)
