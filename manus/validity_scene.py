"""What the fast validity check (:mod:`manus.validity`) keeps the arm's bodies clear of:
the arm's fixed base (column and shoulder, with the ``self`` clearance), the scene's
objects and keep-out zones (with their class's clearance), in the base frame; the arm's
moving bodies a held object keeps the ``self`` clearance from (*movers*, placed by the
kernels at each configuration); and which (body, thing) pairs the collision model checks
(exactly its :attr:`CollisionModel.checks`). A scene object the model moved
(:attr:`CollisionModel.moved`, a person a tracker follows) is where the model has it:
:func:`place_moved` places it anew in the kernels' arrays, no rebuild.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from manus.collision import CollisionModel
from manus.collision_pairs import STATIC_BODIES
from manus.scene import Primitive
from manus.validity_parts import primitive_arrays, primitive_box


class Obstacles(NamedTuple):
    """What the bodies are checked against (O things).

    Attributes:
        prims: each thing, placed in the base frame (a mover: in its joint's frame).
        others: each thing's (name, class, clearance [m]).
        applies: which (body, thing) pairs the model checks, bool (B, O).
        partner: a mover's body (index into the bodies), -1 for a fixed thing, (O,).
        rigid: a mover on the joint of every body checked against it (their distance
            never changes), bool (O,).
        joint: a mover's joint (0: fixed), (O,).
        placed: each scene object's index among the things (where a moved one goes).
    """

    prims: list[Primitive]
    others: list[tuple[str, str, float]]
    applies: np.ndarray
    partner: np.ndarray
    rigid: np.ndarray
    joint: np.ndarray
    placed: dict[str, int]


def obstacles(model: CollisionModel, bodies: list[str]) -> Obstacles:
    """Every thing a body of ``bodies`` may be checked against (see :class:`Obstacles`);
    a scene object where the model has it now (:attr:`CollisionModel.moved`)."""
    scene = model.scene
    prims: list[Primitive] = []
    others: list[tuple[str, str, float]] = []
    placed: dict[str, int] = {}
    for name in STATIC_BODIES:
        i = model.body_index[name]
        obj = model.geom.geometryObjects[i]
        shape = model.shapes[i]
        pose = _static_pose(model, obj.parentJoint, np.asarray(obj.placement.homogeneous))
        required = scene.clearance["self"] if scene is not None else 0.01
        prims.append(Primitive(shape.kind, shape.size, pose))
        others.append((name, "self", required))
    if scene is not None:
        to_base = np.linalg.inv(scene.mount)
        for thing in scene.objects:
            placed[thing.name] = len(prims)
            prims.append(in_base(model.moved.body(thing), to_base))
            others.append((thing.name, thing.cls, scene.clearance[thing.cls]))
        for zone in scene.zones:
            if zone.kind == "keep_out":
                prims.append(in_base(zone.body, to_base))
                others.append((zone.name, "zone", zone.clearance))
    fixed = len(prims)
    joints = [0] * fixed
    for name in dict.fromkeys(c.other for c in model.checks if c.cls == "self"):
        if name not in STATIC_BODIES:  # an arm body a held body is checked against
            i = model.body_index[name]
            obj = model.geom.geometryObjects[i]
            size = model.shapes[i].size
            if name == "gripper":
                size = tuple(2.0 * float(v) for v in obj.geometry.halfSide)  # the opening
            prims.append(Primitive(model.shapes[i].kind, size, obj.placement.homogeneous))
            others.append((name, "self", scene.clearance["self"] if scene is not None else 0.01))
            joints.append(int(obj.parentJoint))
    checked = {(c.body, c.other) for c in model.checks}
    applies = np.array(
        [[(b, o[0]) in checked for o in others] for b in bodies], dtype=np.bool_
    ).reshape(len(bodies), len(others))
    partner = np.array([-1] * fixed + [bodies.index(o[0]) for o in others[fixed:]])
    joint_of = [int(model.geom.geometryObjects[model.body_index[b]].parentJoint) for b in bodies]
    rigid = np.array(
        [
            o >= fixed and all(joint_of[b] == joints[o] for b in np.flatnonzero(applies[:, o]))
            for o in range(len(others))
        ],
        dtype=np.bool_,
    )
    return Obstacles(
        prims, others, applies, partner.astype(np.int64), rigid, np.array(joints), placed
    )


def static_shapes(model: CollisionModel) -> list[tuple[str, tuple[float, ...], np.ndarray, int]]:
    """The arm's static bodies (column, shoulder) as (kind, size [m], placement in its
    joint's frame (4x4), joint): their keep-in cover points are checked too."""
    out = []
    for name in STATIC_BODIES:
        i = model.body_index[name]
        obj = model.geom.geometryObjects[i]
        shape = model.shapes[i]
        out.append(
            (shape.kind, shape.size, np.asarray(obj.placement.homogeneous), int(obj.parentJoint))
        )
    return out


def in_base(body: Primitive, to_base: np.ndarray) -> Primitive:
    """``body`` placed in the base frame (a plane's normal turned with it)."""
    size = body.size
    if body.shape == "plane":
        size = tuple(float(v) for v in to_base[:3, :3] @ np.asarray(size, dtype=float))
    return Primitive(body.shape, size, np.asarray(to_base @ body.pose))


def _static_pose(model: CollisionModel, joint: int, placement: np.ndarray) -> np.ndarray:
    """A static body's pose in the base frame (one on joint 1 turns about its own axis,
    which holds only for a body about that axis)."""
    M = (
        np.asarray(model.model.jointPlacements[joint].homogeneous) @ placement
        if joint
        else placement
    )
    if joint > 1 or (
        joint == 1 and not (np.allclose(M[:2, 3], 0.0) and np.allclose(M[:3, 2], [0, 0, 1]))
    ):
        raise ValueError("a static body must be on the base or turn about joint 1's axis")
    return M


def place_moved(
    model: CollisionModel, found: Obstacles, scene: tuple[np.ndarray, ...], placed: int
) -> int:
    """Put every scene object the model moved where it is now, in ``found`` and in the
    kernels' scene arrays ``scene`` (:attr:`ValidityChecker._scene`: rotations, origins
    and boxes, in place), unless they are there already (the model's moves, ``version``,
    are ``placed``); returns the version placed (cheap: no rebuild)."""
    version = model.moved.version
    if model.scene is None or version == placed:
        return version
    to_base = np.linalg.inv(model.scene.mount)
    for obj in model.scene.objects:
        if obj.name not in model.moved.poses:
            continue
        o = found.placed[obj.name]
        prim = found.prims[o] = in_base(model.moved.body(obj), to_base)
        _, R, t, _ = primitive_arrays([prim])
        scene[1][o], scene[2][o] = R[0], t[0]
        scene[12][o] = primitive_box(prim)
    return version
