"""``fold_in`` and ``fold_out`` steps: the arm's own fold, commanded through the bridge."""

from __future__ import annotations

import math

from manus.config import FOLDED_Q_DEG, UNFOLDED_Q_DEG
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmAction, ArmCommand, ArmCommandReply
from schemas.sequencing import StepKind, TaskStep
from schemas.state import BridgePhase, BridgeState
from services.sequencer.actions import Action
from services.sequencer.step import BY_REQUEST, Phase, Step, StepContext, stop_command

FOLD_END = {
    StepKind.FOLD_OUT: [math.radians(v) for v in UNFOLDED_Q_DEG],
    StepKind.FOLD_IN: [math.radians(v) for v in FOLDED_Q_DEG],
}
"""Where a fold leaves the arm (DH joint angles [rad])."""

FOLDING = {StepKind.FOLD_OUT: BridgePhase.FOLDING_OUT, StepKind.FOLD_IN: BridgePhase.FOLDING_IN}
"""The bridge's phase while it folds."""


class FoldStep(Step):
    """``fold_in`` / ``fold_out``: the bridge's fold command, with the deadman of moves
    (``heartbeat_timeout``: the bridge stops the fold when the heartbeats or the
    controller's commands stop); done once ``state/bridge`` has shown the fold
    (``folding_*``) and then ``running``; failed when the bridge stops it (``stopped``). A
    fold cannot be paused half-way (a pause waits for its end); a cancel stops it
    (``stop``, then ``clear``)."""

    @classmethod
    def leaves_arm_at(cls, spec: TaskStep) -> list[float] | None:
        return list(FOLD_END[StepKind(spec.kind)])

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        super().__init__(spec, ctx)
        self.seen_fold = False

    def begin(self) -> list[Action]:
        self.seen_fold = False
        self.ctx.set_deadline(self.ctx.config.fold_timeout_s)
        self.phase = Phase.FOLDING
        cmd = ArmCommand(
            action=self.spec.kind,
            source="sequencer",
            heartbeat_timeout=self.ctx.config.fold_heartbeat_timeout_s,
        )
        return [self.ctx.query(ep.BRIDGE_COMMAND, cmd, ArmCommandReply, wait=True)]

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        if self.phase == Phase.FOLDING:
            return self._on_fold_reply(reply, error)
        if self.phase == Phase.STOPPING:
            # stop answered: clear, so the arm is back in joint mode and ready.
            if (
                isinstance(reply, ArmCommandReply)
                and reply.ok
                and reply.phase == BridgePhase.STOPPED
            ):
                self.phase = Phase.CLEARING
                clear = ArmCommand(action=ArmAction.CLEAR, source="sequencer")
                return [self.ctx.query(ep.BRIDGE_COMMAND, clear, ArmCommandReply, wait=True)]
            return self.ctx.cancelled(f"{BY_REQUEST}; fold stopped")
        if self.phase == Phase.CLEARING:
            return self.ctx.cancelled(f"{BY_REQUEST}; fold stopped")
        return []

    def _on_fold_reply(self, reply: Message | None, error: str) -> list[Action]:
        if not isinstance(reply, ArmCommandReply):
            return self.ctx.fail(f"can_bridge: {error or 'no answer to the fold'}")
        if not reply.ok:
            return self.ctx.fail(f"can_bridge refused {self.spec.kind}: {reply.message}")
        # Done only after a state/bridge in folding_* and then running: a state published
        # before the bridge took the command may still be on its way.
        return []

    def on_bridge_state(self, bs: BridgeState) -> list[Action] | None:
        if self.phase != Phase.FOLDING:
            return None
        if bs.phase == FOLDING[StepKind(self.spec.kind)]:
            self.seen_fold = True
        elif self.seen_fold and bs.phase == BridgePhase.RUNNING:
            return self.ctx.step_done()
        elif self.seen_fold and bs.phase == BridgePhase.STOPPED:
            return self.ctx.fail(f"can_bridge: phase {bs.phase}: {bs.detail}")
        return None

    @property
    def needs_joint_states(self) -> bool:
        return self.phase == Phase.FOLDING  # the fold's deadman echoes them

    def cancel(self) -> list[Action]:
        if self.phase != Phase.FOLDING:
            return self.ctx.cancelled(BY_REQUEST)
        self.phase = Phase.STOPPING
        return [self.ctx.query(ep.BRIDGE_COMMAND, stop_command(), ArmCommandReply, wait=True)]

    def on_deadline(self) -> list[Action]:
        if self.phase != Phase.FOLDING:
            return []
        timeout = self.ctx.config.fold_timeout_s
        return self.ctx.fail(f"the fold did not complete within {timeout:g} s")

    def cleanup(self) -> list[Action]:
        if self.phase != Phase.FOLDING:
            return []
        return [self.ctx.query(ep.BRIDGE_COMMAND, stop_command(), ArmCommandReply)]
