"""The via-point orientation convention: (yaw, roll, pitch) <-> rotation matrix.

The thesis lists orientations as yaw, roll, pitch (degrees, in that column order) and never
says what they mean. This project defines them (docs/protocol.md, Orientation convention) as
fixed-axis angles in the base frame, applied roll first, then pitch, then yaw:

    R = Rz(yaw) @ Ry(pitch) @ Rx(roll)

which is the usual aerospace Z-Y-X convention. Pitch is kept in [-pi/2, pi/2]; at
pitch = +-pi/2 (gimbal lock) yaw and roll are not separable and the conversion returns
roll = 0 with the whole turn in yaw.

Functions take and return radians. The tuple order used in code is always
(yaw, pitch, roll), as on the command line (what it prints and what it takes);
only via-point files use (yaw, roll, pitch).
"""

from __future__ import annotations

import math

import numpy as np


def rot_x(angle: float) -> np.ndarray:
    """Rotation about x by ``angle`` [rad], shape (3, 3)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> np.ndarray:
    """Rotation about y by ``angle`` [rad], shape (3, 3)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> np.ndarray:
    """Rotation about z by ``angle`` [rad], shape (3, 3)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def ypr_to_matrix(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), angles [rad], shape (3, 3)."""
    return np.asarray(rot_z(yaw) @ rot_y(pitch) @ rot_x(roll))


def matrix_to_ypr(R: np.ndarray) -> tuple[float, float, float]:
    """(yaw, pitch, roll) [rad] of a rotation matrix, the inverse of :func:`ypr_to_matrix`.

    Pitch lies in [-pi/2, pi/2]; yaw and roll in (-pi, pi]. At gimbal lock roll is 0.
    """
    R = np.asarray(R, dtype=float)
    sp = -R[2, 0]
    cp = math.hypot(R[0, 0], R[1, 0])
    # atan2 of sin and cos, not asin: asin loses digits near +-pi/2 (its slope grows
    # without bound), and a matrix rebuilt from the angles would then differ by 1e-10.
    pitch = math.atan2(sp, cp)
    if cp < 1e-9:
        # Gimbal lock: only yaw - roll (pitch = +pi/2) or yaw + roll (-pi/2) is defined.
        yaw = math.atan2(-R[0, 1], R[1, 1])
        return yaw, pitch, 0.0
    yaw = math.atan2(R[1, 0], R[0, 0])
    roll = math.atan2(R[2, 1], R[2, 2])
    return yaw, pitch, roll


def pose_matrix(
    xyz: np.ndarray | tuple[float, ...] | list[float], ypr: tuple[float, float, float]
) -> np.ndarray:
    """Homogeneous transform from a position [m] and (yaw, pitch, roll) [rad], shape (4, 4)."""
    T = np.eye(4)
    T[:3, :3] = ypr_to_matrix(*ypr)
    T[:3, 3] = np.asarray(xyz, dtype=float)
    return T


def rotation_error(R_target: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Rotation vector [rad] taking ``R`` to ``R_target``, base frame, shape (3,).

    Its norm is the angle between the two orientations.
    """
    E = np.asarray(R_target) @ np.asarray(R).T
    cos = max(-1.0, min(1.0, (np.trace(E) - 1.0) / 2.0))
    angle = math.acos(cos)
    axis = np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    s = np.linalg.norm(axis)
    if s < 1e-12:
        if angle < 1e-6:
            return np.zeros(3)
        # angle ~ pi: axis from the symmetric part.
        M = (E + np.eye(3)) / 2.0
        k = int(np.argmax(np.diag(M)))
        v = M[:, k] / math.sqrt(max(M[k, k], 1e-300))
        return np.asarray(v * angle)
    return np.asarray(axis / s * angle)
