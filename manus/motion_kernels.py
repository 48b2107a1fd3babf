"""Compiled kernels of the fast motion check (:meth:`manus.validity.ValidityChecker.
motion_valid`): how far the arm's bodies can move, and conservative advancement along a
straight joint-space motion.

A point of a body moves at most ``sum_j |dq_j| r_j``, with ``r_j`` its largest distance
from joint ``j``'s axis on the way; only the joints beyond ``j`` change that distance, so
``r_j <= reach_j + sum_{k>j} |dq_k| r_k`` (the same bound as the controller's guard and
:mod:`manus.sweep`), with ``reach_j`` taken where the margins were computed.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from manus.distance_bounds import jit
from manus.validity_kernels import margins, pose


@jit
def reach(arm: Any, scratch: Any, out: np.ndarray) -> None:
    """Per joint and body, the farthest any point of the body is from the joint's axis
    at the configuration last posed, into ``out`` (6, B) [m] (0: the joint does not move
    the body). Pieces and cover points both count (the keep-in zones use the latter)."""
    _, p_joint, p_body, _, _, _, _, _, p_rb, _, _, _, _ = arm[:13]
    c_joint, c_body, _, c_radius = arm[13:17]
    frames, centers, _, _, covers = scratch[:5]
    out[:, :] = 0.0
    for j in range(1, frames.shape[0]):
        ox, oy, oz = frames[j, 0, 3], frames[j, 1, 3], frames[j, 2, 3]
        zx, zy, zz = frames[j, 0, 2], frames[j, 1, 2], frames[j, 2, 2]
        for points, joint, body, radius in (
            (centers, p_joint, p_body, p_rb),
            (covers, c_joint, c_body, c_radius),
        ):
            for i in range(points.shape[0]):
                b = body[i]
                if b < 0 or joint[i] < j:
                    continue
                dx, dy, dz = points[i, 0] - ox, points[i, 1] - oy, points[i, 2] - oz
                along = dx * zx + dy * zy + dz * zz
                r = math.sqrt(max(0.0, dx * dx + dy * dy + dz * dz - along * along)) + radius[i]
                out[j - 1, b] = max(out[j - 1, b], r)


@jit
def reach_batch(Q: np.ndarray, arm: Any, scratch: Any, out: np.ndarray) -> None:
    """:func:`reach` at each row of ``Q`` (n, 6) into ``out`` (n, 6, B)."""
    for k in range(Q.shape[0]):
        pose(Q[k], arm, scratch)
        reach(arm, scratch, out[k])


@jit
def travel(box: np.ndarray, levers: np.ndarray, b: int) -> float:
    """How far any point of body ``b`` can move while each joint moves at most ``box``
    (6,) [rad] from where ``levers`` (6, B) were taken: ``sum_j box_j r_j`` with ``r_j``
    grown by the joints beyond ``j`` (they can carry the point further from the axis)."""
    grown = 0.0
    for j in range(box.shape[0] - 1, -1, -1):
        grown += box[j] * (levers[j, b] + grown)
    return grown


@jit
def motion(
    q0: np.ndarray,
    q1: np.ndarray,
    floor: float,
    max_steps: int,
    arm: Any,
    scene: Any,
    scratch: Any,
    free: np.ndarray,
    levers: np.ndarray,
    cap: float,
) -> float:
    """Conservative advancement along the straight line ``q0`` -> ``q1`` [rad]: at each
    configuration the bodies' margins (each at most ``cap`` [m]: cheaper, shorter
    steps), then the longest step over which no point of a body can travel as far as
    its margin. Returns 1.0 when the whole motion is proven, else the fraction where a
    margin came below ``floor`` [m] (or ``max_steps`` ran out): the first place it
    cannot prove."""
    n = q0.shape[0]
    delta = np.abs(q1 - q0)
    box = np.empty(n)
    q = q0.copy()
    t = 0.0
    for _ in range(max_steps):
        for j in range(n):
            q[j] = q0[j] + t * (q1[j] - q0[j])
        tight, _, _ = margins(q, arm, scene, scratch, free, cap)
        if tight < floor:
            return t
        reach(arm, scratch, levers)
        step = 1.0 - t
        for b in range(free.shape[0]):
            if free[b] == math.inf:
                continue
            for j in range(n):
                box[j] = delta[j] * step
            moved = travel(box, levers, b)
            if moved > free[b]:
                # travel is a polynomial in the step with no constant term and no
                # negative coefficient: scaling the step by k < 1 scales it by <= k.
                step *= free[b] / moved
        if t + step >= 1.0:
            return 1.0
        t += step
    return t


@jit
def stretch_bounds(
    moves: np.ndarray, free: np.ndarray, reach: np.ndarray, bound: np.ndarray, far: np.ndarray
) -> None:
    """Per stretch between configurations ``k`` and ``k+1`` of a motion (each joint
    turning at most ``moves[k]`` (6,) [rad] within it), a lower bound of every body's
    margin inside it into ``bound[k]`` [m] and the farthest any point can move into
    ``far[k]`` [m]; ``free`` (n, B) the margins at the configurations, ``reach`` (n, 6,
    B) the reaches there.

    From each end a body moves at most ``f(s)``, the nested bound of the joint moves
    ``s * moves`` (:func:`travel`): a polynomial with no constant term and no negative
    coefficient, so ``f(s) <= s f(1)``; the margin in between is at least the lowest
    point of ``max(m_a - x F_a, m_b - (1 - x) F_b)`` over ``x`` in 0..1.
    """
    n_joints = moves.shape[1]
    for k in range(moves.shape[0]):
        low, most = math.inf, 0.0
        for b in range(free.shape[1]):
            fa = fb = 0.0
            for j in range(n_joints - 1, -1, -1):
                fa += moves[k, j] * (reach[k, j, b] + fa)
                fb += moves[k, j] * (reach[k + 1, j, b] + fb)
            most = max(most, fa, fb)
            ma, mb = free[k, b], free[k + 1, b]
            if math.inf in (ma, mb):
                continue  # nothing for this body to keep clear of
            total = fa + fb
            if total > 0.0:
                x = min(max((ma - mb + fb) / total, 0.0), 1.0)
                low = min(low, ma - x * fa)
            else:
                low = min(low, ma, mb)
        bound[k] = low
        far[k] = most


@jit
def anchor(
    q: np.ndarray, arm: Any, scene: Any, scratch: Any, free: np.ndarray, levers: np.ndarray
) -> float:
    """Each body's margin at ``q`` into ``free`` (B,) and the reaches there into
    ``levers`` (6, B), in one call; returns the tightest margin [m]."""
    tight, _, _ = margins(q, arm, scene, scratch, free, math.inf)
    reach(arm, scratch, levers)
    return float(tight)


@jit
def proven(origin: np.ndarray, free: np.ndarray, levers: np.ndarray, Q: np.ndarray) -> bool:
    """Whether every configuration in the joint-space box from ``origin`` (6,) to the rows
    of ``Q`` (k, 6) keeps each body closer to where it was at ``origin`` than its margin
    there (``free`` (B,), inf: nothing to keep clear of; ``levers`` (6, B) the reaches
    there): :func:`travel` of the box."""
    box = np.zeros(origin.shape[0])
    for k in range(Q.shape[0]):
        for j in range(origin.shape[0]):
            box[j] = max(box[j], abs(Q[k, j] - origin[j]))
    for b in range(free.shape[0]):
        if free[b] == math.inf:
            continue
        if free[b] <= 0.0 or travel(box, levers, b) >= free[b]:
            return False
    return True


@jit
def proven_ahead(
    origin: np.ndarray,
    free: np.ndarray,
    levers: np.ndarray,
    q: np.ndarray,
    first: np.ndarray,
    then: np.ndarray,
    to_q: np.ndarray,
    first_s: float,
    then_s: float,
) -> bool:
    """:func:`proven` for ``q``, ``q1 = q + to_q @ first * first_s`` and ``q1 + to_q @
    then * then_s`` (rates ``first``, ``then`` (6,) held for ``first_s``, ``then_s`` [s];
    ``to_q`` (6, 6) maps them to joint rates): the guard's prediction, in one call."""
    n = origin.shape[0]
    box = np.zeros(n)
    for j in range(n):
        a = 0.0
        c = 0.0
        for k in range(n):
            a += to_q[j, k] * first[k]
            c += to_q[j, k] * then[k]
        q1 = q[j] + a * first_s
        q2 = q1 + c * then_s
        box[j] = max(abs(q[j] - origin[j]), abs(q1 - origin[j]), abs(q2 - origin[j]))
    for b in range(free.shape[0]):
        if free[b] == math.inf:
            continue
        if free[b] <= 0.0 or travel(box, levers, b) >= free[b]:
            return False
    return True
