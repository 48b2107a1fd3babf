"""One tracker's target as the controller knows it: its newest frames, whether it jumped
or is lost, and where it will be when a command acts (latency compensation).

All times are the stack's clock (the frames' capture stamps, the joint states' stamps)
[ns]; positions are in the arm's base frame [m]. Pure: the same frames and joint states
give the same answers.

- **Jumps**: a frame whose point moved further from the previous frame's than
  ``max_speed`` times the time between their captures, plus ``tolerance`` (the tracker's
  noise), jumped (a person does not move that fast: a tracker that found another face).
- **Period**: the median of the newest capture intervals.
- **Latency**: the age of the newest frame at a joint state is its latency plus up to a
  period; the tenth percentile of the ages at the newest 32 joint states estimates the
  latency (the least would take a joint state handled late for a fast tracker).
- **Lost**: at a joint state the newest frame is older than that latency plus
  ``lost_after`` (default two periods): no newer frame came for that long.
- **Prediction**: per coordinate, a Kalman filter of the target's motion (``model``:
  constant acceleration or constant jerk, driven by white noise of density
  ``process_noise``; the tracker's noise ``noise_m``) estimates the motion at the newest
  capture, extrapolated on that model over the delays to the moment asked,
  by at most ``max_prediction_s`` and ``max_prediction_m``; its speed is at most
  ``max_speed``. With a noiseless tracker it follows the motion closely; a noisy one is
  smoothed as much as a person's motion allows.
"""

from __future__ import annotations

import itertools
import math
import statistics
from collections import deque
from typing import NamedTuple

from manus.kinematics import Vec3
from services.controller.follow_config import ORDERS, FollowConfig

_KEEP = 16
"""Frames kept (more than a window at 30 Hz)."""
_AGES = 32
"""Joint states whose target age estimates the latency."""


class Frame(NamedTuple):
    """One frame of the target.

    Attributes:
        stamp_ns: capture time [ns].
        xyz: the target point, base frame [m].
    """

    stamp_ns: int
    xyz: Vec3


class Jump(NamedTuple):
    """A frame that moved further than the target can.

    Attributes:
        distance: how far from the previous frame [m].
        allowed: the most it could have moved [m].
        interval: time between the two captures [s].
    """

    distance: float
    allowed: float
    interval: float


