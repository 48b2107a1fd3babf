"""One fold, from its request to joint mode again (docs/protocol.md, Fold in and fold out).

The bridge drives a fold itself: the fold frame (0x375 out, 0x376 in) at every clean sync
(zeros at a faulty one, or at one its deadman refuses: :mod:`.fold_deadman`) until the arm
reports completion ("arm folded" / "arm unfolded"); then 0x370 at the next sync, then
zero 0x374 until the arm reports joint mode after it. A fold not complete after
``fold_timeout_s`` is the phase machine's arm error (:mod:`.phases`).
"""

from __future__ import annotations

from dataclasses import dataclass

from manus.protocol import GEN_FOLDED, GEN_UNFOLDED, GENERAL_TEXT, FrameId, empty_frame
from services.can_bridge.fold_deadman import FoldDeadman
from services.can_bridge.replies import Reply, stop, zeros

_FRAME = {"fold_out": FrameId.FOLD_OUT, "fold_in": FrameId.FOLD_IN}
_DONE = {"fold_out": GEN_UNFOLDED, "fold_in": GEN_FOLDED}


@dataclass
class Fold:
    """A fold under way (see the module docstring).

    Attributes:
        kind: ``fold_out`` or ``fold_in``.
        start_ns: when it was asked [ns].
        deadman: its deadman (None: asked without one).
        stage: ``folding``, then ``stopping`` (0x370 next), then ``rejoining`` (zeros).
        zero_sent_ns: the sync at which the first zero went out while rejoining [ns].
    """

    kind: str
    start_ns: int
    deadman: FoldDeadman | None = None
    stage: str = "folding"
    zero_sent_ns: int | None = None

    def reply(self, sync_ns: int, clean: bool) -> Reply:
        """The answer to the sync at ``sync_ns`` [ns] whose cycle was ``clean``."""
        if self.stage == "stopping":
            self.stage = "rejoining"
            return stop()
        if self.stage == "rejoining":
            self.zero_sent_ns = sync_ns
            return zeros()
        if not clean:
            return zeros()
        return empty_frame(_FRAME[self.kind]), -1

    def reported(self, code: int) -> str | None:
        """A general message ``code`` of the arm: what changed, in words (None: nothing)."""
        if self.stage != "folding" or code != _DONE[self.kind]:
            return None
        self.stage = "stopping"
        return f"{self.kind}: the arm reports '{GENERAL_TEXT[code]}': 0x370 next"

    def rejoined(self, joint_mode: bool, t_ns: int) -> bool:
        """A status at ``t_ns`` [ns] in ``joint_mode`` completes the fold (after its zeros)."""
        zero = self.zero_sent_ns if self.stage == "rejoining" else None
        return joint_mode and zero is not None and t_ns > zero
