"""Whole motions proven with the fast validity check, Coal only where the margin is
smallest.

:func:`fast_sweep` is the first try of :func:`manus.sweep.sweep`: the same guarantee
(every stretch of the motion proven to keep its margin above zero and above the
reported smallest margin minus ``tolerance``, except stretches no point crosses more
than ``step`` of) from lower bounds of each body's margin
(:meth:`manus.validity.ValidityChecker.margins_batch`, microseconds a configuration)
instead of Coal's distances.

Between two configurations checked, ``t_a`` and ``t_b`` within one segment of the
motion, a body's margin is at least ``min(m_a, m_b, (m_a + m_b - v dt) / 2)``: neither
end's margin can close faster than the body's points move, ``v`` the segment's peak
joint speeds times each joint's lever (the farthest any point of the body can be from
the joint). It starts from the knots and samples no more than :data:`START_M` of travel
apart, and cuts every stretch whose bound is too low into pieces (all of them in one
batch per round). Where a configuration's bound is the smallest of all, Coal computes
its exact margins (:meth:`manus.collision.CollisionModel.probe`, each body's; they are
lower bounds too, only tighter), until the smallest margin is an exact one: that is the
reported clearance, the same kind of number the exact sweep reports. A configuration
that even Coal finds violated, or more than :data:`MAX_EXACT` exact checks, hands the
motion back to the exact sweep (``None``), which names the first violation.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from manus.clearance import Clearance
from manus.collision import CollisionModel
from manus.motion_kernels import stretch_bounds
from manus.validity import checker_for

START_M = 0.2
"""Most travel of any point between two of the first configurations checked [m]."""

MAX_EXACT = 12
"""Most configurations whose exact margins are computed before the exact sweep takes
over."""

CAP_M = 0.25
"""Margins are bounded up to this [m] (a body further from everything counts as this
far: its pairs are skipped, the bound stays true)."""

MAX_ROUNDS = 40
"""Most rounds of cutting stretches before the exact sweep takes over."""


class Proof(NamedTuple):
    """A motion proven clear.

    Attributes:
        worst: the smallest margin found, exact (Coal), with its check, time and angles.
        checked: configurations whose margins were bounded [-].
        exact: of them, those whose distances Coal computed [-].
    """

    worst: Clearance
    checked: int
    exact: int


def fast_sweep(
    model: CollisionModel,
    times: np.ndarray,
    qd_peaks: np.ndarray,
    evaluate: Callable[[np.ndarray], np.ndarray],
    *,
    step: float,
    tolerance: float,
) -> Proof | None:
    """Prove a motion (see the module docstring); None: let the exact sweep decide.

    Args:
        times: knot times [s], shape (S+1,).
        qd_peaks: largest |joint speed| on each segment [rad/s], shape (S, 6).
        evaluate: positions at times [s], shape (n,) -> (n, 6) [rad].
        step: shortest stretch cut (of any point's travel) [m].
        tolerance: how far below the smallest margin the stretches may be [m].
    """
    fast = checker_for(model)
    peaks = np.abs(np.asarray(qd_peaks, dtype=float))
    speed = peaks @ fast.levers()  # (S, B): the fastest any point can move anywhere [m/s]
    T = _start(np.asarray(times, dtype=float), speed.max(axis=1))
    Q = evaluate(T)
    found = fast.margins_batch(Q, CAP_M)
    free, tight, reach = found.free, found.tight, fast.reach_batch(Q)
    exact: dict[float, Clearance] = {}
    checked = len(T)
    worst: Clearance | None = None
    to_probe = [int(np.argmin(tight))]
    for _ in range(MAX_ROUNDS):
        if len(exact) + len(to_probe) > MAX_EXACT:
            return None
        for k in to_probe:
            probe = model.probe(Q[k], float(T[k]), reach=False)
            if probe.best.margin < 0.0:
                return None  # a violation: the exact sweep finds the first and names it
            exact[float(T[k])] = probe.best
            if worst is None or probe.best.margin < worst.margin:
                worst = probe.best
            # Coal's margins are lower bounds too, body by body (held ones included).
            free[k] = np.maximum(free[k], probe.free)
            tight[k] = max(tight[k], min(probe.best.margin, float(free[k].min())))
        assert worst is not None
        floor = max(worst.margin - tolerance, 0.0)
        to_probe = [int(k) for k in np.flatnonzero(tight < floor) if float(T[k]) not in exact]
        if to_probe:
            continue
        cut = _stretches_to_cut(T, free, tight, reach, times, peaks, step, floor)
        if not cut:
            return Proof(worst, checked, len(exact))
        at, pieces = np.array(cut).T
        inner = np.ones(int(pieces.sum()), dtype=bool)
        inner[np.cumsum(pieces) - 1] = False  # the stretches' own ends are there already
        new_T = _pieces(T[at], T[at + 1] - T[at], pieces)[inner]
        new_Q = evaluate(new_T)
        more = fast.margins_batch(new_Q, CAP_M)
        checked += len(new_T)
        order = np.argsort(np.concatenate((T, new_T)), kind="stable")
        T = np.concatenate((T, new_T))[order]
        Q = np.concatenate((Q, new_Q))[order]
        free = np.concatenate((free, more.free))[order]
        tight = np.concatenate((tight, more.tight))[order]
        reach = np.concatenate((reach, fast.reach_batch(new_Q)))[order]
        to_probe = [int(k) for k in np.flatnonzero(tight < floor) if float(T[k]) not in exact]
    return None


def _start(times: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Every knot, and within each segment no more than :data:`START_M` of travel apart
    (``speed``: per segment, the fastest any point moves [m/s])."""
    h = np.diff(times)
    n = np.maximum(1, np.ceil(speed * h / START_M)).astype(np.int64)
    return np.concatenate((times[:1], _pieces(times[:-1], h, n)))


def _pieces(start: np.ndarray, length: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Each interval ``start[i]`` .. ``start[i] + length[i]`` cut into ``n[i]`` even
    pieces: the ends of the pieces, the interval's own end exactly (in order)."""
    k = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n) + 1  # 1..n per interval
    out = np.repeat(start, n) + np.repeat(length, n) * (k / np.repeat(n, n))
    out[np.cumsum(n) - 1] = start + length
    return np.asarray(out)


def _stretches_to_cut(
    T: np.ndarray,
    free: np.ndarray,
    tight: np.ndarray,
    reach: np.ndarray,
    times: np.ndarray,
    peaks: np.ndarray,
    step: float,
    floor: float,
) -> list[tuple[int, int]]:
    """The stretches ``T[i]`` .. ``T[i+1]`` whose bound is below ``floor`` [m], each with
    the number of pieces to cut it into: enough that each piece's travel is about twice
    the ends' room above the floor (bounds: :func:`manus.motion_kernels.stretch_bounds`,
    from each end's margins and reaches and the segment's peak joint speeds)."""
    dt = np.diff(T)
    seg = np.clip(np.searchsorted(times, T[:-1], side="right") - 1, 0, len(peaks) - 1)
    moves = peaks[seg] * dt[:, None]  # (n-1, 6): the most each joint turns [rad]
    bound, travel = np.empty(len(dt)), np.empty(len(dt))
    stretch_bounds(moves, free, reach, bound, travel)
    open_ = np.flatnonzero((bound < floor) & (travel > step))
    if not len(open_):
        return []
    room = np.maximum(np.minimum(tight[open_], tight[open_ + 1]) - floor, step / 2.0)
    pieces = np.clip(np.ceil(travel[open_] / (2.0 * room)), 2, 8).astype(np.int64)
    return list(zip(open_.tolist(), pieces.tolist(), strict=True))
