"""The viewer's deterministic core: bus messages in, Foxglove messages out.

:class:`ViewerCore` takes each sample as it travelled (key, MessagePack payload, time)
and returns the messages to show, each a :class:`FoxMessage` (topic, schema, encoding,
bytes, log time), so the live WebSocket server, ``manus replay --view`` and
``manus export --json`` write the very same channels. Time comes only from its inputs; no
clock, no threads.

Channels (``P`` = the prefix, ``manus`` by default; schema in brackets):

- ``P/viz/robot_description`` [``std_msgs/String``, JSON, ``data`` = the URDF]:
  :meth:`ViewerCore.robot_description`;
- ``P/viz/tf`` [``foxglove.FrameTransforms``]: every link from each valid
  ``state/joints`` (forward kinematics; the fingers from the gripper opening);
- ``P/viz/planned`` [``foxglove.SceneUpdate``]: the trajectory preview and via points of
  each controller goal (entity ``goal``) and planner reply (entity ``plan``);
- ``P/viz/via_poses`` [``foxglove.PosesInFrame``]: the gripper pose at each knot of a goal;
- ``P/viz/executed`` [``foxglove.SceneUpdate``]: the measured gripper path since the last
  goal (forward kinematics of the joint states);
- ``P/viz/true`` [``foxglove.SceneUpdate``]: the simulator's true path (``sim/truth``);
- ``P/viz/scene`` [``foxglove.SceneUpdate``]: the scene and protection zones
  (:mod:`services.viewer.surroundings`: one entity per object and zone, in ``base_link``,
  the scene's version in each entity's metadata): :meth:`ViewerCore.describe` gives the
  one in use (the ``scene`` setting at start), and each ``planner/scene_state`` (a scene
  replaced at run time) replaces every entity;
- ``P/viz/log`` [``foxglove.Log``]: arm warnings and errors, bridge phases, goals and
  results, task events, e-stops, services appearing and vanishing;
- ``P/<suffix>`` [the message's JSON Schema, ``manus/JointState/2`` ...]: each message of
  :data:`JSON_SUFFIXES` as JSON, as ``manus export --json`` writes it.

A payload that does not decode is counted (:attr:`ViewerStats.bad_payloads`), never
raised; keys the viewer does not draw are counted as ignored.
"""

from __future__ import annotations

import base64
import json
import math
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple

import msgpack
from foxglove.messages import FrameTransforms, Log, PosesInFrame, SceneUpdate

from manus.config import DEFAULT_ARM, ArmConfig
from manus.errors import ManusError
from manus.kinematics import fk
from manus.scene import Scene, SceneError, parse_scene, scene_from_setting, start_scene_state
from manus.trajectory import JointTrajectory
from schemas import endpoints as ep
from schemas.base import Message
from schemas.collision import SceneState
from schemas.commands import EStop
from schemas.control import GoalResult, TrajectoryGoal
from schemas.keys import Keys, channel_type
from schemas.liveliness import LivelinessChange
from schemas.planning import PlanReply, Trajectory
from schemas.sequencing import TaskEvent
from schemas.state import ArmStatus, BridgeState, JointState, SimTruth
from services.viewer import scene
from services.viewer.model import ROOT_FRAME, build_visual_urdf, link_transforms, quaternion
from services.viewer.path import GripperPath
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
BAD_PHASES = ("resync", "stopped", "estopped", "arm_error", "shutdown")


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


