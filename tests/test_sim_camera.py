"""The simulated camera: noise, dropouts, latency and occlusion, all seeded, and its
lines of sight checked exactly."""

from __future__ import annotations

import math
from dataclasses import replace

import coal
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from manus.config import ArmConfig
from manus.errors import ConfigError
from manus.scene import Primitive as ScenePrimitive
from manus.scene import default_scene, pose_matrix
from manus.shapes import coal_shape
from schemas.objects import Perception
from services.simulator.arm_bodies import ArmBodies
from services.simulator.camera import Camera
from services.simulator.camera_config import CameraConfig
from services.simulator.config import SimConfig
from services.simulator.core import SimCore
from services.simulator.objects import SimObject
from services.simulator.rays import Occluders, Primitive

QUIET = CameraConfig(dropout=0.0, frame_dropout=0.0, latency_jitter_ms=0.0)
"""The default camera without dropouts and jitter."""


def frames(camera: CameraConfig, seconds: float, seed: int = 0) -> list[tuple[int, Perception]]:
    """(publication time, frame) of a simulator with the shipped objects."""
    core = SimCore(SimConfig(objects="default", camera=camera, seed=seed))
    core.advance(round(seconds * 1e9))
    out = []
    for at, _, msg in core.take_messages():
        assert isinstance(msg, Perception)
        out.append((at, msg))
    return out


def truth_of(seconds: float = 0.0) -> dict[str, np.ndarray]:
    core = SimCore(SimConfig(objects="default", camera=replace(QUIET, enabled=False)))
    core.advance(round(seconds * 1e9))
    return {o.id: np.array([*o.xyz, *o.ypr]) for o in core.truth().objects}


def test_the_noise_has_the_configured_spread_and_no_bias() -> None:
    truth = truth_of()
    errors: dict[str, list[np.ndarray]] = {name: [] for name in truth}
    for _, msg in frames(QUIET, 40.0):
        assert {o.id for o in msg.objects} == set(truth)  # all seen: nothing in the way
        for o in msg.objects:
            error = np.array([*o.xyz, *o.ypr]) - truth[o.id]
            error[3:] = [math.remainder(v, math.tau) for v in error[3:]]
            errors[o.id].append(error)
    sigma = np.repeat([QUIET.noise_mm * 1e-3, math.radians(QUIET.noise_deg)], 3)
    for name, rows in errors.items():
        e = np.array(rows)
        n = len(e)
        assert n >= 395, name
        assert np.all(np.abs(e.mean(axis=0)) < 4.0 * sigma / math.sqrt(n)), name
        assert np.all(np.abs(e.std(axis=0) / sigma - 1.0) < 0.15), (name, e.std(axis=0) / sigma)


def test_dropouts_happen_at_the_configured_rates_and_are_seeded() -> None:
    camera = replace(QUIET, dropout=0.2, frame_dropout=0.1)
    got = frames(camera, 40.0, seed=3)
    captured = 400
    lost = captured - len(got)
    assert abs(lost - 0.1 * captured) < 4 * math.sqrt(captured * 0.1 * 0.9)
    seqs = [msg.seq for _, msg in got]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)  # lost frames leave gaps
    seen = sum(len(msg.objects) for _, msg in got)
    trials = 3 * len(got)
    assert abs(seen - 0.8 * trials) < 4 * math.sqrt(trials * 0.2 * 0.8)
    assert frames(camera, 40.0, seed=3) == got  # the same seed: the same frames
    assert frames(camera, 40.0, seed=4) != got


def test_frames_go_out_after_the_latency_in_order() -> None:
    camera = replace(QUIET, latency_ms=80.0, latency_jitter_ms=30.0, period_ms=50.0)
    got = frames(camera, 5.0)
    assert [msg.stamp_ns for _, msg in got] == [50_000_000 * (k + 1) for k in range(len(got))]
    delays = [(at - msg.stamp_ns) / 1e6 for at, msg in got]
    assert all(80.0 <= d <= 110.0 + 1e-6 for d in delays)
    assert max(delays) - min(delays) > 10.0  # the jitter is there
    times = [at for at, _ in got]
    assert times == sorted(times)


def test_a_removed_object_is_reported_gone_once() -> None:
    core = SimCore(SimConfig(objects="default", camera=QUIET))
    core.advance(1_000_000_000)
    core.take_messages()
    core.objects.remove("bottle")
    core.advance(2_000_000_000)
    got = [msg for _, _, msg in core.take_messages() if isinstance(msg, Perception)]
    assert [m.removed for m in got if m.removed] == [["bottle"]]
    after = [m for m in got if m.stamp_ns > 1_000_000_000]  # captured once it was gone
    assert after and all("bottle" not in {o.id for o in m.objects} for m in after)
    assert next(m for m in got if m.removed) is after[0]


def cup_at(xyz: tuple[float, float, float], name: str = "cup") -> SimObject:
    return SimObject(name, "cup", "cylinder", (0.035, 0.12), pose_matrix(xyz, (0, 0, 0)))


def look_at(eye: tuple[float, float, float], target: tuple[float, float, float]) -> CameraConfig:
    """A quiet camera at ``eye`` [m] looking at ``target`` [m]."""
    d = np.subtract(target, eye)
    pitch = math.degrees(math.atan2(-d[2], math.hypot(d[0], d[1])))
    yaw = math.degrees(math.atan2(d[1], d[0]))
    x, y, z = (v * 1e3 for v in eye)
    return replace(QUIET, xyz_mm=(x, y, z), rpy_deg=(0.0, pitch, yaw))


