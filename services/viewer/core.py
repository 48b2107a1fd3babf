"""The viewer's deterministic core: bus messages in, Foxglove messages out.

:class:`ViewerCore` takes each sample as it travelled (key, MessagePack payload, time)
and returns the messages to show, each a :class:`FoxMessage` (topic, schema, encoding,
bytes, log time), so the live WebSocket server, ``manus replay --view`` and
``manus export --json`` write the very same channels. Time comes only from its inputs; no
clock, no threads.

The channels it writes, and what each shows: :mod:`services.viewer.topics`.

A payload that does not decode is counted (:attr:`ViewerStats.bad_payloads`), never
raised; keys the viewer does not draw are counted as ignored.
"""

from __future__ import annotations

import base64
import json
from collections.abc import Callable
from dataclasses import replace
from typing import Any, NamedTuple

import msgpack
import numpy as np
from foxglove.messages import FrameTransforms, Log, PosesInFrame, SceneUpdate

from manus.errors import ManusError
from manus.kinematics import fk
from manus.scene import Scene, SceneError, parse_scene, scene_from_setting, start_scene_state
from manus.world_follower import WorldFollower
from schemas import endpoints as ep
from schemas.base import Message
from schemas.collision import SceneState
from schemas.control import TrajectoryGoal
from schemas.follow import FollowState
from schemas.keys import Keys, channel_type
from schemas.objects import WorldUpdate
from schemas.planning import PlanReply, Trajectory
from schemas.state import JointState, SimTruth
from services.viewer import scene
from services.viewer.config import ViewerConfig, ViewerStats
from services.viewer.events import EventLog, LogLine
from services.viewer.follow import follow_update
from services.viewer.model import ROOT_FRAME, build_visual_urdf, link_transforms
from services.viewer.objects import drawn_objects
from services.viewer.path import GripperPath
from services.viewer.planned import planned_path
from services.viewer.scene import SchemaInfo
from services.viewer.surroundings import solids
from services.viewer.topics import Topics

JSON_SUFFIXES: tuple[str, ...] = (
    ep.JOINTS,
    ep.STATUS,
    ep.BRIDGE_STATE,
    ep.JOINT_VELOCITY,
    ep.FEEDBACK,
    ep.RESULT,
    ep.EVENTS,
    ep.ESTOP,
    ep.SIM_TRUTH,
    ep.LIVELINESS,
    ep.OBJECTS,
    ep.FOLLOW_STATE,
)
"""Keys forwarded as JSON channels (topic = the key, schema = the message's own)."""

GOAL_REQUEST = ep.GOAL.trace("request")
PLAN_REPLY = ep.PLAN.trace("reply")

ROBOT_DESCRIPTION_SCHEMA = scene.json_schema_info(
    "std_msgs/String",
    {
        "title": "std_msgs/String",
        "type": "object",
        "properties": {"data": {"type": "string", "description": "the URDF (XML)"}},
        "required": ["data"],
    },
)

PLANNED_RGBA = (0.20, 0.60, 1.00, 0.9)
PLAN_RGBA = (0.55, 0.55, 1.00, 0.5)
EXECUTED_RGBA = (1.00, 0.45, 0.10, 1.0)
TRUE_RGBA = (0.20, 0.85, 0.30, 0.8)


class FoxMessage(NamedTuple):
    """One message for Foxglove.

    Attributes:
        topic: channel topic.
        schema: its schema.
        encoding: message encoding (``protobuf`` or ``json``).
        data: the encoded message.
        log_ns: log time [ns] (the input's time).
    """

    topic: str
    schema: SchemaInfo
    encoding: str
    data: bytes
    log_ns: int


Handler = Callable[[Message, int], list["FoxMessage"]]
"""A decoded message and its time [ns] -> the messages to show."""


