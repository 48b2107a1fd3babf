"""The Foxglove viewer: the converter core alone, then live over loopback with a real
Foxglove WebSocket client (tests/foxglove_client.py)."""

from __future__ import annotations

import asyncio
import base64
import dataclasses
import json
import math
import struct
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import websockets
import zenoh
from foxglove.messages import FrameTransforms, Log, PosesInFrame, SceneUpdate
from google.protobuf.timestamp_pb2 import Timestamp
from hypothesis import given
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader

from manus.config import DEFAULT_ARM
from manus.kinematics import fk, joint_frames
from manus.node import Node
from manus.orientation import rot_z, ypr_to_matrix
from manus.scene import Scene, default_scene, default_scene_path, parse_scene
from manus.session import ZenohSettings
from manus.urdf import GRIPPER_FRAME, build_urdf
from schemas.collision import SceneState
from schemas.control import TrajectoryGoal
from schemas.objects import WorldObject, WorldUpdate
from schemas.state import JointState
from services.recorder.reading import Recording, decode
from services.viewer.config import ViewerConfig
from services.viewer.core import GOAL_REQUEST, FoxMessage, ViewerCore
from services.viewer.layout import LAYOUT_FILE, layout_json
from services.viewer.model import (
    LINK_NAMES,
    ROOT_FRAME,
    build_visual_urdf,
    link_transforms,
    quaternion,
)
from services.viewer.server import URDF_URI
from services.viewer.shell import ViewerShell
from tests.conftest import eventually, matched_publisher
from tests.foxglove_client import SUBPROTOCOL, Received, collect, protobuf_decoder

DATA = Path(__file__).parent / "data"
SQUARE = DATA / "thesis_square.mcap"
angles = st.floats(-math.pi, math.pi, allow_nan=False)


def _matrix(translation: Any, rotation: Any) -> np.ndarray:
    """4x4 of a translation (x, y, z) and quaternion (x, y, z, w)."""
    x, y, z, w = rotation
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = translation
    return T


def _ns(text: str) -> int:
    """Nanoseconds of a protobuf Timestamp in its JSON form."""
    ts = Timestamp()
    ts.FromJsonString(text)
    return int(ts.ToNanoseconds())


