"""Paths the sequencer writes itself: moves to named poses.

They are ordinary :class:`schemas.planning.Path` messages for the planner: the sequencer
only computes forward kinematics (the Cartesian pose of a joint configuration) and leaves
inverse kinematics, interpolation and every limit check to the planner. (What is left of
a paused plan is the planner's to make: :class:`schemas.planning.PlanResume`.)
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from manus.config import FOLDED_Q_DEG, UNFOLDED_Q_DEG, ArmConfig
from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from schemas.planning import Path, ViaPoint

POSES: dict[str, tuple[float, ...]] = {
    "home": UNFOLDED_Q_DEG,
    "unfolded": UNFOLDED_Q_DEG,
    "folded": FOLDED_Q_DEG,
}
"""Named poses [deg, DH]: ``home`` is the unfolded pose, where the thesis paths start.
A pose step moves there along a planned path; it does not fold the arm (``fold_in``
does, with the arm's own motion)."""

MAX_JOINT_STEP_DEG = 60.0
"""Largest joint move between two via points of a pose path [deg]."""


def _via(q: Sequence[float], time: float, line: int, cfg: ArmConfig) -> ViaPoint:
    T = fk(np.asarray(q, dtype=float), cfg)
    return ViaPoint(
        xyz=[float(v) for v in T[:3, 3]],
        velocity=[0.0, 0.0, 0.0],
        ypr=list(matrix_to_ypr(T[:3, :3])),
        angular_velocity=[0.0, 0.0, 0.0],
        time=time,
        type=0,
        line=line,
    )


def _start_placeholder() -> ViaPoint:
    # The planner replaces the first via point by the start pose.
    zero = [0.0, 0.0, 0.0]
    return ViaPoint(xyz=zero, velocity=zero, ypr=zero, angular_velocity=zero, time=0.0, type=2)


def pose_path(
    name: str,
    duration: float,
    cfg: ArmConfig,
    *,
    start: Sequence[float] | None = None,
) -> Path:
    """A path from wherever the arm is to the gripper pose of ``name``.

    Two via points (the start, replaced by the planner, and the pose), or, when
    ``start`` is given and some joint must turn more than :data:`MAX_JOINT_STEP_DEG`,
    intermediate via points at the FK of evenly spaced configurations between the two
    (the planner refuses a joint move over 90 deg between via points as a branch flip).

    Args:
        name: a key of :data:`POSES`.
        duration: arrival time of the pose [s] (> 0).
        cfg: arm geometry.
        start: the configuration the move starts from (DH [rad]), if known.

    Raises:
        KeyError: unknown pose name.
    """
    q = np.radians(np.asarray(POSES[name], dtype=float))
    vias = [_start_placeholder()]
    if start is not None:
        q0 = np.asarray(start, dtype=float)
        largest = float(np.max(np.abs(q - q0)))
        pieces = max(1, math.ceil(math.degrees(largest) / MAX_JOINT_STEP_DEG))
        for k in range(1, pieces):
            f = k / pieces
            vias.append(_via(q0 + f * (q - q0), f * duration, 0, cfg))
    vias.append(_via(q, duration, 0, cfg))
    return Path(via_points=vias, source=f"pose {name}")
