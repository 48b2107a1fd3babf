"""Joint configurations of the via points: one IK branch for the whole path.

The start configuration fixes the branch (shoulder, elbow, wrist signs, :func:`branch_of`);
every via point is solved on that branch (all at once with :func:`ik_batch`) and
unwrapped to lie within half a turn of the previous knot. The planner never changes
branch silently: a via point that has no solution on that branch, or whose solution is
more than ``max_knot_jump`` away from the previous knot in any joint, is refused, as is
one outside the workspace, too close to the wrist singularity, or beyond a joint limit.
"""

from __future__ import annotations

import math

import numpy as np

from manus.errors import KinematicsError
from manus.kinematics import BRANCHES, TWO_PI, branch_of, ik_all, ik_batch, wrap
from services.planner.config import PlannerConfig
from services.planner.errors import PlanningError, refuse
from services.planner.labels import KnotLabels

_SIDE = {1: "+", -1: "-"}


def branch_name(branch: tuple[int, int, int]) -> str:
    """``"shoulder +, elbow -, wrist -"``."""
    s, e, w = branch
    return f"shoulder {_SIDE[s]}, elbow {_SIDE[e]}, wrist {_SIDE[w]}"


def check_start(q: np.ndarray, labels: KnotLabels, config: PlannerConfig) -> None:
    """Refuse a start configuration (knot 0 of ``labels``) beyond a joint limit or at the
    wrist singularity."""
    index, line = labels.via_indices[0], labels.lines[0]
    # A path's via point 0 stands for the start; a resumed plan's start is only the start.
    where = f"{labels.label(0)}, the start configuration" if index >= 0 else labels.label(0)
    arm = config.arm
    for j in range(len(q)):
        if not arm.lower[j] <= q[j] <= arm.upper[j]:
            lim = arm.lower[j] if q[j] < arm.lower[j] else arm.upper[j]
            raise refuse(
                "joint_limit",
                f"{where}: joint {j + 1} at {math.degrees(q[j]):.2f} deg is beyond its limit "
                f"{math.degrees(lim):.1f} deg",
                via_point=index,
                line=line,
                joint=j + 1,
                value=float(q[j]),
                limit=lim,
            )
    _check_wrist(q, index, line, where, config)


def solve_knots(
    labels: KnotLabels, poses: np.ndarray, q_start: np.ndarray, config: PlannerConfig
) -> np.ndarray:
    """Joint configuration of every via point [rad], shape (n, 6); row 0 is ``q_start``.

    Args:
        labels: what each knot is (for the via points' indices, lines and source in errors).
        poses: absolute via point poses (row 0: the start's), shape (n, 4, 4) [m].
        q_start: start configuration [rad], shape (6,).
        config: planner settings.

    Raises:
        PlanningError: ``unreachable``, ``branch``, ``singular`` or ``joint_limit``, naming
            the via point, its line, the joint, the value and the limit.
    """
    arm = config.arm
    branch = branch_of(q_start, arm)
    row = int(np.flatnonzero((np.asarray(branch) == BRANCHES).all(axis=1))[0])
    solved = ik_batch(poses[1:], arm)
    q0 = np.asarray(q_start, dtype=float)
    raw = solved.q[:, row]  # (n-1, 6), NaN off the branch
    # Unwrapping each knot near the previous one, all at once: the whole turns to add
    # follow from the cumulative wrapped steps.
    steps = wrap(np.diff(np.vstack([q0, raw]), axis=0))
    near = q0 + np.cumsum(steps, axis=0)
    knots = np.vstack([q0, raw + TWO_PI * np.round((near - raw) / TWO_PI)])
    with np.errstate(invalid="ignore"):
        bad = (
            ~solved.valid[:, row]
            | (wrist_distance(knots[1:, 4]) < effective_wrist_margin(config))
            | (np.abs(np.diff(knots, axis=0)).max(axis=1) > config.max_knot_jump)
            | (knots[1:] < arm.lower_array).any(axis=1)
            | (knots[1:] > arm.upper_array).any(axis=1)
        )
    if bad.any():
        i = int(np.argmax(bad)) + 1
        _explain(labels, i, poses[i], knots[i], knots[i - 1], solved.valid[i - 1], row, config)
    return knots


