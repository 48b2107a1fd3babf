"""Foxglove's own message types, built from plain numbers (``foxglove.messages``).

Every builder returns an SDK message; :func:`encoded` turns it into the bytes and schema
that go on a Foxglove channel (protobuf, with the SDK's schema of that type), so the
converter's outputs are plain values that any sink (the WebSocket server, an MCAP file)
writes the same way.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from typing import Any, NamedTuple, Protocol

from foxglove.messages import (
    Color,
    CubePrimitive,
    CylinderPrimitive,
    FrameTransform,
    FrameTransforms,
    KeyValuePair,
    LinePrimitive,
    LinePrimitiveLineType,
    Log,
    LogLevel,
    Point3,
    Pose,
    PosesInFrame,
    Quaternion,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    SpherePrimitive,
    TextPrimitive,
    Timestamp,
    Vector3,
)

from services.viewer.model import Transform, quaternion
from services.viewer.surroundings import Drawn

LEVELS = {"debug": LogLevel.Debug, "info": LogLevel.Info, "warning": LogLevel.Warning,
          "error": LogLevel.Error}  # fmt: skip
"""Log level names used by the converter -> Foxglove's levels."""


class SchemaInfo(NamedTuple):
    """A channel's schema as Foxglove receives it.

    Attributes:
        name: schema name (``foxglove.FrameTransforms``, ``manus/JointState/2``).
        encoding: schema encoding (``protobuf``, ``jsonschema``).
        data: the schema itself (a FileDescriptorSet, a JSON Schema).
    """

    name: str
    encoding: str
    data: bytes


class _SdkMessage(Protocol):
    @staticmethod
    def get_schema() -> Any: ...

    def encode(self) -> bytes: ...


_SCHEMAS: dict[type, SchemaInfo] = {}


def schema_of(msg_type: type[_SdkMessage]) -> SchemaInfo:
    """The SDK's schema of a Foxglove message type (protobuf)."""
    info = _SCHEMAS.get(msg_type)
    if info is None:
        s = msg_type.get_schema()
        info = _SCHEMAS[msg_type] = SchemaInfo(s.name, s.encoding, bytes(s.data))
    return info


def json_schema_info(name: str, schema: dict[str, Any]) -> SchemaInfo:
    """A JSON Schema as a channel schema."""
    return SchemaInfo(name, "jsonschema", json.dumps(schema, sort_keys=True).encode())


def encoded(msg: _SdkMessage) -> tuple[SchemaInfo, bytes]:
    """(schema, protobuf bytes) of an SDK message."""
    return schema_of(type(msg)), msg.encode()


