"""Velocity commands -> the 0x374 the arm gets, and the freshness rule.

The CAN edge of the command path: a :class:`schemas.commands.JointVelocityCommand`
carries DH joint velocities [rad/s] and a gripper velocity [m/s], which the bridge turns
into the arm's speed steps (:mod:`manus.quantize`): through the joint map, saturated by
one common factor, quantized. Velocities on the steps (the controller chooses them) come
out exactly as chosen.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from manus.errors import ManusError
from manus.protocol import FrameId, MoveCommand
from manus.quantize import (
    JOINT_COUNT_MAX,
    Quantizer,
    gripper_counts,
    joint_rates_to_counts,
    saturate,
)
from schemas.commands import JointVelocityCommand


class CommandError(ManusError, ValueError):
    """A velocity command the bridge cannot send (out of range, not finite)."""


def to_move(cmd: JointVelocityCommand, quantizer: Quantizer) -> MoveCommand:
    """The joint move (0x374) for ``cmd``.

    Raises:
        CommandError: naming the field, the value and the allowed range.
    """
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
