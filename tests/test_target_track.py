"""A tracker's target as the controller keeps it: jumps, period, latency, loss, and the
prediction over the delays (pure, no arm)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from services.controller.follow_config import FollowConfig
from services.controller.target_track import Axes, Frame, TargetTrack

PERIOD_NS = 33_333_333


def _feed(track: TargetTrack, path: object, n: int, noise: float = 0.0, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    for k in range(n):
        t = k * PERIOD_NS
        x, y, z = path(t / 1e9)  # type: ignore[operator]
        e = rng.normal(0.0, noise, 3) if noise else np.zeros(3)
        track.add(Frame(t, (x + e[0], y + e[1], z + e[2])))


def test_a_frame_moving_faster_than_a_person_is_a_jump() -> None:
    track = TargetTrack(FollowConfig(max_target_speed=1.0, jump_tolerance_m=0.01))
    assert track.add(Frame(0, (0.0, 0.0, 0.0))) is None
    assert track.add(Frame(PERIOD_NS, (0.03, 0.0, 0.0))) is None  # 0.9 m/s: a person can
    jump = track.add(Frame(2 * PERIOD_NS, (0.13, 0.0, 0.0)))
    assert jump is not None
    assert jump.distance == pytest.approx(0.10)
    assert jump.allowed == pytest.approx(1.0 * PERIOD_NS / 1e9 + 0.01)
    assert track.add(Frame(PERIOD_NS, (5.0, 0.0, 0.0))) is None  # an old frame: ignored
    assert track.newest == Frame(2 * PERIOD_NS, (0.13, 0.0, 0.0))


def test_the_period_latency_and_loss_come_from_the_stamps() -> None:
    track = TargetTrack(FollowConfig())
    assert track.period_s() is None and track.latency_s() == 0.0
    _feed(track, lambda t: (0.0, 0.0, 0.0), 10)
    assert track.period_s() == pytest.approx(1 / 30, rel=1e-6)
    newest = track.newest
    assert newest is not None
    for age_ms in (40, 73, 60, 40, 66):  # joint states see the newest frame this old
        assert track.observe(newest.stamp_ns + age_ms * 1_000_000) is not None
    assert track.latency_s() == pytest.approx(0.040)
    limit_ns = 40_000_000 + 2 * PERIOD_NS
    assert track.lost(limit_ns, 0.0) is None  # two periods beyond the latency: still there
    why = track.lost(limit_ns + 1_000_000, 0.0)
    assert why is not None and "lost after 67 ms" in why
    assert track.lost(round(0.3e9), 0.5) is None  # a goal's own lost_after


def test_the_prediction_follows_a_sway_over_the_delays() -> None:
    def sway(t: float) -> tuple[float, float, float]:
        return 0.0, 0.05 * math.sin(2 * math.pi * 0.5 * t), 0.0

    cfg = FollowConfig(model="jerk", process_noise=1e4, noise_m=0.0002)
    track = TargetTrack(cfg)
    _feed(track, sway, 200)
    newest = track.newest
    assert newest is not None
    t = newest.stamp_ns + 160_000_000
    predicted = track.predict(t)
    assert predicted is not None
    (_, y, _), (_, vy, _) = predicted
    assert y == pytest.approx(sway(t / 1e9)[1], abs=0.001)  # within 1 mm, 160 ms ahead
    assert vy == pytest.approx(0.05 * math.pi * math.cos(math.pi * t / 1e9), abs=0.02)


def test_a_noisy_tracker_is_smoothed() -> None:
    still = TargetTrack(FollowConfig(noise_m=0.001))
    rng = np.random.default_rng(1)
    raw, kept = [], []
    for k in range(120):
        e = rng.normal(0.0, 0.001)
        still.add(Frame(k * PERIOD_NS, (0.1 + e, 0.2, 0.3)))
        now = still.predict(k * PERIOD_NS)
        assert now is not None
        if k >= 30:
            raw.append(e)
            kept.append(now[0][0] - 0.1)
    assert float(np.std(kept)) < 0.8 * float(np.std(raw))


def test_the_prediction_is_bounded() -> None:
    cfg = FollowConfig(max_prediction_s=0.2, max_prediction_m=0.02, max_target_speed=0.5)
    track = TargetTrack(cfg)
    _feed(track, lambda t: (0.3 * t, 0.0, 0.0), 30)  # 0.3 m/s along x
    newest = track.newest
    assert newest is not None
    far = track.predict(newest.stamp_ns + round(2e9))
    assert far is not None
    assert far[0][0] - newest.xyz[0] == pytest.approx(0.02, abs=1e-6)  # at most 20 mm
    fast = TargetTrack(cfg)
    _feed(fast, lambda t: (0.9 * t, 0.0, 0.0), 30)  # faster than max_target_speed
    p = fast.predict(round(1.1e9))
    assert p is not None and p[1][0] == pytest.approx(0.5)


def test_the_kalman_filter_converges_on_a_line() -> None:
    axes = Axes((0.0, 0.0, 0.0), 3, 0.1, 0.001)
    for k in range(1, 60):
        axes.update((0.1 * k / 30, 0.0, -0.05 * k / 30), 1 / 30)
    (x, _, z), (vx, vy, vz) = axes.ahead(0.5)
    assert vx == pytest.approx(0.1, rel=0.02) and vz == pytest.approx(-0.05, rel=0.02)
    assert abs(vy) < 1e-9
    assert x == pytest.approx(0.1 * 59 / 30 + 0.05, abs=0.002)
    assert z == pytest.approx(-0.05 * 59 / 30 - 0.025, abs=0.002)