class TargetTrack:
    """The newest frames of one tracker (see the module docstring).

    Args:
        config: the follow settings.
        max_speed: the fastest the target may move [m/s] (a goal's, or the config's).
    """

    def __init__(self, config: FollowConfig, max_speed: float | None = None) -> None:
        self.config = config
        self.max_speed = config.max_target_speed if max_speed is None else max_speed
        self.frames: deque[Frame] = deque(maxlen=_KEEP)
        self._ages: deque[int] = deque(maxlen=_AGES)
        self._axes: Axes | None = None
        self._period: float | None = None

    @property
    def newest(self) -> Frame | None:
        """The newest frame (None: none yet)."""
        return self.frames[-1] if self.frames else None

    def add(self, frame: Frame) -> Jump | None:
        """Take a frame (one not newer than the newest is ignored); returns the jump it
        makes (None: none), and keeps it either way."""
        last = self.newest
        if last is not None and frame.stamp_ns <= last.stamp_ns:
            return None
        self.frames.append(frame)
        self._period = None
        if last is None:
            cfg = self.config
            self._axes = Axes(frame.xyz, ORDERS[cfg.model], cfg.process_noise, cfg.noise_m)
            return None
        dt = (frame.stamp_ns - last.stamp_ns) / 1e9
        assert self._axes is not None
        self._axes.update(frame.xyz, dt)
        distance = math.dist(frame.xyz, last.xyz)
        allowed = self.max_speed * dt + self.config.jump_tolerance_m
        return Jump(distance, allowed, dt) if distance > allowed else None

    def period_s(self) -> float | None:
        """The median interval of the newest captures [s] (None: fewer than two frames)."""
        if self._period is not None:
            return self._period
        stamps = [f.stamp_ns for f in self.frames]
        if len(stamps) < 2:
            return None
        self._period = statistics.median(b - a for a, b in itertools.pairwise(stamps)) / 1e9
        return self._period

    def observe(self, stamp_ns: int) -> int | None:
        """A joint state stamped ``stamp_ns``: the newest frame's age then [ns] (None: no
        frame yet), remembered for the latency."""
        last = self.newest
        if last is None:
            return None
        age = stamp_ns - last.stamp_ns
        self._ages.append(age)
        return age

    def latency_s(self) -> float:
        """The tracker's latency estimated from the newest ages [s] (0: none yet): their
        tenth percentile, not their least, so that a joint state handled late (its frame
        newer than its stamp) does not make every age look long."""
        if not self._ages:
            return 0.0
        ages = sorted(self._ages)
        return max(0.0, ages[len(ages) // 10] / 1e9)

    def lost(self, age_ns: int, lost_after_s: float) -> str | None:
        """Why the target counts as lost at a joint state where the newest frame is
        ``age_ns`` old (None: it is not); ``lost_after_s`` 0: two periods (the config's
        ``lost_periods``)."""
        after = lost_after_s
        if after <= 0.0:
            period = self.period_s()
            if period is None:
                return None  # one frame only: the next ones set the period
            after = self.config.lost_periods * period
        latency = self.latency_s()
        if age_ns / 1e9 <= latency + after:
            return None
        return (
            f"no new frame for {(age_ns / 1e9 - latency) * 1e3:.0f} ms beyond its latency "
            f"{latency * 1e3:.0f} ms (lost after {after * 1e3:.0f} ms)"
        )

    def predict(self, t_ns: int) -> tuple[Vec3, Vec3] | None:
        """Where the target will be at ``t_ns`` [m], and its velocity then [m/s] (None:
        no frame yet); see the module docstring."""
        last = self.newest
        if last is None:
            return None
        cfg = self.config
        h = min(max((t_ns - last.stamp_ns) / 1e9, 0.0), cfg.max_prediction_s)
        axes = self._axes
        assert axes is not None
        p = axes.position()
        (x, y, z), (vx, vy, vz) = axes.ahead(h)
        now = axes.ahead(0.0)[1]
        speed = math.sqrt(now[0] * now[0] + now[1] * now[1] + now[2] * now[2])
        slow = min(1.0, self.max_speed / speed) if speed > 0.0 else 1.0
        d = [(x - p[0]) * slow, (y - p[1]) * slow, (z - p[2]) * slow]
        size = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if size > cfg.max_prediction_m:
            d = [c * cfg.max_prediction_m / size for c in d]
        ahead = (vx * slow, vy * slow, vz * slow)
        return (p[0] + d[0], p[1] + d[1], p[2] + d[2]), _capped(ahead, self.max_speed)


def _capped(v: Vec3, cap: float) -> Vec3:
    size = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return v if size <= cap else (v[0] * cap / size, v[1] * cap / size, v[2] * cap / size)


class Axes:
    """A Kalman filter of each coordinate and its first ``order - 1`` derivatives (3:
    constant acceleration, white jerk; 4: constant jerk, white snap) of process noise
    density ``process`` and measurement noise ``noise`` [m], on plain floats (a 4x4 at
    most: lists beat NumPy's per-call cost here). The three coordinates share their
    model, their noises and their frames' times, hence one covariance and one gain.

    Attributes:
        x: per coordinate: position, velocity, acceleration (, jerk) at the newest frame
            [m, m/s, ...].
    """

    def __init__(self, xyz: Vec3, order: int, process: float, noise: float) -> None:
        self.m = order
        self.x = [[v] + [0.0] * (order - 1) for v in xyz]
        self.q, self.r = process, max(noise * noise, 1e-12)
        # the first frame tells nothing of the derivatives: a wide prior
        self.P = [[(self.r if i == 0 else 10.0 ** (2 * i)) if i == j else 0.0 for j in range(order)]
                  for i in range(order)]  # fmt: skip
        self._dt = -1.0
        self._F: list[list[float]] = []
        self._Q: list[list[float]] = []

    def position(self) -> Vec3:
        """The estimated position [m]."""
        return self.x[0][0], self.x[1][0], self.x[2][0]

    def ahead(self, h: float) -> tuple[Vec3, Vec3]:
        """Position [m] and velocity [m/s] extrapolated by ``h`` [s] on the model."""
        m = self.m
        kp = [h**k / math.factorial(k) for k in range(m)]
        kv = [0.0] + [h ** (k - 1) / math.factorial(k - 1) for k in range(1, m)]
        p = [sum(c * x for c, x in zip(kp, row, strict=True)) for row in self.x]
        v = [sum(c * x for c, x in zip(kv, row, strict=True)) for row in self.x]
        return (p[0], p[1], p[2]), (v[0], v[1], v[2])

    def _model(self, dt: float) -> None:
        m, q = self.m, self.q
        fact = math.factorial
        self._F = [[dt ** (j - i) / fact(j - i) if j >= i else 0.0 for j in range(m)]
                   for i in range(m)]  # fmt: skip
        n = 2 * m - 1
        self._Q = [
            [q * dt ** (n - i - j) / (fact(m - 1 - i) * fact(m - 1 - j) * (n - i - j))
             for j in range(m)]
            for i in range(m)
        ]  # fmt: skip
        self._dt = dt

    def update(self, z: Vec3, dt: float) -> None:
        """Predict over ``dt`` [s], then take the measurement ``z`` [m]."""
        if dt != self._dt:
            self._model(dt)
        m, F, Q, P = self.m, self._F, self._Q, self.P
        FP = [[sum(F[i][k] * P[k][j] for k in range(i, m)) for j in range(m)] for i in range(m)]
        N = [[sum(FP[i][k] * F[j][k] for k in range(j, m)) + Q[i][j] for j in range(m)]
             for i in range(m)]  # fmt: skip
        s = N[0][0] + self.r
        K = [N[i][0] / s for i in range(m)]
        self.P = [[N[i][j] - K[i] * N[0][j] for j in range(m)] for i in range(m)]
        for row, zc in zip(self.x, z, strict=True):
            x = [sum(F[i][k] * row[k] for k in range(i, m)) for i in range(m)]
            y = zc - x[0]
            row[:] = [x[i] + K[i] * y for i in range(m)]
