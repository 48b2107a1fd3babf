"""What the objects cost: the simulator's ticks with objects, the camera, the world model.

- ``simulator``: simulated seconds of an idle arm (the default scene, 20 s, best of a
  few runs) without objects, with the shipped three objects, and with them and the
  camera at 10 Hz: the price of objects in lock-step runs;
- ``camera_capture``: one capture of the three objects with the arm in the scene
  (every line of sight against every occluder);
- ``world_model``: one perception frame of three objects into the world model.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

from manus.world import WorldModel
from manus_stack.bench.plan import _stats_ms, _timed
from schemas.objects import Perception
from services.simulator.camera_config import CameraConfig
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.rays import Primitive

IDLE_S = 20.0
"""Simulated time of each simulator run [s]."""


def _simulated(config: SimConfig, runs: int) -> dict[str, float]:
    best = float("inf")
    for _ in range(runs):
        core = SimCore(config)
        started = time.perf_counter()
        core.advance(round(IDLE_S * 1e9))
        best = min(best, time.perf_counter() - started)
    return {"wall_ms_per_simulated_s": round(best * 1e3 / IDLE_S, 3)}


def _capture(runs: int) -> dict[str, Any]:
    core = SimCore(SimConfig(start_pose="unfolded", objects="default"))
    camera = core.camera
    assert camera is not None
    state = core.state
    bodies, poses = core.objects.placed(0, core.model.q_true_deg(state), state.gripper_mm)
    arm = [Primitive(b.shape, b.size, b.pose) for b in bodies]
    objects = list(zip(core.objects.objects, poses, strict=True))
    stats = _stats_ms(_timed(lambda: camera.capture(0, objects, arm), runs))
    seen = [len(msg.objects) for _, msg in camera.due(10**15)]
    occluders = len(arm) + camera.fixed_occluders + len(objects)
    return {**stats, "objects_seen": max(seen), "occluders": occluders}


def _world(runs: int) -> dict[str, Any]:
    core = SimCore(SimConfig(objects="default", camera=replace(CameraConfig(), dropout=0.0)))
    core.advance(1_000_000_000)
    frames = [m for _, _, m in core.take_messages() if isinstance(m, Perception)]
    frame = frames[-1]
    world = WorldModel()
    k = [0]

    def observe() -> None:
        k[0] += 1
        world.observe(replace(frame, stamp_ns=frame.stamp_ns + k[0] * 100_000_000))

    return {**_stats_ms(_timed(observe, runs)), "objects": len(frame.objects)}


def run(quick: bool = False) -> dict[str, Any]:
    """Figures of the simulator with objects, the camera and the world model."""
    runs = 2 if quick else 5
    off = replace(CameraConfig(), enabled=False)
    return {
        "simulator_idle_20s": {
            "no_objects": _simulated(SimConfig(objects="none", camera=off), runs),
            "three_objects": _simulated(SimConfig(objects="default", camera=off), runs),
            "three_objects_camera_10hz": _simulated(SimConfig(objects="default"), runs),
        },
        "camera_capture": _capture(200 if quick else 2000),
        "world_model_frame": _world(500 if quick else 5000),
    }
