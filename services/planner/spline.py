"""Joint-space interpolation: clamped cubic splines and quintic segments.

The thesis's method: docs/protocol.md, Thesis interpolation.

Knot velocities come from the thesis's tridiagonal system: imposing
acceleration continuity at every interior knot j of a cubic Hermite curve gives

    2/h[j-1] v[j-1] + (4/h[j-1] + 4/h[j]) v[j] + 2/h[j] v[j+1]
        = 6 (q[j+1] - q[j]) / h[j]^2 + 6 (q[j] - q[j-1]) / h[j-1]^2

with v[0] and v[n-1] given (moved to the right-hand side: the thesis prints
t1 - t2 where t1 - t0 is meant). The result is the clamped cubic spline. The matrix is
strictly diagonally dominant, so the Thomas algorithm needs no pivoting.

:class:`PiecewisePolynomial` holds any such curve in a normalised power basis per
segment, q(s) = sum_k a_k s^k with s = (t - t_i) / h_i in [0, 1], evaluates it
vectorised, and finds exact extremes of it and its derivatives per segment (roots of
the derivative, batched as companion-matrix eigenvalues), which is what the limit checks
need: a peak between two samples is never missed.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


def clamped_cubic_velocities(
    times: np.ndarray, q: np.ndarray, v_first: np.ndarray, v_last: np.ndarray
) -> np.ndarray:
    """Knot velocities of the clamped cubic spline through ``q``.

    Args:
        times: knot times [s], shape (n,), strictly increasing, n >= 2.
        q: knot positions [rad], shape (n, j).
        v_first: velocity at the first knot [rad/s], shape (j,).
        v_last: velocity at the last knot [rad/s], shape (j,).

    Returns:
        Velocities at every knot [rad/s], shape (n, j) (the given ones at both ends).
    """
    times = np.asarray(times, dtype=float)
    q = np.asarray(q, dtype=float)
    n = len(times)
    v = np.empty_like(q)
    v[0], v[-1] = v_first, v_last
    if n <= 2:
        return v
    h = np.diff(times)
    slope = np.diff(q, axis=0) / h[:, None] ** 2  # (n-1, j)
    # Rows j = 1..n-2: alpha v[j-1] + beta v[j] + gamma v[j+1] = delta.
    alpha = 2.0 / h[:-1]
    beta = 4.0 / h[:-1] + 4.0 / h[1:]
    gamma = 2.0 / h[1:]
    delta = 6.0 * (slope[1:] + slope[:-1])
    delta[0] -= alpha[0] * v[0]
    delta[-1] -= gamma[-1] * v[-1]
    v[1:-1] = _thomas(alpha[1:], beta, gamma[:-1], delta)
    return v


def _thomas(sub: np.ndarray, diag: np.ndarray, sup: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Solve a tridiagonal system (m unknowns, any number of right-hand-side columns).

    Args:
        sub: sub-diagonal, shape (m-1,).
        diag: diagonal, shape (m,).
        sup: super-diagonal, shape (m-1,).
        rhs: right-hand sides, shape (m, j).
    """
    m = len(diag)
    c = np.empty(m)
    d = np.empty_like(rhs)
    c[0] = sup[0] / diag[0] if m > 1 else 0.0
    d[0] = rhs[0] / diag[0]
    for i in range(1, m):
        denom = diag[i] - sub[i - 1] * c[i - 1]
        c[i] = sup[i] / denom if i < m - 1 else 0.0
        d[i] = (rhs[i] - sub[i - 1] * d[i - 1]) / denom
    x = np.empty_like(rhs)
    x[-1] = d[-1]
    for i in range(m - 2, -1, -1):
        x[i] = d[i] - c[i] * x[i + 1]
    return x


