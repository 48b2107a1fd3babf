"""What a sync is answered with: one frame, and the seq of the command it carries."""

from __future__ import annotations

from manus.protocol import ZERO_JOINT_MOVE, Frame, FrameId, empty_frame, move_frame

Reply = tuple[Frame, int]
"""A frame for the current sync and the seq of the velocity command it carries (-1)."""


def zeros() -> Reply:
    """A zero 0x374: the arm holds still (and stays in joint mode)."""
    return move_frame(ZERO_JOINT_MOVE), -1


def stop() -> Reply:
    """0x370: the arm abandons what it does and waits."""
    return empty_frame(FrameId.STOP), -1
