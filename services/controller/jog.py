"""Live control in the controller: the jog stream's intake, its safety, its cycle.

:class:`Jog` holds the newest :class:`~schemas.jog.JogCommand` (checked and turned into
SI speeds by :func:`resolve`), the speed level, and the reference of the motion
(:class:`~services.controller.jog_law.JogRun`); the controller core asks it for each
cycle's counts. Its safety rules:

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
"""

from __future__ import annotations

import math

import numpy as np

from manus.errors import ManusError
from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from manus.quantize import gripper_counts
from schemas.jog import JogCommand, JogFrame, JogKind, JogState, JogUnits
from schemas.state import JointState
from services.controller.config import ControllerConfig
from services.controller.estimator import DriveEstimator
from services.controller.jog_config import JogConfig
from services.controller.jog_law import JogRun, JogTarget, jog_counts, predicted_dh

_TOLERANCE = 1e-9
"""Relative slack of the range checks (a value at the cap is allowed)."""


BAD_JOG_PAYLOAD = "the payload does not decode"
"""What :meth:`ControllerCore.on_bad_jog` is told of a garbage jog payload (live and in
a replay alike)."""


class JogError(ManusError, ValueError):
    """A jog command that cannot be executed (the message names the field, value, limit)."""


def _norm(values: list[float]) -> float:
    return math.sqrt(sum(v * v for v in values))


def _check_values(cmd: JogCommand) -> None:
    for name, enum in (("kind", JogKind), ("units", JogUnits), ("frame", JogFrame)):
        value = getattr(cmd, name)
        allowed = [m.value for m in enum]
        if value not in allowed:
            raise JogError(f"`{name}` {value!r} is not one of {allowed}")
    for name, size in (("linear", 3), ("angular", 3), ("joints", 6)):
        values = getattr(cmd, name)
        if len(values) != size:
            raise JogError(f"`{name}` must hold {size} values, got {len(values)}")
    scalars = [("gripper", cmd.gripper), ("pour", cmd.pour)]
    named = [
        (f"{n}[{i}]", v)
        for n in ("linear", "angular", "joints")
        for i, v in enumerate(getattr(cmd, n))
    ]
    for name, value in named + scalars:
        if not (isinstance(value, int | float) and math.isfinite(value)):
            raise JogError(f"`{name}` = {value!r} is not a finite number")
        if cmd.units == JogUnits.UNITLESS and abs(value) > 1.0 + _TOLERANCE:
            raise JogError(f"`{name}` = {value!r} is outside -1..1 (unitless deflection)")
    if cmd.kind == JogKind.JOINTS and (
        any(cmd.linear) or any(cmd.angular) or cmd.drink or cmd.pour
    ):
        raise JogError("a `joints` command carries joint speeds (and the gripper's) only")
    if cmd.kind == JogKind.TWIST and any(cmd.joints):
        raise JogError("a `twist` command carries no joint speeds (use kind `joints`)")
    if cmd.drink and (cmd.angular[0] or cmd.angular[1]):
        raise JogError(
            f"drink mode holds the cup level: `angular[0]` = {cmd.angular[0]!r} and "
            f"`angular[1]` = {cmd.angular[1]!r} must be 0 (only the yaw, `angular[2]`, turns)"
        )
    if cmd.pour and not cmd.drink:
        raise JogError(f"`pour` = {cmd.pour!r} needs drink mode (`drink` true)")


