"""The CAN bridge core: the PC side of the Manus protocol, deterministic, time from inputs.

Inputs are method calls carrying frames and messages with their times; outputs are
:class:`Outputs` (CAN frames to send now, in order, then messages to publish, the joint
state first). The shell sends the frames first, so no publication ever delays a reply.

Per frame from the arm: :mod:`services.can_bridge.cycle` puts it into its cycle;
a well-formed 0x350 becomes an ``ArmStatus`` and feeds the phase machine
(:mod:`services.can_bridge.phases`); a 0x360 that completes a clean pair becomes a
``JointState`` at once; a fault of the cycle (missing, duplicated, out-of-order, garbled
frame, implausible jump) suppresses the joint state and sends the bridge to ``resync``;
a current 0x37F gets exactly one reply, chosen by the phase. In ``running`` that is the
newest velocity command if it is fresh (:func:`services.can_bridge.commands.is_fresh`),
else zeros.

Only a current sync is answered: one processed more than ``sync_max_age_ms`` after its
arrival sat in a buffer, and a second sync less than one reply window after an answered
one is never answered (one reply per window).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from manus.deadman import Echo, tied_to, token_gone
from manus.protocol import (
    REPLY_IDS,
    Frame,
    FrameId,
    Mode,
    decode_position,
    decode_status,
    move_frame,
)
from manus.quantize import Quantizer, RoundingQuantizer
from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmCommand, ArmCommandReply, EStop, JointVelocityCommand
from schemas.control import Heartbeat
from schemas.liveliness import TokenGone
from services.can_bridge.commands import CommandError, PendingCommand, is_fresh, to_move
from services.can_bridge.config import BridgeConfig
from services.can_bridge.cycle import Cycle, CycleAssembler, Placement
from services.can_bridge.executed import NOTHING, latched
from services.can_bridge.health import WINDOW_NS, Health
from services.can_bridge.phases import MS, PhaseMachine
from services.can_bridge.plausible import FieldCheck
from services.can_bridge.replies import Reply, zeros
from services.can_bridge.reports import arm_status, can_frame, encoder_fields, joint_state

__all__ = ["BridgeConfig", "BridgeCore", "Outputs"]


@dataclass
class Outputs:
    """What one input makes the bridge do.

    Attributes:
        frames: CAN frames to send now, in order.
        messages: (key suffix such as ``state/joints``, message) to publish after sending.
    """

    frames: list[Frame] = field(default_factory=list)
    messages: list[tuple[str, Message]] = field(default_factory=list)


class BridgeCore:
    """The bridge's logic (see the module docstring).

    Args:
        config: settings.
        quantizer: turns the commands' velocities into the arm's speed steps (default:
            :class:`manus.quantize.RoundingQuantizer`; exact for velocities on the steps).
    """

    def __init__(self, config: BridgeConfig | None = None, quantizer: Quantizer | None = None):
        self.config = cfg = config or BridgeConfig()
        self.quantizer: Quantizer = quantizer or RoundingQuantizer()
        self.health = Health()
        self.phases = PhaseMachine(cfg, self.health)
        self.assembler = CycleAssembler(round(cfg.slot_tolerance_ms * MS))
        self.newest_state_seq: int | None = None
        """Seq of the newest joint state published (None before the first)."""
        self.pending: PendingCommand | None = None
        """The newest valid velocity command."""
        self._seq = {ep.JOINTS: 0, ep.STATUS: 0, ep.BRIDGE_STATE: 0, ep.CAN_TX: 0, ep.CAN_RX: 0}
        self._faulted_cycle = -1
        self._last_reply_sync_ns: int | None = None
        self._last_reply_sent_ns: int | None = None
        self._last_sync_ns: int | None = None
        self._last_arm_ns: int | None = None
        self._applied = NOTHING  # what the arm latched at the last sync (:mod:`.executed`)
        self._status: tuple[int, Frame] | None = None  # (cycle index, accepted 0x350)
        self.fields = FieldCheck(cfg.max_field_step)
        """The plausibility of the position fields (:mod:`.plausible`)."""
        self._echo = Echo()  # the newest heartbeat's echo and its sender
        self._state_cycle = -1  # index of the cycle of the newest joint state
        self._report_ns = 0  # stamp of the newest bridge state (kept monotonic)

    @property
    def phase(self) -> str:
        """The current phase (:data:`schemas.state.BRIDGE_PHASES`)."""
        return self.phases.phase

    @property
    def detail(self) -> str:
        """The last notable event, in words."""
        return self.phases.detail

    @property
    def finished(self) -> bool:
        """Shutdown is complete: zeros and 0x370 have been sent."""
        return self.phases.finished

    # -- inputs ---------------------------------------------------------------------------

    def start(self, now_ns: int) -> Outputs:
        """The bus is open: wait for the arm's power-up messages."""
        out = Outputs()
        self.phases.start(now_ns)
        self._report(now_ns, out)
        return out

    def on_frame(self, frame: Frame, now_ns: int) -> Outputs:
        """A frame from the arm, stamped with its arrival time; ``now_ns`` is the time
        it is processed (both [ns], same clock)."""
        out = Outputs()
        self.phases.start(now_ns)
        self._seq[ep.CAN_RX] += 1
        out.messages.append((ep.CAN_RX, can_frame(frame, frame.t_ns, self._seq[ep.CAN_RX] - 1)))
        if frame.id in REPLY_IDS and not frame.remote:
            self._other_node(frame)
            self._report(now_ns, out)
            return out
        self._last_arm_ns = frame.t_ns
        self.phases.frame_seen()
        p = self.assembler.place(frame)
        self._count(p)
        cycle = p.cycle
        if cycle is not None:
            if p.kind == "status" and not p.duplicate:
                self._on_status(frame, p, cycle, out)
            elif p.kind == "position" and p.accepted:
                self._on_position(frame, cycle, out, now_ns)
            if cycle.faults and self.assembler.anchor_ns is not None:
                self._fault(cycle)
            if frame.id == FrameId.SYNC and not p.duplicate:
                self._on_sync(frame, p, now_ns, out)
        self._report(now_ns, out, force=frame.id == FrameId.SYNC)
        return out

    def on_command(self, cmd: JointVelocityCommand, rx_ns: int) -> Outputs:
        """A velocity command from the controller (kept until a newer one arrives)."""
        out = Outputs()
        try:
            self.pending = PendingCommand(cmd, rx_ns, to_move(cmd, self.quantizer))
        except CommandError as exc:
            self.pending = None
            self.health.bad_payloads += 1
            self.phases.detail, self.phases.changed = f"refused: {exc}", True
        self._report(rx_ns, out)
        return out

    def on_bad_payload(self) -> None:
        """A bus message to the bridge failed to decode (the shell's node refused it):
        counted in ``BridgeState.bad_payloads``, published with the next state."""
        self.health.bad_payloads += 1

    def on_estop(self, msg: EStop, rx_ns: int) -> Outputs:
        """E-stop: latch (zeros at the next sync, then 0x370) or release."""
        out = Outputs()
        self.phases.on_estop(msg)
        self._report(rx_ns, out)
        return out

    def on_heartbeat(self, hb: Heartbeat, rx_ns: int) -> Outputs:
        """The supervisor's deadman heartbeat: the newest joint state it echoes is judged
        at the next joint state of a fold with a deadman (:mod:`.fold_deadman`)."""
        self._echo.heard(hb.ref_stamp_ns, hb.source)
        return Outputs()

    def on_token_gone(self, service: str, rx_ns: int) -> Outputs:
        """The token ``alive/<service>`` vanished (its process died or its link was cut): a
        fold with a deadman whose heartbeats that service sent stops at once (phase
        ``stopped``, 0x370 at the next sync; :func:`manus.deadman.tied_to`); the
        controller's: its newest command is dropped (zeros at the next sync, not the
        command of a controller that can no longer stop it). Always published as a
        :class:`~schemas.liveliness.TokenGone`."""
        out = Outputs()
        deadman = self.phases.fold_deadman
        stopped = ""
        if deadman is not None and tied_to(
            service, self._echo.source, deadman.since_ns, self._echo.ns
        ):
            self.phases.stop_fold(token_gone(service))
            stopped = self.phases.detail
        if service == ep.Service.CONTROLLER and self.pending is not None:
            self.pending = None
            stopped = "the controller's liveliness token went: its command dropped, zeros"
        after = -1 if self.newest_state_seq is None else self.newest_state_seq
        out.messages.append(
            (ep.BRIDGE_TOKEN_GONE, TokenGone(service=service, after_seq=after, stopped=stopped))
        )
        self._report(rx_ns, out)
        return out

    def on_arm_command(self, req: ArmCommand, rx_ns: int) -> tuple[ArmCommandReply, Outputs]:
        """``stop``, ``fold_in`` / ``fold_out`` or ``clear`` (the bridge/command queryable)."""
        out = Outputs()
        ok, message = self.phases.on_arm_command(req, rx_ns)
        self._report(rx_ns, out)
        return ArmCommandReply(ok=ok, phase=self.phase, message=message), out

    def on_tick(self, now_ns: int) -> Outputs:
        """Timeouts: silence of the arm, folds that never end (call at least every 20 ms)."""
        out = Outputs()
        self.phases.on_tick(now_ns, self._last_arm_ns)
        self._report(now_ns, out)
        return out

    def on_sent(self, sync_rx_ns: int, sent_ns: int) -> None:
        """The shell sent the reply to the sync received at ``sync_rx_ns`` at ``sent_ns``:
        record the true reply latency (the core assumed it was sent when decided)."""
        self.health.reply_sent(sync_rx_ns, sent_ns)

    def begin_shutdown(self, now_ns: int) -> Outputs:
        """Stop for good: zeros at the next sync, 0x370 at the one after, then silence."""
        out = Outputs()
        self.phases.begin_shutdown()
        self._report(now_ns, out)
        return out

    def force_shutdown(self, now_ns: int) -> Outputs:
        """Send the zeros and 0x370 not sent yet now, without waiting for a sync."""
        out = Outputs()
        for frame in self.phases.force_shutdown():
            self._emit(frame.at(now_ns), now_ns, out)
        self._report(now_ns, out)
        return out

    # -- frames ---------------------------------------------------------------------------

    def _other_node(self, frame: Frame) -> None:
        """A reply to the arm sent by another PC-side node (the guardian's 0x370): counted.
        If it reached the bus within the window of the last sync and before the bridge's
        own reply to that sync, the arm latched it, not ours: ``applied`` says so."""
        self.health.other_node_frames += 1
        sync, sent = self._last_sync_ns, self._last_reply_sent_ns
        if sync is None or not 0 <= frame.t_ns - sync < WINDOW_NS:
            return
        if self._last_reply_sync_ns == sync and sent is not None and frame.t_ns >= sent:
            return  # ours came first: theirs is ignored by the arm
        if self._last_reply_sync_ns == sync:
            self.health.preempted_replies += 1
            self.phases.detail, self.phases.changed = "another node's reply preempted ours", True
        self._applied = latched(frame)

    def _count(self, p: Placement) -> None:
        h = self.health
        h.garbled_frames += p.kind in ("garbled", "unknown")
        h.duplicate_frames += p.duplicate
        h.late_frames += p.late
        h.dropped_frames += p.skipped_frames
        for c in p.closed:
            h.dropped_frames += c.missing
            h.cycles += c.status is not None and c.position is not None and c.sync is not None
            if not c.clean and self.assembler.anchor_ns is not None and c.index > 0:
                self._fault(c)

    def _fault(self, cycle: Cycle) -> None:
        if cycle.index == self._faulted_cycle:
            return
        self._faulted_cycle = cycle.index
        self.phases.on_fault(cycle.faults[-1] if cycle.faults else "cycle incomplete")

    def _on_status(self, frame: Frame, p: Placement, cycle: Cycle, out: Outputs) -> None:
        st = decode_status(frame.data)
        seq = self._seq[ep.STATUS]
        self._seq[ep.STATUS] += 1
        out.messages.append((ep.STATUS, arm_status(st, stamp_ns=frame.t_ns, seq=seq)))
        self._status = (cycle.index, frame) if p.accepted else None
        self.phases.on_status(st, frame.t_ns, cycle)

    def _on_position(self, frame: Frame, cycle: Cycle, out: Outputs, now_ns: int) -> None:
        if self._status is None or self._status[0] != cycle.index or cycle.faults:
            return
        if now_ns - frame.t_ns > self.config.sync_max_age_ms * MS:
            # It sat in a buffer (the bridge was stopped): a controller fed old states
            # would carry on its path as if the arm had followed; the gap stops it instead.
            self.health.buffered_states += 1
            return
        st = decode_status(self._status[1].data)
        pos = decode_position(frame.data)
        if not self._plausible(encoder_fields(st, pos), cycle):
            return
        applied, kind, applied_seq = self._applied
        valid = self.phases.positions_valid and st.mode in (Mode.JOINT, Mode.FOLD_IN, Mode.FOLD_OUT)
        seq = self._seq[ep.JOINTS]
        self._seq[ep.JOINTS] += 1
        js = joint_state(
            st,
            pos,
            stamp_ns=frame.t_ns,
            seq=seq,
            valid=valid,
            applied=applied,
            applied_kind=kind,
            applied_seq=applied_seq,
        )
        self.newest_state_seq = seq
        self._state_cycle = cycle.index
        out.messages.insert(0, (ep.JOINTS, js))
        deadman = self.phases.fold_deadman
        lost = deadman.on_joint_state(frame.t_ns, seq, self._echo.ns) if deadman else None
        if lost is not None:
            self.phases.stop_fold(lost)

    def _plausible(self, fields: tuple[int, ...], cycle: Cycle) -> bool:
        """Position fields may move at most ``max_field_step`` per cycle (:mod:`.plausible`)."""
        if not self.phases.positions_valid:
            self.fields.reset()
            return True
        if self.fields.accept(fields, cycle.index):
            return True
        self.health.garbled_frames += 1
        cycle.faults.append("position fields jumped further than the arm can move")
        return False

    # -- the sync -------------------------------------------------------------------------

    def _on_sync(self, frame: Frame, p: Placement, now_ns: int, out: Outputs) -> None:
        self._last_sync_ns = frame.t_ns
        if now_ns - frame.t_ns > self.config.sync_max_age_ms * MS:
            self.health.buffered_syncs += 1
            return
        last = self._last_reply_sync_ns
        if last is not None and frame.t_ns - last < WINDOW_NS:
            return
        if p.accepted and self.assembler.last_sync_period_ns is not None:
            self.health.period(self.assembler.last_sync_period_ns)
        clean = bool(p.closed) and p.closed[-1].clean and p.closed[-1].sync is frame
        deadman = self.phases.fold_deadman
        if deadman is not None and clean:
            go, why = deadman.on_sync(
                self._state_cycle == p.closed[-1].index, self._fresh(frame.t_ns)
            )
            if why is not None:
                self.phases.stop_fold(why)
            clean = go  # a refused sync is answered as a faulty one: zeros, the arm pauses
        reply = self.phases.on_sync(frame.t_ns, clean, lambda: self._command_reply(frame.t_ns))
        if reply is not None:
            self._last_reply_sync_ns = frame.t_ns
            self._last_reply_sent_ns = now_ns
            self._emit(reply[0].at(now_ns), now_ns, out, reply[1])
            self.health.replies += 1
            self.health.reply_sent(frame.t_ns, now_ns)

    def _fresh(self, sync_ns: int) -> bool:
        """The newest command is fresh for the sync at ``sync_ns`` (the freshness rule)."""
        pending = self.pending
        cfg = self.config
        return pending is not None and is_fresh(
            pending,
            newest_state_seq=self.newest_state_seq,
            max_age_cycles=cfg.command_max_age_cycles,
            sync_ns=sync_ns,
            timeout_ns=round(cfg.command_timeout_ms * MS),
        )

    def _command_reply(self, sync_ns: int) -> Reply:
        """The newest command if it is fresh, else zeros (counted stale)."""
        pending = self.pending
        if pending is not None and self._fresh(sync_ns):
            return move_frame(pending.move), pending.cmd.seq
        self.health.stale_commands += 1
        return zeros()

    def _emit(self, frame: Frame, now_ns: int, out: Outputs, cmd_seq: int = -1) -> None:
        out.frames.append(frame)
        self._seq[ep.CAN_TX] += 1
        out.messages.append((ep.CAN_TX, can_frame(frame, now_ns, self._seq[ep.CAN_TX] - 1)))
        self._applied = latched(frame, cmd_seq)

    # -- reports --------------------------------------------------------------------------

    def _report(self, now_ns: int, out: Outputs, *, force: bool = False) -> None:
        """Publish the bridge state if something changed (or ``force``: every sync)."""
        if not (force or self.phases.changed):
            return
        self.phases.changed = False
        seq = self._seq[ep.BRIDGE_STATE]
        self._seq[ep.BRIDGE_STATE] += 1
        # Stamps never go back (inputs of two threads carry times taken before the lock),
        # so a state published late is known as older by its seq and its stamp.
        self._report_ns = max(self._report_ns, now_ns)
        ph = self.phases
        state = self.health.state(
            stamp_ns=self._report_ns, seq=seq, phase=ph.phase, estop=ph.estop, detail=ph.detail
        )
        out.messages.append((ep.BRIDGE_STATE, state))