def _world(transforms: list[tuple[str, str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Every frame's pose in the root frame, composing parent -> child transforms."""
    world = {ROOT_FRAME: np.eye(4)}
    pending = list(transforms)
    while pending:
        parent, child, T = pending.pop(0)
        if parent in world:
            world[child] = world[parent] @ T
        else:
            pending.append((parent, child, T))
    return world


def _world_of(decoded: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """:func:`_world` of the transforms of a decoded ``foxglove.FrameTransforms``."""
    return _world(
        [
            (
                t["parent_frame_id"],
                t["child_frame_id"],
                _matrix([t["translation"][k] for k in "xyz"], [t["rotation"][k] for k in "xyzw"]),
            )
            for t in decoded
        ]
    )


def _check_links(world: dict[str, np.ndarray], q: list[float]) -> None:
    frames = joint_frames(np.asarray(q), DEFAULT_ARM)
    for i, link in enumerate(LINK_NAMES):  # link i+1 = T_0^i Rz(q_(i+1))
        expected = frames[i].copy()
        expected[:3, :3] = expected[:3, :3] @ rot_z(q[i])
        np.testing.assert_allclose(world[link], expected, atol=1e-9, err_msg=link)
    np.testing.assert_allclose(world[GRIPPER_FRAME], fk(q, DEFAULT_ARM), atol=1e-9)


def _entities_by_id(update: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {e["id"]: e for e in update["entities"]}


def _pose_of(prim: dict[str, Any]) -> np.ndarray:
    p, o = prim["pose"]["position"], prim["pose"]["orientation"]
    return _matrix([p[k] for k in "xyz"], [o[k] for k in "xyzw"])


def _versions(update: dict[str, Any]) -> set[str]:
    """The scene versions in a decoded ``viz/scene`` update's metadata."""
    return {kv["value"] for e in update["entities"] for kv in e["metadata"]
            if kv["key"] == "scene_version"}  # fmt: skip


def _check_scene(update: dict[str, Any], scene: Scene) -> None:
    """A decoded ``viz/scene`` update draws every object and zone of ``scene`` where the
    collision model puts it (mount^-1 pose, in base_link), with its size and version."""
    assert update["deletions"][0]["type"] == "ALL"  # what was drawn before goes
    ents = _entities_by_id(update)
    assert set(ents) == {f"object/{o.name}" for o in scene.objects} | {
        f"zone/{z.name}" for z in scene.zones
    }
    for ent in ents.values():
        assert ent["frame_id"] == ROOT_FRAME and ent["frame_locked"] is True
        meta = {kv["key"]: kv["value"] for kv in ent["metadata"]}
        assert meta["scene_version"] == str(scene.version), ent["id"]
    inv = np.linalg.inv(scene.mount)
    for body, entity, cls in [(o.body, f"object/{o.name}", o.cls) for o in scene.objects] + [
        (z.body, f"zone/{z.name}", z.kind) for z in scene.zones
    ]:
        ent = ents[entity]
        meta = {kv["key"]: kv["value"] for kv in ent["metadata"]}
        assert cls in (meta.get("class"), meta.get("kind")) and meta["shape"] == body.shape
        T = inv @ body.pose
        s = body.size
        if body.shape == "box":
            (cube,) = ent["cubes"]
            np.testing.assert_allclose(_pose_of(cube), T, atol=1e-9, err_msg=entity)
            np.testing.assert_allclose([cube["size"][k] for k in "xyz"], s, atol=1e-12)
        elif body.shape == "sphere":
            (sphere,) = ent["spheres"]
            np.testing.assert_allclose(_pose_of(sphere), T, atol=1e-9, err_msg=entity)
            assert [sphere["size"][k] for k in "xyz"] == pytest.approx([2 * s[0]] * 3)
        elif body.shape in ("cylinder", "capsule"):
            (cyl,) = ent["cylinders"]
            np.testing.assert_allclose(_pose_of(cyl), T, atol=1e-9, err_msg=entity)
            size = [cyl["size"][k] for k in "xyz"]
            assert size == pytest.approx([2 * s[0], 2 * s[0], s[1]])
            ends = sorted(tuple(_pose_of(sp)[:3, 3]) for sp in ent["spheres"])
            want = [] if body.shape == "cylinder" else [
                tuple(T[:3, 3] + k * T[:3, 2] * s[1] / 2) for k in (-1, 1)
            ]  # fmt: skip
            np.testing.assert_allclose(ends, sorted(want), atol=1e-9, err_msg=entity)
        else:  # a plane: a thin square through its point, z along the normal
            (cube,) = ent["cubes"]
            P = _pose_of(cube)
            np.testing.assert_allclose(P[:3, 3], (inv @ body.pose)[:3, 3], atol=1e-9)
            np.testing.assert_allclose(P[:3, 2], inv[:3, :3] @ np.asarray(s), atol=1e-9)
            assert cube["size"]["z"] < 0.01 < cube["size"]["x"]
        colours = {json.dumps(p["color"], sort_keys=True) for k in ("cubes", "spheres",
                   "cylinders") for p in ent[k]}  # fmt: skip
        alpha = json.loads(colours.pop())["a"]
        assert not colours  # one colour per entity
        faint = entity.startswith("zone/") or body.shape == "plane"  # the arm shows through
        assert alpha < 0.5 if faint else alpha > 0.5


def test_scene_entities_sit_where_the_default_scene_puts_them() -> None:
    core = ViewerCore()  # scene setting "": the shipped wheelchair scene
    msg = core.scene_update(42)
    assert (msg.topic, msg.schema.name) == ("manus/viz/scene", SceneUpdate.get_schema().name)
    update = protobuf_decoder(_advert(msg))(msg.data)
    _check_scene(update, default_scene())
    ents = _entities_by_id(update)
    # the file's own numbers: the head (radius 110 mm at (-20, 0, 1230) mm) seen from the
    # shoulder mounted at (350, -420, 1000) mm: 370 mm behind, 420 mm left, 230 mm up
    (head,) = ents["object/head"]["spheres"]
    assert [head["pose"]["position"][k] for k in "xyz"] == pytest.approx([-0.37, 0.42, 0.23])
    assert head["size"]["x"] == pytest.approx(0.22)
    (wheel,) = ents["zone/right_wheel"]["cubes"]
    assert [wheel["pose"]["position"][k] for k in "xyz"] == pytest.approx([-0.425, -0.02, -0.675])
    assert [wheel["size"][k] for k in "xyz"] == pytest.approx([0.65, 0.22, 0.55])
    assert ents["object/head"]["cubes"] == [] and len(ents["object/forearm_right"]["spheres"]) == 2
    assert [d.topic for d in core.describe(5)] == [
        "manus/viz/robot_description",
        "manus/viz/scene",
        "manus/viz/objects",
    ]
    assert ViewerCore(ViewerConfig(scene="none")).scene_update(1).data != msg.data


def test_a_scene_state_replaces_every_entity_and_garbage_is_counted() -> None:
    core = ViewerCore()
    text = default_scene_path().read_text().replace("[1100, 0, 720]", "[1000, 100, 700]")
    state = SceneState(version=3, text=text, source="moved table")
    outs = core.on_sample("manus/planner/scene_state", state.encode(), 77)
    by_topic = {o.topic: o for o in outs}
    update = protobuf_decoder(_advert(by_topic["manus/viz/scene"]))(
        by_topic["manus/viz/scene"].data
    )
    moved = parse_scene(text, "moved table")
    _check_scene(update, Scene(moved.mount, moved.objects, moved.zones, version=3))
    (table,) = _entities_by_id(update)["object/table"]["cubes"]
    assert [table["pose"]["position"][k] for k in "xyz"] == pytest.approx([0.65, 0.52, -0.3])
    log = protobuf_decoder(_advert(by_topic["manus/viz/log"]))(by_topic["manus/viz/log"].data)
    assert "scene version 3" in log["message"]
    assert core.scene is not None and core.scene.version == 3
    bad = SceneState(version=4, text="objects: [", source="bad").encode()
    outs = core.on_sample("manus/planner/scene_state", bad, 78)
    assert [o.topic for o in outs] == ["manus/viz/log"]  # a warning; the scene stays
    assert core.stats.bad_payloads == {"planner/scene_state": 1} and core.scene.version == 3


def test_objects_are_drawn_free_where_seen_and_held_in_the_gripper_frame() -> None:
    """``planner/objects``: a free cup in base_link where perception saw it, a held
    bottle in gripper_frame (frame-locked: it moves with the gripper), every update
    drawing the whole set again; a diff it cannot apply draws nothing."""
    core = ViewerCore()
    cup = WorldObject("cup", "cup", "cylinder", [0.04, 0.1], [0.9, -0.3, 0.79], [0.0, 0.0, 0.0],
                      0.9, 10, "camera")  # fmt: skip
    bottle = WorldObject("bottle", "bottle", "cylinder", [0.035, 0.25], [0.0, 0.01, 0.0],
                         [0.0, 0.0, 1.5], 0.8, 20, "arm", link="gripper_frame",
                         touch_links=["gripper"])  # fmt: skip
    whole = WorldUpdate(stamp_ns=20, version=3, base_version=-1, objects=[cup, bottle])
    (msg,) = [o for o in core.on_sample("manus/planner/objects", whole.encode(), 5)
              if o.topic == "manus/viz/objects"]  # fmt: skip
    update = protobuf_decoder(_advert(msg))(msg.data)
    assert update["deletions"][0]["type"] == "ALL"
    ents = _entities_by_id(update)
    assert set(ents) == {"world/cup", "world/bottle"}
    free, held = ents["world/cup"], ents["world/bottle"]
    assert free["frame_id"] == ROOT_FRAME and held["frame_id"] == "gripper_frame"
    assert held["frame_locked"] is True
    meta = {kv["key"]: kv["value"] for kv in held["metadata"]}
    assert (meta["state"], meta["link"], meta["touch_links"]) == (
        "held",
        "gripper_frame",
        "gripper",
    )
    (cyl,) = free["cylinders"]
    want = np.linalg.inv(default_scene().mount) @ _matrix([0.9, -0.3, 0.79], [0, 0, 0, 1])
    np.testing.assert_allclose(_pose_of(cyl), want, atol=1e-9)
    (cyl,) = held["cylinders"]
    assert [cyl["pose"]["position"][k] for k in "xyz"] == pytest.approx([0.0, 0.01, 0.0])
    assert [cyl["size"][k] for k in "xyz"] == pytest.approx([0.07, 0.07, 0.25])
    # Released: a diff; then one from another version (missed): nothing drawn.
    released = dataclasses.replace(bottle, link="", xyz=[0.8, -0.2, 0.86], touch_links=[])
    diff = WorldUpdate(stamp_ns=30, version=4, base_version=3, objects=[released])
    outs = core.on_sample("manus/planner/objects", diff.encode(), 6)
    update = protobuf_decoder(_advert(outs[-1]))(outs[-1].data)
    assert {e["frame_id"] for e in update["entities"]} == {ROOT_FRAME}
    stray = WorldUpdate(stamp_ns=40, version=9, base_version=8, objects=[])
    assert [o.topic for o in core.on_sample("manus/planner/objects", stray.encode(), 7)] == [
        "manus/planner/objects"
    ]  # forwarded as JSON, not drawn


# -- the model -----------------------------------------------------------------------------


@given(st.lists(angles, min_size=6, max_size=6), st.floats(0.0, 0.09))
def test_link_transforms_compose_to_the_forward_kinematics(q: list[float], gripper: float) -> None:
    tfs = link_transforms(q, gripper, DEFAULT_ARM)
    world = _world([(t.parent, t.child, _matrix(t.translation, t.rotation)) for t in tfs])
    _check_links(world, q)
    # the fingers open symmetrically by the gripper opening (plus their own width)
    left, right = world["finger_left"][:3, 3], world["finger_right"][:3, 3]
    gap = float(np.linalg.norm(left - right))
    assert gap == pytest.approx(gripper + 0.012, abs=1e-9)


@given(angles, angles, angles)
def test_quaternion_of_a_rotation_gives_it_back(yaw: float, pitch: float, roll: float) -> None:
    R = ypr_to_matrix(yaw, pitch, roll)
    q = quaternion(R)
    assert sum(c * c for c in q) == pytest.approx(1.0)
    np.testing.assert_allclose(_matrix((0, 0, 0), q)[:3, :3], R, atol=1e-12)


def test_viewer_config_refuses_nonsense() -> None:
    with pytest.raises(ValueError, match="path_points 1"):
        ViewerConfig(path_points=1)
    with pytest.raises(ValueError, match="preview_dt_s 0"):
        ViewerConfig(preview_dt_s=0)


def _joints(urdf: str) -> dict[str, dict[str, Any]]:
    root = ET.fromstring(urdf)
    out = {}
    for j in root.iter("joint"):
        origin, axis = j.find("origin"), j.find("axis")
        out[j.attrib["name"]] = {
            "type": j.attrib["type"],
            "parent": j.find("parent").attrib["link"],  # type: ignore[union-attr]
            "child": j.find("child").attrib["link"],  # type: ignore[union-attr]
            "origin": dict(origin.attrib) if origin is not None else None,
            "axis": dict(axis.attrib) if axis is not None else None,
        }
    return out


def test_visual_urdf_has_the_joints_of_the_stack_urdf_and_geometry() -> None:
    ours, stack = _joints(build_visual_urdf(DEFAULT_ARM)), _joints(build_urdf())
    for name, joint in stack.items():
        assert ours[name] == joint, name
    assert {"finger_left", "finger_right"} <= set(ours)
    root = ET.fromstring(build_visual_urdf(DEFAULT_ARM))
    assert all(link.find("visual") is not None for link in root.iter("link"))
    assert not any("filename" in el.attrib for el in root.iter())  # no mesh to fetch


def test_shipped_layout_is_current() -> None:
    assert LAYOUT_FILE.read_text() == layout_json(), "regenerate: manus view --layout FILE"
    text = LAYOUT_FILE.read_text()
    for topic in ("manus/viz/robot_description", "manus/viz/log", "manus/controller/feedback"):
        assert topic in text
    three_d = json.loads(text)["content"]["items"][0]["content"]
    assert three_d["panelType"] == "ThreeDee"
    assert three_d["config"]["topics"]["manus/viz/scene"] == {"visible": True}


# -- the core on a recording ---------------------------------------------------------------


def _run_core(path: Path) -> tuple[ViewerCore, list[tuple[Any, list[FoxMessage]]]]:
    rec = Recording(path)
    core = ViewerCore(ViewerConfig(prefix=rec.info.prefix))
    return core, [(m, core.on_sample(m.key, m.payload, m.log_ns)) for m in rec.messages()]


def _advert(msg: FoxMessage) -> dict[str, Any]:
    return {"schemaName": msg.schema.name, "schema": base64.b64encode(msg.schema.data).decode()}


def test_core_turns_a_recording_into_links_paths_and_logs() -> None:
    core, runs = _run_core(SQUARE)
    tf_checked = planned = 0
    for rec, outs in runs:
        by_topic = {o.topic: o for o in outs}
        for o in outs:
            assert o.log_ns == rec.log_ns
        if rec.suffix == "state/joints":
            js = decode(rec)
            assert isinstance(js, JointState)
            assert ("manus/state/joints" in by_topic) is True  # forwarded as JSON
            if not js.valid:
                assert "manus/viz/tf" not in by_topic
                continue
            tf = by_topic["manus/viz/tf"]
            assert tf.schema.name == "foxglove.FrameTransforms" == FrameTransforms.get_schema().name
            msg = protobuf_decoder(_advert(tf))(tf.data)
            ts = msg["transforms"]
            assert {_ns(t["timestamp"]) for t in ts} == {js.stamp_ns}
            _check_links(_world_of(ts), js.position)
            tf_checked += 1
        if rec.suffix == GOAL_REQUEST:
            goal = decode(rec)
            assert isinstance(goal, TrajectoryGoal)
            upd = by_topic["manus/viz/planned"]
            assert upd.schema.name == SceneUpdate.get_schema().name
            ent = protobuf_decoder(_advert(upd))(upd.data)["entities"][0]
            points = [[p[k] for k in "xyz"] for p in ent["lines"][0]["points"]]
            np.testing.assert_allclose(points, goal.trajectory.preview_xyz)
            assert len(ent["spheres"]) == len(goal.trajectory.times)
            poses = by_topic["manus/viz/via_poses"]
            assert poses.schema.name == PosesInFrame.get_schema().name
            planned += 1
    assert tf_checked > 300 and planned == 1
    logs = [o for _, outs in runs for o in outs if o.topic == "manus/viz/log"]
    assert logs and all(o.schema.name == Log.get_schema().name for o in logs)
    texts = [protobuf_decoder(_advert(o))(o.data)["message"] for o in logs]
    assert any("succeeded" in t for t in texts), texts
    assert core.stats.bad_payloads == {}


def test_core_is_deterministic_and_counts_garbage() -> None:
    _, a = _run_core(SQUARE)
    _, b = _run_core(SQUARE)
    assert [o for _, outs in a for o in outs] == [o for _, outs in b for o in outs]
    core = ViewerCore()
    assert core.on_sample("manus/state/joints", b"\xc1garbage", 5) == []
    assert core.on_sample("manus/controller/feedback", b"\x93\x01\x02\x03", 6) == []
    assert core.on_sample("manus/can/rx", b"whatever", 7) == []
    assert core.stats.bad_payloads == {"state/joints": 1, "controller/feedback": 1}
    assert core.stats.ignored == 1
    desc = core.robot_description(9)
    assert json.loads(desc.data)["data"] == build_visual_urdf(DEFAULT_ARM)


def test_json_export_holds_the_viewer_channels_so_the_arm_moves(tmp_path: Path) -> None:
    from manus_stack.cli import main

    out = tmp_path / "square.json.mcap"
    assert main(["export", str(SQUARE), "--json", "-o", str(out)]) == 0
    with out.open("rb") as f:  # every CRC checks out
        assert list(StreamReader(f, validate_crcs=True).records)
    info = Recording(out).info
    tf = info.channels["manus/viz/tf"]
    assert (tf.schema_name, tf.message_encoding) == ("foxglove.FrameTransforms", "protobuf")
    assert info.channels["manus/viz/robot_description"].messages == 1
    assert info.channels["manus/viz/planned"].schema_name == "foxglove.SceneUpdate"
    assert info.channels["manus/state/joints"].message_encoding == "json"  # recorded, once
    assert info.channels["manus/viz/scene"].messages == 1  # the scene in use; no update
    with out.open("rb") as f:
        schema, _, msg = next(iter(make_reader(f).iter_messages(topics=["manus/viz/scene"])))
    assert schema is not None
    advert = {"schemaName": schema.name, "schema": base64.b64encode(schema.data).decode()}
    _check_scene(protobuf_decoder(advert)(msg.data), default_scene())
    valid = [
        js
        for _, js in Recording(SQUARE).decoded(["state/joints"])
        if isinstance(js, JointState) and js.valid
    ]
    assert tf.messages == len(valid)
    with out.open("rb") as f:
        reader = make_reader(f)
        schema, _, first = next(iter(reader.iter_messages(topics=["manus/viz/tf"])))
    assert schema is not None
    advert = {"schemaName": schema.name, "schema": base64.b64encode(schema.data).decode()}
    ts = protobuf_decoder(advert)(first.data)["transforms"]
    world = _world_of(ts)
    _check_links(world, valid[0].position)
    plain = tmp_path / "plain.json.mcap"
    assert main(["export", str(SQUARE), "--json", "--no-view", "-o", str(plain)]) == 0
    assert not any("/viz/" in k for k in Recording(plain).info.channels)


def test_replay_view_serves_a_recording_with_the_arm_moving() -> None:
    import threading

    from manus_stack.view_replay import ViewReplay

    rec = Recording(SQUARE)
    start_ns = rec.info.start_ns + 5 * 10**9  # --start 5
    later = [
        (m, js)
        for m, js in rec.decoded(["state/joints"])
        if isinstance(js, JointState) and js.valid and m.log_ns >= start_ns
    ]
    tf_topic, desc = "manus/viz/tf", "manus/viz/robot_description"
    stop = threading.Event()
    with ViewReplay(str(SQUARE), port=0) as replay:

        def play() -> None:
            if replay.wait_for_client(stop, timeout=20):
                replay.play(rate=None, start_s=5.0, stop=stop)

        player = threading.Thread(target=play)
        player.start()
        try:
            got = asyncio.run(
                collect(
                    f"ws://127.0.0.1:{replay.port}",
                    [tf_topic, desc, "manus/viz/scene"],
                    until=lambda r: len(r.messages.get(tf_topic, [])) >= len(later),
                    timeout=20,
                )
            )
        finally:
            stop.set()
            player.join()
    assert got.messages[desc]
    _check_scene(got.messages["manus/viz/scene"][0][1], default_scene())
    tfs = got.messages[tf_topic]
    assert [t for t, _ in tfs] == [m.log_ns for m, _ in later]  # the recorded log times
    last = tfs[-1][1]["transforms"]
    world = _world_of(last)
    _check_links(world, later[-1][1].position)


# -- live, over loopback -------------------------------------------------------------------


def _publish_recording(session: zenoh.Session, prefix: str, path: Path, suffixes: set[str]) -> int:
    """Put the recorded payloads of ``suffixes`` on the bus under ``prefix``, in order."""
    pubs: dict[str, zenoh.Publisher] = {}
    n = 0
    for rec in Recording(path).messages():
        if rec.suffix not in suffixes:
            continue
        pub = pubs.get(rec.suffix)
        if pub is None:
            pub = pubs[rec.suffix] = session.declare_publisher(
                f"{prefix}/{rec.suffix}", congestion_control=zenoh.CongestionControl.BLOCK
            )
        pub.put(rec.payload)
        n += 1
    for pub in pubs.values():
        pub.undeclare()
    return n


@pytest.mark.slow
def test_live_viewer_serves_the_arm_to_a_foxglove_client(zenoh_settings: ZenohSettings) -> None:
    prefix = zenoh_settings.prefix
    tf_topic, planned_topic = f"{prefix}/viz/tf", f"{prefix}/viz/planned"
    joints_topic, scene_topic = f"{prefix}/state/joints", f"{prefix}/viz/scene"
    moved_text = default_scene_path().read_text().replace("[1100, 0, 720]", "[1000, 100, 700]")
    published: list[str] = []
    with Node("watcher", zenoh_settings) as watcher, ViewerShell(zenoh_settings, port=0) as viewer:
        # every key seen on the bus, to show that the viewer never publishes
        watcher.subscribe_raw(f"{prefix}/**", lambda s, _t: published.append(str(s.key_expr)))
        url = f"ws://127.0.0.1:{viewer.port}"
        rec_joints = [
            m
            for m in Recording(SQUARE).decoded(["state/joints"])
            if m[1].valid  # type: ignore[attr-defined]
        ]

        def enough(r: Received) -> bool:
            return (
                len(r.messages.get(tf_topic, [])) >= len(rec_joints)
                and bool(r.messages.get(planned_topic))
                and 0 in r.assets
                and any(_versions(m) == {"1"} for _, m in r.messages.get(scene_topic, []))
            )

        async def scenario() -> Received:
            task = asyncio.create_task(
                collect(
                    url,
                    [
                        tf_topic,
                        planned_topic,
                        joints_topic,
                        scene_topic,
                        f"{prefix}/viz/robot_description",
                    ],
                    until=enough,
                    timeout=30,
                    assets=[URDF_URI, "package://nothing/here.urdf"],
                )
            )
            # a second client that subscribes to nonsense and sends garbage
            protocols = [websockets.Subprotocol(SUBPROTOCOL)]
            async with websockets.connect(url, subprotocols=protocols) as bad:
                await bad.send(json.dumps({"op": "subscribe", "subscriptions": [
                    {"id": 1, "channelId": 987654}]}))  # fmt: skip
                await bad.send(b"\xff\x00\x01garbage")
                await bad.send("{not json")
                await bad.send(json.dumps({"op": "advertise", "channels": [{"nonsense": 1}]}))
            await asyncio.to_thread(
                eventually, lambda: viewer.sink.client_events["subscribe"] >= 4, 10.0, "subscribed"
            )
            sent = await asyncio.to_thread(
                _publish_recording,
                watcher.session,
                prefix,
                SQUARE,
                {"state/joints", "state/status", "controller/result", GOAL_REQUEST},
            )
            assert sent > 600
            # the planner accepts a moved table: the view follows
            update = SceneState(version=1, text=moved_text, source="moved table")
            watcher.session.put(f"{prefix}/planner/scene_state", update.encode())
            return await task

        got = asyncio.run(scenario())
        stats = viewer.stats()
    # schemas are Foxglove's own
    assert got.channels[tf_topic]["schemaName"] == FrameTransforms.get_schema().name
    assert got.channels[tf_topic]["encoding"] == "protobuf"
    assert got.channels[planned_topic]["schemaName"] == SceneUpdate.get_schema().name
    assert got.channels[joints_topic]["schemaName"] == "manus/JointState/2"
    assert got.channels[joints_topic]["schemaEncoding"] == "jsonschema"
    # the links follow the forward kinematics of the recorded joint states, in order
    tfs = got.messages[tf_topic]
    assert len(tfs) == len(rec_joints)
    for (_, msg), (_, js) in zip(tfs, rec_joints, strict=True):
        _check_links(_world_of(msg["transforms"]), js.position)  # type: ignore[attr-defined]
    # the preview path arrived
    ent = got.messages[planned_topic][-1][1]["entities"][0]
    assert ent["id"] == "goal" and len(ent["lines"][0]["points"]) > 100
    # the scene: the shipped one first (sent on subscription), then the planner's update
    scenes = [m for _, m in got.messages[scene_topic]]
    assert got.channels[scene_topic]["schemaName"] == SceneUpdate.get_schema().name
    _check_scene(scenes[0], default_scene())
    moved = parse_scene(moved_text, "moved table")
    _check_scene(scenes[-1], Scene(moved.mount, moved.objects, moved.zones, version=1))
    # the URDF is served as an asset; an unknown asset is refused
    assert got.assets[0] == build_visual_urdf(DEFAULT_ARM).encode()
    assert isinstance(got.assets.get(1, "error"), str)
    # the bad client was answered or ignored and counted; nothing reached the bus
    assert isinstance(stats["client_problems"], int) and stats["client_problems"] >= 3, stats
    assert stats["dropped"] == 0 and stats["errors"] == 0
    assert all(not k.startswith(f"{prefix}/viz") for k in published)
    assert len(published) == stats["received"]


def test_viewer_drops_and_counts_when_its_queue_is_full(zenoh_settings: ZenohSettings) -> None:
    with ViewerShell(zenoh_settings, port=0, queue_size=1) as viewer:
        viewer._stop.set()  # the worker stops taking: every sample past the first is dropped
        viewer._thread.join()
        with Node("pub", zenoh_settings) as node:
            pub = matched_publisher(node.session, f"{zenoh_settings.prefix}/state/joints")
            for _ in range(50):
                pub.put(b"x")
            eventually(lambda: viewer.received == 50, 5.0, "50 samples received")
        assert viewer.dropped >= 48


def test_manus_view_writes_the_layout(tmp_path: Path) -> None:
    from manus_stack.cli import main

    out = tmp_path / "layout.json"
    assert main(["view", "--layout", str(out)]) == 0
    assert out.read_text() == layout_json()


def test_a_taken_port_is_a_clear_error() -> None:
    from services.viewer.server import FoxgloveSink, ViewerError

    first = FoxgloveSink(port=0)
    try:
        with pytest.raises(ViewerError, match=f"127.0.0.1:{first.port}: .*another manus view"):
            FoxgloveSink(port=first.port)
    finally:
        first.close()


def _playback_request(play: bool, speed: float, seek_ns: int | None, request_id: str) -> bytes:
    """The app's binary playback control request (opcode 3, little-endian)."""
    rid = request_id.encode()
    return (
        struct.pack("<BBfBQ", 3, 0 if play else 1, speed, seek_ns is not None, seek_ns or 0)
        + struct.pack("<I", len(rid))
        + rid
    )


def test_the_apps_playback_bar_pauses_seeks_and_speeds_up_a_view_replay() -> None:
    import threading

    from manus_stack.view_replay import ViewReplay

    stop = threading.Event()
    with ViewReplay(str(SQUARE), port=0) as replay:
        first = replay.first_ns
        player = threading.Thread(target=lambda: replay.play(rate=1.0, stop=stop))

        def paused() -> bool:
            return replay.playback is not None and replay.playback.state == "paused"

        async def scenario() -> tuple[dict[str, Any], list[int]]:
            protocols = [websockets.Subprotocol(SUBPROTOCOL)]
            url = f"ws://127.0.0.1:{replay.port}"
            tf_times: list[int] = []
            async with websockets.connect(url, subprotocols=protocols, max_size=None) as ws:
                info = json.loads(await ws.recv())
                advert = json.loads(await ws.recv())
                tf = next(c for c in advert["channels"] if c["topic"] == "manus/viz/tf")
                await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                    {"id": 1, "channelId": tf["id"]}]}))  # fmt: skip
                await asyncio.to_thread(eventually, lambda: replay.playback is not None, 10.0)
                await ws.send(_playback_request(False, 1.0, None, "pause-1"))
                await asyncio.to_thread(eventually, paused, 5.0, "paused")
                await ws.send(_playback_request(True, 4.0, first + 15 * 10**9, "seek-1"))
                loop = asyncio.get_running_loop()
                deadline = loop.time() + 10
                while loop.time() < deadline and len(tf_times) < 20:
                    frame = await asyncio.wait_for(ws.recv(), deadline - loop.time())
                    if isinstance(frame, bytes) and frame[0] == 1:
                        tf_times.append(struct.unpack_from("<IQ", frame, 1)[1])
            return info, tf_times

        player.start()
        try:
            info, tf_times = asyncio.run(scenario())
        finally:
            stop.set()
            player.join()
        p = replay.playback
    assert p is not None and replay.stats.app_requests >= 2
    assert p.rate == 4.0
    after = [t for t in tf_times if t >= first + 15 * 10**9]
    assert len(after) >= 10, [(t - first) / 1e9 for t in tf_times]  # played on from 15 s
    assert info["op"] == "serverInfo"
