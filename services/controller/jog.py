"""Live control as a command source: the jog stream's intake, its safety, its cycle.

:class:`JogSource` holds the newest :class:`~schemas.jog.JogCommand` (checked and turned
into SI speeds by :func:`~services.controller.jog_command.resolve`), the speed level, and
the reference of the motion (:class:`~services.controller.jog_law.JogRun`); the core asks
it for each cycle's command. It ranks above the goals: a moving jog preempts every goal
(cause ``user_took_over``) and goals are refused while it moves. Its safety rules:

- **Deadman**: a command is as old as the newest joint state the controller had when it
  arrived (judged on the bridge's stamps, so a replay judges the same); at a joint state
  more than ``timeout_ms`` after that, the jog stops (zeros).
- **Zero command** (all speeds zero, or ``kind = "stop"``): stops at once (the core also
  corrects the command of the current cycle if it moved).
- **Bad command** (not finite, outside -1..1 or the caps, an unknown kind, frame or
  units, values that do not belong to the kind) or one that arrives while nothing may
  move (no joint state yet, an arm error, the bridge not ``running``): refused, counted,
  and the arm stops. Not while the bridge only resyncs (a few cycles of zeros after a
  faulty one): a command then is taken and acts from the first joint state after it, so
  a user holding a key jogs on; a resync longer than ``max_outage_ms`` stops the jog.
- After any stop but a zero command (deadman, refusal, an arm error, a bridge phase, a
  long gap), nothing moves again until the user releases the controls: a zero command
  re-arms the jog.
- **Speed levels** 1..``levels``: unitless deflections are scaled to the caps times
  level / levels, SI speeds are limited to that (refused above the top level's caps).

Each command taken is published at once as a :class:`~schemas.jog.JogTaken` (after which
joint state it came: the regression check feeds it there).
"""

from __future__ import annotations

import numpy as np

from manus.quantize import gripper_counts
from schemas import endpoints as ep
from schemas.control import CommandSourceKind, EndCause, GoalAck, Refusal, ResultStatus
from schemas.jog import JOGGING, USER_TOOK_OVER, JogCommand, JogLevel, JogTaken
from schemas.state import JointState
from services.controller.command_source import (
    Command,
    CommandSource,
    Cycle,
    End,
    Host,
    Sent,
    SourceAnswer,
    SourceInput,
)
from services.controller.estimator import DriveEstimator
from services.controller.guard import Verdict
from services.controller.jog_command import JogError, resolve
from services.controller.jog_config import JogConfig
from services.controller.jog_law import JogRun, JogTarget, jog_counts, predicted_dh
from services.controller.jog_limits import FREE, Slowdown
from services.controller.jog_state import guard_limit, jog_reason, jog_state
from services.controller.outbox import Output

_ZERO = np.zeros(6, dtype=np.int64)


