"""Joint interpolation: the thesis's tridiagonal system, quintic segments, exact extremes."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

from manus.trajectory import JointTrajectory, quintic_coefficients
from schemas.planning import Trajectory
from services.planner.spline import (
    PiecewisePolynomial,
    _thomas,
    clamped_cubic_velocities,
    cubic_knot_accelerations,
    quintic_knot_accelerations,
    time_stretch,
)


def _knots(seed: int, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    times = np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 3.0, n - 1))])
    q = rng.uniform(-3.0, 3.0, (n, 6))
    return times, q, rng.normal(size=6), rng.normal(size=6)


def _one_sided(curve: PiecewisePolynomial, order: int) -> tuple[np.ndarray, np.ndarray]:
    """Values of the ``order``-th derivative at each segment's end (s = 1) and start (s = 0):
    the limits from the left at knots 1..n-1 and from the right at knots 0..n-2."""
    c = curve.derivative_coeffs(order)
    return c.sum(axis=1), c[:, 0]


@pytest.mark.parametrize("n", [2, 3, 4, 7, 19])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cubic_equals_scipy_clamped_spline(n: int, seed: int) -> None:
    times, q, v0, vn = _knots(seed, n)
    v = clamped_cubic_velocities(times, q, v0, vn)
    curve = PiecewisePolynomial.hermite(times, q, v)
    reference = CubicSpline(times, q, bc_type=((1, v0), (1, vn)))
    ts = np.linspace(0.0, times[-1], 2001)
    for order in (0, 1, 2):
        assert np.abs(curve.evaluate(ts, order) - reference(ts, order)).max() < 1e-9
    assert np.abs(v - reference(times, 1)).max() < 1e-9


def test_thomas_matches_dense_solve() -> None:
    rng = np.random.default_rng(3)
    m = 9
    sub, sup = rng.uniform(0.1, 1.0, m - 1), rng.uniform(0.1, 1.0, m - 1)
    diag = rng.uniform(2.5, 4.0, m)
    rhs = rng.normal(size=(m, 6))
    A = np.diag(diag) + np.diag(sub, -1) + np.diag(sup, 1)
    assert _thomas(sub, diag, sup, rhs) == pytest.approx(np.linalg.solve(A, rhs), abs=1e-12)


@pytest.mark.parametrize("n", [3, 5, 12])
def test_cubic_is_continuous_to_acceleration_at_the_knots(n: int) -> None:
    times, q, v0, vn = _knots(10 + n, n)
    v = clamped_cubic_velocities(times, q, v0, vn)
    curve = PiecewisePolynomial.hermite(times, q, v)
    for order in (0, 1, 2):
        left, right = _one_sided(curve, order)  # knots 1..n-1 from the left; 0..n-2 right
        scale = np.abs(left).max() + 1.0
        assert np.abs(left[:-1] - right[1:]).max() < 1e-9 * scale, order
    assert curve.evaluate(times) == pytest.approx(q, abs=1e-12)
    assert curve.evaluate(times[[0, -1]], 1) == pytest.approx(np.vstack([v0, vn]), abs=1e-12)
    accel = cubic_knot_accelerations(times, q, v)
    assert curve.evaluate(times, 2) == pytest.approx(accel, abs=1e-9)


@pytest.mark.parametrize("n", [2, 3, 6])
def test_quintic_meets_its_boundary_conditions(n: int) -> None:
    times, q, v0, vn = _knots(20 + n, n)
    v = clamped_cubic_velocities(times, q, v0, vn)
    a = quintic_knot_accelerations(times, q, v)
    assert np.all(a[0] == 0.0) and np.all(a[-1] == 0.0)
    curve = PiecewisePolynomial.hermite(times, q, v, a)
    for order, expected in ((0, q), (1, v), (2, a)):
        left, right = _one_sided(curve, order)
        assert left == pytest.approx(expected[1:], abs=1e-9)
        assert right == pytest.approx(expected[:-1], abs=1e-9)
    # Each segment is the unique quintic of the 6x6 boundary system (manus.trajectory).
    for i in range(n - 1):
        h = times[i + 1] - times[i]
        c = quintic_coefficients(q[i], v[i], a[i], q[i + 1], v[i + 1], a[i + 1], h)
        normalised = c * (h ** np.arange(6))[:, None]
        assert curve.coeffs[i] == pytest.approx(normalised, abs=1e-9)


def test_two_point_quintic_is_the_classic_rest_to_rest_move() -> None:
    times = np.array([0.0, 2.0])
    q = np.array([[0.0] * 6, [1.0] * 6])
    v = clamped_cubic_velocities(times, q, np.zeros(6), np.zeros(6))
    curve = PiecewisePolynomial.hermite(times, q, v, quintic_knot_accelerations(times, q, v))
    s = np.linspace(0.0, 1.0, 11)
    expected = 10 * s**3 - 15 * s**4 + 6 * s**5
    assert curve.evaluate(2.0 * s)[:, 0] == pytest.approx(expected, abs=1e-12)


@pytest.mark.parametrize("quintic", [False, True])
def test_evaluation_agrees_with_the_shared_joint_trajectory(quintic: bool) -> None:
    times, q, v0, vn = _knots(5, 8)
    v = clamped_cubic_velocities(times, q, v0, vn)
    a = quintic_knot_accelerations(times, q, v) if quintic else None
    curve = PiecewisePolynomial.hermite(times, q, v, a)
    msg = Trajectory(
        times=times.tolist(),
        positions=q.tolist(),
        velocities=v.tolist(),
        accelerations=[] if a is None else a.tolist(),
    )
    shared = JointTrajectory(msg)
    ts = np.linspace(0.0, times[-1] - 1e-9, 301)
    q_s, qd_s, qdd_s = shared.sample_many(ts)
    assert curve.evaluate(ts) == pytest.approx(q_s, abs=1e-9)
    assert curve.evaluate(ts, 1) == pytest.approx(qd_s, abs=1e-9)
    assert curve.evaluate(ts, 2) == pytest.approx(qdd_s, abs=1e-7)
    # The controller's scalar twin gives the same positions to the last bit, before the
    # start and after the end too (a second instance: its quintic cache starts empty).
    twin = JointTrajectory(msg)
    for t in [-1.0, *ts.tolist(), float(times[-1]), float(times[-1]) + 1.0]:
        assert twin.position(t) == shared.sample(t).q.tolist()


@given(st.integers(0, 10_000), st.integers(2, 8), st.booleans(), st.integers(0, 2))
def test_extremes_are_exact_bounds_of_dense_samples(
    seed: int, n: int, quintic: bool, order: int
) -> None:
    times, q, v0, vn = _knots(seed, n)
    v = clamped_cubic_velocities(times, q, v0, vn)
    a = quintic_knot_accelerations(times, q, v) if quintic else None
    curve = PiecewisePolynomial.hermite(times, q, v, a)
    ex = curve.extremes(order)
    for seg in range(n - 1):
        ts = np.linspace(times[seg], times[seg + 1], 401)
        values = curve.evaluate(ts, order)
        span = np.abs(values).max() + 1.0
        # Never below a sample (no missed peak), never far above (no invented one).
        assert np.all(ex.high[seg] >= values.max(axis=0) - 1e-9 * span)
        assert np.all(ex.low[seg] <= values.min(axis=0) + 1e-9 * span)
        assert np.all(ex.high[seg] <= values.max(axis=0) + 1e-3 * span)
        assert np.all(ex.low[seg] >= values.min(axis=0) - 1e-3 * span)
        # ... and the reported times give the reported values.
        for j in range(6):
            at = curve.evaluate(np.array([ex.t_high[seg, j]]), order)[0, j]
            assert at == pytest.approx(ex.high[seg, j], rel=1e-9, abs=1e-9)


def test_extremes_survive_flat_and_linear_segments() -> None:
    times = np.array([0.0, 1.0, 2.0])
    q = np.zeros((3, 6))
    q[:, 1] = [0.0, 1.0, 2.0]  # a straight line in joint 2
    v = np.zeros((3, 6))
    v[:, 1] = 1.0
    curve = PiecewisePolynomial.hermite(times, q, v)
    ex = curve.extremes(1)
    assert ex.high[:, 1] == pytest.approx([1.0, 1.0])
    assert np.all(np.isfinite(ex.high)) and np.all(ex.high[:, 0] == 0.0)


def test_uniform_stretch_scales_rates() -> None:
    times, q, v0, vn = _knots(7, 5)
    curve = PiecewisePolynomial.hermite(times, q, clamped_cubic_velocities(times, q, v0, vn))
    slow = curve.stretched(2.0)
    v_peak, _ = curve.peak_abs(1)
    a_peak, _ = curve.peak_abs(2)
    assert slow.peak_abs(1)[0] == pytest.approx(v_peak / 2.0)
    assert slow.peak_abs(2)[0] == pytest.approx(a_peak / 4.0)
    assert time_stretch(np.array([3.0, 1.0]), np.array([1.5, 2.0]), 1) == pytest.approx(2.0)
    assert time_stretch(np.array([8.0]), np.array([2.0]), 2) == pytest.approx(2.0)
    assert time_stretch(np.array([1.0]), np.array([2.0]), 1) == 1.0
