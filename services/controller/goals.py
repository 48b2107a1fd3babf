"""Goal checks: what a trajectory goal must satisfy to be accepted, and tolerance verdicts.

Every refusal and every abort reason names the field, the joint (1-based), the value and
the limit, so that a caller can act on it without reading the code.
"""

from __future__ import annotations

import math

import numpy as np

from manus.config import N_JOINTS
from manus.errors import ManusError
from manus.trajectory import TrajectoryError
from schemas.control import CONTROL_MODES, TrajectoryGoal


class GoalRefusedError(ManusError):
    """A goal cannot be accepted; ``str(exc)`` is the reason sent back in the GoalAck."""


def tolerances(goal: TrajectoryGoal, name: str) -> np.ndarray:
    """The per-joint tolerance ``name`` of ``goal`` [rad], shape (6,); 0 means unchecked.

    An empty list means every joint unchecked; one value applies to every joint.

    Raises:
        GoalRefusedError: wrong length, negative or non-finite value.
    """
    values = list(getattr(goal, name))
    if not values:
        return np.zeros(N_JOINTS)
    if len(values) == 1:
        values = values * N_JOINTS
    if len(values) != N_JOINTS:
        raise GoalRefusedError(
            f"goal {goal.goal_id!r}: `{name}` has {len(values)} values, expected 0, 1 or {N_JOINTS}"
        )
    for j, v in enumerate(values, start=1):
        if not (math.isfinite(v) and v >= 0.0):
            raise GoalRefusedError(
                f"goal {goal.goal_id!r}: `{name}` of joint {j} is {v!r}, expected a "
                "non-negative number [rad]"
            )
    return np.asarray(values, dtype=float)


def check_goal(goal: TrajectoryGoal) -> None:
    """Field checks that need no state.

    Raises:
        GoalRefusedError: naming the field and value.
    """
    if not goal.goal_id:
        raise GoalRefusedError("`goal_id` is empty: give each goal a unique id")
    if goal.mode not in CONTROL_MODES:
        raise GoalRefusedError(
            f"goal {goal.goal_id!r}: `mode` {goal.mode!r} not in {CONTROL_MODES}"
        )
    for name in ("goal_time_tolerance", "position_tolerance", "start_tolerance"):
        value = getattr(goal, name)
        if not (math.isfinite(value) and value >= 0.0):
            raise GoalRefusedError(f"goal {goal.goal_id!r}: `{name}` is {value!r}, expected >= 0")
    if not 0.05 <= goal.speed_scale <= 1.0:
        raise GoalRefusedError(
            f"goal {goal.goal_id!r}: `speed_scale` {goal.speed_scale!r} outside [0.05, 1]"
        )
    rows = goal.trajectory.positions
    if any(len(r) != N_JOINTS for r in rows):
        raise GoalRefusedError(
            f"goal {goal.goal_id!r}: trajectory rows must hold {N_JOINTS} joints"
        )


def check_start(goal: TrajectoryGoal, measured: np.ndarray) -> None:
    """Refuse a trajectory whose first knot is far from the measured joint angles.

    Raises:
        GoalRefusedError: naming the joint, the difference and ``start_tolerance``.
    """
    first = np.asarray(goal.trajectory.positions[0], dtype=float)
    diff = np.abs(first - measured)
    j = int(np.argmax(diff))
    if diff[j] > goal.start_tolerance:
        raise GoalRefusedError(
            f"goal {goal.goal_id!r}: first knot of joint {j + 1} is {math.degrees(diff[j]):.2f} "
            f"deg ({diff[j]:.4f} rad) from the measured angle, above start_tolerance "
            f"{goal.start_tolerance:.4f} rad"
        )


def trajectory_error(goal: TrajectoryGoal, exc: TrajectoryError) -> GoalRefusedError:
    """A refusal for an inconsistent trajectory message."""
    return GoalRefusedError(f"goal {goal.goal_id!r}: trajectory: {exc}")


def violation(error: np.ndarray, tol: np.ndarray, what: str) -> str | None:
    """The first joint whose |error| [rad] exceeds its non-zero tolerance, in words.

    Args:
        error: reference minus measurement [rad], shape (6,).
        tol: tolerances [rad], shape (6,) (0: unchecked).
        what: ``path`` or ``goal``.
    """
    if not tol.any():
        return None  # nothing checked (the default)
    over = (tol > 0.0) & (np.abs(error) > tol)
    if not over.any():
        return None
    j = int(np.argmax(np.where(over, np.abs(error) / np.where(tol > 0, tol, 1.0), 0.0)))
    return (
        f"{what} tolerance: joint {j + 1} error {error[j]:+.4f} rad "
        f"({math.degrees(error[j]):+.2f} deg) exceeds {tol[j]:.4f} rad"
    )
