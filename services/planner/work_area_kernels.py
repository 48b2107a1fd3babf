"""Compiled kernels of the arm's work area (:mod:`.work_area`), in numba: a search asks
them tens of thousands of times a plan, where NumPy's cost per call on six values is ten
times the arithmetic.

``geometry`` packs the arm: ``(l1, l2, l3, l4, work_floor_z, work_base_radius)`` [m].
Cached on disk like :mod:`manus.distance_bounds` (the planner calls each once when it
builds its work area, so a plan never compiles).
"""

from __future__ import annotations

import math

import numpy as np

from manus.distance_bounds import jit


@jit
def area_margin(q: np.ndarray, geometry: np.ndarray) -> float:
    """The gripper's margin to the work area's floor and to the cylinder about the base
    axis at ``q`` [rad] (6,), the smaller of the two [m] (< 0: out); the closed form of
    :func:`.work_area.gripper_positions` for one configuration."""
    l1, l2, l3, l4 = geometry[0], geometry[1], geometry[2], geometry[3]
    floor_z, radius = geometry[4], geometry[5]
    c1, s1 = math.cos(q[0]), math.sin(q[0])
    c23, s23 = math.cos(q[1] + q[2]), math.sin(q[1] + q[2])
    s5 = math.sin(q[4])
    a0, a1, a2 = math.cos(q[3]) * s5, math.sin(q[3]) * s5, math.cos(q[4])
    u = l2 * math.cos(q[1]) + l3 * s23
    v = l2 * math.sin(q[1]) - l3 * c23
    x = c1 * u - s1 * l1 + l4 * (c1 * c23 * a0 - s1 * a1 + c1 * s23 * a2)
    y = s1 * u + c1 * l1 + l4 * (s1 * c23 * a0 + c1 * a1 + s1 * s23 * a2)
    z = -v + l4 * (-s23 * a0 + c23 * a2)
    return float(min(z - floor_z, math.sqrt(x * x + y * y) - radius))


@jit
def area_motion(
    qa: np.ndarray,
    qb: np.ndarray,
    floor: float,
    levers: np.ndarray,
    geometry: np.ndarray,
    step: float,
) -> bool:
    """Whether the area margin stays at or above ``floor`` [m] all along the straight
    joint motion ``qa`` -> ``qb`` [rad], proven by bisection: the margin changes no more
    than the gripper's travel bound (``levers`` (6,) [m] times each joint's move), so on
    a stretch whose ends' margins are ``m0``, ``m1`` and travel ``t`` it is at least
    ``(m0 + m1 - t) / 2``; a stretch that bound does not prove is halved, down to
    ``step`` [m] of travel, where the motion is refused."""
    travel = 0.0
    for j in range(6):
        travel += abs(qb[j] - qa[j]) * levers[j]
    q = np.empty(6)
    stack_s0 = np.empty(64)
    stack_s1 = np.empty(64)
    stack_m0 = np.empty(64)
    stack_m1 = np.empty(64)
    stack_s0[0], stack_s1[0] = 0.0, 1.0
    stack_m0[0], stack_m1[0] = area_margin(qa, geometry), area_margin(qb, geometry)
    top = 1
    while top > 0:
        top -= 1
        s0, s1, m0, m1 = stack_s0[top], stack_s1[top], stack_m0[top], stack_m1[top]
        span = travel * (s1 - s0)
        if m0 + m1 - span >= 2.0 * floor:
            continue
        if span <= step or top + 2 > 64:
            return False
        mid = 0.5 * (s0 + s1)
        for j in range(6):
            q[j] = qa[j] + mid * (qb[j] - qa[j])
        m = area_margin(q, geometry)
        if m < floor:
            return False
        stack_s0[top], stack_s1[top], stack_m0[top], stack_m1[top] = mid, s1, m, m1
        stack_s0[top + 1], stack_s1[top + 1] = s0, mid
        stack_m0[top + 1], stack_m1[top + 1] = m0, m
        top += 2
    return True