def _json_default(value: Any) -> Any:
    """``bytes`` as base64, as the schemas say (``contentEncoding: base64``)."""
    if isinstance(value, bytes | bytearray):
        return base64.b64encode(bytes(value)).decode("ascii")
    raise TypeError(f"{type(value).__name__} is not JSON serializable")


class ViewerCore:
    """Bus samples -> Foxglove messages (see the module docstring for the channels).

    Args:
        config: prefix, geometry and path bounds.
    """

    def __init__(self, config: ViewerConfig | None = None) -> None:
        self.config = config or ViewerConfig()
        self.keys = Keys(self.config.prefix)
        self.stats = ViewerStats()
        self.topics = Topics(self.keys)
        self._executed = GripperPath(
            self.config.path_points, self.config.path_step_m, self.config.path_every
        )
        self._true = GripperPath(
            self.config.path_points, self.config.path_step_m, self.config.path_every
        )
        self.events = EventLog()
        self.joints: JointState | None = None
        """The newest valid joint state (what the arm in the 3D view shows)."""
        self.planned: tuple[list[list[float]], list[list[float]]] = ([], [])
        """The newest goal's path and via points [m] (what ``viz/planned`` shows)."""
        self._urdf = build_visual_urdf(self.config.arm)
        self.scene: Scene | None = scene_from_setting(self.config.scene)
        self._scene_seen = start_scene_state(self.config.scene)  # what is drawn, as announced
        """The scene drawn now (None: none)."""
        self.world = WorldFollower()
        """The world model's objects drawn now (``planner/objects``)."""
        self._handlers = {
            ep.JOINTS: self._joints,
            ep.STATUS: self._logging(self.events.arm_status),
            ep.BRIDGE_STATE: self._logging(self.events.bridge),
            ep.RESULT: self._logging(self.events.result),
            ep.EVENTS: self._logging(self.events.task_event),
            ep.ESTOP: self._logging(self.events.estop),
            ep.SIM_TRUTH: self._truth,
            ep.LIVELINESS: self._logging(self.events.liveliness),
            ep.SCENE_STATE: self._scene_state,
            ep.OBJECTS: self._objects,
            ep.FOLLOW_STATE: self._follow,
            GOAL_REQUEST: self._goal,
            PLAN_REPLY: self._plan_reply,
        }

    @property
    def executed(self) -> list[tuple[float, float, float]]:
        """The executed path now [m] (what ``viz/executed`` shows)."""
        return list(self._executed.points)

    @property
    def urdf(self) -> str:
        """The URDF the viewer draws (:func:`services.viewer.model.build_visual_urdf`)."""
        return self._urdf

    def channels(self) -> list[tuple[str, SchemaInfo, str]]:
        """(topic, schema, encoding) of every channel the core can produce, to advertise
        before the first message."""
        protobuf: list[tuple[str, Any]] = [
            (self.topics.tf, FrameTransforms),
            (self.topics.planned, SceneUpdate),
            (self.topics.via_poses, PosesInFrame),
            (self.topics.executed, SceneUpdate),
            (self.topics.true, SceneUpdate),
            (self.topics.scene, SceneUpdate),
            (self.topics.objects, SceneUpdate),
            (self.topics.follow, SceneUpdate),
            (self.topics.log, Log),
        ]
        out = [(self.topics.robot_description, ROBOT_DESCRIPTION_SCHEMA, "json")]
        out += [(topic, scene.schema_of(t), "protobuf") for topic, t in protobuf]
        for suffix in JSON_SUFFIXES:
            msg_type = channel_type(suffix)
            if msg_type is not None:
                out.append((self.keys(suffix), self.topics.json_schema(msg_type), "json"))
        return out

    def robot_description(self, t_ns: int) -> FoxMessage:
        """The URDF on ``P/viz/robot_description`` (send it to each new subscriber)."""
        data = json.dumps({"data": self._urdf}).encode()
        return FoxMessage(
            self.topics.robot_description, ROBOT_DESCRIPTION_SCHEMA, "json", data, t_ns
        )

    def scene_update(self, t_ns: int) -> FoxMessage:
        """The scene in use on ``P/viz/scene``: every entity before it deleted, then one
        per object and zone (none without a scene)."""
        drawn = solids(self.scene) if self.scene is not None else []
        ents = [scene.solid_entity(d, ROOT_FRAME, t_ns) for d in drawn]
        return self._proto(self.topics.scene, scene.scene_update(ents, t_ns, clear=True), t_ns)

    def objects_update(self, t_ns: int) -> FoxMessage:
        """The world model's objects on ``P/viz/objects``: every entity before it deleted,
        then one per object."""
        mount = self.scene.mount if self.scene is not None else np.eye(4)
        ents = [
            scene.solid_entity(drawn, frame, t_ns)
            for frame, drawn in drawn_objects(self.world.objects.values(), mount)
        ]
        return self._proto(self.topics.objects, scene.scene_update(ents, t_ns, clear=True), t_ns)

    def describe(self, t_ns: int) -> list[FoxMessage]:
        """What a new subscriber needs before the stream makes sense: the robot
        description, the scene in use and the objects."""
        return [self.robot_description(t_ns), self.scene_update(t_ns), self.objects_update(t_ns)]

    def on_sample(self, key: str, payload: bytes, t_ns: int) -> list[FoxMessage]:
        """Messages to show for one bus sample.

        Args:
            key: full key expression it travelled on.
            payload: the MessagePack bytes.
            t_ns: receive (or recorded log) time [ns]: the log time of every output.
        """
        self.stats.inputs += 1
        suffix = self.keys.suffix(key)
        handler = self._handlers.get(suffix)
        forward = suffix in JSON_SUFFIXES
        msg_type = channel_type(suffix) if handler is not None or forward else None
        if msg_type is None:  # not drawn (or a key the table lost: nothing to decode it with)
            self.stats.ignored += 1
            return []
        out: list[FoxMessage] = []
        if forward:  # as it travelled, like manus export --json: no decoding into the type
            try:
                value = msgpack.unpackb(payload, raw=False, strict_map_key=False)
            except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError):
                value = None
            if not isinstance(value, dict):
                self._bad(suffix)
                return []
            data = json.dumps(value, separators=(",", ":"), default=_json_default).encode()
            out.append(FoxMessage(key, self.topics.json_schema(msg_type), "json", data, t_ns))
        if handler is not None:
            try:
                out += handler(msg_type.decode(payload), t_ns)
            except (ManusError, ValueError, IndexError):  # e.g. a trajectory that won't sample
                self._bad(suffix)
        self.stats.outputs += len(out)
        return out

    def _bad(self, suffix: str) -> None:
        self.stats.bad_payloads[suffix] = self.stats.bad_payloads.get(suffix, 0) + 1

    # -- outputs -------------------------------------------------------------------------

    @staticmethod
    def _proto(topic: str, msg: Any, t_ns: int) -> FoxMessage:
        schema, data = scene.encoded(msg)
        return FoxMessage(topic, schema, "protobuf", data, t_ns)

    def _logged(self, lines: list[LogLine], t_ns: int) -> list[FoxMessage]:
        return [
            self._proto(self.topics.log, scene.log(line.level, line.name, line.text, t_ns), t_ns)
            for line in lines
        ]

    def _logging(self, lines_of: Callable[[Any], list[LogLine]]) -> Handler:
        """A handler that only logs: the lines ``lines_of`` gives for the message."""

        def handle(msg: Message, t_ns: int) -> list[FoxMessage]:
            return self._logged(lines_of(msg), t_ns)

        return handle

    def _path(
        self,
        topic: str,
        entity: str,
        path: GripperPath,
        rgba: tuple[float, ...],
        t_ns: int,
        stamp: int,
    ) -> FoxMessage:
        ent = scene.path_entity(entity, ROOT_FRAME, stamp, list(path.points), rgba)
        return self._proto(topic, scene.scene_update([ent], stamp), t_ns)

    def _executed_path(self, t_ns: int, stamp: int) -> FoxMessage:
        return self._path(self.topics.executed, "executed", self._executed, EXECUTED_RGBA, t_ns,
                          stamp)  # fmt: skip

    # -- handlers ------------------------------------------------------------------------

    def _joints(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, JointState)
        if not msg.valid:  # garbage positions before joint mode: nothing to draw
            return []
        self.joints = msg
        cfg = self.config.arm
        tfs = link_transforms(msg.position, msg.gripper, cfg)
        out = [self._proto(self.topics.tf, scene.frame_transforms(tfs, msg.stamp_ns), t_ns)]
        p = fk(msg.position, cfg)[:3, 3]
        if self._executed.add((float(p[0]), float(p[1]), float(p[2]))):
            out.append(self._executed_path(t_ns, msg.stamp_ns))
        return out

    def _truth(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, SimTruth)
        if self._true.add((msg.xyz[0], msg.xyz[1], msg.xyz[2])):
            return [self._path(self.topics.true, "true", self._true, TRUE_RGBA, t_ns, msg.stamp_ns)]
        return []

    def _trajectory_scene(
        self, entity: str, traj: Trajectory, rgba: tuple[float, ...], t_ns: int
    ) -> tuple[Any, list[tuple[list[float], tuple[float, float, float, float]]]]:
        """Scene entity of a trajectory's path and via points, and the knots' poses."""
        drawn = planned_path(traj, self.config.arm, self.config.preview_dt_s)
        labels = [str(i) for i in range(len(drawn.via))] if len(drawn.via) <= 40 else []
        ent = scene.path_entity(
            entity,
            ROOT_FRAME,
            t_ns,
            drawn.points,
            rgba,
            markers=drawn.via,
            labels=labels,
            thickness=0.003,
        )
        if entity == "goal":
            self.planned = (drawn.points, drawn.via)
        return ent, drawn.poses

    def _goal(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, TrajectoryGoal)
        ent, poses = self._trajectory_scene("goal", msg.trajectory, PLANNED_RGBA, t_ns)
        self._executed.clear()
        return [
            self._proto(self.topics.planned, scene.scene_update([ent], t_ns), t_ns),
            self._proto(self.topics.via_poses, scene.poses_in_frame(ROOT_FRAME, t_ns, poses), t_ns),
            self._executed_path(t_ns, t_ns),
            *self._logged(self.events.goal(msg), t_ns),
        ]

    def _plan_reply(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, PlanReply)
        if not msg.ok or msg.trajectory is None:
            return self._logged(self.events.plan_refused(msg), t_ns)
        ent, _ = self._trajectory_scene("plan", msg.trajectory, PLAN_RGBA, t_ns)
        return [self._proto(self.topics.planned, scene.scene_update([ent], t_ns), t_ns)]

    def _objects(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, WorldUpdate)
        before = self.world.version
        self.world.on_update(msg)
        if self.world.version == before and msg.base_version != -1:
            return []  # a diff it cannot apply: drawn again at the next whole set
        return [self.objects_update(t_ns)]

    def _follow(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, FollowState)
        return [self._proto(self.topics.follow, follow_update(msg, t_ns), t_ns)]

    def _scene_state(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, SceneState)
        if msg.same_scene(self._scene_seen):
            return []  # the planner's announcement of the scene drawn (every second)
        self._scene_seen = msg
        try:
            parsed = parse_scene(msg.text, msg.source or "<scene update>")
        except SceneError as exc:  # the planner validated it: another stack's, or garbage
            self._bad(ep.SCENE_STATE)
            return self._logged(self.events.scene(msg, None, str(exc)), t_ns)
        self.scene = replace(parsed, version=msg.version)
        return [self.scene_update(t_ns), *self._logged(self.events.scene(msg, parsed), t_ns)]