@dataclass(frozen=True)
class ViewerConfig:
    """What the viewer draws and how much it keeps.

    Attributes:
        prefix: key prefix of the arm.
        arm: geometry (forward kinematics, URDF).
        path_points: most points kept of the executed and true paths.
        path_step_m: a new path point only after the gripper moved this far [m].
        path_every: publish a path after this many new points.
        preview_dt_s: sampling step [s] of a goal's path when it has no preview.
        scene: the scene drawn until the planner publishes another, as every service's
            ``scene`` setting (``""``: ``$MANUS_SCENE`` or the shipped one; ``default``;
            ``none``; a file: :func:`manus.scene.scene_from_setting`).
    """

    prefix: str = "manus"
    arm: ArmConfig = DEFAULT_ARM
    path_points: int = 3000
    path_step_m: float = 0.0005
    path_every: int = 3
    preview_dt_s: float = 0.05
    scene: str = ""

    def __post_init__(self) -> None:
        if self.path_points < 2 or self.path_every < 1:
            raise ValueError(
                f"path_points {self.path_points} must be >= 2 and path_every {self.path_every} >= 1"
            )
        if not (self.path_step_m >= 0 and self.preview_dt_s > 0):
            raise ValueError(
                f"path_step_m {self.path_step_m} must be >= 0 and preview_dt_s "
                f"{self.preview_dt_s} > 0 [m, s]"
            )