class JogSource(CommandSource):
    """The jog as the controller runs it (see the module docstring).

    Args:
        host: the core holding it.
    """

    KIND = CommandSourceKind.JOG
    PRIORITY = 10
    STOPS_AT_ONCE = True
    BUSY = f"{JOGGING} (controller/jog_state): goals wait until the jog stops"

    def __init__(self, host: Host) -> None:
        super().__init__(host)
        self.config = config = host.config
        self.cfg: JogConfig = config.jog
        self.level = self.cfg.default_level
        self.target: JogTarget | None = None
        """The speeds being executed (None: none)."""
        self.ref_ns: int | None = 0
        """Stamp [ns] of the newest joint state before the newest command (deadman); None:
        it came while the bridge resynced, and is as old as the first joint state after."""
        self.command_seq = -1
        self.stopped: End | None = None
        """Why the jog stopped (None: armed); a zero command re-arms it."""
        self.cause: EndCause | None = None
        """Why it last stopped (None: never)."""
        self.counted = False
        """This stop has counted its refusal (moving commands held back count once)."""
        self.refused = 0
        self.deadman_stops = 0
        self.run: JogRun | None = None
        self.limit = FREE
        """The jog law's slow-down this cycle (motors' speed cap, a zone)."""
        self.guard: Slowdown | None = None
        """What the collision guard did to this cycle's command (None: nothing)."""
        self.announce = False
        """Publish a JogState at the next joint state (a change to show)."""
        self.sender = ""
        """Who sent the newest command (``JogCommand.source``)."""
        self._caps = {n: self.cfg.caps(n) for n in range(1, self.cfg.levels + 1)}
        self._seq = 0

    @property
    def engaged(self) -> bool:
        """A non-zero jog command is being executed."""
        return self.target is not None

    @property
    def reason(self) -> str:
        """The state's words (:func:`.jog_state.jog_reason`): stable while the state is."""
        return jog_reason(self.stopped, self.cause, self.limits())

    # -- the stream --------------------------------------------------------------------------

    def on_command(self, cmd: JogCommand) -> Output:
        """A command of the stream: taken (it acts from the next joint state), or refused
        and counted (the arm stops)."""
        js = self.host.last_js
        stamp = js.stamp_ns if js is not None and js.valid else None
        refused = self.host.admission(self)
        self.sender = cmd.source
        waits = refused is not None and refused.transient and stamp is not None
        self._receive(cmd, stamp, None if refused is None or waits else refused.reason, waits)
        return [self._taken(cmd)]

    def on_bad_command(self, error: str) -> Output:
        """A jog payload that does not decode (the node refused it): counted, the arm stops."""
        self._refuse(f"bad jog payload: {error}")
        return [self._taken(None, error)]

    def set_level(self, req: JogLevel) -> GoalAck:
        """Set the speed level (shown in the next JogState)."""
        level = req.level
        if not 1 <= level <= self.cfg.levels:
            reason = f"level {level!r} outside 1..{self.cfg.levels}"
            return GoalAck(accepted=False, goal_id="", reason=reason, refusal=Refusal.INVALID)
        self.level, self.announce = level, True
        return GoalAck(accepted=True, goal_id="")

    INPUTS = (SourceInput(ep.JOG, on_command, bad=on_bad_command),)
    ANSWERS = (SourceAnswer(ep.JOG_LEVEL, set_level),)

    def preemption(self) -> End | None:
        """A moving jog ends every goal: the user took over."""
        if not self.engaged:
            return None
        why = f"{USER_TOOK_OVER}: jog command from {self.sender!r}"
        return End(ResultStatus.PREEMPTED, EndCause.USER_TOOK_OVER, why)

    def stop(self, end: End) -> None:
        """A fault stops a moving jog until the controls are released."""
        if self.engaged:
            self._latch(end)

    # -- the cycle ---------------------------------------------------------------------------

    def command(self, cycle: Cycle) -> Command | None:
        """The deadman, then this cycle's counts while a jog moves."""
        if self.target is None:
            return None
        self._deadman(cycle.js)
        if not self.engaged:  # the deadman stopped it
            return None
        counts, grip = self._counts(cycle.joints)
        if cycle.gap:  # nothing is known of the cycle(s) missed: stop, start afresh
            counts, grip, self.run = _ZERO, 0, None
        return Command(counts, grip)

    def guarded(self, command: Command, verdict: Verdict) -> None:
        """The collision guard slowed or stopped the jog: a limit in its state."""
        self.guard = guard_limit(verdict)

    def reports(self, sent: Sent) -> Output:
        """The JogState while a jog runs, and once after each change."""
        show = self.target is not None or self.announce
        if not show:
            return []
        self.announce = False
        limits = self.limits()
        reason = jog_reason(self.stopped, self.cause, limits) if limits or self.cause else ""
        self.guard = None  # the guard's verdict holds for this cycle only
        msg = jog_state(
            sent.js,
            self._seq,
            target=self.target,
            stopped=self.stopped,
            cause=self.cause,
            limits=limits,
            reason=reason,
            level=(self.level, self.cfg.levels),
            caps=self._caps[self.level],
            counts=(self.command_seq, self.refused, self.deadman_stops),
            arm=self.config.arm,
        )
        self._seq += 1
        return [(ep.JOG_STATE, msg)]

    def limits(self) -> list[Slowdown]:
        """What holds the running jog back now: the level's caps, the jog law's limit,
        the collision guard (empty when it does not run)."""
        if self.target is None:
            return []
        found = list(self.target.caps)
        if self.limit.scale < 1.0:
            found.append(self.limit)
        if self.guard is not None:
            found.append(self.guard)
        return found

    # -- internals ---------------------------------------------------------------------------

    def _taken(self, cmd: JogCommand | None, error: str = "") -> tuple[str, JogTaken]:
        js = self.host.last_js
        after = js.seq if js is not None else -1
        return ep.JOG_TAKEN, JogTaken(after_seq=after, command=cmd, error=error)

    def _receive(
        self, cmd: JogCommand, stamp_ns: int | None, not_ready: str | None, waits: bool = False
    ) -> None:
        """``stamp_ns``: the newest joint state's stamp (None: none yet); ``not_ready``:
        why nothing may move now (None: it may); ``waits``: the bridge resyncs, so a moving
        command is taken but acts from the first joint state after (the bridge sends zeros
        meanwhile, and a resync that outlasts ``max_outage_ms`` stops every source)."""
        what = f"jog command seq {cmd.seq} from {cmd.source!r} refused"
        try:
            target = resolve(cmd, self.level, self.cfg)
        except JogError as exc:
            self._refuse(f"{what}: {exc}")
            return
        if target is not None and (stamp_ns is None or not_ready is not None):
            why = not_ready or "no valid joint state yet (is the bridge running?)"
            self._hold_back(End(ResultStatus.ABORTED, EndCause.NOT_READY, f"{what}: {why}"))
            return
        self.command_seq = cmd.seq
        if target is None or stamp_ns is None:
            if self.target is not None or self.stopped is not None:
                self.cause, self.announce = EndCause.RELEASED, True
            self.target, self.run, self.stopped = None, None, None
            return
        if self.stopped is not None:
            self._hold_back(None)  # still held: the user must release the controls first
            return
        if self.target is None:
            self.announce = True
        self.target, self.ref_ns = target, None if waits else stamp_ns

    def _refuse(self, why: str) -> None:
        """Count a bad command and stop (a stop already in force stays as it is)."""
        self.refused += 1
        self.announce = True
        if self.stopped is None:
            self._latch(End(ResultStatus.ABORTED, EndCause.BAD_COMMAND, why), counted=True)

    def _hold_back(self, end: End | None) -> None:
        """A moving command that may not move the arm: the jog stops with ``end`` if it
        runs; the stop counts one refusal, however many commands it holds back."""
        if self.stopped is None and end is not None:
            self._latch(end)
        if not self.counted:
            self.refused += 1
            self.counted = True
        self.announce = True

    def _latch(self, end: End, *, counted: bool = False) -> None:
        """Stop (zeros from the next cycle) until a zero command re-arms the jog."""
        self.target, self.run = None, None
        self.stopped, self.cause, self.counted = end, end.cause, counted
        self.announce = True

    def _deadman(self, js: JointState) -> None:
        """Stop if the newest command is older than the timeout at this joint state."""
        if self.target is None:
            return
        if self.ref_ns is None:
            self.ref_ns = js.stamp_ns
        age = js.stamp_ns - self.ref_ns
        if age > self.cfg.timeout_ns:
            self.deadman_stops += 1
            why = (
                f"deadman: no jog command within jog_timeout {self.cfg.timeout_ms:g} ms (the "
                f"newest arrived after the joint state {age / 1e6:.0f} ms before seq {js.seq})"
            )
            self._latch(End(ResultStatus.ABORTED, EndCause.DEADMAN, why))

    def _counts(self, est: DriveEstimator) -> tuple[np.ndarray, int]:
        """This cycle's motor counts, shape (6,), and gripper counts."""
        target = self.target
        self.limit = FREE
        if target is None:
            return np.zeros(6, dtype=np.int64), 0
        grip = gripper_counts(target.gripper)
        if not target.arm_moves or est.x is None:  # after a gap: zeros, start afresh
            self.run = None
            return np.zeros(6, dtype=np.int64), grip
        q_pred = predicted_dh(est, self.config)
        if self.run is None or not self.run.follows(target):
            self.run = JogRun.start(target, q_pred, self.config)
        step = self.run.step(target, q_pred, self.cfg, self.config)
        self.limit = step.limit
        holding = step.limit.scale <= 0.0  # stopped at a zone: hold without a limit cycle
        return jog_counts(step.q_target, est, self.config, holding), grip