def stamp(t_ns: int) -> Timestamp:
    """Foxglove timestamp of a time [ns] (negative times clip to 0)."""
    t_ns = max(t_ns, 0)
    return Timestamp(t_ns // 1_000_000_000, t_ns % 1_000_000_000)


def color(rgba: Sequence[float]) -> Color:
    r, g, b, a = rgba
    return Color(r=r, g=g, b=b, a=a)


def frame_transforms(transforms: Iterable[Transform], t_ns: int) -> FrameTransforms:
    """``foxglove.FrameTransforms`` of parent -> child transforms, all stamped ``t_ns``."""
    ts = stamp(t_ns)
    return FrameTransforms(
        transforms=[
            FrameTransform(
                timestamp=ts,
                parent_frame_id=tf.parent,
                child_frame_id=tf.child,
                translation=Vector3(x=tf.translation[0], y=tf.translation[1], z=tf.translation[2]),
                rotation=Quaternion(
                    x=tf.rotation[0], y=tf.rotation[1], z=tf.rotation[2], w=tf.rotation[3]
                ),
            )
            for tf in transforms
        ]
    )


def _pose(xyz: Sequence[float], quat: Sequence[float] = (0.0, 0.0, 0.0, 1.0)) -> Pose:
    return Pose(
        position=Vector3(x=xyz[0], y=xyz[1], z=xyz[2]),
        orientation=Quaternion(x=quat[0], y=quat[1], z=quat[2], w=quat[3]),
    )


def path_entity(
    entity_id: str,
    frame: str,
    t_ns: int,
    points: Sequence[Sequence[float]],
    rgba: Sequence[float],
    *,
    thickness: float = 0.004,
    markers: Sequence[Sequence[float]] = (),
    marker_size: float = 0.012,
    labels: Sequence[str] = (),
) -> SceneEntity:
    """A line strip through ``points`` [m] (and optional spheres with labels at
    ``markers``), in ``frame``."""
    lines = []
    if len(points) >= 2:
        lines.append(
            LinePrimitive(
                type=LinePrimitiveLineType.LineStrip,
                pose=_pose((0.0, 0.0, 0.0)),
                thickness=thickness,
                scale_invariant=False,
                points=[Point3(x=p[0], y=p[1], z=p[2]) for p in points],
                color=color(rgba),
            )
        )
    size = Vector3(x=marker_size, y=marker_size, z=marker_size)
    spheres = [SpherePrimitive(pose=_pose(m), size=size, color=color(rgba)) for m in markers]
    texts = [
        TextPrimitive(
            pose=_pose((m[0], m[1], m[2] + marker_size)),
            billboard=True,
            font_size=12.0,
            scale_invariant=True,
            color=color((1.0, 1.0, 1.0, 1.0)),
            text=label,
        )
        for m, label in zip(markers, labels, strict=False)
    ]
    return SceneEntity(
        timestamp=stamp(t_ns),
        frame_id=frame,
        id=entity_id,
        frame_locked=False,
        lines=lines,
        spheres=spheres,
        texts=texts,
    )


def solid_entity(drawn: Drawn, frame: str, t_ns: int) -> SceneEntity:
    """A scene object or zone (:func:`services.viewer.surroundings.solids`) as an entity
    in ``frame``, frame-locked (it moves with the frame, not left where it was drawn), its
    metadata the object's."""
    cubes, spheres, cylinders = [], [], []
    for solid in drawn.solids:
        pose = _pose([float(v) for v in solid.pose[:3, 3]], quaternion(solid.pose[:3, :3]))
        size = Vector3(x=solid.size[0], y=solid.size[1], z=solid.size[2])
        if solid.shape == "cube":
            cubes.append(CubePrimitive(pose=pose, size=size, color=color(solid.rgba)))
        elif solid.shape == "sphere":
            spheres.append(SpherePrimitive(pose=pose, size=size, color=color(solid.rgba)))
        else:
            cylinders.append(
                CylinderPrimitive(
                    pose=pose, size=size, bottom_scale=1.0, top_scale=1.0, color=color(solid.rgba)
                )
            )
    return SceneEntity(
        timestamp=stamp(t_ns),
        frame_id=frame,
        id=drawn.entity,
        frame_locked=True,
        metadata=[KeyValuePair(key=k, value=v) for k, v in drawn.metadata.items()],
        cubes=cubes,
        spheres=spheres,
        cylinders=cylinders,
    )


def scene_update(entities: Sequence[SceneEntity], t_ns: int, *, clear: bool = False) -> SceneUpdate:
    """``foxglove.SceneUpdate`` adding or replacing ``entities`` (same id replaces);
    ``clear`` first deletes every entity of the topic."""
    deletions = (
        [SceneEntityDeletion(timestamp=stamp(t_ns), type=SceneEntityDeletionType.All, id="")]
        if clear
        else []
    )
    return SceneUpdate(deletions=deletions, entities=list(entities))


def delete_entities(ids: Sequence[str], t_ns: int) -> SceneUpdate:
    """``foxglove.SceneUpdate`` deleting the entities ``ids``."""
    deletions = [
        SceneEntityDeletion(timestamp=stamp(t_ns), type=SceneEntityDeletionType.MatchingId, id=i)
        for i in ids
    ]
    return SceneUpdate(deletions=deletions, entities=[])


def poses_in_frame(
    frame: str, t_ns: int, poses: Sequence[tuple[Sequence[float], Sequence[float]]]
) -> PosesInFrame:
    """``foxglove.PosesInFrame`` of (xyz [m], quaternion xyzw) poses."""
    return PosesInFrame(
        timestamp=stamp(t_ns), frame_id=frame, poses=[_pose(p, q) for p, q in poses]
    )


def log(level: str, name: str, message: str, t_ns: int) -> Log:
    """``foxglove.Log`` line from ``name`` (the service it concerns)."""
    return Log(timestamp=stamp(t_ns), level=LEVELS[level], message=message, name=name)