def cubic_knot_accelerations(times: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Accelerations at the knots of the cubic Hermite curve (q, v) [rad/s^2], shape (n, j).

    At an interior knot both neighbouring segments agree when ``v`` is the clamped
    spline's; the value is taken from the segment that starts there (the last knot from
    the segment that ends there).
    """
    h = np.diff(np.asarray(times, dtype=float))[:, None]
    dq = np.diff(q, axis=0)
    a = np.empty_like(np.asarray(q, dtype=float))
    a[:-1] = 6.0 * dq / h**2 - (4.0 * v[:-1] + 2.0 * v[1:]) / h
    a[-1] = -6.0 * dq[-1] / h[-1] ** 2 + (2.0 * v[-2] + 4.0 * v[-1]) / h[-1]
    return a


class Extremes(NamedTuple):
    """Smallest and largest value of a curve on each segment, and where.

    Attributes:
        low: smallest value, shape (segments, j).
        t_low: its time [s], shape (segments, j).
        high: largest value, shape (segments, j).
        t_high: its time [s], shape (segments, j).
    """

    low: np.ndarray
    t_low: np.ndarray
    high: np.ndarray
    t_high: np.ndarray


class PiecewisePolynomial:
    """Piecewise polynomial joint curves, one normalised power basis per segment.

    Args:
        times: knot times [s], shape (n,), strictly increasing.
        coeffs: a_k of q(s) = sum_k a_k s^k on each segment, s = (t - t_i) / h_i,
            shape (n-1, degree+1, j) [rad].
    """

    def __init__(self, times: np.ndarray, coeffs: np.ndarray) -> None:
        self.times = np.asarray(times, dtype=float)
        self.coeffs = np.asarray(coeffs, dtype=float)
        self.h = np.diff(self.times)

    @classmethod
    def hermite(
        cls, times: np.ndarray, q: np.ndarray, v: np.ndarray, a: np.ndarray | None = None
    ) -> PiecewisePolynomial:
        """Cubic Hermite segments through (q, v), or quintic ones through (q, v, a)."""
        times = np.asarray(times, dtype=float)
        h = np.diff(times)[:, None]
        p0, p1 = q[:-1], q[1:]
        dp = p1 - p0
        v0, v1 = h * v[:-1], h * v[1:]
        if a is None:
            c = [p0, v0, 3.0 * dp - 2.0 * v0 - v1, -2.0 * dp + v0 + v1]
        else:
            a0, a1 = h * h * a[:-1], h * h * a[1:]
            c = [
                p0,
                v0,
                0.5 * a0,
                10.0 * dp - 6.0 * v0 - 4.0 * v1 - 1.5 * a0 + 0.5 * a1,
                -15.0 * dp + 8.0 * v0 + 7.0 * v1 + 1.5 * a0 - a1,
                6.0 * dp - 3.0 * v0 - 3.0 * v1 - 0.5 * a0 + 0.5 * a1,
            ]
        return cls(times, np.stack(c, axis=1))

    @property
    def duration(self) -> float:
        """Time of the last knot [s]."""
        return float(self.times[-1])

    def stretched(self, factor: float) -> PiecewisePolynomial:
        """The same path with time stretched by ``factor`` (velocities / factor)."""
        return PiecewisePolynomial(self.times * factor, self.coeffs)

    def derivative_coeffs(self, order: int) -> np.ndarray:
        """Coefficients of the ``order``-th time derivative, same basis, shape (n-1, ., j)."""
        c = self.coeffs
        for _ in range(order):
            k = np.arange(1, c.shape[1], dtype=float)
            c = c[:, 1:] * k[None, :, None]
        return np.asarray(c / self.h[:, None, None] ** order)

    def evaluate(self, ts: np.ndarray, order: int = 0) -> np.ndarray:
        """Values (or ``order``-th derivatives) at times ``ts``, clipped to the knot span,
        shape (m, j)."""
        ts = np.clip(np.asarray(ts, dtype=float), self.times[0], self.times[-1])
        seg = np.clip(np.searchsorted(self.times, ts, side="right") - 1, 0, len(self.h) - 1)
        s = (ts - self.times[seg]) / self.h[seg]
        c = self.derivative_coeffs(order)[seg]  # (m, degree+1, j)
        out = c[:, -1]
        for k in range(c.shape[1] - 2, -1, -1):
            out = out * s[:, None] + c[:, k]
        return np.asarray(out)

    def extremes(self, order: int = 0) -> Extremes:
        """Exact smallest and largest value of the ``order``-th derivative per segment."""
        c = self.derivative_coeffs(order)  # (S, d+1, j)
        S, d1, J = c.shape
        flat = np.moveaxis(c, 2, 1).reshape(S * J, d1)
        s = _critical_points(flat)  # (S*J, K), all in [0, 1]
        values = _horner(flat, s)
        lo_i, hi_i = values.argmin(axis=1), values.argmax(axis=1)
        rows = np.arange(S * J)
        start = np.repeat(self.times[:-1], J)
        span = np.repeat(self.h, J)

        def shaped(x: np.ndarray) -> np.ndarray:
            return x.reshape(S, J)

        return Extremes(
            low=shaped(values[rows, lo_i]),
            t_low=shaped(start + s[rows, lo_i] * span),
            high=shaped(values[rows, hi_i]),
            t_high=shaped(start + s[rows, hi_i] * span),
        )

    def peak_abs(self, order: int) -> tuple[np.ndarray, np.ndarray]:
        """Largest |value| of the ``order``-th derivative over the whole curve, per joint,
        and its time [s]: two arrays of shape (j,)."""
        ex = self.extremes(order)
        mag = np.concatenate([-ex.low, ex.high], axis=0)  # (2S, j)
        when = np.concatenate([ex.t_low, ex.t_high], axis=0)
        i = mag.argmax(axis=0)
        cols = np.arange(mag.shape[1])
        return mag[i, cols], when[i, cols]


def _horner(c: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Row-wise polynomial values: c (M, d+1) ascending, s (M, K) -> (M, K)."""
    out = np.broadcast_to(c[:, -1:], s.shape).copy()
    for k in range(c.shape[1] - 2, -1, -1):
        out = out * s + c[:, k : k + 1]
    return out


