"""The arm's own work area: where the Manus itself refuses to go.

The arm stops a motion that would take the gripper below its work area's floor or into
the vertical cylinder about its base axis (warning 1), or straighten the elbow closer
than a margin (warning 2): docs/protocol.md, Limits; the simulator models the same
rules (``services/simulator/workspace.py``). A goal plan must keep them all along, or
the arm stops part way. The values are the arm's (:class:`manus.config.ArmConfig`:
``work_floor_z``, ``work_base_radius``, ``stretched_margin``).

A configuration's *area margin* is the smaller of the gripper's height above the floor
and its distance beyond the cylinder [m]; its *elbow margin* how far q3 is from
straight, less the margin [rad]. Motions are proven by bisection and a travel bound: the
gripper's height and distance from the base axis change no more than the joint moves
times the joints' levers to it (:attr:`WorkArea.levers`; joint 1 changes neither), and
q3 moves linearly along a straight joint motion.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.config import ArmConfig
from manus.kinematics import gripper_position
from services.planner.work_area_kernels import area_margin, area_motion

STRAIGHT_Q3 = math.pi / 2
"""q3 at which the upper arm and the forearm are aligned (the elbow straight) [rad]."""

STEP_M = 0.004
"""Shortest stretch of a motion a proof halves [m] of gripper travel (on a stretch the
margin is at least its ends' mean less half its travel)."""


class AreaMargin(NamedTuple):
    """Where a configuration stands in the work area.

    Attributes:
        area: the gripper's margin to the floor and to the base cylinder [m] (< 0: out).
        elbow: |q3 - straight| less the stretched margin [rad] (< 0: too straight).
        what: which rule is tightest, in words.
    """

    area: float
    elbow: float
    what: str


class WorkArea:
    """The arm's work-area rules (see the module docstring).

    Args:
        arm: the arm (its geometry and its work area).
    """

    def __init__(self, arm: ArmConfig) -> None:
        self.arm = arm
        # Farthest the gripper frame can be from each joint's axis: the link lengths
        # beyond it (a bound for every configuration). Joint 1 turns about the vertical
        # base axis, which moves neither the gripper's height nor its distance from that
        # axis: the area margin does not depend on it.
        self.levers = np.array(
            [0.0, arm.l2 + arm.l3 + arm.l4, arm.l3 + arm.l4, arm.l4, arm.l4, 0.0]
        )
        self._geometry = np.array(
            [arm.l1, arm.l2, arm.l3, arm.l4, arm.work_floor_z, arm.work_base_radius]
        )
        # Compile (or load) the kernels now: a plan never does.
        area_motion(np.zeros(6), np.full(6, 0.1), 0.0, self.levers, self._geometry, STEP_M)

    def margins(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Area margins [m] and elbow margins [rad] of configurations ``Q`` [rad], (n, 6)
        -> two arrays of shape (n,)."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        x, y, z = gripper_positions(Q, self.arm)
        area = np.minimum(z - self.arm.work_floor_z, np.hypot(x, y) - self.arm.work_base_radius)
        return area, elbow_margin(Q[:, 2], self.arm.stretched_margin)

    def margin(self, q: np.ndarray) -> AreaMargin:
        """Where ``q`` [rad] stands, with the tightest rule named."""
        q = np.asarray(q, dtype=float)
        p = gripper_position(q, self.arm)
        floor = float(p[2] - self.arm.work_floor_z)
        radial = float(math.hypot(p[0], p[1]) - self.arm.work_base_radius)
        elbow = float(elbow_margin(q[2:3], self.arm.stretched_margin)[0])
        if elbow * self.arm.l3 < min(floor, radial):
            what = (
                f"the elbow {math.degrees(elbow + self.arm.stretched_margin):.1f} deg from "
                f"straight (the arm keeps {math.degrees(self.arm.stretched_margin):.0f} deg)"
            )
        elif floor <= radial:
            side = "above" if floor >= 0.0 else "below"
            what = (
                f"the gripper {abs(floor) * 1e3:.1f} mm {side} the work area's floor "
                f"(z {self.arm.work_floor_z * 1e3:.0f} mm)"
            )
        else:
            side = "outside" if radial >= 0.0 else "inside"
            what = (
                f"the gripper {abs(radial) * 1e3:.1f} mm {side} the cylinder about the base "
                f"axis (radius {self.arm.work_base_radius * 1e3:.0f} mm)"
            )
        return AreaMargin(min(floor, radial), elbow, what)

    def motion(self, qa: np.ndarray, qb: np.ndarray, floor: float) -> bool:
        """Whether the straight joint motion ``qa`` -> ``qb`` [rad] keeps the area margin
        at or above ``floor`` [m] and the elbow margin at or above 0 all along.

        The area margin is proven by bisection (compiled,
        :func:`.work_area_kernels.area_motion`): on a stretch it is at least its ends'
        mean less half the gripper's travel bound there (no point of the gripper moves
        further); a stretch that bound leaves unproven is halved down to :data:`STEP_M`
        of travel."""
        qa, qb = np.asarray(qa, dtype=float), np.asarray(qb, dtype=float)
        if not _elbow_clear(qa[2], qb[2], self.arm.stretched_margin):
            return False
        return bool(area_motion(qa, qb, floor, self.levers, self._geometry, STEP_M))

    def tightest(self, q: np.ndarray) -> float:
        """The smaller of the area margin [m] and the elbow margin as a length along the
        forearm [m] at ``q`` [rad] (6,) (< 0: out): one configuration, compiled."""
        q = np.asarray(q, dtype=float)
        area = area_margin(q, self._geometry)
        bend = abs(math.remainder(float(q[2]) - STRAIGHT_Q3, 2 * math.pi))
        elbow = (bend - self.arm.stretched_margin) * self.arm.l3
        return min(area, elbow)

    def curve_problem(self, Q: np.ndarray, step: float) -> str | None:
        """The first configuration of ``Q`` [rad], (n, 6), sampled along a trajectory no
        more than ``step`` [m] of gripper travel apart, whose area margin is below
        ``step`` (the samples' spacing: a dip between two samples is no deeper), or
        whose elbow is too straight; None when clear."""
        area, elbow = self.margins(Q)
        bad = (area < step) | (elbow < 0.0)
        if not bad.any():
            return None
        return self.margin(Q[int(np.argmax(bad))]).what


def elbow_margin(q3: np.ndarray, margin: float) -> np.ndarray:
    """|q3 - straight| (modulo a turn) less ``margin`` [rad], shape of ``q3``."""
    bend = np.abs(np.remainder(np.asarray(q3) - STRAIGHT_Q3 + math.pi, 2 * math.pi) - math.pi)
    return np.asarray(bend - margin)


def _elbow_clear(a: float, b: float, margin: float) -> bool:
    """Whether q3 moving linearly from ``a`` to ``b`` [rad] stays ``margin`` away from
    every straight angle (pi/2 + k 2pi)."""
    lo, hi = min(a, b), max(a, b)
    k = math.ceil((lo - margin - STRAIGHT_Q3) / (2 * math.pi))
    return STRAIGHT_Q3 + k * 2 * math.pi > hi + margin


def gripper_positions(Q: np.ndarray, arm: ArmConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gripper positions (x, y, z) [m] of configurations ``Q`` [rad], (n, 6): the closed
    form of :func:`manus.kinematics.gripper_position`, vectorised (a test keeps them
    equal)."""
    q1, q2, q3, q4, q5 = Q[:, 0], Q[:, 1], Q[:, 2], Q[:, 3], Q[:, 4]
    c1, s1 = np.cos(q1), np.sin(q1)
    c23, s23 = np.cos(q2 + q3), np.sin(q2 + q3)
    s5 = np.sin(q5)
    a0, a1, a2 = np.cos(q4) * s5, np.sin(q4) * s5, np.cos(q5)
    u = arm.l2 * np.cos(q2) + arm.l3 * s23
    v = arm.l2 * np.sin(q2) - arm.l3 * c23
    zx = c1 * c23 * a0 - s1 * a1 + c1 * s23 * a2
    zy = s1 * c23 * a0 + c1 * a1 + s1 * s23 * a2
    zz = -s23 * a0 + c23 * a2
    return (
        c1 * u - s1 * arm.l1 + arm.l4 * zx,
        s1 * u + c1 * arm.l1 + arm.l4 * zy,
        -v + arm.l4 * zz,
    )
