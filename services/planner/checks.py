"""Checks along the whole interpolated trajectory, not only at the via points.

Joint limits, the wrist singularity and the elbow branch use the exact range of each
joint over each segment (:meth:`PiecewisePolynomial.extremes`); the shoulder branch,
which depends on two joints at once, is sampled (``check_samples`` per segment, plus a
sign change test, so a crossing between samples is still caught). Joint speeds and
accelerations use their exact peaks; with speed scaling the whole trajectory is slowed
uniformly by the smallest factor that respects every limit.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.viapoints import MAX_TIME_S
from services.planner.config import PlannerConfig
from services.planner.errors import refuse
from services.planner.knots import branch_name, effective_wrist_margin, wrist_distance
from services.planner.labels import KnotLabels
from services.planner.spline import PiecewisePolynomial, time_stretch


def check_geometry(
    curve: PiecewisePolynomial,
    labels: KnotLabels,
    branch: tuple[int, int, int],
    config: PlannerConfig,
) -> None:
    """Refuse a trajectory that breaks a joint limit, nears the wrist singularity or
    changes IK branch anywhere between its knots.

    Raises:
        PlanningError: ``joint_limit``, ``singular`` or ``branch``, naming the segment's
            knots (via points and lines), the joint, the time, the value and the limit.
    """
    arm = config.arm
    ex = curve.extremes(0)
    lower, upper = arm.lower_array, arm.upper_array
    margin = effective_wrist_margin(config)
    # Wrist: the range of q5 over a segment comes within `margin` of some k pi.
    k5 = np.ceil((ex.low[:, 4] - margin) / math.pi)
    near_wrist = k5 * math.pi <= ex.high[:, 4] + margin
    # Elbow: sin(q3 - pi/2) keeps its sign unless q3 - pi/2 strictly crosses some k pi.
    k3 = np.floor((ex.low[:, 2] - math.pi / 2) / math.pi) + 1
    elbow_flip = k3 * math.pi < ex.high[:, 2] - math.pi / 2
    bad = (ex.low < lower).any(axis=1) | (ex.high > upper).any(axis=1) | near_wrist | elbow_flip
    if bad.any():
        seg = int(np.argmax(bad))
        index, line = labels.via_indices[seg + 1], labels.lines[seg + 1]
        for j in range(len(lower)):
            for value, when, lim, broken in (
                (ex.low[seg, j], ex.t_low[seg, j], lower[j], ex.low[seg, j] < lower[j]),
                (ex.high[seg, j], ex.t_high[seg, j], upper[j], ex.high[seg, j] > upper[j]),
            ):
                if broken:
                    raise refuse(
                        "joint_limit",
                        f"{labels.between(seg)}: joint {j + 1} reaches {math.degrees(value):.2f} "
                        f"deg at t = {when:.3f} s, beyond its limit {math.degrees(lim):.1f} deg",
                        via_point=index,
                        line=line,
                        joint=j + 1,
                        value=float(value),
                        limit=float(lim),
                    )
        if near_wrist[seg]:
            ts = np.linspace(curve.times[seg], curve.times[seg + 1], 4 * config.check_samples + 1)
            q5 = curve.evaluate(ts)[:, 4]
            i = int(wrist_distance(q5).argmin())
            raise refuse(
                "singular",
                f"{labels.between(seg)}: the wrist passes within {math.degrees(margin):.1f} deg "
                f"of its singularity (joint 5 at {math.degrees(q5[i]):.2f} deg at "
                f"t = {ts[i]:.3f} s; joints 4 and 6 aligned)",
                via_point=index,
                line=line,
                joint=5,
                value=float(q5[i]),
                limit=margin,
            )
        crossing = float(k3[seg] * math.pi + math.pi / 2)
        raise refuse(
            "branch",
            f"{labels.between(seg)}: the elbow straightens (joint 3 crosses "
            f"{math.degrees(crossing):.0f} deg) and would flip branch ({branch_name(branch)}); "
            "add via points",
            via_point=index,
            line=line,
            joint=3,
            value=float(ex.high[seg, 2]),
            limit=crossing,
        )
    _check_shoulder(curve, labels, branch, config)


def _check_shoulder(
    curve: PiecewisePolynomial,
    labels: KnotLabels,
    branch: tuple[int, int, int],
    config: PlannerConfig,
) -> None:
    arm = config.arm
    m = config.check_samples
    ts = (curve.times[:-1, None] + curve.h[:, None] * np.linspace(0.0, 1.0, m + 1)).ravel()
    q = curve.evaluate(ts)
    u = arm.l2 * np.cos(q[:, 1]) + arm.l3 * np.sin(q[:, 1] + q[:, 2])
    wrong = branch[0] * u < 0.0
    if wrong.any():
        i = int(np.argmax(wrong))
        seg = min(i // (m + 1), len(curve.h) - 1)
        raise refuse(
            "branch",
            f"{labels.between(seg)}: the wrist centre crosses the shoulder axis at "
            f"t = {ts[i]:.3f} s and the shoulder would flip branch ({branch_name(branch)}); "
            "add via points",
            via_point=labels.via_indices[seg + 1],
            line=labels.lines[seg + 1],
            value=float(u[i]),
            limit=0.0,
        )


class RateCheck(NamedTuple):
    """The trajectory after the speed and acceleration check.

    Attributes:
        curve: the (possibly time-stretched) trajectory.
        time_scale: the stretch applied (1: none).
        notes: what was done, for the user.
    """

    curve: PiecewisePolynomial
    time_scale: float
    notes: list[str]


def check_rates(
    curve: PiecewisePolynomial,
    labels: KnotLabels,
    config: PlannerConfig,
    *,
    speed_scaling: bool,
    moving_ends: bool = False,
) -> RateCheck:
    """Check every joint's peak speed and acceleration against the arm's limits.

    Args:
        curve: the trajectory.
        labels: its knots (for messages).
        config: the arm's limits.
        speed_scaling: stretch time uniformly instead of refusing.
        moving_ends: the curve starts or ends moving (said in the note of a stretch).

    Raises:
        PlanningError: ``speed_limit`` (without ``speed_scaling``), naming the joint, the
            time, the value, the limit and the stretch that would fix it.
    """
    arm = config.arm
    v_peak, v_time = curve.peak_abs(1)
    a_peak, a_time = curve.peak_abs(2)
    v_lim, a_lim = np.asarray(arm.max_speed), np.asarray(arm.max_accel)
    k_speed = time_stretch(v_peak, v_lim, 1)
    k_accel = time_stretch(a_peak, a_lim, 2)
    stretch = max(k_speed, k_accel)
    if stretch <= 1.0:
        return RateCheck(curve, 1.0, [])
    if k_speed >= k_accel:
        j = int(np.argmax(v_peak / v_lim))
        what = (
            f"joint {j + 1} speed {math.degrees(v_peak[j]):.1f} deg/s at t = {v_time[j]:.3f} s "
            f"is above its limit {math.degrees(v_lim[j]):.1f} deg/s"
        )
        value, limit, when = float(v_peak[j]), float(v_lim[j]), float(v_time[j])
    else:
        j = int(np.argmax(a_peak / a_lim))
        what = (
            f"joint {j + 1} acceleration {math.degrees(a_peak[j]):.1f} deg/s^2 at "
            f"t = {a_time[j]:.3f} s is above its limit {math.degrees(a_lim[j]):.1f} deg/s^2"
        )
        value, limit, when = float(a_peak[j]), float(a_lim[j]), float(a_time[j])
    seg = int(np.clip(np.searchsorted(curve.times, when, side="right") - 1, 0, len(curve.h) - 1))
    if not speed_scaling:
        raise refuse(
            "speed_limit",
            f"{labels.between(seg)}: {what}; the path's times would have to be {stretch:.3f}x "
            "longer (ask for speed scaling, or give later times)",
            via_point=labels.via_indices[seg + 1],
            line=labels.lines[seg + 1],
            joint=j + 1,
            value=value,
            limit=limit,
        )
    # A hair more than the exact ratio so that rounding cannot leave a peak above a limit.
    stretch *= 1.0 + 1e-9
    if curve.duration * stretch > MAX_TIME_S:
        raise refuse(
            "speed_limit",
            f"{labels.between(seg)}: {what}; slowing the path down enough would make it "
            f"last {curve.duration * stretch:.4g} s, more than {MAX_TIME_S:g} s",
            via_point=labels.via_indices[seg + 1],
            line=labels.lines[seg + 1],
            joint=j + 1,
            value=value,
            limit=limit,
        )
    notes = [
        f"time stretched {stretch:.4f}x (duration {curve.duration:.3f} s -> "
        f"{curve.duration * stretch:.3f} s) because {what}"
    ]
    if moving_ends:
        notes.append(f"the boundary velocities are slowed by the same factor ({stretch:.4f}x)")
    return RateCheck(curve.stretched(stretch), stretch, notes)