def _critical_points(c: np.ndarray) -> np.ndarray:
    """0, 1 and the real parts of the roots of each row's derivative, clipped to [0, 1].

    Evaluating a polynomial at extra points of [0, 1] never overstates its extremes, so
    complex roots with a small imaginary part (double roots) are safe to keep.
    """
    M, d1 = c.shape
    ends = np.tile([0.0, 1.0], (M, 1))
    degree = d1 - 2  # of the derivative
    if degree < 1:
        return ends
    b = c[:, 1:] * np.arange(1, d1, dtype=float)  # derivative, ascending, (M, degree+1)
    scale = np.abs(b).max(axis=1)
    lead = b[:, -1].copy()
    # A vanishing leading coefficient only sends a root far outside [0, 1]; keep the
    # companion matrix finite by flooring it (relative to the row's size).
    floor = 1e-12 * np.where(scale > 0.0, scale, 1.0)
    lead = np.where(np.abs(lead) < floor, np.where(lead < 0.0, -floor, floor), lead)
    if degree == 1:
        roots = (-b[:, 0] / lead)[:, None]
    else:
        comp = np.zeros((M, degree, degree))
        comp[:, np.arange(1, degree), np.arange(degree - 1)] = 1.0
        comp[:, :, -1] = -b[:, :-1] / lead[:, None]
        roots = np.linalg.eigvals(comp).real
    roots = np.where(np.isfinite(roots), roots, 0.0)
    return np.concatenate([ends, np.clip(roots, 0.0, 1.0)], axis=1)


def quintic_knot_accelerations(times: np.ndarray, q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Knot accelerations for the quintic plan [rad/s^2], shape (n, j).

    Interior knots keep the clamped cubic spline's accelerations (continuous); both ends
    get zero, so the arm starts and stops without an acceleration step.
    """
    a = cubic_knot_accelerations(times, q, v)
    a[0] = 0.0
    a[-1] = 0.0
    return a


def time_stretch(peak: np.ndarray, limit: np.ndarray, power: int) -> float:
    """Smallest uniform time stretch bringing ``peak`` within ``limit`` for a quantity
    that scales as 1 / stretch**power (1: velocity, 2: acceleration); at least 1."""
    ratio = float(np.max(np.asarray(peak) / np.asarray(limit)))
    return max(1.0, math.pow(ratio, 1.0 / power))
