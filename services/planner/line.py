"""Straight Cartesian lines (MoveIt's Pilz LIN): approach and retreat along the gripper's
axis, or any line, checked before anything moves.

The gripper's position moves on the straight line from where it is to the end pose (a
base-frame pose, or a displacement in the gripper's frame), its orientation turning
evenly (slerp) meanwhile; samples every :data:`STEP_M` along it (and every
:data:`STEP_RAD` of turn) are solved on the start's IK branch (:func:`manus.kinematics.
ik_batch`), each unwrapped near the one before. The samples become the knots of the
trajectory, timed by a trapezoidal speed profile along the line (``speed`` times
:data:`MAX_SPEED_M_S` and :data:`MAX_ACCEL_M_S2`), then stretched if a joint's speed or
acceleration limit needs it, and swept through the scene.

A line is refused, naming where (millimetres along it) and why, when it leaves the
reach (``unreachable``), comes within the wrist margin of the wrist singularity or
needs a joint to jump (near the elbow or shoulder singularity: ``singular``), breaks a
joint limit (``joint_limit``), or brings a body too close to something (``collision``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.config import ArmConfig
from manus.errors import KinematicsError
from manus.kinematics import BRANCHES, branch_of, fk, ik_all, ik_batch, wrap
from manus.orientation import ypr_to_matrix
from schemas.goals import LineFrame, LineMotion
from services.planner.config import PlannerConfig
from services.planner.errors import PlanningError, refuse
from services.planner.goal_target import describe_pose
from services.planner.knots import effective_wrist_margin, wrist_distance

STEP_M = 0.002
"""Largest distance between two samples of the line [m]."""

STEP_RAD = math.radians(1.0)
"""Largest turn of the gripper between two samples [rad]."""

MAX_JOINT_STEP = math.radians(5.0)
"""Largest move of any joint between two samples [rad]: more means a singularity."""

MAX_SPEED_M_S = 0.2
"""The gripper's cruise speed at ``speed`` 1 [m/s]."""

MAX_ACCEL_M_S2 = 0.4
"""The gripper's acceleration at ``speed`` 1 [m/s^2]."""

MAX_LENGTH_M = 2.0
"""Longest line [m]."""

ROTATION_M = 0.1
"""How long a turn of the gripper counts when the line is timed [m/rad]."""


class Line(NamedTuple):
    """A line solved in joint space.

    Attributes:
        knots: joint configurations along it [rad], shape (n, 6); the first is the start.
        times: when each is reached [s], shape (n,).
        along: how far along the line each is [m], shape (n,).
        label: how messages name the line.
    """

    knots: np.ndarray
    times: np.ndarray
    along: np.ndarray
    label: str


def end_pose(goal: LineMotion, T0: np.ndarray) -> np.ndarray:
    """The line's end pose [m], (4, 4), from the start pose ``T0``.

    Raises:
        PlanningError: ``invalid``: values not finite.
    """
    values = [*goal.xyz, *(goal.ypr or [])]
    if not all(math.isfinite(v) for v in values):
        raise refuse("invalid", f"line goal: `xyz` and `ypr` must be finite, got {values}")
    R = ypr_to_matrix(*goal.ypr) if goal.ypr is not None else None
    T1 = np.eye(4)
    if goal.frame == LineFrame.TOOL:
        step = np.eye(4)
        step[:3, 3] = goal.xyz
        if R is not None:
            step[:3, :3] = R
        T1 = T0 @ step
    else:
        T1[:3, :3] = R if R is not None else T0[:3, :3]
        T1[:3, 3] = goal.xyz
    return T1


def solve_line(q0: np.ndarray, T1: np.ndarray, config: PlannerConfig, speed: float) -> Line:
    """The line from ``q0``'s gripper pose to ``T1``, solved and timed.

    Raises:
        PlanningError: ``unreachable``, ``singular``, ``joint_limit`` or ``invalid``
            (a line of zero or too great a length), naming the millimetre along it.
    """
    arm = config.arm
    T0 = fk(q0, arm)
    label = f"line from {describe_pose(T0)} to {describe_pose(T1)}"
    p0, p1 = T0[:3, 3], T1[:3, 3]
    length = float(np.linalg.norm(p1 - p0))
    turn = _angle(T0[:3, :3].T @ T1[:3, :3])
    if length > MAX_LENGTH_M:
        raise refuse(
            "invalid", f"{label}: {length * 1e3:.0f} mm long, more than {MAX_LENGTH_M * 1e3:.0f} mm"
        )
    n = max(1, math.ceil(length / STEP_M), math.ceil(turn / STEP_RAD))
    if length < 1e-6 and turn < 1e-6:
        raise refuse("invalid", f"{label}: the gripper is already there")
    s = np.linspace(0.0, 1.0, n + 1)
    poses = np.repeat(np.eye(4)[None], n + 1, axis=0)
    poses[:, :3, 3] = p0 + s[:, None] * (p1 - p0)
    poses[:, :3, :3] = _slerp(T0[:3, :3], T1[:3, :3], s)
    along = s * length
    knots = _solve(q0, poses, along, label, arm, config)
    # A turn counts as a length of ROTATION_M per radian, so a pure turn is timed too.
    effective = s * max(length, turn * ROTATION_M)
    return Line(knots, _profile(effective, speed), along, label)