def resolve(cmd: JogCommand, level: int, cfg: JogConfig) -> JogTarget | None:
    """The SI speeds a command asks for at speed level ``level`` (None: stop).

    Raises:
        JogError: the command is malformed or out of range (module docstring).
    """
    _check_values(cmd)
    if cmd.kind == JogKind.STOP:
        return None
    share = cfg.share(level)
    lin, ang, pour = list(cmd.linear), list(cmd.angular), cmd.pour
    joints, grip = list(cmd.joints), cmd.gripper
    if cmd.units == JogUnits.UNITLESS:  # a deflection of the level's share of the caps
        lin = [v * cfg.max_linear * share for v in lin]
        ang = [v * cfg.max_angular * share for v in ang]
        pour *= cfg.max_angular * share
        joints = [v * cfg.max_joint * share for v in joints]
        grip *= cfg.max_gripper * share
    else:
        for name, size, cap, unit, k in (
            ("linear", _norm(lin), cfg.max_linear, "mm/s", 1000.0),
            ("angular", _norm(ang), cfg.max_angular, "deg/s", 180.0 / math.pi),
            ("pour", abs(pour), cfg.max_angular, "deg/s", 180.0 / math.pi),
            ("joints", max(map(abs, joints)), cfg.max_joint, "deg/s", 180.0 / math.pi),
            ("gripper", abs(grip), cfg.max_gripper, "mm/s", 1000.0),
        ):
            if size > cap * (1.0 + _TOLERANCE):
                raise JogError(
                    f"`{name}` speed {size * k:.1f} {unit} is above the cap {cap * k:.1f} {unit}"
                )
    # One factor for a twist (its direction, and a straight line, are kept).
    sizes = (
        (_norm(lin), cfg.max_linear),
        (_norm(ang) + abs(pour), cfg.max_angular),
        (max(map(abs, joints)), cfg.max_joint),
    )
    f = min([1.0] + [cap * share / size for size, cap in sizes if size > 0.0])
    grip = max(-cfg.max_gripper * share, min(cfg.max_gripper * share, grip))
    target = JogTarget(
        cmd.kind,
        cmd.frame,
        tuple(v * f for v in lin),
        tuple(v * f for v in ang),
        tuple(v * f for v in joints),
        grip,
        cmd.drink,
        pour * f,
    )
    if not target.arm_moves and target.gripper == 0.0:
        return None
    return target


class Jog:
    """The jog as the controller runs it (see the module docstring).

    Args:
        config: controller settings (its ``jog`` holds the jog's own).
    """

    def __init__(self, config: ControllerConfig) -> None:
        self.config = config
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
        self._seq = 0

    @property
    def engaged(self) -> bool:
        """A non-zero jog command is being executed."""
        return self.target is not None

    def receive(self, cmd: JogCommand, stamp_ns: int | None, not_ready: str | None) -> None:
        """A command from the stream; ``stamp_ns``: the newest joint state's stamp (None:
        none yet); ``not_ready``: why nothing may move now (None: it may)."""
        what = f"jog command seq {cmd.seq} from {cmd.source!r} refused"
        try:
            target = resolve(cmd, self.level, self.cfg)
        except JogError as exc:
            self.refuse(f"{what}: {exc}")
            return
        if target is not None and (stamp_ns is None or not_ready is not None):
            # counted once per stop: a joystick held through an e-stop is one refusal
            self.refused += 0 if self.latched else 1
            self.stop(f"{what}: {not_ready or 'no valid joint state yet (is the bridge running?)'}")
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

    def refuse(self, why: str) -> None:
        """Count a refused command and stop."""
        self.refused += 1
        self.stop(why)

    def stop(self, why: str) -> None:
        """Stop (zeros from the next cycle) until a zero command re-arms the jog."""
        if self.target is None and self.latched:
            self.reason = why
            return
        self.target, self.run = None, None
        self.latched = why
        self.reason = f"stopped: {why}; release the controls (a zero command) to jog again"
        self.announce = True

    def set_level(self, level: int) -> str | None:
        """Set the speed level; the reason when refused (None: accepted)."""
        if not 1 <= level <= self.cfg.levels:
            return f"level {level!r} outside 1..{self.cfg.levels}"
        self.level, self.announce = level, True
        return None

    def deadman(self, js: JointState) -> None:
        """Stop if the newest command is older than the timeout at this joint state."""
        if self.target is None:
            return
        age = js.stamp_ns - self.ref_ns
        if age > self.cfg.timeout_ns:
            self.deadman_stops += 1
            self.stop(
                f"deadman: no jog command within jog_timeout {self.cfg.timeout_ms:g} ms (the "
                f"newest arrived after the joint state {age / 1e6:.0f} ms before seq {js.seq})"
            )

    def cycle(self, est: DriveEstimator) -> tuple[np.ndarray, int]:
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

    def state(self, js: JointState) -> JogState | None:
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
