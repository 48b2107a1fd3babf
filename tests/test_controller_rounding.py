"""The default mode's Cartesian-aware rounding against its definition, candidate by candidate."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from manus.config import DEFAULT_ARM
from manus.joint_map import M_ENCODER_TO_DH
from manus.kinematics import jacobian
from services.controller.config import ControllerConfig
from services.controller.laws import cartesian_rounding, rounding_gains

CONFIG = ControllerConfig()
GAIN = 0.0037  # rad per count by the cycle's end: about (60 ms - lag) x 5 deg/s


def _by_definition(
    wanted: list[float], miss: list[float], gain: float, q: list[float]
) -> tuple[np.ndarray, float, float]:
    """Every floor/ceil choice (clipped to the range) scored as the docstring says:
    (best choice, its cost, the runner-up's cost)."""
    J = jacobian(np.array(q), DEFAULT_ARM)
    J[3:] *= CONFIG.rounding_rotation_m
    G = J @ M_ENCODER_TO_DH
    k = (CONFIG.rounding_joint_m * gain) ** 2
    costs = []
    for bits in itertools.product((0, 1), repeat=6):
        c = np.clip(np.floor(wanted) + bits, -10, 10)
        err = G @ (np.array(miss) + gain * c)
        costs.append((float(err @ err + k * np.sum((c - wanted) ** 2)), tuple(c)))
    costs.sort()
    return np.array(costs[0][1], dtype=np.int64), costs[0][0], costs[1][0]


joints = st.lists(st.floats(-1.5, 1.5), min_size=6, max_size=6)
counts = st.lists(st.floats(-10.0, 10.0), min_size=6, max_size=6)
misses = st.lists(st.floats(-0.01, 0.01), min_size=6, max_size=6)


@given(counts, misses, joints)
def test_the_choice_is_the_cheapest_of_the_64(
    wanted: list[float], miss: list[float], q: list[float]
) -> None:
    got = cartesian_rounding(wanted, miss, GAIN, q, CONFIG)
    best, cost, runner_up = _by_definition(wanted, miss, GAIN, q)
    if runner_up - cost > 1e-12 * max(1.0, cost):  # not a tie (then either is right)
        assert got.tolist() == best.tolist()
    assert got.dtype == np.int64
    assert all(math.floor(w) <= c <= math.floor(w) + 1 for w, c in zip(wanted, got, strict=True))


@pytest.mark.parametrize("edge", [10.0, -10.0, 9.9999])
def test_counts_at_the_limit_stay_in_range(edge: float) -> None:
    wanted = [edge, 0.4, -3.5, edge, 2.0, -0.2]
    q = [0.1, 0.5, -0.5, 0.2, -1.0, 0.3]
    miss = [0.001, -0.002, 0.0, 0.001, 0.0005, -0.001]
    got = cartesian_rounding(wanted, miss, GAIN, q, CONFIG)
    assert got.tolist() == _by_definition(wanted, miss, GAIN, q)[0].tolist()
    assert np.abs(got).max() <= 10


@given(joints, st.floats(0.001, 0.01))
def test_rounding_gains_are_the_weighted_jacobian_in_motor_space(
    q: list[float], scale: float
) -> None:
    J = jacobian(np.array(q), DEFAULT_ARM)
    J[3:] *= CONFIG.rounding_rotation_m
    assert rounding_gains(q, CONFIG, scale) == pytest.approx(
        scale * (J @ M_ENCODER_TO_DH), abs=1e-15
    )
