"""DH joint rates <-> motor increments ("counts"), saturation and quantizers.

Units and ranges: docs/protocol.md, Increments and units of moves.

The arm takes one signed byte per joint and per 20 ms: joint increments in 0.1 deg per 20 ms
(one count = 5 deg/s, range -10..10) and gripper increments in 0.1 mm per 20 ms (one count =
5 mm/s, range -15..15). Joint counts are **motor** increments: the joint 2/3 coupling
(docs/protocol.md, Encoder map) is applied here through :mod:`manus.joint_map`, never
copied.

This is the arm's speed table, shared by the bridge (which turns SI velocities into the
0x374's bytes at the CAN edge, and what the arm executes back into SI) and the
controller (which must choose one of the speeds itself: its dead-beat law and its
Cartesian rounding decide which, knowing the reference the bridge never sees). Rounding a
wanted rate to one of 21 speeds is the arm's defining limitation, so the
quantizer is a replaceable piece (:class:`Quantizer`): :class:`RoundingQuantizer` is the
thesis's nearest integer, :class:`ErrorFeedbackQuantizer` carries the rounding residual
to the next call so that the running mean of the counts equals the wanted rate.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from manus.errors import ManusError
from manus.joint_map import (
    dh_increments_to_encoder,
    encoder_increments_to_dh,
    encoder_increments_to_dh_list,
)
from manus.protocol import GRIPPER_INC_MAX, JOINT_INC_MAX

COUNT_RAD_S: float = math.radians(5.0)
"""Motor speed of one joint count [rad/s]: 0.1 deg per 20 ms = 5 deg/s."""

GRIPPER_COUNT_M_S: float = 0.005
"""Gripper speed of one gripper count [m/s]: 0.1 mm per 20 ms = 5 mm/s."""

JOINT_COUNT_MAX: int = JOINT_INC_MAX
"""Largest joint count magnitude (10 = 50 deg/s)."""

GRIPPER_COUNT_MAX: int = GRIPPER_INC_MAX
"""Largest gripper count magnitude (15 = 75 mm/s)."""


class QuantizeError(ManusError, ValueError):
    """An input to a rate conversion or quantizer has the wrong shape or is not finite."""


def _vector6(values: np.ndarray, what: str) -> np.ndarray:
    arr = np.asarray(values, dtype=float)
    if arr.shape != (6,):
        raise QuantizeError(f"{what}: shape {arr.shape}, expected (6,)")
    if not np.isfinite(arr).all():
        bad = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise QuantizeError(f"{what}: joint {bad + 1} is {arr[bad]}, expected a finite number")
    return arr


def joint_rates_to_counts(qd_dh: np.ndarray) -> np.ndarray:
    """Float motor counts from DH joint rates, with the joint 2/3 coupling.

    Args:
        qd_dh: DH joint velocities [rad/s], shape (6,).

    Returns:
        Motor increments [counts = 0.1 deg per 20 ms], shape (6,), not rounded nor limited.
    """
    qd = _vector6(qd_dh, "joint rates [rad/s]")
    return np.asarray(dh_increments_to_encoder(qd) / COUNT_RAD_S)


def counts_to_joint_rates(counts: np.ndarray) -> np.ndarray:
    """DH joint rates [rad/s], shape (6,), that motor counts, shape (6,), produce."""
    c = _vector6(counts, "motor counts")
    return np.asarray(encoder_increments_to_dh(c) * COUNT_RAD_S)


def step_rates(counts: Sequence[int]) -> list[float]:
    """:func:`counts_to_joint_rates` on six plain integers (every cycle: the controller's
    command, the bridge's applied speeds): the same products, a zero rate is +0.0."""
    return [r * COUNT_RAD_S for r in encoder_increments_to_dh_list(counts)]


def saturate(counts: np.ndarray, limit: float = float(JOINT_COUNT_MAX)) -> np.ndarray:
    """Scale all joints by one factor so that the largest magnitude is at most ``limit``.

    The direction of the motion in motor space is kept (docs/protocol.md, Thesis control
    loop, step 4); counts already within the limit are returned unchanged (as a new array).

    Args:
        counts: float motor counts, shape (6,).
        limit: largest allowed magnitude [counts], > 0.
    """
    if not limit > 0:
        raise QuantizeError(f"saturate: limit {limit} must be > 0")
    c = _vector6(counts, "motor counts")
    peak = float(np.abs(c).max())
    if peak <= limit:
        return c.copy()
    return np.asarray(c * (limit / peak))


def saturate_values(counts: Sequence[float], limit: float = float(JOINT_COUNT_MAX)) -> list[float]:
    """:func:`saturate` on six plain floats (the controller's cycle; a test keeps the two
    equal): the same checks, the same operations, a list back."""
    if not limit > 0:
        raise QuantizeError(f"saturate: limit {limit} must be > 0")
    c = [float(v) for v in counts]
    if len(c) != 6:
        raise QuantizeError(f"motor counts: shape ({len(c)},), expected (6,)")
    if not math.isfinite(sum(c)):  # a NaN or an infinity (six counts cannot overflow)
        i, v = next((i, v) for i, v in enumerate(c) if not math.isfinite(v))
        raise QuantizeError(f"motor counts: joint {i + 1} is {v}, expected a finite number")
    peak = max(abs(v) for v in c)
    if peak <= limit:
        return c
    k = limit / peak
    return [v * k for v in c]


def _round_half_away(x: np.ndarray) -> np.ndarray:
    # Symmetric rounding: +0.5 and -0.5 round away from zero alike (np.rint rounds to even,
    # which would make +2.5 and +3.5 behave differently).
    return np.asarray(np.sign(x) * np.floor(np.abs(x) + 0.5))


class Quantizer(Protocol):
    """Float motor counts, shape (6,), -> integer counts, shape (6,), within -limit..limit."""

    def __call__(self, counts: np.ndarray) -> np.ndarray:
        """Quantize one cycle's counts; returns an int64 array of shape (6,)."""
        ...

    def reset(self) -> None:
        """Forget any state carried between calls (after a stop, a fault or a new goal)."""
        ...


class RoundingQuantizer:
    """Nearest integer (half away from zero), clamped to -limit..limit: the thesis's choice.

    Args:
        limit: largest count magnitude (default 10, the arm's joint range).
    """

    def __init__(self, limit: int = JOINT_COUNT_MAX) -> None:
        if not 1 <= limit <= JOINT_COUNT_MAX:
            raise QuantizeError(f"RoundingQuantizer: limit {limit} outside 1..{JOINT_COUNT_MAX}")
        self.limit = limit

    def __call__(self, counts: np.ndarray) -> np.ndarray:
        """Integer counts, shape (6,), nearest to ``counts`` and within the range."""
        c = _vector6(counts, "motor counts")
        return np.asarray(np.clip(_round_half_away(c), -self.limit, self.limit), dtype=np.int64)

    def reset(self) -> None:
        """Nothing to forget: rounding has no state."""


class ErrorFeedbackQuantizer:
    """First-order sigma-delta: the rounding residual of one call is added to the next.

    Over N calls with wanted counts c_k within the range, the sum of the output equals
    the sum of the c_k up to less than one count per joint, so the running mean of the
    commanded speed converges to the wanted speed (at the cost of alternating between
    two neighbouring speeds). Inputs beyond the range are clamped first, so the residual
    stays within half a count.

    Args:
        limit: largest count magnitude (default 10, the arm's joint range).
    """

    def __init__(self, limit: int = JOINT_COUNT_MAX) -> None:
        if not 1 <= limit <= JOINT_COUNT_MAX:
            raise QuantizeError(
                f"ErrorFeedbackQuantizer: limit {limit} outside 1..{JOINT_COUNT_MAX}"
            )
        self.limit = limit
        self.residual = np.zeros(6)
        """Rounding error carried to the next call [counts], shape (6,)."""

    def __call__(self, counts: np.ndarray) -> np.ndarray:
        """Integer counts, shape (6,), for ``counts`` plus the carried residual."""
        c = np.clip(_vector6(counts, "motor counts"), -self.limit, self.limit)
        wanted = c + self.residual
        out = np.clip(_round_half_away(wanted), -self.limit, self.limit)
        self.residual = wanted - out
        return np.asarray(out, dtype=np.int64)

    def reset(self) -> None:
        """Drop the carried residual."""
        self.residual = np.zeros(6)


def gripper_counts(v_m_s: float) -> int:
    """Gripper increment [counts = 0.1 mm per 20 ms] for a gripper speed [m/s].

    Rounded to the nearest count (half away from zero) and clamped to -15..15.
    """
    if not math.isfinite(v_m_s):
        raise QuantizeError(f"gripper speed {v_m_s} m/s: expected a finite number")
    raw = float(_round_half_away(np.array([v_m_s / GRIPPER_COUNT_M_S]))[0])
    return int(max(-GRIPPER_COUNT_MAX, min(GRIPPER_COUNT_MAX, raw)))
