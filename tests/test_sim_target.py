"""The simulator's moving target: its true motion, its tracker's frames (rate, latency,
noise, loss), the user's head moving with it in the true distances, and its settings."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from manus.errors import ConfigError
from manus.scene import default_scene
from manus_stack.lockstep import LockStep
from schemas import endpoints as ep
from schemas.base import Message
from schemas.target import TargetPose
from services.simulator.config import SimConfig, load_sim_config
from services.simulator.core import SimCore
from services.simulator.target_config import (
    MOUTH_XYZ_MM,
    LostWindow,
    TargetConfig,
    TargetMove,
)

S = 1_000_000_000


def _core(**target: object) -> SimCore:
    cfg = TargetConfig(enabled=True, **target)  # type: ignore[arg-type]
    return SimCore(SimConfig(start_pose="unfolded", target=cfg))


def _frames(core: SimCore, until_s: float) -> list[tuple[int, TargetPose]]:
    core.advance(round(until_s * S))
    out = []
    for at, suffix, msg in core.take_messages():
        if suffix == ep.TARGET:  # (the camera's frames beside them)
            assert isinstance(msg, TargetPose)
            out.append((at, msg))
    return out


def test_frames_come_at_the_rate_each_its_latency_after_its_capture() -> None:
    frames = _frames(_core(rate_hz=20.0, latency_ms=35.0), 1.0)
    assert [m.seq for _, m in frames] == list(range(len(frames)))
    assert len(frames) == 20  # captures at 0, 50, ..., 950 ms, published 35 ms later
    for at, m in frames:
        assert at - m.stamp_ns == 35_000_000
        assert m.stamp_ns % 50_000_000 == 0 and m.source == "mouth" and m.tracked
    rest = np.array(MOUTH_XYZ_MM) / 1000.0
    assert np.allclose(frames[0][1].xyz, rest)  # no sway, no noise: at rest


def test_the_target_sways_moves_and_its_head_goes_with_it() -> None:
    move = TargetMove(at_s=1.0, by_mm=(60.0, 0.0, -20.0), over_s=0.5)
    core = _core(sway_mm=(0.0, 20.0, 0.0), sway_hz=0.5, moves=(move,))
    target = core.target
    assert target is not None and target.body_rest is not None
    quarter = round(0.5 * S)  # a quarter period: the sway at its amplitude
    assert target.offset(quarter)[1] == pytest.approx(0.020)
    assert target.offset(round(1.25 * S))[0] == pytest.approx(0.030)  # half way (symmetric)
    end = target.offset(round(4.0 * S))
    assert end[0] == pytest.approx(0.060) and end[2] == pytest.approx(-0.020)
    body = target.body_pose(round(4.0 * S))
    assert body is not None
    assert np.allclose(body[:3, 3] - target.body_rest[:3, 3], end)
    truth = target.truth(round(4.0 * S))
    assert truth.body == "head" and np.allclose(truth.body_xyz, body[:3, 3])


def test_a_lost_target_is_silent_or_reported_untracked() -> None:
    lost = (LostWindow(at_s=0.5, for_s=1.0),)
    silent = _frames(_core(lost=lost, latency_ms=0.0), 2.0)
    stamps = [m.stamp_ns / S for _, m in silent]
    assert not any(0.5 <= t < 1.5 for t in stamps)
    assert any(t < 0.5 for t in stamps) and any(t >= 1.5 for t in stamps)
    told = _frames(_core(lost=lost, lost_reports="untracked", latency_ms=0.0), 2.0)
    untracked = [m for _, m in told if not m.tracked]
    assert untracked and all(0.5 <= m.stamp_ns / S < 1.5 for m in untracked)
    assert all(m.confidence == 0.0 for m in untracked)
    core = _core(lost=lost)
    assert core.target is not None and not core.target.truth(round(0.7 * S)).visible


def test_noise_jitter_and_drops_are_seeded_and_keep_the_order() -> None:
    def run(seed: int) -> list[tuple[int, TargetPose]]:
        cfg = TargetConfig(enabled=True, noise_mm=2.0, jitter_ms=30.0, drop=0.2)
        core = SimCore(SimConfig(seed=seed, start_pose="unfolded", target=cfg))
        return _frames(core, 3.0)

    a, b, c = run(1), run(1), run(2)
    assert [(t, m.encode()) for t, m in a] == [(t, m.encode()) for t, m in b]
    assert [m.xyz for _, m in a] != [m.xyz for _, m in c]
    times = [t for t, _ in a]
    assert times == sorted(times)
    assert 50 < len(a) < 85  # 90 captures, about a fifth dropped
    errors = np.array([m.xyz for _, m in a]) - np.array(MOUTH_XYZ_MM) / 1000.0
    assert 0.001 < float(errors.std()) < 0.003


def test_the_true_distance_to_the_person_follows_the_head() -> None:
    still = SimCore(SimConfig(start_pose="unfolded"))
    mount = default_scene().mount
    gripper = (mount @ np.array([*still.truth().xyz, 1.0]))[:3]
    head = np.array([-0.020, 0.0, 1.230])
    way = gripper - head
    by = way * (1.0 - 0.2 / float(np.linalg.norm(way)))  # the head 200 mm from the gripper
    bx, by_, bz = (float(v) * 1000.0 for v in by)
    lean = TargetMove(at_s=0.1, by_mm=(bx, by_, bz), over_s=0.0)
    moved = _core(moves=(lean,))
    for core in (still, moved):
        core.advance(round(0.5 * S))
    a, b = still.truth(), moved.truth()
    assert a.person_clearance is not None and b.person_clearance is not None
    assert a.target is None and b.target is not None
    assert b.person_clearance < a.person_clearance - 0.05  # the head came toward the arm
    assert b.person_pair.endswith("/head")
    assert b.min_person_clearance == pytest.approx(b.person_clearance, abs=0.02)


def test_lock_step_publishes_the_frames_on_the_bus() -> None:
    cfg = SimConfig(target=TargetConfig(enabled=True, rate_hz=10.0, latency_ms=20.0))
    ls = LockStep(cfg)
    got: list[tuple[int, TargetPose]] = []

    def take(msg: Message, t: int) -> list[tuple[str, Message]]:
        assert isinstance(msg, TargetPose)
        got.append((t, msg))
        return []

    ls.subscribe(ep.TARGET, take)
    ls.run_for(1.0)
    assert len(got) == 10
    for t, m in got:
        assert t == m.stamp_ns + 20_000_000 + ls.bus_latency_ns


def test_settings_are_checked_and_read_from_a_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="rate_hz"):
        TargetConfig(rate_hz=0.0)
    with pytest.raises(ConfigError, match="lost_reports"):
        TargetConfig(lost_reports="loud")
    with pytest.raises(ConfigError, match="by_mm"):
        TargetMove(at_s=1.0, by_mm=(1.0, 2.0))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="not a person of the scene"):
        _core(body="table")
    path = tmp_path / "sim.json"
    target = {
        "enabled": True,
        "sway_mm": [0, 15, 5],
        "moves": [{"at_s": 3, "by_mm": [50, 0, -10], "over_s": 0.6}],
        "lost": [{"at_s": 6, "for_s": 1}],
    }
    path.write_text(json.dumps({"target": target}))
    cfg = load_sim_config(path).target
    assert cfg.enabled and cfg.sway_mm == (0.0, 15.0, 5.0)
    assert cfg.moves == (TargetMove(3.0, (50.0, 0.0, -10.0), 0.6),)
    path.write_text(json.dumps({"target": {"moves": [{"at": 3}]}}))
    with pytest.raises(ConfigError, match=r"target\.moves"):
        load_sim_config(path)
    path.write_text(json.dumps({"target": {"speed": 3}}))
    with pytest.raises(ConfigError, match="unknown target setting `speed`"):
        load_sim_config(path)


def test_move_share_is_a_smooth_step() -> None:
    move = TargetMove(at_s=1.0, by_mm=(10.0, 0.0, 0.0), over_s=2.0)
    assert move.share(0.5) == 0.0 and move.share(3.5) == 1.0
    assert move.share(2.0) == pytest.approx(0.5)
    jump = TargetMove(at_s=1.0, by_mm=(10.0, 0.0, 0.0))
    assert jump.share(1.0) == 0.0 and jump.share(1.0 + 1e-9) == 1.0
    assert math.isclose(move.share(1.01), 0.0, abs_tol=1e-4)  # starts with zero speed