@dataclass
class ViewerStats:
    """Counters of the core.

    Attributes:
        inputs: samples received.
        outputs: Foxglove messages produced.
        bad_payloads: samples that did not decode, by key suffix.
        ignored: samples on keys the viewer does not draw.
    """

    inputs: int = 0
    outputs: int = 0
    bad_payloads: dict[str, int] = field(default_factory=dict)
    ignored: int = 0


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
        self._status: tuple[str, int] = ("none", 0)
        self._phase = ""
        self.joints: JointState | None = None
        """The newest valid joint state (what the arm in the 3D view shows)."""
        self.planned: tuple[list[list[float]], list[list[float]]] = ([], [])
        """The newest goal's path and via points [m] (what ``viz/planned`` shows)."""
        self._urdf = build_visual_urdf(self.config.arm)
        self.scene: Scene | None = scene_from_setting(self.config.scene)
        self._scene_seen = start_scene_state(self.config.scene)  # what is drawn, as announced
        """The scene drawn now (None: none)."""
        self._handlers = {
            ep.JOINTS: self._joints,
            ep.STATUS: self._arm_status,
            ep.BRIDGE_STATE: self._bridge,
            ep.RESULT: self._result,
            ep.EVENTS: self._task_event,
            ep.ESTOP: self._estop,
            ep.SIM_TRUTH: self._truth,
            ep.LIVELINESS: self._liveliness,
            ep.SCENE_STATE: self._scene_state,
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

    def describe(self, t_ns: int) -> list[FoxMessage]:
        """What a new subscriber needs before the stream makes sense: the robot
        description and the scene in use."""
        return [self.robot_description(t_ns), self.scene_update(t_ns)]

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

    def _log(self, level: str, name: str, text: str, t_ns: int) -> FoxMessage:
        return self._proto(self.topics.log, scene.log(level, name, text, t_ns), t_ns)

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
        cfg = self.config.arm
        poses = []
        for q in traj.positions:
            T = fk(q, cfg)
            poses.append(([float(v) for v in T[:3, 3]], quaternion(T[:3, :3])))
        if traj.preview_xyz:
            points = [list(p) for p in traj.preview_xyz]
        else:
            jt = JointTrajectory(traj)
            n = max(2, math.ceil(jt.duration / self.config.preview_dt_s) + 1)
            points = [
                [float(v) for v in fk(jt.sample(jt.duration * i / (n - 1)).q, cfg)[:3, 3]]
                for i in range(n)
            ]
        via = [list(v) for v in traj.via_xyz] if traj.via_xyz else [p for p, _ in poses]
        labels = [str(i) for i in range(len(via))] if len(via) <= 40 else []
        ent = scene.path_entity(
            entity, ROOT_FRAME, t_ns, points, rgba, markers=via, labels=labels, thickness=0.003
        )
        if entity == "goal":
            self.planned = (points, via)
        return ent, poses

    def _goal(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, TrajectoryGoal)
        ent, poses = self._trajectory_scene("goal", msg.trajectory, PLANNED_RGBA, t_ns)
        self._executed.clear()
        traj = msg.trajectory
        text = (
            f"goal {msg.goal_id}: {len(traj.times)} knots, {traj.times[-1]:.2f} s, mode {msg.mode}"
        )
        return [
            self._proto(self.topics.planned, scene.scene_update([ent], t_ns), t_ns),
            self._proto(self.topics.via_poses, scene.poses_in_frame(ROOT_FRAME, t_ns, poses), t_ns),
            self._executed_path(t_ns, t_ns),
            self._log("info", "controller", text, t_ns),
        ]

    def _plan_reply(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, PlanReply)
        if not msg.ok or msg.trajectory is None:
            reason = msg.error.message if msg.error is not None else "no trajectory"
            return [self._log("warning", "planner", f"plan refused: {reason}", t_ns)]
        ent, _ = self._trajectory_scene("plan", msg.trajectory, PLAN_RGBA, t_ns)
        return [self._proto(self.topics.planned, scene.scene_update([ent], t_ns), t_ns)]

    def _arm_status(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, ArmStatus)
        now = (msg.msg_class, msg.msg_code)
        if now == self._status or msg.msg_class == "general":
            return []
        self._status = now
        if msg.msg_class == "none":
            return [self._log("info", "arm", "message cleared", t_ns)]
        level = "error" if msg.msg_class == "error" else "warning"
        return [self._log(level, "arm", f"{msg.msg_class} {msg.msg_code}: {msg.text}", t_ns)]

    def _bridge(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, BridgeState)
        if msg.phase == self._phase:
            return []
        self._phase = msg.phase
        level = "warning" if msg.phase in BAD_PHASES else "info"
        detail = f" ({msg.detail})" if msg.detail else ""
        return [self._log(level, "can_bridge", f"phase {msg.phase}{detail}", t_ns)]

    def _result(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, GoalResult)
        level = {"succeeded": "info", "aborted": "error"}.get(msg.status, "warning")
        errs = msg.path_via_errors
        err = (
            f", via error mean {1000 * sum(errs) / len(errs):.2f} max {1000 * max(errs):.2f} mm"
            if errs
            else ""
        )
        text = f"{msg.kind} goal {msg.goal_id} {msg.status}: {msg.reason}{err}"
        return [self._log(level, "controller", text, t_ns)]

    def _task_event(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, TaskEvent)
        if msg.event == "step_progress":
            return []
        level = {"failed": "error", "step_failed": "error", "cancelled": "warning"}.get(
            msg.event, "info"
        )
        step = f" step {msg.step + 1}/{msg.total} {msg.kind}" if msg.step >= 0 else ""
        reason = f": {msg.reason}" if msg.reason else ""
        return [self._log(level, "sequencer", f"task {msg.task_id}{step} {msg.event}{reason}",
                          t_ns)]  # fmt: skip

    def _estop(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, EStop)
        what = "engaged" if msg.engaged else "released"
        reason = f": {msg.reason}" if msg.reason else ""
        return [self._log("error" if msg.engaged else "info", msg.source or "estop",
                          f"e-stop {what}{reason}", t_ns)]  # fmt: skip

    def _scene_state(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, SceneState)
        if msg.same_scene(self._scene_seen):
            return []  # the planner's announcement of the scene drawn (every second)
        self._scene_seen = msg
        try:
            parsed = parse_scene(msg.text, msg.source or "<scene update>")
        except SceneError as exc:  # the planner validated it: another stack's, or garbage
            self._bad(ep.SCENE_STATE)
            return [self._log("warning", "planner", f"scene {msg.version} not drawn: {exc}", t_ns)]
        self.scene = replace(parsed, version=msg.version)
        text = (
            f"scene version {msg.version} ({parsed.source}): {len(parsed.objects)} objects, "
            f"{len(parsed.zones)} zones"
        )
        return [self.scene_update(t_ns), self._log("info", "planner", text, t_ns)]

    def _liveliness(self, msg: Message, t_ns: int) -> list[FoxMessage]:
        assert isinstance(msg, LivelinessChange)
        if msg.kind != "alive":
            return []
        what = "up" if msg.alive else "gone"
        return [self._log("info" if msg.alive else "warning", msg.service or "liveliness",
                          f"{msg.service} {what}", t_ns)]  # fmt: skip
