"""What the arm makes of a frame from the PC: a reply it can latch, or a reason to ignore it.

docs/protocol.md, Replies from the PC: 0x370 stop, 0x375 fold out and 0x376 fold in carry no
data (DLC 0); 0x371 Cartesian and 0x374 joint moves carry eight signed bytes. An increment
beyond its range is clamped to the range and reported as warning 7 ("unspecified warning 7:
increment out of range, clamped" - the real arm's reaction is undocumented). A DLC-0 frame
with the id of 0x350 or 0x360 is an acknowledgement some PC programs send: accepted and
ignored.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from manus.protocol import FrameId, MoveCommand, decode_move, move_limits

WARN_CLAMPED = 7
"""Warning code raised when a reply's increment was out of range and clamped."""

Ignored = Literal["ack", "bad", "unknown"]
"""Why a frame is not a reply: acknowledgement, wrong DLC or remote, unknown id."""

_EMPTY = (FrameId.STOP, FrameId.FOLD_OUT, FrameId.FOLD_IN)
_MOVES = (FrameId.JOINT, FrameId.CARTESIAN)


@dataclass(frozen=True)
class Reply:
    """A well-formed reply.

    Attributes:
        kind: :attr:`FrameId.STOP`, ``JOINT``, ``CARTESIAN``, ``FOLD_OUT`` or ``FOLD_IN``.
        move: the (clamped) increments of a move, None otherwise.
        clamped: some increment was out of range and has been clamped.
    """

    kind: FrameId
    move: MoveCommand | None = None
    clamped: bool = False


def clamp_move(cmd: MoveCommand) -> tuple[MoveCommand, bool]:
    """``cmd`` with every increment clamped to its range, and whether any was."""
    values = (cmd.lift, *cmd.axes, cmd.gripper)
    limits = move_limits(cmd.frame_id)
    clamped = tuple(max(-lim, min(lim, v)) for v, lim in zip(values, limits, strict=True))
    if clamped == values:
        return cmd, False
    lift, a1, a2, a3, a4, a5, a6, grip = clamped
    return MoveCommand(cmd.frame_id, lift, (a1, a2, a3, a4, a5, a6), grip), True


def classify(frame_id: int, data: bytes, remote: bool, dlc: int) -> Reply | Ignored:
    """Interpret one frame from the PC (no timing: the core judges the window)."""
    if frame_id in (FrameId.STATUS, FrameId.POSITION):
        return "ack" if dlc == 0 and not remote else "bad"
    if frame_id not in (*_EMPTY, *_MOVES):
        return "unknown"
    fid = FrameId(frame_id)
    if remote:
        return "bad"
    if fid in _EMPTY:
        return Reply(fid) if dlc == 0 else "bad"
    if dlc != 8 or len(data) != 8:
        return "bad"
    cmd, clamped = clamp_move(decode_move(fid, data))
    return Reply(fid, cmd, clamped)