def _explain(
    labels: KnotLabels,
    i: int,
    T: np.ndarray,
    q: np.ndarray,
    previous: np.ndarray,
    valid: np.ndarray,
    row: int,
    config: PlannerConfig,
) -> None:
    """Raise the error of via point ``i``, the first one found wrong (in that order:
    workspace, branch existence, wrist, jump, joint limits)."""
    arm = config.arm
    index, line = labels.via_indices[i], labels.lines[i]
    where = labels.label(i)
    s, e, w = (int(b) for b in BRANCHES[row])
    branch = (s, e, w)
    if not valid.any():
        raise _unreachable(T, index, line, where, config)
    if not valid[row]:
        # Reachable but not on this branch: only the exact wrist singularity does that.
        raise refuse(
            "singular",
            f"{where}: the wrist is exactly singular there (joints 4 and 6 aligned)",
            via_point=index,
            line=line,
            joint=5,
            value=0.0,
            limit=config.wrist_margin,
        )
    _check_wrist(q, index, line, where, config)
    jump = np.abs(q - previous)
    j = int(jump.argmax())
    if jump[j] > config.max_knot_jump:
        raise refuse(
            "branch",
            f"{where}: joint {j + 1} would jump {math.degrees(jump[j]):.1f} deg from the "
            f"previous via point (more than {math.degrees(config.max_knot_jump):.0f} deg) "
            f"to stay on the start's IK branch ({branch_name(branch)}): the path needs "
            "a branch flip; add via points or start from another configuration",
            via_point=index,
            line=line,
            joint=j + 1,
            value=float(jump[j]),
            limit=config.max_knot_jump,
        )
    for j in range(len(q)):
        if not arm.lower[j] <= q[j] <= arm.upper[j]:
            lim = arm.lower[j] if q[j] < arm.lower[j] else arm.upper[j]
            raise refuse(
                "joint_limit",
                f"{where}: joint {j + 1} would be at {math.degrees(q[j]):.2f} deg, beyond "
                f"its limit {math.degrees(lim):.1f} deg",
                via_point=index,
                line=line,
                joint=j + 1,
                value=float(q[j]),
                limit=lim,
            )
    raise AssertionError(f"via point {i} was flagged but no check fails")  # pragma: no cover


def effective_wrist_margin(config: PlannerConfig) -> float:
    """The planner's wrist margin, never below the arm's own singularity tolerance [rad]."""
    return max(config.wrist_margin, math.asin(min(1.0, config.arm.singular_tol)))


def wrist_distance(q5: np.ndarray | float) -> np.ndarray:
    """Distance of joint 5 from its nearest singular angle (0 or +-pi) [rad]."""
    q5 = np.asarray(q5, dtype=float)
    return np.asarray(np.abs(q5 - np.pi * np.round(q5 / np.pi)))


def _check_wrist(q: np.ndarray, index: int, line: int, where: str, config: PlannerConfig) -> None:
    margin = effective_wrist_margin(config)
    distance = float(wrist_distance(q[4]))
    if distance < margin:
        singular_at = math.degrees(math.pi * round(float(q[4]) / math.pi))
        raise refuse(
            "singular",
            f"{where}: wrist singularity: joint 5 at {math.degrees(q[4]):.2f} deg is within "
            f"{math.degrees(margin):.1f} deg of {singular_at:.0f} deg (joints 4 and 6 aligned)",
            via_point=index,
            line=line,
            joint=5,
            value=float(q[4]),
            limit=margin,
        )


def _unreachable(
    T: np.ndarray, index: int, line: int, where: str, config: PlannerConfig
) -> PlanningError:
    try:
        ik_all(T, config.arm)
        why = "no IK solution"
        value: float | None = None
        limit: float | None = None
    except KinematicsError as exc:
        why, value, limit = str(exc), exc.value, exc.limit
    return refuse(
        "unreachable",
        f"{where}: outside the workspace: {why}",
        via_point=index,
        line=line,
        value=value,
        limit=limit,
    )