def seen(
    camera: CameraConfig, objects: list[SimObject], occluders: tuple[Primitive, ...] = ()
) -> set[str]:
    """What ``camera`` reports of ``objects`` (at their poses) with the scene and the
    ``occluders`` in the way."""
    cam = Camera(camera, np.random.default_rng(0), default_scene())
    cam.capture(0, [(o, o.pose) for o in objects], list(occluders))
    ((_, msg),) = cam.due(10**12)
    return {o.id for o in msg.objects}


CUP = (0.95, 0.0, 0.80)


def test_the_person_hides_what_is_behind_them() -> None:
    cup = cup_at(CUP)
    assert seen(look_at((-0.30, 0.0, 1.30), CUP), [cup]) == set()  # the head is in the way
    assert seen(look_at((-0.30, -0.45, 1.30), CUP), [cup]) == {"cup"}  # beside it


def test_the_arm_hides_what_is_behind_it() -> None:
    q = np.radians((0.0, 30.0, -30.0, 0.0, -60.0, 0.0))
    bodies, _ = ArmBodies(ArmConfig(), default_scene().mount).place(q, 0.09)
    forearm = next(b for b in bodies if b.name == "forearm").pose[:3, 3]
    below = (float(forearm[0]), float(forearm[1]), float(forearm[2]) - 0.4)
    above = (float(forearm[0]), float(forearm[1]), float(forearm[2]) + 0.5)
    camera = replace(look_at(above, below), rpy_deg=(0.0, 90.0, 0.0))
    cup = cup_at(below)
    arm = tuple(Primitive(b.shape, b.size, b.pose) for b in bodies)
    assert seen(camera, [cup], arm) == set()
    assert seen(camera, [cup]) == {"cup"}


def test_objects_hide_each_other_and_nothing_outside_the_view_is_seen() -> None:
    camera = look_at((0.10, -0.25, 1.45), CUP)
    eye = np.array([0.10, -0.25, 1.45])
    middle = eye + 0.7 * (np.array(CUP) - eye)
    box = SimObject("box", "cereal", "box", (0.2, 0.2, 0.2), pose_matrix(list(middle), (0, 0, 0)))
    assert seen(camera, [cup_at(CUP), box]) == {"box"}
    assert seen(camera, [cup_at(CUP)]) == {"cup"}
    assert seen(camera, [cup_at((-0.5, -0.6, 0.9))]) == set()  # behind the camera
    assert seen(replace(camera, range_m=(0.2, 1.0)), [cup_at(CUP)]) == set()  # too far


PRIMITIVES = {
    "box": st.tuples(*[st.floats(0.02, 0.5)] * 3),
    "sphere": st.tuples(st.floats(0.02, 0.3)),
    "cylinder": st.tuples(st.floats(0.02, 0.3), st.floats(0.02, 0.6)),
    "capsule": st.tuples(st.floats(0.02, 0.3), st.floats(0.02, 0.6)),
}
POINT = st.tuples(*[st.floats(-0.8, 0.8)] * 3)


@st.composite
def occluder(draw: st.DrawFn) -> Primitive:
    shape = draw(st.sampled_from(sorted(PRIMITIVES)))
    rpy = [draw(st.floats(-math.pi, math.pi)) for _ in range(3)]
    return Primitive(shape, draw(PRIMITIVES[shape]), pose_matrix(list(draw(POINT)), rpy))


@given(occluder(), POINT, st.lists(POINT, min_size=1, max_size=8))
@settings(max_examples=300)
def test_lines_of_sight_agree_with_coal(
    primitive: Primitive, eye: tuple[float, ...], ends: list[tuple[float, ...]]
) -> None:
    start, points = np.array(eye), np.array(ends)
    hit = Occluders([primitive]).blocked(start, points)[0]
    geometry, pose = coal_shape(ScenePrimitive(primitive.shape, primitive.size, primitive.pose))
    for end, blocked in zip(points, hit, strict=True):
        length = float(np.linalg.norm(end - start))
        if length < 1e-6:
            continue
        z = (end - start) / length
        x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z])
        segment = coal.Capsule(1e-9, length)
        d = coal.distance(
            segment,
            coal.Transform3s(R, (start + end) / 2.0),
            geometry,
            coal.Transform3s(pose[:3, :3], pose[:3, 3]),
            coal.DistanceRequest(),
            coal.DistanceResult(),
        )
        if abs(d) > 1e-6:
            assert bool(blocked) == (d < 0.0), (primitive, start, end, d)


def test_camera_settings_are_checked_and_come_from_the_simulator_file() -> None:
    config = SimConfig.from_mapping(
        {"camera": {"period_ms": 50, "noise_mm": 1.5}, "objects": "default"}, source="sim.json"
    )
    assert (config.camera.period_ms, config.camera.noise_mm) == (50, 1.5)
    with pytest.raises(ConfigError, match=r"sim.json: camera: unknown camera setting `noise`"):
        SimConfig.from_mapping({"camera": {"noise": 1}}, source="sim.json")
    with pytest.raises(ConfigError, match=r"camera: `fov_deg` must be in \[1, 179\], got 200"):
        CameraConfig(fov_deg=(200.0, 40.0))
    with pytest.raises(ConfigError, match=r"camera: `dropout` must be in \[0, 1\], got 1.5"):
        CameraConfig(dropout=1.5)
