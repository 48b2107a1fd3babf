"""Cartesian mode (0x371): gripper increments -> motor speeds, and the pose it reports.

The arm's own Cartesian controller is not documented; this model resolves the commanded
gripper twist through the pseudo-inverse of the geometric Jacobian
(:func:`manus.kinematics.jacobian`), re-evaluated every 20 ms tick at the motor angles,
and scales the result down uniformly if a motor would exceed the 50 deg/s maximum.
The yaw, pitch and roll increments are taken as small rotations about the base z, y and
x axes (for increments of 0.1 deg this equals the rates of the Z-Y-X angles of
:mod:`manus.orientation` to first order, away from pitch = +-90 deg).
"""

from __future__ import annotations

import math

import numpy as np

from manus.config import ArmConfig
from manus.joint_map import dh_increments_to_encoder, encoder_to_dh
from manus.kinematics import fk, jacobian
from manus.orientation import matrix_to_ypr
from manus.protocol import JOINT_UNIT_DEG, TICK_S, XYZ_UNIT_MM, MoveCommand

MAX_MOTOR_SPEED_DEG_S = 50.0
"""The arm's fastest motor speed [deg/s] (10 counts of 0.1 deg per 20 ms)."""
PINV_RCOND = 1e-3
"""Singular values below this fraction of the largest are ignored by the pseudo-inverse."""
I16 = 32767


def cartesian_motor_rates(motor_deg: np.ndarray, cmd: MoveCommand, arm: ArmConfig) -> np.ndarray:
    """Motor speeds [deg/s] that move the gripper as the Cartesian command asks, shape (6,).

    Args:
        motor_deg: motor angles now, shape (6,) [deg].
        cmd: a (clamped) 0x371 command: X, Y, Z [0.022 mm], yaw, pitch, roll [0.1 deg]
            per 20 ms.
        arm: the arm geometry.
    """
    axes = np.asarray(cmd.axes, dtype=float)
    if not axes.any():
        return np.zeros(6)
    v = axes[:3] * (XYZ_UNIT_MM / 1000.0) / TICK_S
    yaw, pitch, roll = axes[3:] * math.radians(JOINT_UNIT_DEG) / TICK_S
    twist = np.concatenate([v, [roll, pitch, yaw]])
    q = encoder_to_dh(np.radians(motor_deg))
    dq = np.linalg.pinv(jacobian(q, arm), rcond=PINV_RCOND) @ twist
    rates = np.degrees(dh_increments_to_encoder(dq))
    fastest = float(np.abs(rates).max())
    if fastest > MAX_MOTOR_SPEED_DEG_S:
        rates *= MAX_MOTOR_SPEED_DEG_S / fastest
    return np.asarray(rates)


def cartesian_fields(motor_deg: np.ndarray, arm: ArmConfig) -> tuple[int, ...]:
    """The six position fields of Cartesian mode for these motor angles.

    Returns:
        (X, Y, Z) [0.022 mm] and (yaw, pitch, roll) [0.1 deg], each clamped to int16.
    """
    T = fk(encoder_to_dh(np.radians(motor_deg)), arm)
    xyz = T[:3, 3] * 1000.0 / XYZ_UNIT_MM
    ypr = np.degrees(matrix_to_ypr(T[:3, :3])) / JOINT_UNIT_DEG
    return tuple(max(-I16, min(I16, round(float(v)))) for v in (*xyz, *ypr))
