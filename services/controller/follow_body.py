"""The person bodies a tracker's frames report (docs/follow.md, The person moves): each
frame's body pose checked against its place in the scene (``max_body_shift_m``), kept,
and placed in the collision guard and the follow source's scene once per joint state."""

from __future__ import annotations

import functools
import math

import numpy as np

from manus.orientation import ypr_to_matrix
from manus.scene import Scene
from schemas.target import TargetPose
from services.controller.command_source import Host
from services.controller.follow_space import FollowSpace


@functools.lru_cache(maxsize=64)
def _ypr_matrix(yaw: float, pitch: float, roll: float) -> np.ndarray:
    R = ypr_to_matrix(yaw, pitch, roll)
    R.flags.writeable = False
    return R


def rotation(ypr: list[float]) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) of (yaw, pitch, roll) [rad], (3, 3) (a tracker's
    orientations repeat: cached, read-only)."""
    return _ypr_matrix(ypr[0], ypr[1], ypr[2])


class Bodies:
    """Body poses waiting to be placed (see the module docstring).

    Args:
        bound: the farthest a body may be reported from its place in the scene [m].
    """

    def __init__(self, bound: float) -> None:
        self.bound = bound
        self._due: dict[str, np.ndarray] = {}
        self._rests: dict[tuple[int, str], tuple[float, float, float] | None] = {}

    def take(self, msg: TargetPose, space: FollowSpace, scene: Scene | None) -> str | None:
        """Keep the frame's body pose to place at the next joint state; why not (None:
        kept, or nothing to place)."""
        if not msg.body or len(msg.body_xyz) != 3 or len(msg.body_ypr) != 3:
            return None
        rest = self._rest_of(scene, msg.body)
        if rest is None:
            return f"the target's body {msg.body!r} is not a person of the scene"
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = rotation(msg.body_ypr), msg.body_xyz
        if msg.frame != "chair":  # the guard places scene objects in the chair frame
            pose = space.pose_to_chair(pose)
        shift = math.dist(pose[:3, 3], rest)
        if shift > self.bound:
            return (
                f"the target's body {msg.body!r} reported {shift * 1e3:.0f} mm from its place "
                f"in the scene, more than max_body_shift_m {self.bound * 1e3:.0f} mm"
            )
        self._due[msg.body] = pose
        return None

    def place(self, host: Host, space: FollowSpace, shown: dict[str, np.ndarray]) -> None:
        """Place the kept poses in the guard (``host``), in ``space`` and in ``shown``
        (base frame, for the state)."""
        for name, pose in self._due.items():
            host.move_object(name, pose)
            base = space.to_base @ pose
            space.move_person(name, base)
            shown[name] = base
        self._due.clear()

    def _rest_of(self, scene: Scene | None, name: str) -> tuple[float, float, float] | None:
        """Where the person object ``name`` is in the scene (chair frame; None: none)."""
        key = (id(scene), name)
        if key not in self._rests:
            found = next((o for o in scene.objects if o.name == name), None) if scene else None
            xyz = found.body.pose[:3, 3] if found is not None and found.cls == "person" else None
            self._rests[key] = (
                None if xyz is None else (float(xyz[0]), float(xyz[1]), float(xyz[2]))
            )
        return self._rests[key]
