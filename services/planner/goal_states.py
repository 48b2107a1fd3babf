"""The joint configurations that reach a goal: every valid IK branch is a goal state.

A pose target is turned into candidate poses (the pose itself; with ``free_axis``,
:data:`FREE_AXIS_STEPS` turns about the gripper's approach axis; with tolerances,
:data:`TOLERANCE_SAMPLES` seeded poses within them), each solved for every closed-form IK
branch (:func:`manus.kinematics.ik_batch`), each solution moved by whole turns to lie
within the joint limits and nearest the start. Configurations too close to something
(the class clearances, the zones, the arm itself) are skipped. What is left, nearest the
start first (joint-space distance), are the goal states of the search.

Refusals name the reason: the gripper position inside a keep-out zone or outside the
keep-in zone, or every solution outside the arm's own work area (``zone``,
:mod:`.work_area`); no IK solution (``unreachable``, with the workspace's reason);
every solution beyond a joint limit (``joint_limit``, the nearest one named); every
solution too close to something (``goal_collision``, each branch with what it hits).
"""

from __future__ import annotations

import math

import numpy as np

from manus.config import ArmConfig
from manus.errors import KinematicsError
from manus.kinematics import BRANCHES, TWO_PI, ik_all, ik_batch, wrap
from manus.scene import Primitive, Scene
from manus.shapes import inner_distances
from services.planner.errors import refuse
from services.planner.goal_target import Target
from services.planner.knots import branch_name
from services.planner.validity import Validity
from services.planner.work_area import WorkArea

FREE_AXIS_STEPS = 12
"""Turns about the gripper's axis tried for a ``free_axis`` goal (every 30 deg)."""

TOLERANCE_SAMPLES = 8
"""Seeded poses within a goal's tolerances tried besides the pose itself."""

MAX_GOAL_STATES = 32
"""Most goal states handed to the search (the nearest the start)."""

_SHIFTS = TWO_PI * np.array([0.0, -1.0, 1.0, -2.0, 2.0])


def goal_states(
    target: Target,
    start: np.ndarray,
    arm: ArmConfig,
    validity: Validity,
    scene: Scene | None,
    seed: int,
    work: WorkArea,
) -> np.ndarray:
    """Valid goal configurations [rad], shape (k, 6), k >= 1, nearest ``start`` first.

    Raises:
        PlanningError: ``zone``, ``unreachable``, ``joint_limit`` or ``goal_collision``
            (see the module docstring), naming the target.
    """
    if target.joints is not None:
        candidates = target.joints[None, :]
        _check_limits(candidates[0], arm, target.label)
        branches = [""]
    else:
        assert target.pose is not None
        _check_zones(target.pose, scene, target.label)
        candidates, branches = _solve(target, start, arm, seed)
    area, elbow = work.margins(candidates)
    inside = (area >= 0.0) & (elbow >= 0.0)
    if not inside.any():
        what = work.margin(candidates[0]).what
        raise refuse(
            "zone",
            f"{target.label}: outside the arm's own work area ({what}): the arm refuses to "
            "go there (warning 1 or 2)",
            value=float(area[0]),
            limit=0.0,
        )
    candidates = candidates[inside]
    branches = [b for b, ok in zip(branches, inside, strict=True) if ok]
    order = np.argsort(np.linalg.norm(candidates - start, axis=1), kind="stable")
    kept: list[np.ndarray] = []
    hits: dict[str, str] = {}
    zone_only = True
    for i in order:
        q = candidates[i]
        if any(float(np.abs(q - k).max()) < 1e-9 for k in kept):
            continue
        if validity.margins(q).tightest >= 0.0:
            kept.append(q)
            if len(kept) >= MAX_GOAL_STATES:
                break
        elif branches[i] not in hits:
            found = validity.explain(q)
            zone_only = zone_only and found.check.cls == "zone"
            hits[branches[i]] = found.describe()
    if not kept:
        what = "; ".join(f"{b}: {h}" if b else h for b, h in hits.items())
        reason = "zone" if zone_only else "goal_collision"
        raise refuse(
            reason, f"{target.label}: every configuration reaching it is too close: {what}"
        )
    return np.array(kept)


def _check_limits(q: np.ndarray, arm: ArmConfig, label: str) -> None:
    for j in range(len(q)):
        if not arm.lower[j] <= q[j] <= arm.upper[j]:
            lim = arm.lower[j] if q[j] < arm.lower[j] else arm.upper[j]
            raise refuse(
                "joint_limit",
                f"{label}: joint {j + 1} at {math.degrees(q[j]):.2f} deg is beyond its limit "
                f"{math.degrees(lim):.1f} deg",
                joint=j + 1,
                value=float(q[j]),
                limit=float(lim),
            )


