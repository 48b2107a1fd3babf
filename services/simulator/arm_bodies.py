"""The true arm's bodies at a configuration, in the chair frame, with the gripper's fingers.

The collision model (:mod:`manus.collision`) sizes the gripper as one solid box (palm,
fingers and the space between them), which is right for keeping it away from the scene
but wrong for an object between the jaws: that object is meant to be there. Here the
gripper is its two fingers, each ``FINGER_THICKNESS`` thick at +-(opening / 2 +
thickness / 2) along the jaw axis (the gripper frame's x), as long and as wide as the
gripper box; the other bodies are the URDF's (:func:`manus.urdf.collision_shapes`),
placed by Pinocchio's forward kinematics. The simulator's objects touch these bodies
(:mod:`services.simulator.object_contacts`) and the simulated camera's view is blocked by
them (:mod:`services.simulator.camera`).
"""

from __future__ import annotations

from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from manus.config import ArmConfig
from manus.urdf import FINGER_THICKNESS, GRIPPER_DEPTH, build_urdf, collision_shapes

FINGERS = ("finger_left", "finger_right")
"""The names of the two fingers (left: +x of the gripper frame)."""


class Body(NamedTuple):
    """One arm body placed in the chair frame.

    Attributes:
        name: ``upper_arm``, ``forearm``, ..., ``finger_left``, ``finger_right``.
        geometry: its Coal shape (in its own frame).
        pose: its placement in the chair frame [m], (4, 4).
        radius: the radius of a sphere about ``pose``'s origin that holds it [m].
        shape: ``cylinder``, ``sphere`` or ``box``.
        size: cylinder (radius, length), sphere (radius,), box (x, y, z) [m].
    """

    name: str
    geometry: Any
    pose: np.ndarray
    radius: float
    shape: str
    size: tuple[float, ...]


def _radius(kind: str, size: tuple[float, ...]) -> float:
    if kind == "sphere":
        return size[0]
    if kind == "cylinder":
        return float(np.hypot(size[0], size[1] / 2.0))
    return float(np.linalg.norm(size)) / 2.0


class ArmBodies:
    """Places the arm's bodies (see the module docstring).

    Args:
        cfg: arm geometry.
        mount: the arm's base frame in the chair frame, (4, 4).
    """

    def __init__(self, cfg: ArmConfig, mount: np.ndarray) -> None:
        urdf = build_urdf(cfg)
        self.model = pin.buildModelFromXML(urdf)
        self.data = self.model.createData()
        gm = pin.buildGeomFromUrdfString(self.model, urdf, pin.GeometryType.COLLISION)
        self.mount = np.asarray(mount, dtype=float)
        self._tip = np.eye(4)
        self._tip[2, 3] = cfg.l4  # link 6 -> the gripper frame (DH d6)
        # (joint, placement in the joint's frame, the body placed at identity)
        self._bodies: list[tuple[int, np.ndarray, Body]] = []
        for obj, shape in zip(gm.geometryObjects, collision_shapes(cfg), strict=True):
            if shape.name == "gripper":
                self._gripper = (obj.parentJoint, obj.placement.homogeneous.copy())
                continue
            radius = _radius(shape.kind, shape.size)
            body = Body(shape.name, obj.geometry, np.eye(4), radius, shape.kind, shape.size)
            self._bodies.append((obj.parentJoint, obj.placement.homogeneous.copy(), body))
        size = (FINGER_THICKNESS, 0.05, GRIPPER_DEPTH)
        self._finger = Body("", coal.Box(*size), np.eye(4), _radius("box", size), "box", size)
        self._key = b""
        self._placed: tuple[list[Body], np.ndarray] = ([], np.eye(4))

    def place(self, q: np.ndarray, opening: float) -> tuple[list[Body], np.ndarray]:
        """The bodies at DH angles ``q`` [rad] with the jaws ``opening`` [m] apart, and the
        gripper frame's pose, both in the chair frame (the same arguments twice in a row
        cost nothing)."""
        q = np.asarray(q, dtype=float)
        key = q.tobytes() + np.float64(opening).tobytes()
        if key == self._key:
            return self._placed
        pin.forwardKinematics(self.model, self.data, q)
        frames = [self.mount @ self.data.oMi[j].homogeneous for j in range(self.model.njoints)]
        bodies = [body._replace(pose=frames[joint] @ local) for joint, local, body in self._bodies]
        joint, local = self._gripper
        for name, side in zip(FINGERS, (1.0, -1.0), strict=True):
            finger = local.copy()
            finger[:3, 3] += finger[:3, 0] * side * (opening / 2.0 + FINGER_THICKNESS / 2.0)
            bodies.append(self._finger._replace(name=name, pose=frames[joint] @ finger))
        self._key = key
        self._placed = (bodies, frames[-1] @ self._tip)
        return self._placed


def transform(pose: np.ndarray) -> coal.Transform3s:
    """A Coal placement of a (4, 4) pose."""
    return coal.Transform3s(np.ascontiguousarray(pose[:3, :3]), np.ascontiguousarray(pose[:3, 3]))


def distance(a: Any, pose_a: np.ndarray | Any, b: Any, pose_b: np.ndarray | Any) -> float:
    """The signed distance between two Coal shapes at their poses [m] (< 0: penetrating);
    a pose is (4, 4) or already a Coal placement."""
    where_a = transform(pose_a) if isinstance(pose_a, np.ndarray) else pose_a
    where_b = transform(pose_b) if isinstance(pose_b, np.ndarray) else pose_b
    result = coal.DistanceResult()
    return float(coal.distance(a, where_a, b, where_b, _REQUEST, result))


_REQUEST = coal.DistanceRequest()
