"""Belt play: the joint side lags its motor through a dead band (worst on joints 4-6).

The encoders sit on the motors, so the play is invisible to the readings; with its
widths known (a calibration), the controller can still aim the joint side rather than
the motor: :class:`PlayModel` keeps an estimate of each belt's output from the motor
estimates (the output moves only when the motor pushes it at either end of the band)
and turns a wanted output angle into the motor angle that puts it there. Motor space,
rad, shape (6,).
"""

from __future__ import annotations

import numpy as np


class PlayModel:
    """Outputs of the six belts, estimated (see the module docstring).

    Args:
        width: full dead band of each motor's belt [rad], shape (6,); 0: no play.
        dead_zone: an output this close to its target is left alone [rad].
    """

    def __init__(self, width: np.ndarray, dead_zone: float) -> None:
        self.half = np.asarray(width, dtype=float) / 2.0
        self.dead_zone = dead_zone
        self.active = bool(np.any(self.half > 0.0))
        """Some belt has play."""
        self.output: np.ndarray | None = None
        """Estimated belt outputs at the last snapshot [rad] (None: not known yet)."""

    def reset(self) -> None:
        """Forget the outputs (after a gap)."""
        self.output = None

    def update(self, motor: np.ndarray) -> None:
        """Drag the outputs along with the estimated motor angles of a new snapshot."""
        if self.output is None:
            self.output = np.asarray(motor, dtype=float).copy()  # unknown: centred
        self.output = np.clip(self.output, motor - self.half, motor + self.half)

    def motor_target(self, wanted: np.ndarray, motor_then: np.ndarray) -> np.ndarray:
        """Motor angles that bring the outputs to ``wanted``.

        Args:
            wanted: output angles wanted at the end of the command's cycle [rad].
            motor_then: predicted motor angles when the command starts acting [rad].
        """
        if self.output is None:
            return np.asarray(wanted, dtype=float)
        out = np.clip(self.output, motor_then - self.half, motor_then + self.half)
        up = wanted > out + self.dead_zone
        down = wanted < out - self.dead_zone
        # Inside the dead zone: any motor angle within half a band of the output keeps
        # it still; stay as close to where the motor will be as that allows.
        stay = np.clip(motor_then, wanted - self.half, wanted + self.half)
        return np.where(up, wanted + self.half, np.where(down, wanted - self.half, stay))
