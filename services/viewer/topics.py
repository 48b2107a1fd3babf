"""The viewer's Foxglove topics of one prefix, and the JSON schemas of the forwarded types."""

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
        self.log = f"{viz}/log"
        self._json: dict[type[Message], SchemaInfo] = {}

    def json_schema(self, msg_type: type[Message]) -> SchemaInfo:
        info = self._json.get(msg_type)
        if info is None:
            info = self._json[msg_type] = scene.json_schema_info(
                msg_type.TYPE_NAME, msg_type.json_schema()
            )
        return info