def _check_zones(T: np.ndarray, scene: Scene | None, label: str) -> None:
    """Refuse a gripper position inside a keep-out zone (or within its clearance) or
    outside the keep-in zone."""
    if scene is None:
        return
    to_base = np.linalg.inv(scene.mount)
    point = T[:3, 3:4]
    for zone in scene.zones:
        body = Primitive(zone.body.shape, zone.body.size, to_base @ zone.body.pose)
        inner = float(inner_distances(body, point)[0])
        if zone.kind == "keep_out" and inner > -zone.clearance:
            raise refuse(
                "zone",
                f"{label}: the gripper would be inside the keep-out zone {zone.name!r} "
                f"({scene.where(zone.line)}; {inner * 1e3:.1f} mm in, clearance "
                f"{zone.clearance * 1e3:.0f} mm)",
                value=inner,
                limit=-zone.clearance,
            )
        if zone.kind == "keep_in" and inner < zone.clearance:
            raise refuse(
                "zone",
                f"{label}: the gripper would be outside the keep-in zone {zone.name!r} "
                f"({scene.where(zone.line)}; {-inner * 1e3:.1f} mm out, clearance "
                f"{zone.clearance * 1e3:.0f} mm)",
                value=inner,
                limit=zone.clearance,
            )


def target_poses(target: Target, seed: int) -> np.ndarray:
    """The target pose, its turns about the gripper's axis (``free_axis``) and seeded
    poses within its tolerances [m], shape (n, 4, 4), the target itself first."""
    assert target.pose is not None
    T = target.pose
    turns = [0.0]
    if target.free_axis:
        turns = [TWO_PI * k / FREE_AXIS_STEPS for k in range(FREE_AXIS_STEPS)]
    poses = [T @ _about_z(a) for a in turns]
    if target.position_tolerance > 0.0 or target.angle_tolerance > 0.0:
        rng = np.random.default_rng(seed)
        for _ in range(TOLERANCE_SAMPLES):
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            offset = direction * target.position_tolerance * rng.uniform() ** (1.0 / 3.0)
            axis = rng.normal(size=3)
            axis /= np.linalg.norm(axis)
            R = _rotation(axis, target.angle_tolerance * rng.uniform())
            turn = rng.uniform(0.0, TWO_PI) if target.free_axis else 0.0
            P = np.eye(4)
            P[:3, :3] = R @ T[:3, :3]
            P[:3, 3] = T[:3, 3] + offset
            poses.append(P @ _about_z(turn))
    return np.array(poses)


def _solve(
    target: Target, start: np.ndarray, arm: ArmConfig, seed: int
) -> tuple[np.ndarray, list[str]]:
    """Every IK solution of the target's poses within the joint limits, nearest
    ``start`` by whole turns; with each one's branch name."""
    assert target.pose is not None
    solved = ik_batch(target_poses(target, seed), arm)
    if not solved.valid.any():
        try:
            ik_all(target.pose, arm)
            why = "no IK solution"
        except KinematicsError as exc:
            why = str(exc)
        raise refuse("unreachable", f"{target.label}: outside the workspace: {why}")
    rows = solved.q[solved.valid]  # (m, 6)
    branch_rows = np.broadcast_to(np.arange(len(BRANCHES)), solved.valid.shape)[solved.valid]
    near = start + wrap(rows - start)
    shifted = near[:, :, None] + _SHIFTS  # (m, 6, 5)
    lower, upper = arm.lower_array[None, :, None], arm.upper_array[None, :, None]
    inside = (shifted >= lower) & (shifted <= upper)
    cost = np.where(inside, np.abs(shifted - start[None, :, None]), np.inf)
    pick = cost.argmin(axis=2)
    fitted = np.take_along_axis(shifted, pick[:, :, None], axis=2)[:, :, 0]
    ok = inside.any(axis=2).all(axis=1)
    if not ok.any():
        excess = np.maximum(arm.lower_array - near, near - arm.upper_array)  # (m, 6)
        r, j = np.unravel_index(int(np.argmin(np.where(excess > 0, excess, np.inf))), excess.shape)
        value = float(near[r, j])
        lim = arm.lower[j] if value < arm.lower[j] else arm.upper[j]
        raise refuse(
            "joint_limit",
            f"{target.label}: every IK solution breaks a joint limit; nearest: joint {j + 1} "
            f"at {math.degrees(value):.1f} deg, limit {math.degrees(lim):.1f} deg",
            joint=int(j) + 1,
            value=value,
            limit=float(lim),
        )
    names = [branch_name(_signs(BRANCHES[b])) for b in branch_rows[ok]]
    return np.asarray(fitted[ok]), names


def _signs(row: np.ndarray) -> tuple[int, int, int]:
    return int(row[0]), int(row[1]), int(row[2])


def _about_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    return T


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` [rad] about the unit ``axis`` (Rodrigues), shape (3, 3)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.asarray(np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K))
