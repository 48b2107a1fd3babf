"""Rate <-> count conversion, saturation and quantizers of manus.quantize."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from manus.joint_map import dh_increments_to_encoder, encoder_increments_to_dh
from manus.quantize import (
    COUNT_RAD_S,
    GRIPPER_COUNT_M_S,
    ErrorFeedbackQuantizer,
    QuantizeError,
    Quantizer,
    RoundingQuantizer,
    counts_to_joint_rates,
    gripper_counts,
    joint_rates_to_counts,
    saturate,
    saturate_values,
)

rates = st.lists(st.floats(-3.0, 3.0, allow_nan=False), min_size=6, max_size=6).map(np.array)
counts_in_range = st.lists(st.floats(-10.0, 10.0), min_size=6, max_size=6).map(np.array)
counts_any = st.lists(st.floats(-200.0, 200.0), min_size=6, max_size=6).map(np.array)


def test_unit_of_one_count() -> None:
    assert math.degrees(COUNT_RAD_S) == pytest.approx(5.0)
    assert pytest.approx(0.005) == GRIPPER_COUNT_M_S


def test_known_coupling_values() -> None:
    # dq2 = +5 deg/s alone: de2 = -1 count, de3 = dq3 - dq2 = -1 count.
    qd = np.radians([0.0, 5.0, 0.0, 0.0, 0.0, 0.0])
    assert joint_rates_to_counts(qd) == pytest.approx([0, -1, -1, 0, 0, 0])
    # dq3 = +10 deg/s alone moves motor 3 only.
    qd = np.radians([0.0, 0.0, 10.0, 0.0, 0.0, 0.0])
    assert joint_rates_to_counts(qd) == pytest.approx([0, 0, 2, 0, 0, 0])
    # Motor 2 alone (+1 count) turns DH joint 2 by -5 deg/s and DH joint 3 by -5 deg/s.
    assert np.degrees(counts_to_joint_rates(np.array([0, 1, 0, 0, 0, 0.0]))) == pytest.approx(
        [0, -5, -5, 0, 0, 0]
    )


@given(rates)
def test_rates_to_counts_is_the_joint_map(qd: np.ndarray) -> None:
    assert joint_rates_to_counts(qd) == pytest.approx(
        dh_increments_to_encoder(qd) / COUNT_RAD_S, abs=1e-12
    )


@given(counts_any)
def test_counts_to_rates_is_the_joint_map(c: np.ndarray) -> None:
    assert counts_to_joint_rates(c) == pytest.approx(
        encoder_increments_to_dh(c) * COUNT_RAD_S, abs=1e-12
    )


@given(rates)
def test_round_trip_both_ways(qd: np.ndarray) -> None:
    assert counts_to_joint_rates(joint_rates_to_counts(qd)) == pytest.approx(qd, abs=1e-12)
    c = joint_rates_to_counts(qd)
    assert joint_rates_to_counts(counts_to_joint_rates(c)) == pytest.approx(c, abs=1e-9)


@given(counts_any, st.floats(0.5, 10.0))
def test_saturation_keeps_direction_and_limit(c: np.ndarray, limit: float) -> None:
    s = saturate(c, limit)
    assert np.max(np.abs(s)) <= limit + 1e-12
    peak = float(np.max(np.abs(c)))
    if peak <= limit:
        assert np.array_equal(s, c)
    else:
        # One common factor: s = k c with 0 < k < 1, so direction and ratios are kept.
        k = limit / peak
        assert s == pytest.approx(c * k, abs=1e-12)
        assert np.max(np.abs(s)) == pytest.approx(limit)
        assert np.all(s * c >= 0.0)  # no joint reverses


@given(counts_any, st.floats(0.5, 10.0))
def test_scalar_saturation_equals_the_array_one(c: np.ndarray, limit: float) -> None:
    assert saturate_values(c.tolist(), limit) == saturate(c, limit).tolist()


def test_saturate_does_not_alias_its_input() -> None:
    c = np.array([1.0, 2, 3, 4, 5, 6])
    s = saturate(c)
    s[0] = 99.0
    assert c[0] == 1.0


@pytest.mark.parametrize("make", [RoundingQuantizer, ErrorFeedbackQuantizer])
@given(c=counts_any)
def test_quantizers_stay_in_range_and_are_integers(make: type[Quantizer], c: np.ndarray) -> None:
    q = make()
    for _ in range(3):
        out = q(c)
        assert out.shape == (6,)
        assert out.dtype == np.int64
        assert np.all(np.abs(out) <= 10)


@given(counts_in_range)
def test_rounding_is_nearest(c: np.ndarray) -> None:
    out = RoundingQuantizer()(c)
    assert np.all(np.abs(out - c) <= 0.5 + 1e-12)


def test_rounding_is_symmetric_at_halves() -> None:
    q = RoundingQuantizer()
    assert list(q(np.array([0.5, -0.5, 2.5, -2.5, 3.5, 0.49]))) == [1, -1, 3, -3, 4, 0]
    assert list(q(np.array([11.0, -30, 10.4, -10.6, 0, 0]))) == [10, -10, 10, -10, 0, 0]


@given(counts_in_range, st.integers(1, 300))
def test_error_feedback_running_mean_is_the_wanted_rate(c: np.ndarray, n: int) -> None:
    q = ErrorFeedbackQuantizer()
    total = np.zeros(6)
    for _ in range(n):
        total += q(c)
    # Sum of outputs = n c - residual, |residual| <= 0.5: the mean error decays as 1/n.
    assert np.all(np.abs(total - n * c) <= 0.5 + 1e-9)
    assert np.all(np.abs(q.residual) <= 0.5 + 1e-9)


@given(st.lists(counts_in_range, min_size=1, max_size=60))
def test_error_feedback_tracks_a_varying_rate(seq: list[np.ndarray]) -> None:
    q = ErrorFeedbackQuantizer()
    total = np.zeros(6)
    for c in seq:
        total += q(c)
    assert np.all(np.abs(total - np.sum(seq, axis=0)) <= 0.5 + 1e-9)


def test_error_feedback_beats_rounding_on_a_slow_rate() -> None:
    c = np.array([0.3, -0.3, 1.4, 0, 0, 0])
    ef, rnd = ErrorFeedbackQuantizer(), RoundingQuantizer()
    s_ef = np.sum([ef(c) for _ in range(100)], axis=0)
    s_rnd = np.sum([rnd(c) for _ in range(100)], axis=0)
    assert list(s_ef) == [30, -30, 140, 0, 0, 0]
    assert list(s_rnd) == [0, 0, 100, 0, 0, 0]


def test_error_feedback_reset_drops_residual() -> None:
    q = ErrorFeedbackQuantizer()
    q(np.full(6, 0.4))
    assert np.all(q.residual != 0)
    q.reset()
    assert np.all(q.residual == 0)
    assert np.all(q(np.full(6, 0.4)) == 0)


def test_error_feedback_clamps_beyond_range_without_windup() -> None:
    q = ErrorFeedbackQuantizer()
    for _ in range(50):
        assert np.all(q(np.full(6, 25.0)) == 10)
    assert np.all(np.abs(q.residual) <= 0.5)
    # Back to zero at once: no wound-up residual keeps the arm moving.
    assert np.all(q(np.zeros(6)) == 0)


@given(st.floats(-1.0, 1.0))
def test_gripper_counts_rounded_and_clamped(v: float) -> None:
    g = gripper_counts(v)
    assert -15 <= g <= 15
    exact = v / GRIPPER_COUNT_M_S
    if abs(exact) <= 15:
        assert abs(g - exact) <= 0.5 + 1e-9
    else:
        assert g == (15 if v > 0 else -15)


def test_gripper_known_values() -> None:
    assert gripper_counts(0.005) == 1
    assert gripper_counts(-0.0125) == -3
    assert gripper_counts(0.002) == 0
    assert gripper_counts(1.0) == 15


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: joint_rates_to_counts(np.zeros(5)), "shape (5,), expected (6,)"),
        (lambda: joint_rates_to_counts(np.array([0, 0, np.nan, 0, 0, 0])), "joint 3 is nan"),
        (lambda: saturate(np.zeros(6), 0.0), "limit 0.0 must be > 0"),
        (lambda: saturate_values([0.0] * 6, 0.0), "limit 0.0 must be > 0"),
        (lambda: saturate_values([0.0] * 5), "shape (5,), expected (6,)"),
        (lambda: saturate_values([1.0, 2.0, math.nan, math.inf, 0, 0]), "joint 3 is nan"),
        (lambda: saturate_values([1.0, 2.0, 3.0, -math.inf, 0, 0]), "joint 4 is -inf"),
        (lambda: RoundingQuantizer(limit=11), "limit 11 outside 1..10"),
        (lambda: RoundingQuantizer()(np.array([np.inf, 0, 0, 0, 0, 0])), "joint 1 is inf"),
        (lambda: gripper_counts(math.nan), "gripper speed nan"),
    ],
)
def test_errors_name_value_and_limit(call: object, message: str) -> None:
    with pytest.raises(QuantizeError, match=None) as info:
        call()  # type: ignore[operator]
    assert message in str(info.value)
