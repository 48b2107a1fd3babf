"""Whole motions through the collision model: continuous where the margins allow.

:func:`sweep` samples a motion so that no point of the arm travels more than ``step``
(10 mm) between samples, and skips ahead where the margins are larger than the travel
in between: from each checked configuration, each body advances as far as no point of it
can have moved more than its own smallest margin (its speed bounded by each joint's peak
speed times the body's distance from that joint's axis): no gap can close in between
(conservative advancement). :func:`straight_motion_problem` checks the arm's own fold
motions, straight lines in joint space.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from manus.collision import Clearance, CollisionModel

STEP_M = 0.010
"""Largest travel of any point of the arm between two checked samples [m]."""


class Sweep(NamedTuple):
    """What :func:`sweep` found.

    Attributes:
        worst: the smallest margin over the checked samples.
        violation: the first sample whose margin is negative (None: none).
        checked: configurations whose distances were computed [-].
        samples: configurations on the 10 mm grid [-].
    """

    worst: Clearance
    violation: Clearance | None
    checked: int
    samples: int


def sweep(
    model: CollisionModel,
    times: np.ndarray,
    qd_peaks: np.ndarray,
    evaluate: Callable[[np.ndarray], np.ndarray],
    *,
    step: float = STEP_M,
) -> Sweep:
    """Check a motion against every check, continuously where the margins allow.

    From each checked configuration the next one is as far along as no point of the
    arm can have travelled more than the smallest margin there (so no gap can have
    closed: conservative advancement), and never more than ``step`` where that
    margin is smaller. The speed bound is Coal-free: per joint, its peak speed on the
    segment times the farthest any body beyond it is from its axis (measured at the
    configuration, plus the travel allowed), segment by segment.

    Args:
        times: knot times [s], shape (S+1,).
        qd_peaks: largest |joint speed| on each segment [rad/s], shape (S, 6).
        evaluate: positions at times [s], shape (n,) -> (n, 6) [rad].
        step: largest travel of any point between two samples where the margins
            are smaller than that [m].
    """
    times = np.asarray(times, dtype=float)
    peaks = np.abs(np.asarray(qd_peaks, dtype=float))
    # One vectorised evaluation on a grid no coarser than a step of the slowest
    # bound; each advance lands on the last grid time it may reach (never beyond).
    grid = _grid(model, times, peaks, step)
    Q = evaluate(grid)
    i, seg, checked = 0, 0, 0
    worst: Clearance | None = None
    while True:
        t = float(grid[i])
        found, free, reach = model.probe(Q[i], t)
        checked += 1
        if worst is None or found.margin < worst.margin:
            worst = found
        if found.margin < 0.0:
            return Sweep(worst, found, checked, len(grid))
        if i == len(grid) - 1:
            return Sweep(worst, None, checked, len(grid))
        while seg < len(times) - 2 and t >= times[seg + 1]:
            seg += 1
        t_next = _advance(t, seg, times, peaks, free, reach, step)
        i = max(i + 1, int(np.searchsorted(grid, t_next, side="right")) - 1)


def _advance(
    t: float,
    seg: int,
    times: np.ndarray,
    peaks: np.ndarray,
    free: np.ndarray,
    reach: np.ndarray,
    step: float,
) -> float:
    """The latest time [s] no body can have travelled past its allowance from ``t``: its
    margin, or ``step`` where that is smaller; each segment at its own peak speeds."""
    bound = np.isfinite(free)  # bodies with something to keep clear of
    if not bound.any():
        return float(times[-1])
    travel = np.maximum(free[bound], step)
    radius = reach[:, bound] + travel  # (6, bodies): distance from each axis, at most
    left = travel.copy()  # what each body may still travel [m]
    while True:
        end = float(times[seg + 1])
        speed = peaks[seg] @ radius
        need = np.where(speed > 0.0, left / np.where(speed > 0.0, speed, 1.0), math.inf)
        dt = float(need.min())
        if t + dt <= end or seg == len(times) - 2:
            return min(t + dt, float(times[-1]))
        left = left - speed * (end - t)
        t, seg = end, seg + 1


def _grid(model: CollisionModel, times: np.ndarray, peaks: np.ndarray, step: float) -> np.ndarray:
    """Sample times: every knot, and per segment no more than ``step`` of travel apart
    for a body as far out as the arm reaches (a coarse bound: the sweep's own steps
    are longer except near obstacles)."""
    reach = model.extent + 1.0
    parts = [times[:1]]
    for s in range(len(times) - 1):
        t0, t1 = float(times[s]), float(times[s + 1])
        v = float(peaks[s].sum()) * reach
        n = max(1, math.ceil(v * (t1 - t0) / step))
        parts.append(np.linspace(t0, t1, n + 1)[1:])
    return np.concatenate(parts)


def straight_motion_problem(
    model: CollisionModel, q_from: np.ndarray, q_to: np.ndarray, what: str
) -> str | None:
    """Check the straight joint-space motion from ``q_from`` to ``q_to`` [rad], the way
    the arm's own fold procedures move (every motor at a constant speed, all arriving
    together; the joint map is affine, so a straight line in joint space too).

    Returns:
        None when clear, else one line: ``what``, where along it, the body, the object
        and the distance.
    """
    a, b = np.asarray(q_from, dtype=float), np.asarray(q_to, dtype=float)
    delta = b - a
    found = sweep(
        model, np.array([0.0, 1.0]), np.abs(delta)[None, :], lambda ts: a + np.outer(ts, delta)
    )
    bad = found.violation
    if bad is None:
        return None
    start = ", ".join(f"{v:.0f}" for v in np.degrees(a))
    return (
        f"{what} from ({start}) deg would bring the {bad.describe()} "
        f"{bad.time * 100:.0f} % of the way"
    )
