"""The CAN bridge core: the PC side of the Manus protocol, deterministic, time from inputs.

Inputs are method calls carrying frames and messages with their times; outputs are
:class:`Outputs` (CAN frames to send now, in order, then messages to publish). The shell
sends the frames first, so no publication ever delays a reply.

Phases (:data:`schemas.state.BRIDGE_PHASES`) and what each sync (0x37F) is answered with:

- ``waiting_power_up``: one 0x370 at the first sync (stops a motion latched by an earlier
  session), then silence until "absolute angles measured" (or ``power_up_timeout_ms``,
  or the arm already reports a move mode).
- ``entering_joint_mode``: zero 0x374 until a 0x350 after it reports joint mode.
- ``initialising``: the ``init_moves`` of motors 4-6 (thesis 4.2.1), one per clean sync,
  then zeros; then ``running``. Joint states are marked valid from then on.
- ``running``: the newest *fresh* velocity command, else zeros (counted stale).
- ``resync``: after any missing, duplicated, off-slot or garbled frame: zeros until
  ``clean_cycles_to_resume`` clean cycles (:mod:`services.can_bridge.cycle`).
- ``folding_out`` / ``folding_in``: 0x375 / 0x376 at every clean sync (zeros at a faulty
  one) until the arm reports "arm unfolded" / "arm folded"; then 0x370, then zero 0x374
  until joint mode, then ``running`` with detail "fold_out complete" / "fold_in complete".
- ``stopped``, ``arm_error``: 0x370 at every sync until ``clear``.
- ``estopped``: zeros at the first sync, 0x370 at every later one, until released.
- shutting down: zeros, then 0x370, then phase ``shutdown`` and silence.

Only a current sync is answered: one processed more than ``sync_max_age_ms`` after its
arrival sat in a buffer, and a second sync less than one reply window after an answered
one is never answered (one reply per window).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from manus.protocol import (
    ERROR_TEXT,
    GEN_ANGLES_MEASURED,
    GEN_FOLDED,
    GEN_UNFOLDED,
    GENERAL_TEXT,
    ZERO_JOINT_MOVE,
    Frame,
    FrameId,
    MessageClass,
    Mode,
    MoveCommand,
    decode_move,
    decode_position,
    decode_status,
    empty_frame,
    move_frame,
)
from manus.quantize import Quantizer, RoundingQuantizer
from schemas.base import Message
from schemas.commands import ArmCommand, ArmCommandReply, EStop, JointVelocityCommand
from schemas.state import CanFrame
from services.can_bridge.commands import CommandError, PendingCommand, is_fresh, to_move
from services.can_bridge.config import BridgeConfig
from services.can_bridge.cycle import Cycle, CycleAssembler, Placement
from services.can_bridge.health import WINDOW_NS, Health
from services.can_bridge.reports import arm_status, encoder_fields, joint_state, mode_name

__all__ = ["BridgeConfig", "BridgeCore", "Outputs"]

MS = 1_000_000
START_UP = ("opening", "waiting_power_up", "entering_joint_mode", "initialising")
_FOLD_FRAME = {"fold_out": FrameId.FOLD_OUT, "fold_in": FrameId.FOLD_IN}
_FOLD_DONE = {"fold_out": GEN_UNFOLDED, "fold_in": GEN_FOLDED}
_APPLIED_KIND = {
    FrameId.JOINT: "joint",
    FrameId.STOP: "stop",
    FrameId.FOLD_IN: "fold_in",
    FrameId.FOLD_OUT: "fold_out",
}
_NO_COUNTS = (0, 0, 0, 0, 0, 0, 0, 0)


@dataclass
class Outputs:
    """What one input makes the bridge do.

    Attributes:
        frames: CAN frames to send now, in order.
        messages: (key suffix such as ``state/joints``, message) to publish after sending.
    """

    frames: list[Frame] = field(default_factory=list)
    messages: list[tuple[str, Message]] = field(default_factory=list)


@dataclass
class _Fold:
    kind: str  # "fold_out" | "fold_in"
    start_ns: int
    stage: str = "folding"  # then "stopping" (0x370 next), "rejoining" (zero 0x374)
    zero_sent_ns: int | None = None


class BridgeCore:
    """The bridge's logic (see the module docstring).

    Args:
        config: settings.
        quantizer: turns float motor counts into integers for commands without
            ``counts`` (default: :class:`manus.quantize.RoundingQuantizer`).
    """

    def __init__(self, config: BridgeConfig | None = None, quantizer: Quantizer | None = None):
        self.config = cfg = config or BridgeConfig()
        self.quantizer: Quantizer = quantizer or RoundingQuantizer()
        self.phase = "opening"
        self.detail = ""
        self.estop = False
        self.health = Health()
        self.assembler = CycleAssembler(round(cfg.slot_tolerance_ms * MS))
        self.powered = False
        """The arm reported "absolute angles measured" (or is known to be up)."""
        self.initialised = False
        """The start-up moves are done: joint 4-6 encoders report true values."""
        self.newest_state_seq: int | None = None
        self.pending: PendingCommand | None = None
        self._seq = {"state/joints": 0, "state/status": 0, "state/bridge": 0, "tx": 0, "rx": 0}
        self._start_ns: int | None = None
        self._first_status_ns: int | None = None
        self._leftover_stop_sent = False
        self._zero_sent_ns: int | None = None  # a zero 0x374 sent while entering joint mode
        self._init_step = 0
        self._estop_zero_sent = False
        self._fold: _Fold | None = None
        self._clean_run = 0
        self._faulted_cycle = -1
        self._last_reply_sync_ns: int | None = None
        self._last_arm_ns: int | None = None
        self._silence_reported = False
        self._applied: tuple[tuple[int, ...], str, int] = (_NO_COUNTS, "none", -1)
        self._status: tuple[int, Frame] | None = None  # (cycle index, 0x350) in its slot
        self._ref: tuple[tuple[int, ...], int] | None = None  # plausible fields, cycle
        self._rejected: tuple[tuple[int, ...], int] | None = None
        self._shutdown_stage = 0  # 1: zeros next, 2: 0x370 next, 3: done

    # -- inputs ---------------------------------------------------------------------------

    def start(self, now_ns: int) -> Outputs:
        """The bus is open: wait for the arm's power-up messages."""
        out = Outputs()
        if self.phase == "opening":
            self._start_ns = now_ns
            self._set_phase("waiting_power_up", "bus open: waiting for the arm", now_ns, out)
        return out

    def on_frame(self, frame: Frame, now_ns: int) -> Outputs:
        """A frame from the arm, stamped with its arrival time; ``now_ns`` is the time
        it is processed (both [ns], same clock)."""
        out = self.start(now_ns) if self.phase == "opening" else Outputs()
        self._seq["rx"] += 1
        out.messages.append(("can/rx", _can_frame(frame, frame.t_ns, self._seq["rx"] - 1)))
        self._last_arm_ns = frame.t_ns
        if self._silence_reported:
            self._silence_reported = False
            self._note("frames from the arm again", now_ns, out)
        p = self.assembler.place(frame)
        self._count(p, now_ns, out)
        if p.kind == "unknown" or p.cycle is None:
            return out
        if frame.id == FrameId.STATUS and p.kind == "status" and not p.duplicate:
            self._on_status(frame, p, now_ns, out)
        elif frame.id == FrameId.POSITION and p.in_slot:
            self._on_position(frame, p.cycle, now_ns, out)
        if p.cycle.faults and self.assembler.anchor_ns is not None:
            self._fault(p.cycle, now_ns, out)
        if frame.id == FrameId.SYNC and not p.duplicate:
            self._on_sync(frame, p, now_ns, out)
        return out

    def on_command(self, cmd: JointVelocityCommand, rx_ns: int) -> Outputs:
        """A velocity command from the controller (kept until a newer one arrives)."""
        out = Outputs()
        try:
            self.pending = PendingCommand(cmd, rx_ns, to_move(cmd, self.quantizer))
        except CommandError as exc:
            self.pending = None
            self.health.bad_payloads += 1
            self._note(f"refused: {exc}", rx_ns, out)
        return out

    def on_estop(self, msg: EStop, rx_ns: int) -> Outputs:
        """E-stop: latch (zeros at the next sync, then 0x370) or release."""
        out = Outputs()
        who = f"{msg.source}: {msg.reason}" if msg.reason else msg.source
        if msg.engaged and not self.estop:
            self.estop, self._estop_zero_sent, self._fold = True, False, None
            self._set_phase("estopped", f"e-stop engaged by {who}", rx_ns, out)
        elif not msg.engaged and self.estop:
            self.estop = False
            self._rejoin(f"e-stop released by {who}", rx_ns, out)
        return out

    def on_arm_command(self, req: ArmCommand, rx_ns: int) -> tuple[ArmCommandReply, Outputs]:
        """``stop``, ``fold_in`` / ``fold_out`` or ``clear`` (the bridge/command queryable)."""
        out = Outputs()
        ok, message = self._arm_command(req, rx_ns, out)
        return ArmCommandReply(ok=ok, phase=self.phase, message=message), out

    def on_tick(self, now_ns: int) -> Outputs:
        """Timeouts: silence of the arm, folds that never end (call at least every 20 ms)."""
        out = Outputs()
        if self._start_ns is None:
            return out
        last = self._last_arm_ns if self._last_arm_ns is not None else self._start_ns
        silent_ns = now_ns - last
        if not self._silence_reported and silent_ns > self.config.silence_timeout_ms * MS:
            self._silence_reported = True
            self._clean_run = 0
            what = f"no frames from the arm for {silent_ns / 1e6:.0f} ms"
            if self.phase == "running":
                self.health.resyncs += 1
                self._set_phase("resync", what, now_ns, out)
            else:
                self._note(what, now_ns, out)
        fold = self._fold
        if fold is not None and now_ns - fold.start_ns > self.config.fold_timeout_s * 1e9:
            self._fold = None
            text = f"{fold.kind} not complete after {self.config.fold_timeout_s:g} s"
            self._set_phase("arm_error", text, now_ns, out)
        return out

    def on_sent(self, sync_rx_ns: int, sent_ns: int) -> None:
        """The shell sent the reply to the sync received at ``sync_rx_ns`` at ``sent_ns``:
        record the true reply latency (the core assumed it was sent when decided)."""
        self.health.reply_sent(sync_rx_ns, sent_ns)

    def begin_shutdown(self, now_ns: int) -> Outputs:
        """Stop for good: zeros at the next sync, 0x370 at the one after, then silence."""
        out = Outputs()
        if self._shutdown_stage == 0:
            self._shutdown_stage = 1
            self._note("shutting down: zeros then 0x370 at the next syncs", now_ns, out)
        return out

    def force_shutdown(self, now_ns: int) -> Outputs:
        """Send zeros and 0x370 now, without waiting for syncs (no sync came in time)."""
        out = Outputs()
        if self._shutdown_stage < 3:
            stages = [move_frame(ZERO_JOINT_MOVE), empty_frame(FrameId.STOP)]
            for f in stages[max(0, self._shutdown_stage - 1) :]:
                self._emit(f.at(now_ns), now_ns, out)
            self._shutdown_stage = 3
            self._set_phase("shutdown", "zeros and 0x370 sent without sync", now_ns, out)
        return out

    @property
    def finished(self) -> bool:
        """Shutdown is complete: zeros and 0x370 have been sent."""
        return self._shutdown_stage == 3

    # -- frames ---------------------------------------------------------------------------

    def _count(self, p: Placement, now_ns: int, out: Outputs) -> None:
        h = self.health
        h.garbled_frames += p.kind in ("garbled", "unknown")
        h.duplicate_frames += p.duplicate
        h.dropped_frames += p.skipped_frames
        for c in p.closed:
            h.dropped_frames += c.missing
            complete = c.status is not None and c.position is not None and c.sync is not None
            h.cycles += complete
            if not c.clean and self.assembler.anchor_ns is not None and c.index > 0:
                self._fault(c, now_ns, out)

    def _on_status(self, frame: Frame, p: Placement, now_ns: int, out: Outputs) -> None:
        st = decode_status(frame.data)
        cycle = p.cycle
        assert cycle is not None
        self._seq["state/status"] += 1
        seq = self._seq["state/status"] - 1
        out.messages.append(("state/status", arm_status(st, stamp_ns=frame.t_ns, seq=seq)))
        if self._first_status_ns is None:
            self._first_status_ns = frame.t_ns
        self._status = (cycle.index, frame) if p.in_slot else None
        if st.msg_class == MessageClass.ERROR:
            self._arm_error(st.msg_code, now_ns, out)
        elif st.msg_class == MessageClass.GENERAL:
            self._general(st.msg_code, now_ns, out)
        if not self.powered and st.mode in (Mode.JOINT, Mode.FOLD_IN, Mode.FOLD_OUT):
            self.powered = True
        if self.phase == "waiting_power_up" and self.powered:
            self._set_phase("entering_joint_mode", "arm ready: zero 0x374", now_ns, out)
        self._mode_seen(st.mode, frame.t_ns, cycle, now_ns, out)

    def _general(self, code: int, now_ns: int, out: Outputs) -> None:
        if code == GEN_ANGLES_MEASURED:
            self.powered = True
        fold = self._fold
        if fold is not None and fold.stage == "folding" and code == _FOLD_DONE[fold.kind]:
            fold.stage = "stopping"
            said = GENERAL_TEXT[code]
            self._note(f"{fold.kind}: the arm reports '{said}': 0x370 next", now_ns, out)

    def _arm_error(self, code: int, now_ns: int, out: Outputs) -> None:
        text = f"arm error {code}: {ERROR_TEXT.get(code, f'unspecified error {code}')}"
        if self.phase in ("arm_error", "shutdown"):
            return
        self._fold = None
        if self.phase == "estopped":
            self._note(text, now_ns, out)
            return
        self._set_phase("arm_error", text, now_ns, out)

    def _mode_seen(self, mode: int, t_ns: int, cycle: Cycle, now_ns: int, out: Outputs) -> None:
        joint = mode == Mode.JOINT
        if self.phase == "entering_joint_mode":
            if joint and self._zero_sent_ns is not None and t_ns > self._zero_sent_ns:
                if self.initialised:
                    self._set_phase("running", "joint mode", now_ns, out)
                else:
                    self._init_step = 0
                    self._set_phase("initialising", "joint mode: start-up moves", now_ns, out)
        elif self.phase in ("running", "resync") and not joint:
            cycle.faults.append(f"arm reports mode {mode_name(mode)}, expected joint")
        fold = self._fold
        if (
            fold is not None
            and fold.stage == "rejoining"
            and joint
            and fold.zero_sent_ns is not None
            and t_ns > fold.zero_sent_ns
        ):
            self._fold = None
            self._set_phase("running", f"{fold.kind} complete", now_ns, out)

    def _on_position(self, frame: Frame, cycle: Cycle, now_ns: int, out: Outputs) -> None:
        if self._status is None or self._status[0] != cycle.index or cycle.faults:
            return
        st = decode_status(self._status[1].data)
        pos = decode_position(frame.data)
        if not self._plausible(encoder_fields(st, pos), cycle):
            return
        applied, kind, applied_seq = self._applied
        valid = self.initialised and self.phase not in START_UP
        valid = valid and st.mode in (Mode.JOINT, Mode.FOLD_IN, Mode.FOLD_OUT)
        seq = self._seq["state/joints"]
        self._seq["state/joints"] += 1
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
        out.messages.insert(0, ("state/joints", js))

    def _plausible(self, fields: tuple[int, ...], cycle: Cycle) -> bool:
        """Position fields may move at most ``max_field_step`` per cycle from the last
        accepted ones; two consecutive cycles that agree with each other re-base."""
        if self.phase in START_UP or not self.initialised:
            self._ref, self._rejected = None, None
            return True
        step = self.config.max_field_step
        ref, rejected = self._ref, self._rejected
        if ref is None or _near(fields, ref[0], step * (cycle.index - ref[1])):
            self._ref, self._rejected = (fields, cycle.index), None
            return True
        if rejected is not None and _near(fields, rejected[0], step * (cycle.index - rejected[1])):
            self._ref, self._rejected = (fields, cycle.index), None
            return True
        self._rejected = (fields, cycle.index)
        self.health.garbled_frames += 1
        cycle.faults.append("position fields jumped further than the arm can move")
        return False

    def _fault(self, cycle: Cycle, now_ns: int, out: Outputs) -> None:
        if cycle.index == self._faulted_cycle and cycle.faults:
            return
        self._faulted_cycle = cycle.index
        self._clean_run = 0
        reason = cycle.faults[-1] if cycle.faults else "cycle incomplete"
        if self.phase == "running":
            self.health.resyncs += 1
            self._set_phase("resync", reason, now_ns, out)
        elif self.phase == "resync":
            self._note(reason, now_ns, out)

    # -- the sync -------------------------------------------------------------------------

    def _on_sync(self, frame: Frame, p: Placement, now_ns: int, out: Outputs) -> None:
        cfg = self.config
        if now_ns - frame.t_ns > cfg.sync_max_age_ms * MS:
            self.health.buffered_syncs += 1
            self._publish_state(now_ns, out)
            return
        last = self._last_reply_sync_ns
        if last is not None and frame.t_ns - last < WINDOW_NS:
            return
        if p.in_slot and self.assembler.last_sync_period_ns is not None:
            self.health.period(self.assembler.last_sync_period_ns)
        clean = bool(p.closed) and p.closed[-1].clean and p.closed[-1].sync is frame
        self._check_power_up_timeout(frame.t_ns, now_ns, out)
        reply = self._reply(frame.t_ns, clean, now_ns, out)
        if reply is not None:
            frame_out, cmd_seq = reply
            self._last_reply_sync_ns = frame.t_ns
            self._emit(frame_out.at(now_ns), now_ns, out, cmd_seq)
            self.health.replies += 1
            self.health.reply_sent(frame.t_ns, now_ns)
        self._publish_state(now_ns, out)

    def _check_power_up_timeout(self, t_ns: int, now_ns: int, out: Outputs) -> None:
        first = self._first_status_ns
        if self.phase != "waiting_power_up" or self.powered or first is None:
            return
        if t_ns - first >= self.config.power_up_timeout_ms * MS:
            self.powered = True
            text = (
                f"no 'absolute angles measured' within {self.config.power_up_timeout_ms:g} ms: "
                "assuming the arm is up; zero 0x374"
            )
            self._set_phase("entering_joint_mode", text, now_ns, out)

    def _reply(
        self, sync_ns: int, clean: bool, now_ns: int, out: Outputs
    ) -> tuple[Frame, int] | None:
        """The one frame for this sync and the velocity command seq it carries (-1)."""
        zeros = (move_frame(ZERO_JOINT_MOVE), -1)
        stop = (empty_frame(FrameId.STOP), -1)
        if self._shutdown_stage:
            return self._shutdown_reply(now_ns, out)
        phase = self.phase
        if phase in ("opening", "waiting_power_up"):
            if self._leftover_stop_sent:
                return None
            self._leftover_stop_sent = True
            return stop
        if phase == "entering_joint_mode":
            self._zero_sent_ns = sync_ns
            return zeros
        if phase == "initialising":
            return self._init_reply(clean, now_ns, out)
        if phase == "running":
            return self._command_reply(sync_ns, clean)
        if phase == "resync":
            self._clean_run = self._clean_run + 1 if clean else 0
            if self._clean_run >= self.config.clean_cycles_to_resume:
                text = f"in step again after {self._clean_run} clean cycles"
                self._set_phase("running", text, now_ns, out)
            return zeros
        if phase in ("folding_out", "folding_in"):
            return self._fold_reply(sync_ns, clean, now_ns, out)
        if phase == "estopped" and not self._estop_zero_sent:
            self._estop_zero_sent = True
            return zeros
        return stop  # stopped, arm_error, estopped

    def _init_reply(self, clean: bool, now_ns: int, out: Outputs) -> tuple[Frame, int]:
        moves = self.config.init_moves
        if not clean or self._init_step > len(moves):
            return move_frame(ZERO_JOINT_MOVE), -1
        if self._init_step == len(moves):
            self.initialised = True
            self._ref = None
            self._set_phase("running", "initialised: commands reach the arm", now_ns, out)
            return move_frame(ZERO_JOINT_MOVE), -1
        m = moves[self._init_step]
        self._init_step += 1
        return move_frame(MoveCommand(FrameId.JOINT, 0, (0, 0, 0, m, m, m), 0)), -1

    def _command_reply(self, sync_ns: int, clean: bool) -> tuple[Frame, int]:
        pending = self.pending
        cfg = self.config
        fresh = pending is not None and is_fresh(
            pending,
            newest_state_seq=self.newest_state_seq,
            max_age_cycles=cfg.command_max_age_cycles,
            sync_ns=sync_ns,
            timeout_ns=round(cfg.command_timeout_ms * MS),
        )
        if clean and fresh and pending is not None:
            return move_frame(pending.move), pending.cmd.seq
        self.health.stale_commands += clean
        return move_frame(ZERO_JOINT_MOVE), -1

    def _fold_reply(
        self, sync_ns: int, clean: bool, now_ns: int, out: Outputs
    ) -> tuple[Frame, int]:
        fold = self._fold
        assert fold is not None
        if fold.stage == "stopping":
            fold.stage = "rejoining"
            return empty_frame(FrameId.STOP), -1
        if fold.stage == "rejoining" or not clean:
            if fold.stage == "rejoining":
                fold.zero_sent_ns = sync_ns
            return move_frame(ZERO_JOINT_MOVE), -1
        return empty_frame(_FOLD_FRAME[fold.kind]), -1

    def _shutdown_reply(self, now_ns: int, out: Outputs) -> tuple[Frame, int] | None:
        stage = self._shutdown_stage
        if stage == 1:
            self._shutdown_stage = 2
            return move_frame(ZERO_JOINT_MOVE), -1
        if stage == 2:
            self._shutdown_stage = 3
            self._set_phase("shutdown", "zeros and 0x370 sent", now_ns, out)
            return empty_frame(FrameId.STOP), -1
        return None

    def _emit(self, frame: Frame, now_ns: int, out: Outputs, cmd_seq: int = -1) -> None:
        out.frames.append(frame)
        self._seq["tx"] += 1
        out.messages.append(("can/tx", _can_frame(frame, now_ns, self._seq["tx"] - 1)))
        fid = FrameId(frame.id)
        if fid == FrameId.JOINT:
            mv = decode_move(fid, frame.data)
            counts = (mv.lift, *mv.axes, mv.gripper)
        else:
            counts = _NO_COUNTS
        self._applied = (counts, _APPLIED_KIND.get(fid, "none"), cmd_seq)

    # -- arm commands ---------------------------------------------------------------------

    def _arm_command(self, req: ArmCommand, rx_ns: int, out: Outputs) -> tuple[bool, str]:
        phase, who = self.phase, req.source or "?"
        if self._shutdown_stage or phase == "shutdown":
            return False, "the bridge is shutting down"
        if req.action == "stop":
            if phase in ("estopped", "arm_error", "stopped"):
                return True, f"already stopped ({phase})"
            self._fold = None
            self._set_phase("stopped", f"stop requested by {who}", rx_ns, out)
            return True, "0x370 at every sync until clear"
        if req.action in ("fold_in", "fold_out"):
            if self.estop:
                return False, "e-stop latched: release it first"
            if phase == "arm_error":
                return False, f"arm error ({self.detail}): clear it first"
            if phase in START_UP:
                return False, f"the bridge is not ready yet (phase {phase})"
            self._fold = _Fold(req.action, rx_ns)
            self._set_phase(
                f"folding_{req.action[5:]}", f"{req.action} requested by {who}", rx_ns, out
            )
            return True, f"{req.action} held until the arm reports completion"
        # clear
        if self.estop:
            return False, "e-stop latched: publish EStop(engaged=false) to release it"
        if phase in ("folding_in", "folding_out"):
            return False, f"{phase} in progress: send stop first"
        if phase in ("stopped", "arm_error"):
            self._rejoin(f"cleared by {who}", rx_ns, out)
            return True, f"re-entering joint mode (phase {self.phase})"
        return True, f"nothing to clear (phase {phase})"

    def _rejoin(self, why: str, now_ns: int, out: Outputs) -> None:
        self._zero_sent_ns = None
        if self.powered:
            self._set_phase("entering_joint_mode", f"{why}: zero 0x374", now_ns, out)
        else:
            self._set_phase("waiting_power_up", f"{why}: waiting for the arm", now_ns, out)

    # -- reports --------------------------------------------------------------------------

    def _set_phase(self, phase: str, detail: str, now_ns: int, out: Outputs) -> None:
        self.phase, self.detail = phase, detail
        self._publish_state(now_ns, out)

    def _note(self, detail: str, now_ns: int, out: Outputs) -> None:
        self.detail = detail
        self._publish_state(now_ns, out)

    def _publish_state(self, now_ns: int, out: Outputs) -> None:
        seq = self._seq["state/bridge"]
        self._seq["state/bridge"] += 1
        state = self.health.state(
            stamp_ns=now_ns, seq=seq, phase=self.phase, estop=self.estop, detail=self.detail
        )
        out.messages.append(("state/bridge", state))


def _near(a: tuple[int, ...], b: tuple[int, ...], limit: int) -> bool:
    return all(abs(x - y) <= limit for x, y in zip(a, b, strict=True))


def _can_frame(frame: Frame, stamp_ns: int, seq: int) -> CanFrame:
    return CanFrame(
        stamp_ns=stamp_ns,
        seq=seq,
        id=frame.id & 0x7FF,
        data=frame.data,
        remote=frame.remote,
        dlc=min(frame.dlc, 8),
    )
