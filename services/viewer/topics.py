"""The viewer's Foxglove topics of one prefix, and the JSON schemas of the forwarded types.

Channels (``P`` = the prefix, ``manus`` by default; schema in brackets):

- ``P/viz/robot_description`` [``std_msgs/String``, JSON, ``data`` = the URDF]:
  :meth:`~services.viewer.core.ViewerCore.robot_description`;
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
  the scene's version in each entity's metadata):
  :meth:`~services.viewer.core.ViewerCore.describe` gives the one in use (the ``scene``
  setting at start), and each ``planner/scene_state`` (a scene replaced at run time)
  replaces every entity;
- ``P/viz/objects`` [``foxglove.SceneUpdate``]: the world model's objects
  (``planner/objects``, :mod:`services.viewer.objects`): free ones where perception saw
  them, held ones in ``gripper_frame`` (they move with the gripper); each update replaces
  every entity;
- ``P/viz/follow`` [``foxglove.SceneUpdate``] (:mod:`services.viewer.follow`): a follow
  goal's target, predicted target, standoff point, tracked point and the person's body;
- ``P/viz/log`` [``foxglove.Log``] (:mod:`services.viewer.events`): arm warnings and
  errors, bridge phases, goals and results, task events, e-stops, services appearing and
  vanishing;
- ``P/<suffix>`` [the message's JSON Schema, ``manus/JointState/2`` ...]: each message of
  :data:`~services.viewer.core.JSON_SUFFIXES` as JSON, as ``manus export --json`` writes it.
"""

from __future__ import annotations

from schemas.base import Message
from schemas.keys import Keys
from services.viewer import scene
from services.viewer.scene import SchemaInfo


class Topics:
    """Topic names of one prefix and the JSON schemas of the forwarded types."""

    def __init__(self, keys: Keys) -> None:
        viz = keys("viz")
        self.robot_description = f"{viz}/robot_description"
        self.tf = f"{viz}/tf"
        self.planned = f"{viz}/planned"
        self.via_poses = f"{viz}/via_poses"
        self.executed = f"{viz}/executed"
        self.true = f"{viz}/true"
        self.scene = f"{viz}/scene"
        self.objects = f"{viz}/objects"
        self.follow = f"{viz}/follow"
        self.log = f"{viz}/log"
        self._json: dict[type[Message], SchemaInfo] = {}

    def json_schema(self, msg_type: type[Message]) -> SchemaInfo:
        info = self._json.get(msg_type)
        if info is None:
            info = self._json[msg_type] = scene.json_schema_info(
                msg_type.TYPE_NAME, msg_type.json_schema()
            )
        return info
