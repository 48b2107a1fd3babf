"""The bridge's phase machine: why the phase changes and what each sync is answered with.

Phases (:data:`schemas.state.BRIDGE_PHASES`) and the reply to each current 0x37F:

- ``waiting_power_up``: one 0x370 at the first sync (stops a motion latched by an earlier
  session), then nothing until "absolute angles measured" (or ``power_up_timeout_ms`` of
  cycles without it, or the arm already reports a move mode).
- ``entering_joint_mode``: zero 0x374 until a 0x350 after it reports joint mode.
- ``initialising``: the ``init_moves`` of motors 4-6 (docs/protocol.md, Start-up), one per
  clean sync, then zeros; then ``running``. Joint states are valid from then on.
- ``running``: the newest fresh velocity command, else zeros (the core decides).
- ``resync``: zeros until ``clean_cycles_to_resume`` clean cycles.
- ``folding_out`` / ``folding_in``: 0x375 / 0x376 at every clean sync (zeros at a faulty
  one) until the arm reports "arm unfolded" / "arm folded"; then 0x370, then zero 0x374
  until joint mode, then ``running`` with detail "fold_out complete" / "fold_in complete".
  A fold with a deadman (:mod:`.fold_deadman`) also answers zeros at a sync the deadman
  refuses, and ends in ``stopped`` when it gives up (:meth:`PhaseMachine.stop_fold`).
- ``stopped``, ``arm_error``: 0x370 at every sync until ``clear``.
- ``estopped``: zeros at the first sync, 0x370 at every later one, until released.
- shutting down (any phase): zeros, then 0x370, then phase ``shutdown`` and silence.

The machine never publishes: it sets :attr:`PhaseMachine.changed`, and the core publishes
the bridge state after each input that changed something.
"""

from __future__ import annotations

from collections.abc import Callable

from manus.protocol import (
    ERROR_TEXT,
    GEN_ANGLES_MEASURED,
    ZERO_JOINT_MOVE,
    Frame,
    FrameId,
    MessageClass,
    Mode,
    MoveCommand,
    StatusFrame,
    empty_frame,
    move_frame,
)
from schemas.commands import ArmCommand, EStop
from services.can_bridge.config import BridgeConfig
from services.can_bridge.cycle import Cycle
from services.can_bridge.fold import Fold
from services.can_bridge.fold_deadman import FoldDeadman
from services.can_bridge.health import Health
from services.can_bridge.replies import Reply, stop, zeros
from services.can_bridge.reports import mode_name

MS = 1_000_000
START_UP = ("opening", "waiting_power_up", "entering_joint_mode", "initialising")
"""Phases before the first ``running``: positions are not valid yet."""
_MOVE_MODES = (Mode.JOINT, Mode.FOLD_IN, Mode.FOLD_OUT)


