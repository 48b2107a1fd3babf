"""Whole motions through the collision model: continuous checking by conservative
advancement, from both ends of every stretch.

:func:`sweep` first tries :func:`manus.fast_sweep.fast_sweep` (the fast check's bounds,
Coal only where the margin is smallest); a motion it cannot prove goes through
:func:`exact_sweep`, described here.

:func:`sweep` computes distances (:meth:`CollisionModel.pair_margins`, Coal) at few
configurations of a motion and proves the stretches in between: at a checked
configuration each moving body has a margin (its distance to the nearest thing it must
keep clear of, minus that class's clearance), and no gap of the body can have closed
while no point of it has moved further than that margin. How far the points have moved
comes from the motion itself: its positions on a grid (every knot, and no more than
:data:`GRID_M` of any point's travel apart), each body's cover points there
(:class:`manus.travel.BodyPoints`, vectorised over the whole grid), and in between each
segment's peak joint speeds times each joint's farthest reach to the body. A body's
margin anywhere in a stretch is at least the larger of what its two ends leave (margin
minus travel from that end).

It starts at the knots and adds configurations in the stretches whose bound is too low
(as many as their ends' margins say they need, else one where the bound is lowest) until
every stretch is proven to stay above zero and above the smallest margin found minus
``tolerance`` (all open stretches bounded in one vectorised pass per round); between
two grid samples it halves the stretch (off the grid), down to ``step``. Pairs that
stay :data:`NEAR_M` apart all along the motion (by boxes that hold each body over the
whole motion) are set aside for it: their least possible margin caps the body's, and
when that cap is below the smallest margin found the motion is swept again with every
pair, so the reported check is always the motion's tightest.

Stated limits: a violation shallower than ``step`` (2 mm) can lie inside a stretch no
point crosses more than ``step`` of, and the smallest margin reported is at most
``tolerance`` (10 mm) above the motion's true smallest (a check every 10 mm of travel:
within 5 mm). :func:`straight_motion_problem` checks the arm's own fold motions,
straight lines in joint space.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from manus.clearance import Check, Clearance
from manus.collision import CollisionModel
from manus.fast_sweep import fast_sweep
from manus.travel import BodyPoints

STEP_M = 0.002
"""Shortest stretch refined [m] (of any point's travel): a violation shallower than it
may go unseen inside one."""

TOLERANCE_M = 0.010
"""How far [m] the stretches between checked configurations may come below the smallest
margin found: the reported smallest margin is within it of the motion's true one."""

GRID_M = 0.020
"""Largest travel of any point between two grid samples [m], by the speed bound (finer
grids cost more per round than they save in Coal queries)."""


NEAR_M = 0.15
"""Pairs whose boxes stay this far apart [m] all along a motion are set aside: the
distances are asked of Coal only for the others (:meth:`CollisionModel.restrict`)."""

MAX_PIECES = 8
"""Most pieces a stretch is cut into in one round."""


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
    (3, m) (coordinates first), per keep-in zone each body's margin [m] (B,), its grid
    sample (-1: between samples)."""

    t: float
    q: np.ndarray
    points: np.ndarray
    keep_in: list[np.ndarray]
    k: int


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
        step: shortest stretch refined (of any point's travel) [m].
        tolerance: how far below the smallest margin found the unchecked stretches may
            be [m].
    """
    proof = fast_sweep(model, times, qd_peaks, evaluate, step=step, tolerance=tolerance)
    if proof is not None:
        return Sweep(proof.worst, None, proof.checked, proof.checked)
    return exact_sweep(model, times, qd_peaks, evaluate, step=step, tolerance=tolerance)


def exact_sweep(
    model: CollisionModel,
    times: np.ndarray,
    qd_peaks: np.ndarray,
    evaluate: Callable[[np.ndarray], np.ndarray],
    *,
    step: float = STEP_M,
    tolerance: float = TOLERANCE_M,
) -> Sweep:
    """:func:`sweep` with Coal's distances at every configuration it checks (what
    :func:`sweep` falls back on when the fast check cannot prove the motion)."""
    motion = _Motion(model, np.asarray(times, dtype=float), qd_peaks, evaluate)
    lo, hi = motion.boxes()
    aside = model.restrict(lo, hi, NEAR_M)
    try:
        found = motion.run(tolerance, step)
    finally:
        model.unrestrict()
    if found.violation is None and float(aside.min()) < found.worst.margin:
        found = motion.run(tolerance, step)  # the smallest may be a pair set aside: name it
    return found


class _Checked(NamedTuple):
    """A configuration whose distances were computed: where, each moving body's margin
    [m] (B,), and the tightest check."""

    at: _At
    free: np.ndarray
    found: Clearance


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

    def run(self, tolerance: float, step: float) -> Sweep:
        """Check the knots, then refine (:meth:`refine`)."""
        last = len(self.grid) - 1
        knots = np.unique(np.clip(np.searchsorted(self.grid, self.times), 0, last))
        checked = self.refine([self.check(self.sample(k)) for k in knots], tolerance, step)
        bad = [c.found for c in checked if c.found.margin < 0.0]
        worst = bad[0] if bad else min((c.found for c in checked), key=lambda f: f.margin)
        return Sweep(worst, bad[0] if bad else None, len(checked), last + 1)

    def boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """Per moving body, a box that holds it all along the motion [m], low and high
        corners (3, B): its cover points' extent over the grid, grown by its radius and
        :data:`GRID_M` (no point travels further between two samples)."""
        b, W = self.bodies, self.points
        grow = b.radius + GRID_M
        lo = np.minimum.reduceat(W.min(axis=2), b.starts, axis=1) - grow
        hi = np.maximum.reduceat(W.max(axis=2), b.starts, axis=1) + grow
        return lo, hi

    def sample(self, k: int) -> _At:
        return _At(
            float(self.grid[k]),
            self.Q[k],
            self.points[:, :, k],
            [m[:, k] for _, m in self.keep_in],
            k,
        )

    def check(self, at: _At) -> _Checked:
        """Compute the distances at ``at``."""
        found, free = self.probe(at)
        return _Checked(at, free, found)

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

    def refine(self, checked: list[_Checked], tolerance: float, step: float) -> list[_Checked]:
        """Check more configurations until no stretch between two checked ones can come
        below the smallest margin found minus ``tolerance``, nor below zero: per body,
        the larger of the two ends' lower bounds (its margin there minus its travel
        bound from there). A stretch on the grid is cut into as many even pieces as
        its ends' margin above that floor says it needs (twice that slack of travel per
        piece, at most :data:`MAX_PIECES`), which settles most stretches in one round;
        otherwise a new configuration goes where the bound is lowest (or halfway,
        between two grid samples); a stretch no point can cross more than
        ``step`` of is left as it is. All open stretches are bounded in one vectorised
        pass per round. Once a violation is found only the stretches before the first
        one are refined further (the first one along the motion is the one reported)."""
        out = list(checked)
        pending = list(range(len(out) - 1))
        while pending:
            bad = next((c.at.t for c in out if c.found.margin < 0.0), math.inf)
            pending = [i for i in pending if out[i + 1].at.t <= bad]
            if not pending:
                break
            worst = min(c.found.margin for c in out)
            lows, farthest, inner_best = self._bounds(out, pending)
            floor = max(worst - tolerance, 0.0)
            added: list[tuple[int, list[_At]]] = []
            for n, i in enumerate(pending):
                if lows[n] >= floor or farthest[n] <= step:
                    continue
                a, b = out[i].at, out[i + 1].at
                slack = min(out[i].found.margin, out[i + 1].found.margin) - floor
                pieces = math.ceil(farthest[n] / max(2.0 * slack, GRID_M))
                if a.k >= 0 and b.k >= 0 and pieces > 2 and b.k - a.k > 2:
                    p, span = min(pieces, MAX_PIECES, b.k - a.k), b.k - a.k
                    added.append(
                        (i, [self.sample(a.k + (2 * span * j + p) // (2 * p)) for j in range(1, p)])
                    )
                    continue
                k = inner_best(n)
                added.append((i, [self.sample(k) if k >= 0 else self.at_time((a.t + b.t) / 2)]))
            pending = []
            shift = 0
            for i, ats in added:
                j = i + shift
                out[j + 1 : j + 1] = [self.check(at) for at in ats]
                pending += list(range(j, j + len(ats) + 1))
                shift += len(ats)
        return out

    def at_time(self, t: float) -> _At:
        """The configuration at ``t`` [s] (between grid samples)."""
        q = self.evaluate(np.array([t]))[0]
        points = self.bodies.world(q[None])
        return _At(t, q, points[:, :, 0], [m[:, 0] for _, m in self.bodies.keep_in(points)], -1)

    def _bounds(
        self, out: list[_Checked], pending: list[int]
    ) -> tuple[np.ndarray, np.ndarray, Callable[[int], int]]:
        """For the stretches ``out[i]`` to ``out[i + 1]``, ``i`` in ``pending``: the lower
        bound of the margin [m], the farthest any body can travel between the two ends
        [m], and a function giving the inner grid sample where the bound is lowest (-1:
        none)."""
        G, grid = len(self.grid), self.grid
        extra: list[_At] = []  # ends between grid samples: appended after the grid

        def row(at: _At) -> int:
            if at.k >= 0:
                return at.k
            extra.append(at)
            return G + len(extra) - 1

        ra = np.array([row(out[i].at) for i in pending])
        rb = np.array([row(out[i + 1].at) for i in pending])
        lo = np.searchsorted(grid, [out[i].at.t for i in pending], side="right")
        hi = np.searchsorted(grid, [out[i + 1].at.t for i in pending], side="left")
        counts = hi - lo + 2  # the inner samples and the two ends
        starts_arr = np.cumsum(counts) - counts
        last = starts_arr + counts - 1
        rows = np.repeat(lo - 1 - starts_arr, counts) + np.arange(int(counts.sum()))
        rows[starts_arr], rows[last] = ra, rb
        starts = starts_arr.tolist()
        points, Q, T = self.points, self.Q, grid
        if extra:
            points = np.concatenate((points, np.stack([e.points for e in extra], axis=-1)), axis=2)
            Q = np.concatenate((Q, np.array([e.q for e in extra])))
            T = np.concatenate((grid, [e.t for e in extra]))
        at_end = np.stack((np.repeat(ra, counts), np.repeat(rb, counts)))  # (2, R)
        ts = T[rows]
        body = self.bodies
        moved = body.displacement(points, rows, at_end)  # (2, R, B)
        moved += (np.abs(Q[rows][None] - Q[at_end]) @ body.moves) * body.radius
        pair = np.repeat(np.arange(len(pending)), counts)
        free = np.array([[out[i].free for i in pending], [out[i + 1].free for i in pending]])
        free = free[:, pair]  # (2, R, B)
        seg = np.clip(
            np.searchsorted(self.times, ts[:-1], side="right") - 1, 0, len(self.peaks) - 1
        )
        spread = self.speed[seg] * np.diff(ts)[:, None]
        travel = (moved[:, :-1] + moved[:, 1:] + spread) * 0.5
        per_interval = (free[:, :-1] - travel).max(axis=0).min(axis=1)
        across = np.array(starts[1:], dtype=np.int64) - 1  # intervals between stretches
        per_interval[across] = np.inf
        lows = np.minimum.reduceat(per_interval, starts)
        reach = travel[0].max(axis=1)
        reach[across] = 0.0
        farthest = np.maximum.reduceat(reach, starts)
        per_sample = (free - moved).max(axis=0).min(axis=1)

        def inner_best(n: int) -> int:
            first, stop = starts[n] + 1, int(last[n])
            if stop <= first:
                return -1
            return int(rows[first + int(np.argmin(per_sample[first:stop]))])

        return lows, farthest, inner_best


def _body_points(model: CollisionModel) -> BodyPoints:
    """The model's :class:`BodyPoints`, built once per model and kept by it
    (:attr:`CollisionModel.derived`)."""
    found = model.derived.get("body_points")
    if not isinstance(found, BodyPoints):
        found = model.derived["body_points"] = BodyPoints(model)
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
    start = ", ".join(str(round(v)) for v in np.degrees(a))  # no "-0"
    return (
        f"{what} from ({start}) deg would bring the {bad.describe()} "
        f"{bad.time * 100:.0f} % of the way"
    )
