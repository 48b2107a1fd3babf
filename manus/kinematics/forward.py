"""Forward kinematics and the geometric Jacobian of the DH model (NumPy).

The DH table and the convention are in :mod:`manus.kinematics`; the scalar closed forms
of the same quantities for the controller's cycle are in
:mod:`manus.kinematics.closed_form`.
"""

from __future__ import annotations

import math

import numpy as np

from manus.config import N_JOINTS, ArmConfig

_ALPHA = (-math.pi / 2, 0.0, math.pi / 2, -math.pi / 2, math.pi / 2, 0.0)


def dh_table(cfg: ArmConfig) -> list[tuple[float, float, float]]:
    """The (a, alpha, d) of each joint [m, rad, m], in joint order."""
    return [
        (0.0, _ALPHA[0], 0.0),
        (cfg.l2, _ALPHA[1], cfg.l1),
        (0.0, _ALPHA[2], 0.0),
        (0.0, _ALPHA[3], cfg.l3),
        (0.0, _ALPHA[4], 0.0),
        (0.0, _ALPHA[5], cfg.l4),
    ]


def dh_matrix(a: float, alpha: float, d: float, theta: float) -> np.ndarray:
    """A_i = Rz(theta) Tz(d) Tx(a) Rx(alpha), shape (4, 4)."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def joint_frames(q: np.ndarray, cfg: ArmConfig) -> list[np.ndarray]:
    """T_0^i for i = 0..6 (base first, gripper last), each shape (4, 4)."""
    frames = [np.eye(4)]
    for (a, alpha, d), theta in zip(dh_table(cfg), q, strict=True):
        frames.append(frames[-1] @ dh_matrix(a, alpha, d, float(theta)))
    return frames


def fk(q: np.ndarray | tuple[float, ...] | list[float], cfg: ArmConfig) -> np.ndarray:
    """Gripper pose T_0^6 for DH joint angles ``q`` [rad], shape (6,) -> (4, 4) [m]."""
    return joint_frames(np.asarray(q, dtype=float), cfg)[-1]


def fk_position(q: np.ndarray, cfg: ArmConfig) -> np.ndarray:
    """Gripper position [m], shape (3,)."""
    return fk(q, cfg)[:3, 3]


def fk_batch(q: np.ndarray, cfg: ArmConfig) -> np.ndarray:
    """Gripper poses for many configurations: (N, 6) [rad] -> (N, 4, 4) [m]."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[0]
    out = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    for (a, alpha, d), theta in zip(dh_table(cfg), q.T, strict=True):
        ct, st = np.cos(theta), np.sin(theta)
        ca, sa = math.cos(alpha), math.sin(alpha)
        A = np.zeros((n, 4, 4))
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = ct, -st * ca, st * sa, a * ct
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st, ct * ca, -ct * sa, a * st
        A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa, ca, d
        A[:, 3, 3] = 1.0
        out = out @ A
    return out


def jacobian(q: np.ndarray, cfg: ArmConfig) -> np.ndarray:
    """Geometric Jacobian at the gripper frame origin, base-frame axes.

    Rows 0-2 map joint rates [rad/s] to linear velocity [m/s], rows 3-5 to angular
    velocity [rad/s]. Shape (6, 6).
    """
    frames = joint_frames(np.asarray(q, dtype=float), cfg)
    p_e = frames[-1][:3, 3]
    J = np.zeros((6, N_JOINTS))
    for i in range(N_JOINTS):
        z = frames[i][:3, 2]
        p = frames[i][:3, 3]
        J[:3, i] = np.cross(z, p_e - p)
        J[3:, i] = z
    return J
