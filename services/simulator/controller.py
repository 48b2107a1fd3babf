"""The arm's command execution: from the latched reply to mode, fold and drive intents.

What the Manus electronics do with the one reply latched per cycle (docs/protocol.md, Replies
from the PC):

- 0x374 / 0x371: joint (mode 4) or Cartesian (mode 1) move, repeated until replaced;
  position fields become meaningful from the first one on.
- 0x370: stop: zero motion latched, fold abandoned, latched error cleared, mode kept.
- 0x375 / 0x376: fold out (mode 5) / fold in (mode 6) toward the stored pose, all motors
  arriving together; the fold advances only in the cycles after a sync it answered and
  pauses otherwise. Reaching the pose posts "arm unfolded" / "arm folded".
- The first motion after power-up starts ``first_motion_delay_ms`` late (the drives
  are enabled then); the first command moving joints 4-6 starts the stale-encoder clock.
- While an error is latched, the arm holds and ignores every reply but 0x370.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from manus.protocol import (
    GEN_FOLDED,
    GEN_UNFOLDED,
    GRIPPER_UNIT_MM,
    JOINT_UNIT_DEG,
    TICK_S,
    FrameId,
    Mode,
    MoveCommand,
)
from services.simulator.arm import Intent, dh_to_motor_deg, fold_rates
from services.simulator.cartesian import cartesian_motor_rates
from services.simulator.config import MS, SimConfig
from services.simulator.replies import Reply

_FOLD_MODE = {FrameId.FOLD_IN: Mode.FOLD_IN, FrameId.FOLD_OUT: Mode.FOLD_OUT}
_FOLD_DONE = {FrameId.FOLD_IN: GEN_FOLDED, FrameId.FOLD_OUT: GEN_UNFOLDED}

Outcome = Literal["none", "stop", "ignored", "applied"]
"""What :meth:`ArmController.activate` did: no reply, a stop, ignored (error), applied."""


@dataclass
class FoldProcedure:
    """A running fold in (0x376) or fold out (0x375).

    Attributes:
        kind: :attr:`FrameId.FOLD_IN` or :attr:`FrameId.FOLD_OUT`.
        target_deg: motor angles of the fold pose, shape (6,) [deg].
        rates_deg_s: constant motor speeds toward it, shape (6,) [deg/s].
        held: the PC answered the last sync with this fold frame (else the fold pauses).
        done: the pose has been reached (and the general message posted).
    """

    kind: FrameId
    target_deg: np.ndarray
    rates_deg_s: np.ndarray
    held: bool = True
    done: bool = False

    @property
    def done_message(self) -> int:
        """The general message code posted at the end."""
        return _FOLD_DONE[self.kind]


class ArmController:
    """Mode, active command and fold procedure of the arm (see the module docstring).

    Args:
        config: the simulator configuration.

    Attributes:
        mode: the mode nibble the arm reports.
        positions_valid: a move mode has been active since power-up.
        active: the latched move being executed (None: stopped, or a fold).
        active_clamped: the active move had an out-of-range increment.
        fold: the fold procedure in progress or completed, if any.
        drives_on_ns: when the drives start obeying (first motion + delay), None before.
        stale_until_ns: when joints 4-6 stop reporting stale values, None before their
            first commanded move.
    """

    def __init__(self, config: SimConfig) -> None:
        self.config = config
        self.mode = Mode.NONE
        self.positions_valid = False
        self.active: MoveCommand | None = None
        self.active_clamped = False
        self.fold: FoldProcedure | None = None
        self.drives_on_ns: int | None = None
        self.stale_until_ns: int | None = None

    def activate(
        self, reply: Reply | None, t_ns: int, motor_deg: np.ndarray, *, error: bool
    ) -> Outcome:
        """Make the reply latched in the last window active at ``t_ns`` (T+80 ms)."""
        if reply is None:
            self._pause_fold()
            return "none"
        if reply.kind == FrameId.STOP:
            self.active, self.fold, self.active_clamped = None, None, False
            return "stop"
        if error:
            self._pause_fold()
            return "ignored"
        if reply.move is not None:
            self.fold = None
            self.active, self.active_clamped = reply.move, reply.clamped
            self.mode = Mode.JOINT if reply.kind == FrameId.JOINT else Mode.CARTESIAN
            self.positions_valid = True
            moving = not reply.move.is_zero
            wrist = bool(np.any(self.move_rates(reply.move, motor_deg)[3:] != 0.0))
        else:
            fold = self._hold_fold(reply.kind, motor_deg)
            moving = not fold.done
            wrist = bool(np.any(fold.rates_deg_s[3:] != 0.0))
        if moving and self.drives_on_ns is None:
            self.drives_on_ns = t_ns + round(self.config.first_motion_delay_ms * MS)
        if wrist and self.stale_until_ns is None:
            self.stale_until_ns = t_ns + round(self.config.stale_duration_ms * MS)
        return "applied"

    def halt(self) -> None:
        """An error occurred: drop the active move and pause any fold."""
        self.active, self.active_clamped = None, False
        self._pause_fold()

    def intent(
        self, t0_ns: int, motor_deg: np.ndarray, stuck: np.ndarray, *, error: bool
    ) -> Intent:
        """What the drives do over the tick starting at ``t0_ns``."""
        gate_open = self.drives_on_ns is not None and t0_ns >= self.drives_on_ns
        if not gate_open or error:
            return Intent(np.zeros(6), stuck=stuck)
        fold = self.fold
        if fold is not None:
            # A paused or finished fold holds the arm still, without coasting.
            rates = fold.rates_deg_s if fold.held and not fold.done else np.zeros(6)
            return Intent(rates, fold_target_deg=fold.target_deg, stuck=stuck, checks=False)
        if self.active is None:
            return Intent(np.zeros(6), stuck=stuck)
        grip = self.active.gripper * (GRIPPER_UNIT_MM / TICK_S)
        return Intent(self.move_rates(self.active, motor_deg), grip, stuck=stuck)

    def move_rates(self, cmd: MoveCommand, motor_deg: np.ndarray) -> np.ndarray:
        """Target motor speeds of a move at these motor angles [deg/s], shape (6,)."""
        if cmd.frame_id == FrameId.JOINT:
            return np.asarray(cmd.axes, dtype=float) * (JOINT_UNIT_DEG / TICK_S)
        return cartesian_motor_rates(motor_deg, cmd, self.config.arm)

    def _pause_fold(self) -> None:
        if self.fold is not None:
            self.fold.held = False

    def _hold_fold(self, kind: FrameId, motor_deg: np.ndarray) -> FoldProcedure:
        cfg = self.config
        fold = self.fold
        if fold is None or fold.kind != kind:
            pose = cfg.folded_q_deg if kind == FrameId.FOLD_IN else cfg.unfolded_q_deg
            target = dh_to_motor_deg(np.asarray(pose, dtype=float))
            fold = FoldProcedure(kind, target, np.zeros(6), held=False)
            self.fold = fold
        self.active, self.active_clamped = None, False
        self.mode = _FOLD_MODE[kind]
        if not fold.held and not fold.done:
            # (Re)start: a straight line from here, every motor arriving together.
            fold.rates_deg_s = fold_rates(motor_deg, fold.target_deg, cfg.fold_speed_deg_s)
        fold.held = True
        return fold