class PhaseMachine:
    """The phases (see the module docstring).

    Args:
        config: bridge settings.
        health: the counters (resyncs are counted here).
    """

    def __init__(self, config: BridgeConfig, health: Health) -> None:
        self.config = config
        self.health = health
        self.phase = "opening"
        self.detail = ""
        self.estop = False
        self.changed = False
        """Something worth a bridge-state report happened (the core clears it)."""
        self.powered = False
        """The arm reported "absolute angles measured" (or is known to be up)."""
        self.initialised = False
        """The start-up moves are done: joint 4-6 encoders report true values."""
        self.start_ns: int | None = None
        self._first_status_ns: int | None = None
        self._leftover_stop_sent = False
        self._zero_sent_ns: int | None = None
        self._init_step = 0
        self._estop_zero_sent = False
        self._fold: Fold | None = None
        self._clean_run = 0
        self._silent = False
        self._shutdown_stage = 0  # 1: zeros next, 2: 0x370 next, 3: done

    @property
    def positions_valid(self) -> bool:
        """Joint states of this phase carry meaningful positions (given a move mode)."""
        return self.initialised and self.phase not in START_UP

    @property
    def finished(self) -> bool:
        """Shutdown is complete: zeros and 0x370 have been sent."""
        return self._shutdown_stage == 3

    @property
    def fold_deadman(self) -> FoldDeadman | None:
        """The deadman of a fold still driving the arm (None: none, or no fold)."""
        fold = self._fold
        return fold.deadman if fold is not None and fold.stage == "folding" else None

    # -- events ---------------------------------------------------------------------------

    def start(self, now_ns: int) -> None:
        """The bus is open."""
        if self.phase == "opening":
            self.start_ns = now_ns
            self._set("waiting_power_up", "bus open: waiting for the arm")

    def frame_seen(self) -> None:
        """Any frame from the arm arrived."""
        if self._silent:
            self._silent = False
            self._note("frames from the arm again")

    def on_status(self, st: StatusFrame, t_ns: int, cycle: Cycle) -> None:
        """A well-formed 0x350 arrived at ``t_ns``; a wrong mode marks ``cycle`` faulty."""
        if self._first_status_ns is None:
            self._first_status_ns = t_ns
        if st.msg_class == MessageClass.ERROR:
            self._arm_error(st.msg_code)
        elif st.msg_class == MessageClass.GENERAL:
            self._general(st.msg_code)
        if st.mode in _MOVE_MODES:
            self.powered = True
        if self.phase == "waiting_power_up" and self.powered:
            self._set("entering_joint_mode", "arm ready: zero 0x374")
        joint = st.mode == Mode.JOINT
        if self.phase == "entering_joint_mode":
            if joint and self._zero_sent_ns is not None and t_ns > self._zero_sent_ns:
                if self.initialised:
                    self._set("running", "joint mode")
                else:
                    self._init_step = 0
                    self._set("initialising", "joint mode: start-up moves")
        elif self.phase in ("running", "resync") and not joint:
            cycle.faults.append(f"arm reports mode {mode_name(st.mode)}, expected joint")
        fold = self._fold
        if fold is not None and fold.rejoined(joint, t_ns):
            self._fold = None
            self._set("running", f"{fold.kind} complete")

    def on_fault(self, reason: str) -> None:
        """The current or last cycle was not clean."""
        self._clean_run = 0
        if self.phase == "running":
            self.health.resyncs += 1
            self._set("resync", reason)
        elif self.phase == "resync":
            self._note(reason)

    def on_sync(self, sync_ns: int, clean: bool, command: Callable[[], Reply]) -> Reply | None:
        """The reply to a current sync arrived at ``sync_ns`` (None: stay silent).

        Args:
            sync_ns: the sync's arrival time [ns].
            clean: the cycle it ends was clean.
            command: the running phase's reply (fresh command or zeros), called only then.
        """
        if self._shutdown_stage:
            return self._shutdown_reply()
        self._power_up_timeout(sync_ns)
        if self.phase == "running":
            return command() if clean else zeros()
        reply = _PHASE_REPLIES.get(self.phase, PhaseMachine._stop_reply)
        return reply(self, sync_ns, clean)

    def on_estop(self, msg: EStop) -> None:
        """Latch or release the e-stop."""
        who = f"{msg.source}: {msg.reason}" if msg.reason else msg.source
        if msg.engaged and not self.estop:
            self.estop, self._estop_zero_sent, self._fold = True, False, None
            self._set("estopped", f"e-stop engaged by {who}")
        elif not msg.engaged and self.estop:
            self.estop = False
            self._rejoin(f"e-stop released by {who}")

    def on_arm_command(self, req: ArmCommand, rx_ns: int) -> tuple[bool, str]:
        """``stop``, ``fold_in`` / ``fold_out`` or ``clear``: (accepted, what happens)."""
        who = req.source or "?"
        if self._shutdown_stage or self.phase == "shutdown":
            return False, "the bridge is shutting down"
        if req.action == "stop":
            return self._request_stop(who)
        if req.action in ("fold_in", "fold_out"):
            return self._request_fold(req.action, rx_ns, who, req.heartbeat_timeout)
        return self._request_clear(who)

    def on_tick(self, now_ns: int, last_frame_ns: int | None) -> None:
        """Timeouts: silence of the arm (``last_frame_ns``: its last frame), endless folds."""
        if self.start_ns is None:
            return
        silent_ns = now_ns - (last_frame_ns if last_frame_ns is not None else self.start_ns)
        if not self._silent and silent_ns > self.config.silence_timeout_ms * MS:
            self._silent = True
            self.on_fault(f"no frames from the arm for {silent_ns / 1e6:.0f} ms")
            if self.phase != "resync":
                self._note(f"no frames from the arm for {silent_ns / 1e6:.0f} ms")
        fold = self._fold
        if fold is not None and now_ns - fold.start_ns > self.config.fold_timeout_s * 1e9:
            self._fold = None
            self._set(
                "arm_error", f"{fold.kind} not complete after {self.config.fold_timeout_s:g} s"
            )

    def stop_fold(self, why: str) -> None:
        """The fold's deadman gave up: ``stopped`` (0x370 at every sync until ``clear``)."""
        fold = self._fold
        if fold is None:
            return
        self._fold = None
        self._set("stopped", f"{fold.kind} stopped: {why}")

    def begin_shutdown(self) -> None:
        """Zeros at the next sync, 0x370 at the one after, then silence."""
        if self._shutdown_stage == 0:
            self._shutdown_stage = 1
            self._note("shutting down: zeros then 0x370 at the next syncs")

    def force_shutdown(self) -> list[Frame]:
        """The shutdown frames not sent yet, to send now without a sync."""
        if self._shutdown_stage == 3:
            return []
        frames = [move_frame(ZERO_JOINT_MOVE), empty_frame(FrameId.STOP)]
        frames = frames[max(0, self._shutdown_stage - 1) :]
        self._shutdown_stage = 3
        self._set("shutdown", "zeros and 0x370 sent without sync")
        return frames

    # -- internals ------------------------------------------------------------------------

    def _request_stop(self, who: str) -> tuple[bool, str]:
        if self.phase in ("estopped", "arm_error", "stopped"):
            return True, f"already stopped ({self.phase})"
        self._fold = None
        self._set("stopped", f"stop requested by {who}")
        return True, "0x370 at every sync until clear"

    def _request_fold(self, action: str, rx_ns: int, who: str, timeout: float) -> tuple[bool, str]:
        if self.estop:
            return False, "e-stop latched: release it first"
        if self.phase == "arm_error":
            return False, f"arm error ({self.detail}): clear it first"
        if self.phase in START_UP:
            return False, f"the bridge is not ready yet (phase {self.phase})"
        self._fold = Fold(action, rx_ns)
        deadman = ""
        if timeout > 0.0:
            self._fold.deadman = FoldDeadman(timeout, self.config.fold_missed_cycles_to_stop)
            deadman = (
                f" while the heartbeat (timeout {timeout * 1000:.0f} ms) and the controller last"
            )
        self._set(f"folding_{action[5:]}", f"{action} requested by {who}")
        return True, f"{action} held until the arm reports completion{deadman}"

    def _request_clear(self, who: str) -> tuple[bool, str]:
        phase = self.phase
        if self.estop:
            return False, "e-stop latched: publish EStop(engaged=false) to release it"
        if phase in ("folding_in", "folding_out"):
            return False, f"{phase} in progress: send stop first"
        if phase in ("stopped", "arm_error"):
            self._rejoin(f"cleared by {who}")
            return True, f"re-entering joint mode (phase {self.phase})"
        return True, f"nothing to clear (phase {phase})"

    # Replies to a sync by phase (``running`` is answered in :meth:`on_sync`); each takes
    # the sync's arrival time [ns] and whether its cycle was clean.

    def _power_up_reply(self, sync_ns: int, clean: bool) -> Reply | None:
        if self._leftover_stop_sent:
            return None
        self._leftover_stop_sent = True
        return stop()

    def _joint_mode_reply(self, sync_ns: int, clean: bool) -> Reply:
        self._zero_sent_ns = sync_ns
        return zeros()

    def _resync_reply(self, sync_ns: int, clean: bool) -> Reply:
        self._clean_run = self._clean_run + 1 if clean else 0
        if self._clean_run >= self.config.clean_cycles_to_resume:
            self._set("running", f"in step again after {self._clean_run} clean cycles")
        return zeros()

    def _estop_reply(self, sync_ns: int, clean: bool) -> Reply:
        if not self._estop_zero_sent:
            self._estop_zero_sent = True
            return zeros()
        return stop()

    def _stop_reply(self, sync_ns: int, clean: bool) -> Reply:
        return stop()  # stopped, arm_error

    def _general(self, code: int) -> None:
        if code == GEN_ANGLES_MEASURED:
            self.powered = True
        note = self._fold.reported(code) if self._fold is not None else None
        if note is not None:
            self._note(note)

    def _arm_error(self, code: int) -> None:
        if self.phase in ("arm_error", "shutdown"):
            return
        text = f"arm error {code}: {ERROR_TEXT.get(code, f'unspecified error {code}')}"
        self._fold = None
        if self.phase == "estopped":
            self._note(text)
        else:
            self._set("arm_error", text)

    def _power_up_timeout(self, sync_ns: int) -> None:
        first = self._first_status_ns
        if self.phase != "waiting_power_up" or self.powered or first is None:
            return
        if sync_ns - first >= self.config.power_up_timeout_ms * MS:
            self.powered = True
            self._set(
                "entering_joint_mode",
                f"no 'absolute angles measured' within {self.config.power_up_timeout_ms:g} "
                "ms: assuming the arm is up; zero 0x374",
            )

    def _init_reply(self, sync_ns: int, clean: bool) -> Reply:
        moves = self.config.init_moves
        if not clean or self._init_step > len(moves):
            return zeros()
        if self._init_step == len(moves):
            self.initialised = True
            self._set("running", "initialised: commands reach the arm")
            return zeros()
        m = moves[self._init_step]
        self._init_step += 1
        return move_frame(MoveCommand(FrameId.JOINT, 0, (0, 0, 0, m, m, m), 0)), -1

    def _fold_reply(self, sync_ns: int, clean: bool) -> Reply:
        assert self._fold is not None
        return self._fold.reply(sync_ns, clean)

    def _shutdown_reply(self) -> Reply | None:
        if self._shutdown_stage == 1:
            self._shutdown_stage = 2
            return zeros()
        if self._shutdown_stage == 2:
            self._shutdown_stage = 3
            self._set("shutdown", "zeros and 0x370 sent")
            return stop()
        return None

    def _rejoin(self, why: str) -> None:
        self._zero_sent_ns = None
        if self.powered:
            self._set("entering_joint_mode", f"{why}: zero 0x374")
        else:
            self._set("waiting_power_up", f"{why}: waiting for the arm")

    def _set(self, phase: str, detail: str) -> None:
        self.phase, self.detail, self.changed = phase, detail, True

    def _note(self, detail: str) -> None:
        self.detail, self.changed = detail, True


_PHASE_REPLIES: dict[str, Callable[[PhaseMachine, int, bool], Reply | None]] = {
    "opening": PhaseMachine._power_up_reply,
    "waiting_power_up": PhaseMachine._power_up_reply,
    "entering_joint_mode": PhaseMachine._joint_mode_reply,
    "initialising": PhaseMachine._init_reply,
    "resync": PhaseMachine._resync_reply,
    "folding_out": PhaseMachine._fold_reply,
    "folding_in": PhaseMachine._fold_reply,
    "estopped": PhaseMachine._estop_reply,
}
"""What a sync is answered with in each phase but ``running`` (others: 0x370)."""