def _solve(
    q0: np.ndarray,
    poses: np.ndarray,
    along: np.ndarray,
    label: str,
    arm: ArmConfig,
    config: PlannerConfig,
) -> np.ndarray:
    """Every sample on ``q0``'s branch, unwrapped near the previous one; refusals name
    the first sample that fails."""
    branch = branch_of(q0, arm)
    row = int(np.flatnonzero((np.asarray(branch) == BRANCHES).all(axis=1))[0])
    solved = ik_batch(poses[1:], arm)
    raw = solved.q[:, row]
    steps = wrap(np.diff(np.vstack([q0, raw]), axis=0))
    knots = np.vstack([q0, q0 + np.cumsum(np.nan_to_num(steps), axis=0)])
    margin = effective_wrist_margin(config)

    def where(i: int) -> str:
        return f"{label}: at {along[i] * 1e3:.0f} mm of {along[-1] * 1e3:.0f} mm"

    first = float(wrist_distance(q0[4]))
    if first < margin:
        raise refuse(
            "singular",
            f"{where(0)}: the wrist starts within {math.degrees(margin):.1f} deg of its "
            f"singularity (joint 5 at {math.degrees(q0[4]):.2f} deg)",
            joint=5,
            value=float(q0[4]),
            limit=margin,
        )
    for i in range(1, len(knots)):
        if not solved.valid[i - 1, row]:
            raise _unreachable(poses[i], where(i), solved.valid[i - 1].any(), arm)
        q = knots[i]
        if float(wrist_distance(q[4])) < margin:
            raise refuse(
                "singular",
                f"{where(i)}: the line crosses the wrist singularity (joint 5 at "
                f"{math.degrees(q[4]):.2f} deg, within {math.degrees(margin):.1f} deg; "
                "joints 4 and 6 aligned)",
                joint=5,
                value=float(q[4]),
                limit=margin,
            )
        jump = np.abs(q - knots[i - 1])
        j = int(jump.argmax())
        if jump[j] > MAX_JOINT_STEP:
            beyond = np.flatnonzero(~solved.valid[i - 1 :].any(axis=1))
            if len(beyond):  # the arm stretches out before the line leaves its reach
                k = i + int(beyond[0])
                error = _unreachable(poses[k], where(k), False, arm)
                raise refuse(
                    "unreachable",
                    f"{error.error.message} (the arm is stretched out from "
                    f"{along[i] * 1e3:.0f} mm on)",
                )
            raise refuse(
                "singular",
                f"{where(i)}: joint {j + 1} would jump {math.degrees(jump[j]):.1f} deg in "
                f"{STEP_M * 1e3:.0f} mm: the line passes a singularity (arm stretched, or "
                "the wrist over the shoulder's axis)",
                joint=j + 1,
                value=float(jump[j]),
                limit=MAX_JOINT_STEP,
            )
        for k in range(len(q)):
            if not arm.lower[k] <= q[k] <= arm.upper[k]:
                lim = arm.lower[k] if q[k] < arm.lower[k] else arm.upper[k]
                raise refuse(
                    "joint_limit",
                    f"{where(i)}: joint {k + 1} would be at {math.degrees(q[k]):.1f} deg, "
                    f"beyond its limit {math.degrees(lim):.1f} deg",
                    joint=k + 1,
                    value=float(q[k]),
                    limit=float(lim),
                )
    return knots


def _unreachable(T: np.ndarray, where: str, other_branch: bool, arm: ArmConfig) -> PlanningError:
    if other_branch:
        return refuse(
            "singular",
            f"{where}: the arm would have to change its IK branch (the elbow straightens "
            "or the wrist passes over the shoulder's axis)",
        )
    try:
        ik_all(T, arm)
        why = "no IK solution"
    except KinematicsError as exc:
        why = str(exc)
    return refuse("unreachable", f"{where}: the line leaves the arm's reach: {why}")


def _profile(d: np.ndarray, speed: float) -> np.ndarray:
    """Times [s] at which a trapezoidal speed profile (rest to rest) passes the distances
    ``d`` [m] along the line, shape (n,), increasing from 0."""
    total = float(d[-1])
    v, a = speed * MAX_SPEED_M_S, speed * MAX_ACCEL_M_S2
    ramp = v * v / a  # distance of both ramps together
    if ramp > total:  # a triangle: never reaches the cruise speed
        v = math.sqrt(a * total)
        ramp = total
    t_ramp = v / a
    half = ramp / 2.0
    t_end = 2.0 * t_ramp + (total - ramp) / v
    t = np.where(
        d <= half,
        np.sqrt(2.0 * np.maximum(d, 0.0) / a),
        np.where(
            d <= total - half,
            t_ramp + (d - half) / v,
            t_end - np.sqrt(2.0 * np.maximum(total - d, 0.0) / a),
        ),
    )
    return np.asarray(t)


def _angle(R: np.ndarray) -> float:
    return math.acos(max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) / 2.0)))


def _slerp(R0: np.ndarray, R1: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Rotations turning evenly from ``R0`` to ``R1`` at fractions ``s``, (n, 3, 3)."""
    E = R0.T @ R1
    angle = _angle(E)
    out = np.repeat(R0[None], len(s), axis=0)
    if angle < 1e-12:
        return out
    axis = np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    norm = float(np.linalg.norm(axis))
    if norm < 1e-9:  # a half turn: the axis from the symmetric part
        M = (E + np.eye(3)) / 2.0
        k = int(np.argmax(np.diag(M)))
        axis = M[:, k] / math.sqrt(max(float(M[k, k]), 1e-300))
    else:
        axis = axis / norm
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    for i, f in enumerate(s):
        theta = f * angle
        out[i] = R0 @ (np.eye(3) + math.sin(theta) * K + (1.0 - math.cos(theta)) * (K @ K))
    return out
