"""Evaluation of joint trajectories: piecewise cubic or quintic Hermite.

A :class:`schemas.planning.Trajectory` carries, at each knot, positions and velocities
(and accelerations for quintic segments). Between two knots the joint follows the unique
cubic (quintic) polynomial matching those values at both ends. A clamped cubic spline
is exactly a cubic Hermite curve whose knot velocities come from the spline system, so
this one representation carries both kinds of plan without loss.

Before the first knot the trajectory holds the first position; after the last it holds
the last position (velocity and acceleration zero there if the knots say so).
"""

from __future__ import annotations

import bisect
from typing import NamedTuple

import numpy as np

from manus.errors import ManusError
from schemas.planning import Trajectory


class TrajectoryError(ManusError, ValueError):
    """A trajectory message is inconsistent (shapes, times, values)."""


class Sample(NamedTuple):
    """The reference at one time.

    Attributes:
        q: positions [rad], shape (n,).
        qd: velocities [rad/s], shape (n,).
        qdd: accelerations [rad/s^2], shape (n,).
        segment: index of the knot interval (-1 before the start, len-1 after the end).
    """

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    segment: int


class JointTrajectory:
    """Fast evaluation of a :class:`Trajectory` (validated at construction).

    Args:
        msg: the trajectory message.

    Raises:
        TrajectoryError: naming the field and the knot.
    """

    def __init__(self, msg: Trajectory) -> None:
        self.times = np.asarray(msg.times, dtype=float)
        self.q = np.asarray(msg.positions, dtype=float)
        self.qd = np.asarray(msg.velocities, dtype=float)
        self.quintic = bool(msg.accelerations)
        k = len(self.times)
        if k < 1:
            raise TrajectoryError("trajectory has no knots")
        if self.q.ndim != 2 or self.q.shape[0] != k:
            raise TrajectoryError(f"positions: expected {k} rows, got shape {self.q.shape}")
        n = self.q.shape[1]
        if self.qd.shape != (k, n):
            raise TrajectoryError(f"velocities: expected shape {(k, n)}, got {self.qd.shape}")
        self.qdd = np.asarray(msg.accelerations, dtype=float) if self.quintic else np.zeros((k, n))
        if self.qdd.shape != (k, n):
            raise TrajectoryError(f"accelerations: expected shape {(k, n)}, got {self.qdd.shape}")
        if k > 1 and not np.all(np.diff(self.times) > 0):
            i = int(np.argmax(np.diff(self.times) <= 0)) + 1
            raise TrajectoryError(
                f"times must increase strictly: knot {i} at {self.times[i]:.6g} s "
                f"after {self.times[i - 1]:.6g} s"
            )
        if not (
            np.isfinite(self.times).all()
            and np.isfinite(self.q).all()
            and np.isfinite(self.qd).all()
            and np.isfinite(self.qdd).all()
        ):
            raise TrajectoryError("trajectory holds a NaN or infinite value")
        self.n_joints = n
        self.msg = msg
        self._knots: list[float] = self.times.tolist()
        """The knot times as plain floats (the per-sample search)."""
        self._quintics: dict[int, np.ndarray] = {}
        """Quintic coefficients of the segments sampled so far, by segment."""
        self._rows: tuple[list[list[float]], list[list[float]]] = (
            self.q.tolist(),
            self.qd.tolist(),
        )
        """Knot positions and velocities as plain floats (:meth:`position`)."""
        self._quintic_rows: dict[int, list[list[float]]] = {}
        """:attr:`_quintics` as plain floats, by segment."""

    @property
    def duration(self) -> float:
        """Time of the last knot [s]."""
        return float(self.times[-1])

    @property
    def start(self) -> np.ndarray:
        """First knot's positions [rad]."""
        return np.asarray(self.q[0])

    @property
    def end(self) -> np.ndarray:
        """Last knot's positions [rad]."""
        return np.asarray(self.q[-1])

    def segment(self, t: float) -> int:
        """Index i of the interval [t_i, t_{i+1}) holding ``t`` (-1 before, k-1 after)."""
        knots = self._knots
        if t < knots[0]:
            return -1
        if t >= knots[-1]:
            return len(knots) - 1
        return bisect.bisect_right(knots, t) - 1

    def sample(self, t: float) -> Sample:
        """Positions, velocities and accelerations at time ``t`` [s]."""
        i = self.segment(t)
        if i < 0:
            return Sample(self.q[0].copy(), np.zeros(self.n_joints), np.zeros(self.n_joints), -1)
        if i >= len(self.times) - 1:
            last = len(self.times) - 1
            return Sample(
                self.q[last].copy(), np.zeros(self.n_joints), np.zeros(self.n_joints), last
            )
        h = self._knots[i + 1] - self._knots[i]
        s = (t - self._knots[i]) / h
        if self.quintic:
            c = self._quintics.get(i)
            if c is None:
                c = self._quintics[i] = quintic_coefficients(
                    self.q[i],
                    self.qd[i],
                    self.qdd[i],
                    self.q[i + 1],
                    self.qd[i + 1],
                    self.qdd[i + 1],
                    h,
                )
            q, qd, qdd = _quintic(c, s * h)
        else:
            q, qd, qdd = _cubic(self.q[i], self.qd[i], self.q[i + 1], self.qd[i + 1], h, s)
        return Sample(q, qd, qdd, i)

    def position(self, t: float) -> list[float]:
        """Positions at time ``t`` [s] as plain floats: ``sample(t).q``, the same operations
        in the same order on Python floats (the controller's cycle, where NumPy's per-call
        overhead on six values costs more than the arithmetic; a test keeps them equal)."""
        knots = self._knots
        positions = self._rows[0]
        i = self.segment(t)
        if i < 0:
            return list(positions[0])
        if i >= len(knots) - 1:
            return list(positions[-1])
        h = knots[i + 1] - knots[i]
        s = (t - knots[i]) / h
        if self.quintic:
            c = self._quintic_rows.get(i)
            if c is None:
                self.sample(t)  # solves and caches the segment's coefficients
                c = self._quintic_rows[i] = self._quintics[i].tolist()
            x = s * h
            return [
                c0 + x * (c1 + x * (c2 + x * (c3 + x * (c4 + x * c5))))
                for c0, c1, c2, c3, c4, c5 in zip(*c, strict=True)
            ]
        s2, s3 = s * s, s * s * s
        w0, w1 = 2 * s3 - 3 * s2 + 1, (s3 - 2 * s2 + s) * h
        w2, w3 = -2 * s3 + 3 * s2, (s3 - s2) * h
        p0, p1 = positions[i], positions[i + 1]
        v0, v1 = self._rows[1][i], self._rows[1][i + 1]
        return [
            w0 * a + w1 * b + w2 * c + w3 * d for a, b, c, d in zip(p0, v0, p1, v1, strict=True)
        ]

    def sample_many(self, ts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities, accelerations at each of ``ts``, each shape (m, n)."""
        rows = [self.sample(float(t)) for t in np.asarray(ts, dtype=float)]
        return (
            np.array([r.q for r in rows]),
            np.array([r.qd for r in rows]),
            np.array([r.qdd for r in rows]),
        )


def _cubic(
    p0: np.ndarray, v0: np.ndarray, p1: np.ndarray, v1: np.ndarray, h: float, s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cubic Hermite on [0, h] at normalised time s in [0, 1]."""
    s2, s3 = s * s, s * s * s
    # Weights of (p0, v0, p1, v1) in the position, velocity and acceleration: one row
    # each, so that the three come out of the same four products.
    w = np.array(
        [
            [2 * s3 - 3 * s2 + 1, (s3 - 2 * s2 + s) * h, -2 * s3 + 3 * s2, (s3 - s2) * h],
            [(6 * s2 - 6 * s) / h, 3 * s2 - 4 * s + 1, (-6 * s2 + 6 * s) / h, 3 * s2 - 2 * s],
            [(12 * s - 6) / (h * h), (6 * s - 4) / h, (-12 * s + 6) / (h * h), (6 * s - 2) / h],
        ]
    )
    q, qd, qdd = w[:, 0:1] * p0 + w[:, 1:2] * v0 + w[:, 2:3] * p1 + w[:, 3:4] * v1
    return q, qd, qdd


def quintic_coefficients(
    p0: np.ndarray,
    v0: np.ndarray,
    a0: np.ndarray,
    p1: np.ndarray,
    v1: np.ndarray,
    a1: np.ndarray,
    h: float,
) -> np.ndarray:
    """Coefficients c0..c5 (shape (6, n)) of q(t) = sum c_k t^k on [0, h] meeting the ends.

    Solves the 6x6 boundary system directly (the thesis's printed solution has
    typos: docs/protocol.md, Thesis interpolation).
    """
    A = np.array(
        [
            [1, 0, 0, 0, 0, 0],
            [0, 1, 0, 0, 0, 0],
            [0, 0, 2, 0, 0, 0],
            [1, h, h**2, h**3, h**4, h**5],
            [0, 1, 2 * h, 3 * h**2, 4 * h**3, 5 * h**4],
            [0, 0, 2, 6 * h, 12 * h**2, 20 * h**3],
        ],
        dtype=float,
    )
    b = np.vstack([p0, v0, a0, p1, v1, a1])
    return np.asarray(np.linalg.solve(A, b))


def _quintic(c: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position, velocity and acceleration at ``t`` [s] of the quintic with coefficients
    ``c``, shape (6, n) (:func:`quintic_coefficients`)."""
    q = c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))))
    qd = c[1] + t * (2 * c[2] + t * (3 * c[3] + t * (4 * c[4] + t * 5 * c[5])))
    qdd = 2 * c[2] + t * (6 * c[3] + t * (12 * c[4] + t * 20 * c[5]))
    return q, qd, qdd
