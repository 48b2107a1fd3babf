"""Velocity commands -> the 0x374 the arm gets, and the freshness rule.

A :class:`schemas.commands.JointVelocityCommand` either carries ``counts`` (already
quantized by the sender: lift, motors 1..6, gripper) which are only range-checked, or
DH joint velocities [rad/s] and a gripper velocity [m/s] which the bridge converts with
the joint map, saturates by one common factor and quantizes (:mod:`manus.quantize`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from manus.errors import ManusError
from manus.protocol import FrameId, MoveCommand, move_limits
from manus.quantize import (
    JOINT_COUNT_MAX,
    Quantizer,
    gripper_counts,
    joint_rates_to_counts,
    saturate,
)
from schemas.commands import JointVelocityCommand

_NAMES = ("lift", "motor 1", "motor 2", "motor 3", "motor 4", "motor 5", "motor 6", "gripper")


class CommandError(ManusError, ValueError):
    """A velocity command the bridge cannot send (out of range, not finite)."""


def to_move(cmd: JointVelocityCommand, quantizer: Quantizer) -> MoveCommand:
    """The joint move (0x374) for ``cmd``.

    Raises:
        CommandError: naming the field, the value and the allowed range.
    """
    if cmd.counts is not None:
        limits = move_limits(FrameId.JOINT)
        for name, v, lim in zip(_NAMES, cmd.counts, limits, strict=True):
            if not -lim <= v <= lim:
                raise CommandError(
                    f"command seq {cmd.seq} from {cmd.source!r}: counts {name} = {v} "
                    f"outside -{lim}..{lim}"
                )
        lift, a1, a2, a3, a4, a5, a6, grip = (int(v) for v in cmd.counts)
        return MoveCommand(FrameId.JOINT, lift, (a1, a2, a3, a4, a5, a6), grip)
    try:
        counts = quantizer(saturate(joint_rates_to_counts(np.asarray(cmd.velocity))))
        grip = gripper_counts(cmd.gripper_velocity)
    except ManusError as exc:
        raise CommandError(f"command seq {cmd.seq} from {cmd.source!r}: {exc}") from exc
    a1, a2, a3, a4, a5, a6 = (int(v) for v in counts)
    assert max(abs(a) for a in (a1, a2, a3, a4, a5, a6)) <= JOINT_COUNT_MAX
    return MoveCommand(FrameId.JOINT, 0, (a1, a2, a3, a4, a5, a6), grip)


@dataclass(frozen=True)
class PendingCommand:
    """The newest valid velocity command.

    Attributes:
        cmd: the command as received.
        rx_ns: when it arrived [ns].
        move: the joint move it becomes.
    """

    cmd: JointVelocityCommand
    rx_ns: int
    move: MoveCommand


def is_fresh(
    pending: PendingCommand,
    *,
    newest_state_seq: int | None,
    max_age_cycles: int,
    sync_ns: int,
    timeout_ns: int,
) -> bool:
    """The freshness rule of docs/architecture.md.

    A command answering a joint state (``ref_seq >= 0``) is fresh if that state is the
    newest published one or at most ``max_age_cycles`` older; one with ``ref_seq = -1``
    if it arrived at most ``timeout_ns`` before the sync at ``sync_ns``.
    """
    ref = pending.cmd.ref_seq
    if ref >= 0:
        return newest_state_seq is not None and 0 <= newest_state_seq - ref <= max_age_cycles
    return 0 <= sync_ns - pending.rx_ns <= timeout_ns
