"""Time for a path of joint waypoints: the project's spline, its limits, and the sweep.

A search's path is straight in joint space between its waypoints, and only those
straight motions were proven clear. The trajectory through them is the planner's own
interpolation (:mod:`.spline`): knot times from each stretch's largest joint move at
``speed`` times the joints' speed and acceleration limits, the clamped cubic spline's
knot velocities (or quintic segments with zero acceleration at both ends), then one
uniform time stretch that brings every joint's exact peak speed and acceleration within
those limits (:func:`~services.planner.spline.time_stretch`).

A spline rounds the corners of the path, so it can leave what was proven: the curve is
checked again, whole (joint limits by exact extremes, the arm's work area, and the
fast conservative check at samples no more than :data:`SAMPLE_M` of any point's travel
apart). Where it fails, the stretch's midpoint (on the straight path) becomes one more
knot, so that the curve hugs the path there, up to :data:`MAX_INSERTIONS` times; if the
curve still fails, every knot gets zero velocity: each stretch is then exactly its
straight motion (the arm stops at each waypoint). The exact, continuous sweep of the
final curve (:func:`manus.sweep.sweep`) is the planner's shared stage
(:meth:`services.planner.planner.Planner.plan`), after this.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from manus.config import ArmConfig
from services.planner.spline import (
    PiecewisePolynomial,
    clamped_cubic_velocities,
    quintic_knot_accelerations,
    time_stretch,
)
from services.planner.work_area import WorkArea

MAX_INSERTIONS = 6
"""Knots added where the spline leaves what was proven, before stopping at each waypoint."""

MIN_SEGMENT_S = 0.2
"""Shortest time between two knots [s]."""

WORK_STEP_M = 0.002
"""Largest change of the work-area margin between two samples of a curve [m]."""

SAMPLE_M = 0.004
"""Largest travel of any point of the arm between two samples of the spline's check [m]
(the final sweep, exact and continuous, is the planner's shared stage)."""

SAMPLE_LEVERS = np.array([1.0, 1.0, 0.6, 0.3, 0.3, 0.2])
"""Farthest any point of the arm is from each joint's axis [m] (generous bounds: the
gripper is at most 0.99 m from the shoulder)."""


class Timed(NamedTuple):
    """A path with time.

    Attributes:
        curve: the trajectory (its knots: the waypoints and any inserted ones).
        knots: the knot positions [rad], shape (n, 6).
        velocities: the knot velocities [rad/s], shape (n, 6).
        accelerations: knot accelerations [rad/s^2], shape (n, 6) (quintic), else None.
        notes: what was done, for the user.
    """

    curve: PiecewisePolynomial
    knots: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray | None
    notes: list[str]


class Unfit(NamedTuple):
    """Why no timing of the path passed: the last check's finding (one line)."""

    problem: str


def knot_times(knots: np.ndarray, arm: ArmConfig, speed: float) -> np.ndarray:
    """Times of the knots [s], shape (n,): each stretch as long as a rest-to-rest cubic
    needs for its largest joint move at ``speed`` times the limits (at least
    :data:`MIN_SEGMENT_S`)."""
    step = np.abs(np.diff(knots, axis=0))
    v = speed * np.asarray(arm.max_speed)
    a = speed * np.asarray(arm.max_accel)
    h = np.maximum(1.5 * step / v, np.sqrt(6.0 * step / a)).max(axis=1)
    return np.concatenate([[0.0], np.cumsum(np.maximum(h, MIN_SEGMENT_S))])


def fit(
    knots: np.ndarray,
    arm: ArmConfig,
    speed: float,
    *,
    quintic: bool,
    valid: Callable[[np.ndarray], np.ndarray] | None,
    work: WorkArea | None = None,
    smooth: bool = True,
) -> Timed | Unfit:
    """Time ``knots`` (see the module docstring).

    Args:
        knots: waypoints [rad], shape (n, 6), n >= 2, straight motions between them
            proven clear.
        arm: joint limits, speed and acceleration limits.
        speed: fraction of the speed and acceleration limits to use (0, 1].
        quintic: quintic segments instead of the cubic spline.
        valid: which of many configurations [rad], (m, 6), keep every clearance (the fast
            check, batched: (m,) bool); None: no scene.
        work: the arm's work area to keep all along (None: not kept).
        smooth: try the spline first (False: stop at each waypoint at once).
    """
    knots = np.asarray(knots, dtype=float)
    notes: list[str] = []
    problem = ""
    if smooth and len(knots) > 2:
        for _ in range(MAX_INSERTIONS + 1):
            timed = _timed(knots, arm, speed, quintic, stop=False)
            bad, problem = _check(timed[0], arm, valid, work)
            if bad < 0:
                return Timed(*timed, notes)
            knots = np.insert(knots, bad + 1, 0.5 * (knots[bad] + knots[bad + 1]), axis=0)
        notes.append(
            f"the arm stops at each waypoint: a spline through them {problem} even with "
            f"{MAX_INSERTIONS} knots more"
        )
        knots = _without_inserted(knots)
    timed = _timed(knots, arm, speed, quintic, stop=True)
    bad, problem = _check(timed[0], arm, None, work)
    if bad >= 0:
        return Unfit(problem)
    return Timed(*timed, notes)


def _without_inserted(knots: np.ndarray) -> np.ndarray:
    """Drop knots that lie on the straight line between their neighbours (inserted)."""
    keep = [0]
    for i in range(1, len(knots) - 1):
        a, b, c = knots[keep[-1]], knots[i], knots[i + 1]
        d = c - a
        t = float(np.dot(b - a, d) / max(float(np.dot(d, d)), 1e-300))
        if float(np.abs(a + t * d - b).max()) > 1e-9:
            keep.append(i)
    keep.append(len(knots) - 1)
    return np.asarray(knots[keep])


def _timed(
    knots: np.ndarray, arm: ArmConfig, speed: float, quintic: bool, *, stop: bool
) -> tuple[PiecewisePolynomial, np.ndarray, np.ndarray, np.ndarray | None]:
    """The curve through ``knots`` within ``speed`` times the limits, with its knots, knot
    velocities and accelerations (after the stretch)."""
    times = knot_times(knots, arm, speed)
    zero = np.zeros(knots.shape[1])
    if stop:
        velocities = np.zeros_like(knots)
    else:
        velocities = clamped_cubic_velocities(times, knots, zero, zero)
    accelerations = None
    if quintic:
        accelerations = (
            np.zeros_like(knots) if stop else quintic_knot_accelerations(times, knots, velocities)
        )
    curve = PiecewisePolynomial.hermite(times, knots, velocities, accelerations)
    k = within_limits(curve, arm, speed)
    if k > 1.0:
        curve = curve.stretched(k)
        velocities = velocities / k
        accelerations = None if accelerations is None else accelerations / (k * k)
    return curve, knots, velocities, accelerations


def within_limits(curve: PiecewisePolynomial, arm: ArmConfig, speed: float) -> float:
    """The uniform time stretch (>= 1) that brings every joint's exact peak speed and
    acceleration within ``speed`` times its limits (a hair more than the exact ratio, so
    that rounding leaves no peak above a limit)."""
    v_peak, _ = curve.peak_abs(1)
    a_peak, _ = curve.peak_abs(2)
    stretch = max(
        time_stretch(v_peak, speed * np.asarray(arm.max_speed), 1),
        time_stretch(a_peak, speed * np.asarray(arm.max_accel), 2),
    )
    return stretch * (1.0 + 1e-9) if stretch > 1.0 else 1.0


def _check(
    curve: PiecewisePolynomial,
    arm: ArmConfig,
    valid: Callable[[np.ndarray], np.ndarray] | None,
    work: WorkArea | None,
) -> tuple[int, str]:
    """The first failing segment of ``curve`` (-1: none) and what fails there: a joint
    limit, the work area, a clearance at one of the samples :func:`samples` takes
    (``valid``; None: not checked here)."""
    ex = curve.extremes(0)
    lower, upper = arm.lower_array, arm.upper_array
    beyond = (ex.low < lower).any(axis=1) | (ex.high > upper).any(axis=1)
    if beyond.any():
        seg = int(np.argmax(beyond))
        j = int(np.argmax((ex.low[seg] < lower) | (ex.high[seg] > upper)))
        value = ex.low[seg, j] if ex.low[seg, j] < lower[j] else ex.high[seg, j]
        return seg, f"takes joint {j + 1} to {math.degrees(value):.1f} deg, beyond its limit"
    if work is not None:
        seg, problem = work_area_problem(curve, work)
        if seg >= 0:
            return seg, f"leaves the arm's work area ({problem})"
    if valid is None:
        return -1, ""
    segment, Q = samples(curve, SAMPLE_LEVERS, SAMPLE_M)
    ok = valid(Q)
    if ok.all():
        return -1, ""
    k = int(np.argmin(ok))
    return int(
        segment[k]
    ), f"comes too close to something at t = {float(curve.times[segment[k]]):.2f} s"


def samples(
    curve: PiecewisePolynomial, levers: np.ndarray, step: float
) -> tuple[np.ndarray, np.ndarray]:
    """Configurations along ``curve`` no more than ``step`` [m] apart for a point whose
    speed is at most the joint speeds times ``levers`` [m], shape (6,): each sample's
    segment (m,) and the configurations [rad] (m, 6), every knot included."""
    speed = curve.extremes(1)
    peaks = np.maximum(np.abs(speed.low), np.abs(speed.high))  # (S, 6)
    counts = np.maximum(1, np.ceil((peaks @ levers) * curve.h / step)).astype(np.int64)
    segment = np.repeat(np.arange(len(counts)), counts + 1)
    starts = np.repeat(np.cumsum(counts + 1) - counts - 1, counts + 1)
    within = np.arange(int((counts + 1).sum())) - starts
    ts = curve.times[segment] + curve.h[segment] * within / counts[segment]
    return segment, curve.evaluate(ts)


def work_area_problem(curve: PiecewisePolynomial, work: WorkArea) -> tuple[int, str]:
    """The first segment of ``curve`` whose gripper leaves the arm's work area (or whose
    elbow straightens too far), sampled every :data:`WORK_STEP_M` of the area margin's
    change bound; (-1, "") when clear."""
    segment, Q = samples(curve, work.levers, WORK_STEP_M)
    area, elbow = work.margins(Q)
    bad = (area < WORK_STEP_M) | (elbow < 0.0)
    if not bad.any():
        return -1, ""
    k = int(np.argmax(bad))
    return int(segment[k]), work.margin(Q[k]).what
