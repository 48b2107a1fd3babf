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
  period; the smallest age of the newest 32 joint states estimates the latency.
- **Lost**: at a joint state the newest frame is older than that latency plus
  ``lost_after`` (default two periods): no newer frame came for that long.
- **Prediction**: a line (``velocity``) or a parabola (``acceleration``) fitted by least
  squares to the frames of the newest ``window_s``, evaluated at the newest capture,
  extrapolated over the delays to the moment asked, by at most ``max_prediction_s`` and
  ``max_prediction_m``; its speed is at most ``max_speed``.
"""

from __future__ import annotations

import itertools
import math
import statistics
from collections import deque
from typing import NamedTuple

from manus.kinematics import Vec3
from services.controller.follow_config import FollowConfig

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
        if last is None:
            return None
        dt = (frame.stamp_ns - last.stamp_ns) / 1e9
        distance = math.dist(frame.xyz, last.xyz)
        allowed = self.max_speed * dt + self.config.jump_tolerance_m
        return Jump(distance, allowed, dt) if distance > allowed else None

    def period_s(self) -> float | None:
        """The median interval of the newest captures [s] (None: fewer than two frames)."""
        stamps = [f.stamp_ns for f in self.frames]
        if len(stamps) < 2:
            return None
        return statistics.median(b - a for a, b in itertools.pairwise(stamps)) / 1e9

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
        """The tracker's latency estimated from the newest ages [s] (0: none yet)."""
        return max(0.0, min(self._ages) / 1e9) if self._ages else 0.0

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
        """Where the target will be at ``t_ns`` [m], and its velocity [m/s] (None: no
        frame yet); see the module docstring."""
        last = self.newest
        if last is None:
            return None
        cfg = self.config
        used = [f for f in self.frames if last.stamp_ns - f.stamp_ns <= cfg.window_s * 1e9]
        p, v, a = _fit(used, last.stamp_ns, cfg.prediction == "acceleration")
        speed = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        if speed > self.max_speed:
            k = self.max_speed / speed
            v, a = (v[0] * k, v[1] * k, v[2] * k), (0.0, 0.0, 0.0)
        h = min(max((t_ns - last.stamp_ns) / 1e9, 0.0), cfg.max_prediction_s)
        d = [v[i] * h + 0.5 * a[i] * h * h for i in range(3)]
        size = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if size > cfg.max_prediction_m:
            d = [x * cfg.max_prediction_m / size for x in d]
        return (p[0] + d[0], p[1] + d[1], p[2] + d[2]), v


def _fit(frames: list[Frame], t0_ns: int, quadratic: bool) -> tuple[Vec3, Vec3, Vec3]:
    """Position, velocity and acceleration at ``t0_ns`` of the least-squares line (or
    parabola) through ``frames``: (p, v, a) [m, m/s, m/s^2]; a parabola needs 3 frames, a
    line 2 (fewer: the newest point, at rest)."""
    n = len(frames)
    last = frames[-1].xyz
    if n < 2 or (quadratic and n < 3):
        if n >= 2:
            quadratic = False
        else:
            return last, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    ts = [(f.stamp_ns - t0_ns) / 1e9 for f in frames]
    if not quadratic:
        tm = sum(ts) / n
        stt = sum((t - tm) ** 2 for t in ts)
        out_p, out_v = [], []
        for i in range(3):
            xs = [f.xyz[i] for f in frames]
            xm = sum(xs) / n
            slope = sum((t - tm) * (x - xm) for t, x in zip(ts, xs, strict=True)) / stt
            out_v.append(slope)
            out_p.append(xm + slope * (0.0 - tm))
        return (out_p[0], out_p[1], out_p[2]), (out_v[0], out_v[1], out_v[2]), (0.0, 0.0, 0.0)
    # normal equations of x = c0 + c1 t + c2 t^2 (t about the newest capture: small)
    s = [sum(t**k for t in ts) for k in range(5)]
    m = ((s[0], s[1], s[2]), (s[1], s[2], s[3]), (s[2], s[3], s[4]))
    coefs = []
    for i in range(3):
        b = [sum(f.xyz[i] * t**k for f, t in zip(frames, ts, strict=True)) for k in range(3)]
        coefs.append(_solve3(m, b))
    p = (coefs[0][0], coefs[1][0], coefs[2][0])
    v = (coefs[0][1], coefs[1][1], coefs[2][1])
    a = (2.0 * coefs[0][2], 2.0 * coefs[1][2], 2.0 * coefs[2][2])
    return p, v, a


def _solve3(m: tuple[Vec3, Vec3, Vec3], b: list[float]) -> Vec3:
    """``m x = b`` for a symmetric 3x3 ``m`` (Cramer's rule)."""
    (a, bb, c), (d, e, f), (g, h, i) = m

    def det(r0: Vec3, r1: Vec3, r2: Vec3) -> float:
        return (
            r0[0] * (r1[1] * r2[2] - r1[2] * r2[1])
            - r0[1] * (r1[0] * r2[2] - r1[2] * r2[0])
            + r0[2] * (r1[0] * r2[1] - r1[1] * r2[0])
        )

    full = det((a, bb, c), (d, e, f), (g, h, i))
    x0 = det((b[0], bb, c), (b[1], e, f), (b[2], h, i)) / full
    x1 = det((a, b[0], c), (d, b[1], f), (g, b[2], i)) / full
    x2 = det((a, bb, b[0]), (d, e, b[1]), (g, h, b[2])) / full
    return x0, x1, x2
