"""The floor of following: what the 60 ms cycle and the arm's 21 speeds per joint allow.

An oracle that knows the target's whole future and the arm's exact state, on an ideal
arm (no gain errors, no belt play, no encoder rounding, no delay between deciding and
acting), still has to hold one speed per joint for each 60 ms cycle, a multiple of
5 deg/s of its motor between -50 and 50, through the drives' first-order lag. Per
cycle it takes, of the 64 choices of rounding each joint's ideal speed up or down (the
ideal speed: the one that lands the motors on the target's pose at the cycle's end,
through the lag), the one whose tracked point stays nearest the target over the cycle
(position, and orientation weighted by the Cartesian rounding's ``rounding_rotation_m``,
at the truth's 10 ms samples). Its error is the floor: no controller of this arm does
better on average (a one-cycle look-ahead, so an upper bound of the true optimum, by
little: a speed's effect on the next cycle is the lag's 20 ms tail).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from manus.config import ArmConfig
from manus.joint_map import dh_to_encoder, encoder_to_dh
from manus.kinematics import fk, fk_batch, jacobian
from manus.orientation import rotation_error
from manus.quantize import COUNT_RAD_S, JOINT_COUNT_MAX

_CORNERS = np.array([[(k >> j) & 1 for j in range(6)] for k in range(64)], dtype=float)
CYCLE_S = 0.060
SAMPLES = 6
"""Samples per cycle (every 10 ms, as the bench's truth)."""


def pose_ik(
    q0: np.ndarray, p: np.ndarray, R: np.ndarray, offset: np.ndarray, arm: ArmConfig
) -> np.ndarray:
    """DH angles near ``q0`` [rad] whose tracked point (``offset`` in the gripper frame) is
    at ``p`` [m] with orientation ``R``: Gauss-Newton steps."""
    q = q0.copy()
    for _ in range(4):
        T = fk(q, arm)
        tip = T[:3, 3] + T[:3, :3] @ offset
        e = np.concatenate((p - tip, rotation_error(R, T[:3, :3])))
        J = jacobian(q, arm)
        off = T[:3, :3] @ offset
        J[:3] += np.cross(J[3:].T, off).T
        q = q + np.linalg.solve(J, e)
    return q


def floor_errors(
    target: Callable[[float], np.ndarray],
    R: np.ndarray,
    q0: np.ndarray,
    seconds: float,
    arm: ArmConfig,
    *,
    offset: np.ndarray | None = None,
    tau_s: float = 0.020,
    rotation_m: float = 0.05,
) -> np.ndarray:
    """The oracle's position errors [m] at every 10 ms sample over ``seconds``.

    Args:
        target: the tracked point's wanted position at time t [s], base frame [m], (3,).
        R: the orientation held, (3, 3).
        q0: DH angles at t = 0 [rad] (on the target, at rest).
        seconds: how long.
        arm: the arm's geometry.
        offset: the tracked point in the gripper frame [m] (default: the origin).
        tau_s: the drives' lag [s].
        rotation_m: weight of the orientation error [m/rad].
    """
    off = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
    x = dh_to_encoder(np.asarray(q0, dtype=float))
    s = np.zeros(6)
    q_star = np.asarray(q0, dtype=float)
    decay = tau_s * (1.0 - math.exp(-CYCLE_S / tau_s))
    ts = np.arange(1, SAMPLES + 1) * (CYCLE_S / SAMPLES)
    lags = tau_s * (1.0 - np.exp(-ts / tau_s))  # (SAMPLES,)
    errors: list[float] = []
    for k in range(round(seconds / CYCLE_S)):
        t0 = k * CYCLE_S
        q_star = pose_ik(q_star, target(t0 + CYCLE_S), R, off, arm)
        x_end = dh_to_encoder(q_star)
        u = (x_end - x - s * decay) / (CYCLE_S - decay)  # lands on x_end at the cycle's end
        ideal = np.clip(u / COUNT_RAD_S, -JOINT_COUNT_MAX, JOINT_COUNT_MAX)
        cand = np.clip(np.floor(ideal) + _CORNERS, -JOINT_COUNT_MAX, JOINT_COUNT_MAX)
        U = cand * COUNT_RAD_S  # (64, 6)
        # motors at each sample: x + U t + (s - U) lag(t)
        X = x + U[:, None, :] * ts[None, :, None] + (s - U)[:, None, :] * lags[None, :, None]
        T = fk_batch(encoder_to_dh(X.reshape(-1, 6)), arm).reshape(64, SAMPLES, 4, 4)
        tips = T[..., :3, 3] + np.einsum("csij,j->csi", T[..., :3, :3], off)
        want = np.array([target(t0 + t) for t in ts])  # (SAMPLES, 3)
        pos = ((tips - want[None]) ** 2).sum(axis=2)  # (64, SAMPLES)
        E = np.einsum("csij,kj->csik", T[..., :3, :3], R)  # R_c R^T
        tr = np.clip((np.trace(E, axis1=2, axis2=3) - 1.0) / 2.0, -1.0, 1.0)
        rot = np.arccos(tr) ** 2 * rotation_m**2
        best = int((pos + rot).sum(axis=1).argmin())
        errors += np.sqrt(pos[best]).tolist()
        e_end = math.exp(-CYCLE_S / tau_s)
        x = x + U[best] * CYCLE_S + (s - U[best]) * decay
        s = U[best] + (s - U[best]) * e_end
    return np.asarray(errors)
