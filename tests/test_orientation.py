"""The via-point orientation convention R = Rz(yaw) Ry(pitch) Rx(roll)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from manus.orientation import matrix_to_ypr, rot_x, rot_y, rot_z, rotation_error, ypr_to_matrix

yaw_roll = st.floats(-math.pi + 1e-9, math.pi, allow_nan=False)
pitch = st.floats(-math.pi / 2 + 1e-6, math.pi / 2 - 1e-6, allow_nan=False)


def test_convention_is_fixed_axis_roll_then_pitch_then_yaw() -> None:
    R = ypr_to_matrix(0.3, 0.2, 0.1)
    assert np.allclose(R, rot_z(0.3) @ rot_y(0.2) @ rot_x(0.1))
    # A pure yaw of 90 deg turns the x axis into y.
    assert np.allclose(ypr_to_matrix(math.pi / 2, 0, 0) @ [1, 0, 0], [0, 1, 0])


@given(yaw_roll, pitch, yaw_roll)
def test_round_trip(yaw: float, p: float, roll: float) -> None:
    y2, p2, r2 = matrix_to_ypr(ypr_to_matrix(yaw, p, roll))
    assert np.allclose(ypr_to_matrix(y2, p2, r2), ypr_to_matrix(yaw, p, roll), atol=1e-12)
    assert (y2, p2, r2) == pytest.approx((yaw, p, roll), abs=1e-7)


def test_gimbal_lock_keeps_the_rotation() -> None:
    R = ypr_to_matrix(0.4, math.pi / 2, 0.1)
    y, p, r = matrix_to_ypr(R)
    assert r == 0.0 and p == pytest.approx(math.pi / 2)
    assert np.allclose(ypr_to_matrix(y, p, r), R, atol=1e-9)


@given(yaw_roll, pitch, yaw_roll)
def test_rotation_error_is_the_angle_between(yaw: float, p: float, roll: float) -> None:
    R = ypr_to_matrix(yaw, p, roll)
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    angle = 0.3
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    Rd = (np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K) @ R
    assert np.allclose(rotation_error(Rd, R), axis * angle, atol=1e-9)
    assert np.allclose(rotation_error(R, R), 0.0)
