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
  and the arm stops.
- After any stop but a zero command (deadman, refusal, an arm error, a bridge phase, a
  long gap), nothing moves again until the user releases the controls: a zero command
  re-arms the jog.
- **Speed levels** 1..``levels``: unitless deflections are scaled to the caps times
  level / levels, SI speeds are limited to that (refused above the top level's caps).

Each command taken is published at once as a :class:`~schemas.jog.JogTaken` (after which
joint state it came: the regression check feeds it there).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from manus.quantize import gripper_counts
from schemas import endpoints as ep
from schemas.control import CommandSourceKind, EndCause, GoalAck, Refusal, ResultStatus
from schemas.jog import JOGGING, USER_TOOK_OVER, JogCommand, JogLevel, JogState, JogTaken
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
from services.controller.jog_command import JogError, resolve
from services.controller.jog_config import JogConfig
from services.controller.jog_law import JogRun, JogTarget, jog_counts, predicted_dh
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
        """The speeds being executed (None: stopped)."""
        self.ref_ns = 0
        """Stamp [ns] of the newest joint state before the newest command (deadman)."""
        self.command_seq = -1
        self.latched = ""
        """Why the jog stopped ('' : armed); a zero command re-arms it."""
        self.reason = ""
        self.scale = 1.0
        self.refused = 0
        self.deadman_stops = 0
        self.run: JogRun | None = None
        self.announce = False
        """Publish a JogState at the next joint state (a change to show)."""
        self.sender = ""
        """Who sent the newest command (``JogCommand.source``)."""
        self._seq = 0

    @property
    def engaged(self) -> bool:
        """A non-zero jog command is being executed."""
        return self.target is not None

    # -- the stream --------------------------------------------------------------------------

    def on_command(self, cmd: JogCommand) -> Output:
        """A command of the stream: taken (it acts from the next joint state), or refused
        and counted (the arm stops)."""
        js = self.host.last_js
        stamp = js.stamp_ns if js is not None and js.valid else None
        refused = self.host.admission(self)
        self.sender = cmd.source
        self._receive(cmd, stamp, refused.reason if refused is not None else None)
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
            self._latch(end.reason)

    # -- the cycle ---------------------------------------------------------------------------

    def command(self, cycle: Cycle) -> Command | None:
        """The deadman, then this cycle's counts while a jog moves."""
        self._deadman(cycle.js)
        if not self.engaged:
            return None
        counts, grip = self._counts(cycle.joints)
        if cycle.gap:  # nothing is known of the cycle(s) missed: stop, start afresh
            counts, grip, self.run = _ZERO, 0, None
        return Command(counts, grip)

    def reports(self, sent: Sent) -> Output:
        """The JogState while a jog runs, and once after each change."""
        jog = self._state(sent.js)
        if jog is None:
            return []
        if sent.guard and jog.active:  # the collision guard slowed or stopped the jog
            jog = dataclasses.replace(jog, reason=f"collision guard {sent.guard}")
        return [(ep.JOG_STATE, jog)]

    # -- internals ---------------------------------------------------------------------------

    def _taken(self, cmd: JogCommand | None, error: str = "") -> tuple[str, JogTaken]:
        js = self.host.last_js
        after = js.seq if js is not None else -1
        return ep.JOG_TAKEN, JogTaken(after_seq=after, command=cmd, error=error)

    def _receive(self, cmd: JogCommand, stamp_ns: int | None, not_ready: str | None) -> None:
        """``stamp_ns``: the newest joint state's stamp (None: none yet); ``not_ready``:
        why nothing may move now (None: it may)."""
        what = f"jog command seq {cmd.seq} from {cmd.source!r} refused"
        try:
            target = resolve(cmd, self.level, self.cfg)
        except JogError as exc:
            self._refuse(f"{what}: {exc}")
            return
        if target is not None and (stamp_ns is None or not_ready is not None):
            # counted once per stop: a joystick held through an e-stop is one refusal
            self.refused += 0 if self.latched else 1
            self._latch(
                f"{what}: {not_ready or 'no valid joint state yet (is the bridge running?)'}"
            )
            return
        self.command_seq = cmd.seq
        if target is None or stamp_ns is None:
            if self.target is not None or self.latched:
                self.reason, self.announce = ("released" if self.latched else ""), True
            self.target, self.run, self.latched = None, None, ""
            return
        if self.latched:
            return  # still held: the user must release the controls first
        if self.target is None:
            self.announce = True
        self.target, self.ref_ns = target, stamp_ns

    def _refuse(self, why: str) -> None:
        """Count a refused command and stop."""
        self.refused += 1
        self._latch(why)

    def _latch(self, why: str) -> None:
        """Stop (zeros from the next cycle) until a zero command re-arms the jog."""
        if self.target is None and self.latched:
            self.reason = why
            return
        self.target, self.run = None, None
        self.latched = why
        self.reason = f"stopped: {why}; release the controls (a zero command) to jog again"
        self.announce = True

    def _deadman(self, js: JointState) -> None:
        """Stop if the newest command is older than the timeout at this joint state."""
        if self.target is None:
            return
        age = js.stamp_ns - self.ref_ns
        if age > self.cfg.timeout_ns:
            self.deadman_stops += 1
            self._latch(
                f"deadman: no jog command within jog_timeout {self.cfg.timeout_ms:g} ms (the "
                f"newest arrived after the joint state {age / 1e6:.0f} ms before seq {js.seq})"
            )

    def _counts(self, est: DriveEstimator) -> tuple[np.ndarray, int]:
        """This cycle's motor counts, shape (6,), and gripper counts."""
        target = self.target
        self.scale = 1.0
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
        self.scale, self.reason = step.limit.scale, step.limit.reason
        holding = step.limit.scale <= 0.0  # stopped at a zone: hold without a limit cycle
        return jog_counts(step.q_target, est, self.config, holding), grip

    def _state(self, js: JointState) -> JogState | None:
        """The JogState to publish with this joint state (None: nothing to show)."""
        if not (self.engaged or self.announce):
            return None
        self.announce = False
        T = fk(js.position, self.config.arm)
        target = self.target
        msg = JogState(
            stamp_ns=js.stamp_ns,
            seq=self._seq,
            active=target is not None,
            kind=target.kind if target is not None else "",
            frame=target.frame if target is not None else "",
            drink=target.drink if target is not None else False,
            level=self.level,
            levels=self.cfg.levels,
            scale=self.scale,
            reason=self.reason,
            command_seq=self.command_seq,
            refused=self.refused,
            deadman_stops=self.deadman_stops,
            actual_xyz=[float(v) for v in T[:3, 3]],
            actual_ypr=[float(v) for v in matrix_to_ypr(T[:3, :3])],
        )
        self._seq += 1
        return msg
