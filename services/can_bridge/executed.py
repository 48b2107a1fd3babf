"""What the arm executes: the reply it latched at the last sync, as ``JointState`` reports it.

The arm latches one reply per sync window: normally the bridge's own (its frame and the
seq of the velocity command it carried), but another node's reply (the guardian's 0x370)
that reached the bus first in that window is the one the arm executes. The next joint
state reports which (``applied_kind``, ``applied_seq``) and its speed steps
(``applied_velocity``: :mod:`.reports` turns them into SI).
"""

from __future__ import annotations

from typing import NamedTuple

from manus.protocol import Frame, FrameId, decode_move

_KIND = {
    FrameId.JOINT: "joint",
    FrameId.STOP: "stop",
    FrameId.FOLD_IN: "fold_in",
    FrameId.FOLD_OUT: "fold_out",
}
_NO_STEPS = (0, 0, 0, 0, 0, 0, 0, 0)


class Latched(NamedTuple):
    """A reply the arm latched.

    Attributes:
        steps: lift, motors 1..6, gripper [speed steps] (zeros unless a joint move).
        kind: :class:`schemas.state.AppliedKind` (``none`` for an unknown frame).
        seq: the velocity command it carried (-1: none, or another node's).
    """

    steps: tuple[int, ...]
    kind: str
    seq: int


NOTHING = Latched(_NO_STEPS, "none", -1)
"""Before the first reply."""


def latched(frame: Frame, seq: int = -1) -> Latched:
    """The reply ``frame`` as the arm executes it (``seq``: the command it carries)."""
    fid = FrameId(frame.id)
    steps = _NO_STEPS
    if fid == FrameId.JOINT and len(frame.data) == 8:
        mv = decode_move(fid, frame.data)
        steps = (mv.lift, *mv.axes, mv.gripper)
    return Latched(steps, _KIND.get(fid, "none"), seq)
