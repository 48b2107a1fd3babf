"""Whole motions through the collision model: continuous checking by conservative
advancement.

:func:`sweep` computes distances at few configurations of a motion and proves the
stretches in between clear: at a checked configuration each moving body has a margin
(its distance to the nearest thing it must keep clear of, minus that class's
clearance), and while no point of the body can have moved further than that, no gap can
have closed. How far the points have moved comes from the motion itself: its positions
on a fine grid (every knot, and no more than 10 mm of any point's travel apart), each
body's cover points there (:class:`manus.travel.BodyPoints`, vectorised over the whole
grid), and in between the segment's peak joint speeds times each joint's farthest reach
to the body. The next configuration checked is the first grid sample the bound cannot
reach; far from obstacles a few cover a whole trajectory, near them the advance shrinks
to ``step``.

Two tolerances, both stated: a violation shallower than ``step / 2`` (1 mm) can lie
between two checked configurations, and the smallest margin reported is at most
``tolerance + step`` above the motion's true smallest (each advance also keeps every
body above the smallest margin found so far minus ``tolerance``).
:func:`straight_motion_problem` checks the arm's own fold motions, straight lines in
joint space.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from manus.collision import Check, Clearance, CollisionModel
from manus.travel import BodyPoints

STEP_M = 0.002
"""Smallest advance: the travel [m] a body may make past its margin when that margin is
smaller (a violation shallower than half of it may go unseen)."""

TOLERANCE_M = 0.020
"""How far [m] the stretches between checked configurations may come below the smallest
margin found: the reported smallest margin is within ``TOLERANCE_M + STEP_M`` of the
motion's true one (a check every 10 mm of travel: within 5 mm)."""

GRID_M = 0.010
"""Largest travel of any point between two grid samples [m], by the speed bound."""

_WINDOW = 48
"""Grid intervals bounded by the first vectorised step of an advance (doubling after)."""


class Sweep(NamedTuple):
    """What :func:`sweep` found.

    Attributes:
        worst: the smallest margin over the checked configurations.
        violation: the first checked configuration whose margin is negative (None: none).
        checked: configurations whose distances were computed [-].
        samples: configurations on the motion's grid [-].
    """

    worst: Clearance
    violation: Clearance | None
    checked: int
    samples: int


class _At(NamedTuple):
    """A configuration of the motion: time [s], angles [rad] (6,), cover points [m]
    (n, 3), per keep-in zone each body's margin [m] (B,)."""

    t: float
    q: np.ndarray
    points: np.ndarray
    keep_in: list[np.ndarray]


def sweep(
    model: CollisionModel,
    times: np.ndarray,
    qd_peaks: np.ndarray,
    evaluate: Callable[[np.ndarray], np.ndarray],
    *,
    step: float = STEP_M,
    tolerance: float = TOLERANCE_M,
) -> Sweep:
    """Check a motion continuously against every check (see the module docstring).

    Args:
        times: knot times [s], shape (S+1,).
        qd_peaks: largest |joint speed| on each segment [rad/s], shape (S, 6).
        evaluate: positions at times [s], shape (n,) -> (n, 6) [rad].
        step: smallest advance of any point [m].
        tolerance: how far below the smallest margin found the unchecked stretches may
            be [m].
    """
    motion = _Motion(model, np.asarray(times, dtype=float), qd_peaks, evaluate)
    at, j = motion.sample(0), 1  # j: the first grid sample after at.t
    checked = 0
    worst: Clearance | None = None
    while True:
        found, free = motion.probe(at)
        checked += 1
        if worst is None or found.margin < worst.margin:
            worst = found
        if found.margin < 0.0 or j >= len(motion.grid) or not np.isfinite(free).any():
            violation = found if found.margin < 0.0 else None
            return Sweep(worst, violation, checked, len(motion.grid))
        floor = max(0.0, worst.margin - tolerance)
        allowance = np.where(np.isfinite(free), np.maximum(free - floor, step), np.inf)
        k = motion.first_unproven(at, j, allowance)
        if k is None:
            return Sweep(worst, None, checked, len(motion.grid))  # proven to the end
        if k >= j:
            at, j = motion.sample(k), k + 1
        else:  # not even to the next grid sample: creep by the speed bound
            at = motion.between(at, j, allowance)


