"""The arm's drives as the controller models them: motor angles, speeds and the commands in flight.

The arm integrates motor increments through a first-order speed lag (docs/protocol.md, The
60 ms cycle: the new speed is reached after a ~60 ms transient) and reports motor angles
rounded to 0.1 deg.
:class:`DriveEstimator` keeps, per motor, an estimate of the true angle and speed at the
last snapshot: it predicts the motion from the increments the bridge reports as applied
(``JointState.applied_velocity``) and intersects the interval of positions consistent with every
earlier reading (moved by the predicted motion, widened by the drives' speed gain
error) with the new reading's quantization cell (a set-membership observer). The
estimate is the middle of that interval: finer than the encoder once a few readings have
crossed cell boundaries, and never further than half a unit from the reading.

All angles here are motor (encoder) angles in rad, speeds in rad/s, n values per
quantity (6 motors, or 1 for the gripper in m and m/s).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def lag_factor(tau_s: float, horizon_s: float) -> float:
    """tau (1 - e^(-h/tau)) [s]: how far a speed change lags the position over ``horizon_s``."""
    if tau_s <= 0.0:
        return 0.0
    return tau_s * (1.0 - math.exp(-horizon_s / tau_s))


def lag_advance(
    x: np.ndarray, v: np.ndarray, u: np.ndarray, dt_s: float, tau_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """Position and speed after ``dt_s`` [s] at target speed ``u`` through the lag.

    Args:
        x: positions now, shape (n,).
        v: speeds now, shape (n,).
        u: target speeds held over the interval, shape (n,).
        dt_s: interval [s], >= 0.
        tau_s: time constant [s] (0: the speed jumps at once).
    """
    c = lag_factor(tau_s, dt_s)
    decay = math.exp(-dt_s / tau_s) if tau_s > 0.0 else 0.0
    return x + u * dt_s + (v - u) * c, u + (v - u) * decay


def deadbeat_speed(
    x: Sequence[float], v: Sequence[float], target: Sequence[float], dt_s: float, tau_s: float
) -> list[float]:
    """The constant target speed that brings the lagged drive from (x, v) to ``target`` in ``dt_s``.

    Inverts :func:`lag_advance` for ``u``, axis by axis on plain floats.
    """
    c = lag_factor(tau_s, dt_s)
    span = dt_s - c
    return [(t - x0 - v0 * c) / span for x0, v0, t in zip(x, v, target, strict=True)]


class DriveEstimator:
    """Estimated true positions and speeds at the last snapshot (see the module docstring).

    Axis by axis on plain floats: with six values, NumPy's per-call overhead would cost
    more than the arithmetic (the same operations as :func:`lag_advance`).

    Args:
        tau_s: the drives' time constant [s].
        half_cell: half the reading's resolution [rad or m] (0: trust the reading).
        n: number of axes.
    """

    def __init__(self, tau_s: float, half_cell: float, n: int, gain_error: float = 0.02) -> None:
        self.tau_s = tau_s
        self.half_cell = half_cell
        self.gain_error = gain_error
        self.n = n
        self.lo = [0.0] * n
        """Smallest position consistent with every reading so far, n values."""
        self.hi = [0.0] * n
        """Largest position consistent with every reading so far, n values."""
        self.x: list[float] | None = None
        """Estimated positions at the last snapshot, n values (None: no reading yet)."""
        self.v = [0.0] * n
        """Estimated speeds at the last snapshot, n values."""
        self.u = [0.0] * n
        """Target speeds acting from the last snapshot on (the applied command), n values."""

    def reset(self) -> None:
        """Forget everything (after a gap in the readings)."""
        self.x = None
        self.v = [0.0] * self.n
        self.u = [0.0] * self.n

    @property
    def in_flight(self) -> bool:
        """A non-zero command acts from the last snapshot on (zeros now would not stop
        the drives where they are)."""
        return any(self.u)

    def update(
        self, reading: Sequence[float], applied: Sequence[float], dt_s: float
    ) -> list[float]:
        """Take a new snapshot ``dt_s`` [s] after the last one.

        Args:
            reading: the reported positions, n values.
            applied: target speeds acting from this snapshot on, n values.
            dt_s: time since the previous snapshot [s].

        Returns:
            The estimated positions at this snapshot, n values.
        """
        half = self.half_cell
        targets = [float(u) for u in applied]
        if self.x is None:
            lo = [r - half for r in reading]
            hi = [r + half for r in reading]
            v = targets
        else:
            c = lag_factor(self.tau_s, dt_s)
            decay = math.exp(-dt_s / self.tau_s) if self.tau_s > 0.0 else 0.0
            gain_error = self.gain_error
            lo, hi, v = [], [], []
            last = (self.x, self.v, self.u, self.lo, self.hi)
            for r, x0, v0, u, lo0, hi0 in zip(reading, *last, strict=True):
                moved = x0 + u * dt_s + (v0 - u) * c - x0
                v.append(u + (v0 - u) * decay)
                # The model's own uncertainty: the drives' speed gain error on the motion.
                slack = gain_error * abs(moved) + 1e-9
                lo_r, hi_r = r - half, r + half
                lo_m, hi_m = lo0 + moved - slack, hi0 + moved + slack
                if lo_m <= hi_r and hi_m >= lo_r:  # consistent: intersect
                    # max(lo_r, lo_m) and min(hi_r, hi_m), without the calls
                    lo_r = lo_m if lo_m > lo_r else lo_r
                    hi_r = hi_m if hi_m < hi_r else hi_r
                lo.append(lo_r)
                hi.append(hi_r)
        self.lo, self.hi = lo, hi
        self.x = [(a + b) / 2.0 for a, b in zip(lo, hi, strict=True)]
        self.v, self.u = v, targets
        return self.x

    def predict(self, horizon_s: float) -> tuple[list[float], list[float]]:
        """Positions and speeds ``horizon_s`` [s] after the last snapshot under the applied
        command (:func:`lag_advance`), n values each.

        Raises:
            RuntimeError: no reading has been taken.
        """
        if self.x is None:
            raise RuntimeError("DriveEstimator.predict before the first update")
        c = lag_factor(self.tau_s, horizon_s)
        decay = math.exp(-horizon_s / self.tau_s) if self.tau_s > 0.0 else 0.0
        x, v = [], []
        for x0, v0, u in zip(self.x, self.v, self.u, strict=True):
            x.append(x0 + u * horizon_s + (v0 - u) * c)
            v.append(u + (v0 - u) * decay)
        return x, v
