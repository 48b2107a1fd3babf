"""``planner/attach``: a grasped object becomes part of the arm, a released one goes back
into the world where it is (docs/objects.md, Attached objects).

The planner owns the world model (:class:`manus.world.WorldModel`), so it answers; the
sequencer's grasp step asks, with the arm's configuration at the grasp or the release
(``position``, and its joint state's stamp). The gripper frame there is ``mount @
fk(position)`` in the chair frame (the scene's mount; no scene: the identity). Rules:

- **attach** (``link`` = ``gripper_frame``): the object's pose in the gripper frame is
  the request's ``xyz``/``ypr`` if it gives them; else, attached already, where it is
  held (a new attach changes only what it may touch: the table it was lifted from, once
  it is clear); else its world pose seen from the gripper, centred between the jaws
  (closing jaws centre what they hold along their axis, the gripper frame's x), refused
  when its centre is further than :data:`MAX_GRIP_OFFSET_M` from the grasp point (it
  cannot be between the jaws: perception and the arm disagree);
- **detach** (``link`` ''): back into the chair frame at the gripper frame times its
  pose in it, where it is now;
- ``touch_links`` are arm bodies (:func:`manus.urdf.collision_shapes` names),
  ``touch_objects`` objects of the scene in use.

Refused, with nothing changed, naming the object and the reason: an unknown object (the
known ones listed), an object named like an arm body, another link, a position that is
not 6 finite angles, an unknown touch link or touch object, a pose given by half, an
object not between the jaws, an object attached elsewhere, detaching one that is not
attached.
"""

from __future__ import annotations

import math
from collections.abc import Collection

import numpy as np

from manus.config import ArmConfig
from manus.kinematics import fk
from manus.orientation import pose_matrix
from manus.urdf import GRIPPER_FRAME, collision_shapes
from manus.world import WorldModel
from manus.world_follower import WorldError
from schemas.objects import AttachReply, AttachRequest, WorldUpdate

MAX_GRIP_OFFSET_M = 0.1
"""Farthest an object's centre may be from the grasp point (the gripper frame's origin)
to be attached where perception saw it [m]: the jaws reach 90 mm behind it (the palm)."""


def answer(
    world: WorldModel,
    request: AttachRequest,
    mount: np.ndarray,
    arm: ArmConfig,
    scene_objects: Collection[str],
) -> tuple[AttachReply, list[WorldUpdate]]:
    """Attach or detach as ``request`` says (see the module docstring).

    Args:
        world: the world model (changed when accepted).
        request: the request.
        mount: the arm's base in the chair frame, (4, 4).
        arm: the arm's geometry (its kinematics, its bodies' names).
        scene_objects: the names of the scene's objects.

    Returns:
        The reply, and the world model's updates to publish (none when refused).
    """
    try:
        gripper = _gripper_pose(request, mount, arm)
        _check_names(request, arm, scene_objects)
        if request.link:
            grip = _grip(world, request, gripper)
            updates = world.attach(
                request.object_id,
                request.link,
                grip,
                request.stamp_ns,
                request.touch_links,
                request.touch_objects,
            )
        else:
            held = world.pose(request.object_id)  # checks the object exists
            updates = world.detach(request.object_id, gripper @ held, request.stamp_ns)
    except WorldError as exc:
        return AttachReply(accepted=False, version=world.version, error=str(exc)), []
    obj = world.objects[request.object_id]
    return AttachReply(accepted=True, version=world.version, object=obj), updates


def _gripper_pose(request: AttachRequest, mount: np.ndarray, arm: ArmConfig) -> np.ndarray:
    what = f"object {request.object_id!r}"
    if request.link not in ("", GRIPPER_FRAME):
        raise WorldError(f"{what}: link {request.link!r}: objects attach to {GRIPPER_FRAME!r}")
    if len(request.position) != 6 or not all(math.isfinite(v) for v in request.position):
        raise WorldError(f"{what}: position must be 6 finite angles, got {request.position}")
    return np.asarray(mount @ fk(np.asarray(request.position, dtype=float), arm))


def _check_names(request: AttachRequest, arm: ArmConfig, scene_objects: Collection[str]) -> None:
    what = f"object {request.object_id!r}"
    bodies = [s.name for s in collision_shapes(arm)]
    if request.object_id in bodies:
        raise WorldError(f"{what}: an arm body has that name: it cannot be held")
    for name in request.touch_links:
        if name not in bodies:
            raise WorldError(f"{what}: touch link {name!r} is not an arm body ({bodies})")
    for name in request.touch_objects:
        if name not in scene_objects:
            known = sorted(scene_objects)
            raise WorldError(f"{what}: touch object {name!r} is not in the scene ({known})")
    if (request.xyz is None) != (request.ypr is None):
        raise WorldError(f"{what}: give both xyz and ypr of its pose in the link, or neither")


def _grip(world: WorldModel, request: AttachRequest, gripper: np.ndarray) -> np.ndarray:
    """The object's pose in the gripper frame (see the module docstring)."""
    pose = world.pose(request.object_id)  # checks the object exists
    if request.xyz is not None and request.ypr is not None:
        return pose_matrix(request.xyz, (request.ypr[0], request.ypr[1], request.ypr[2]))
    if world.objects[request.object_id].link:
        return pose  # held already: where it is held
    grip = np.linalg.solve(gripper, pose)
    offset = float(np.linalg.norm(grip[:3, 3]))
    if offset > MAX_GRIP_OFFSET_M:
        raise WorldError(
            f"object {request.object_id!r} is {offset * 1e3:.0f} mm from the grasp point, more "
            f"than {MAX_GRIP_OFFSET_M * 1e3:.0f} mm: it is not between the jaws"
        )
    grip[0, 3] = 0.0  # the jaws centre it along their axis
    return np.asarray(grip)