class _Motion:
    """A motion on its grid: angles, cover points and keep-in margins at every sample,
    and the bounds of how far the bodies travel in between."""

    def __init__(
        self,
        model: CollisionModel,
        times: np.ndarray,
        qd_peaks: np.ndarray,
        evaluate: Callable[[np.ndarray], np.ndarray],
    ) -> None:
        self.model = model
        self.bodies = _body_points(model)
        self.times = times
        self.peaks = np.abs(np.asarray(qd_peaks, dtype=float))
        self.evaluate = evaluate
        b = self.bodies
        # Per segment and body: how fast any point of the body can move [m/s].
        self.speed = self.peaks @ b.levers + (self.peaks @ b.moves) * b.radius
        self.grid = _grid(times, self.speed)
        self.Q = evaluate(self.grid)
        self.points = b.world(self.Q)
        self.keep_in = b.keep_in(self.points)
        segment = np.clip(
            np.searchsorted(times, self.grid[:-1], side="right") - 1, 0, len(self.peaks) - 1
        )
        self.spread = self.speed[segment] * np.diff(self.grid)[:, None]  # (G-1, B) [m]

    def sample(self, k: int) -> _At:
        return _At(float(self.grid[k]), self.Q[k], self.points[k], [m[k] for _, m in self.keep_in])

    def between(self, at: _At, j: int, allowance: np.ndarray) -> _At:
        """The configuration as far from ``at`` as the speed bound allows (before grid
        sample ``j``)."""
        seg = min(int(np.searchsorted(self.times, at.t, side="right")) - 1, len(self.peaks) - 1)
        speed = self.speed[seg]
        dt = float(np.min(allowance / np.where(speed > 0.0, speed, 1e-12)))
        t = min(at.t + dt, float(self.grid[j]))
        q = self.evaluate(np.array([t]))[0]
        points = self.bodies.world(q[None])
        return _At(t, q, points[0], [m[0] for _, m in self.bodies.keep_in(points)])

    def probe(self, at: _At) -> tuple[Clearance, np.ndarray]:
        """The tightest check at ``at`` and each moving body's margin [m] (B,)."""
        free, tight, row = self.model.pair_margins(at.q)
        check = self.model.checks[row] if row >= 0 else Check("", "", "self", 0.0)
        for (zone, _), margins in zip(self.keep_in, at.keep_in, strict=True):
            np.minimum(free, margins, out=free)
            b = int(np.argmin(margins))
            if margins[b] < tight:
                tight, check = float(margins[b]), zone._replace(body=self.bodies.names[b])
        return Clearance(tight, tight + check.required, check, at.t, at.q), free

    def first_unproven(self, at: _At, j: int, allowance: np.ndarray) -> int | None:
        """The last grid sample (``>= j``) up to which no body of the motion from ``at``
        can have moved past its ``allowance`` [m]; ``j - 1`` when not even sample ``j``
        is reached; None when the motion is proven to its end.

        Over an interval whose ends have moved ``D0`` and ``D1`` and whose points move no
        faster than ``v`` for ``dt``, nothing has moved more than ``(D0 + D1 + v dt) / 2``.
        """
        b, last = self.bodies, len(self.grid) - 1
        seg = min(int(np.searchsorted(self.times, at.t, side="right")) - 1, len(self.peaks) - 1)
        first_spread = self.speed[seg] * (self.grid[j] - at.t)
        k, window = j, _WINDOW
        while True:
            stop = min(k + window, last)
            window *= 2
            moved = b.displacement(self.points[k : stop + 1], at.points)
            moved += (np.abs(self.Q[k : stop + 1] - at.q) @ b.moves) * b.radius
            if k == j and ((moved[0] + first_spread) / 2.0 > allowance).any():
                return j - 1
            spread = self.spread[k:stop]
            bad = ((moved[:-1] + moved[1:] + spread) / 2.0 > allowance).any(axis=1)
            if bad.any():
                return k + int(np.argmax(bad))
            if stop == last:
                return None
            k = stop


def _body_points(model: CollisionModel) -> BodyPoints:
    """The model's :class:`BodyPoints`, built once per model."""
    found = getattr(model, "_body_points", None)
    if found is None:
        found = BodyPoints(model)
        model._body_points = found  # type: ignore[attr-defined]
    return found


def _grid(times: np.ndarray, speed: np.ndarray) -> np.ndarray:
    """Sample times: every knot, and per segment no more than :data:`GRID_M` of any
    point's travel apart (``speed``: per segment and body, the bound [m/s])."""
    h = np.diff(times)
    n = np.maximum(1, np.ceil(speed.max(axis=1) * h / GRID_M)).astype(np.int64)
    segment = np.repeat(np.arange(len(h)), n)
    within = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n) + 1  # 1..n
    inner = times[segment] + h[segment] * (within / n[segment])
    inner[np.cumsum(n) - 1] = times[1:]  # the knots exactly
    return np.concatenate((times[:1], inner))


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
