"""What the fast validity check (:mod:`manus.validity`) keeps the arm's bodies clear of:
the arm's fixed base (column and shoulder, with the ``self`` clearance), the scene's
objects and keep-out zones (with their class's clearance), in the base frame, and which
(body, thing) pairs the collision model checks (exactly its :attr:`CollisionModel.checks`).
"""

from __future__ import annotations

import numpy as np

from manus.collision import CollisionModel
from manus.collision_pairs import STATIC_BODIES
from manus.scene import Primitive


def fixed_obstacles(
    model: CollisionModel, bodies: list[str]
) -> tuple[list[Primitive], list[tuple[str, str, float]], np.ndarray]:
    """Every fixed thing a body may be checked against, placed in the base frame, with
    its (name, class, clearance [m]), and which (body, thing) pairs the model checks
    (bool, (len(bodies), things))."""
    scene = model.scene
    prims: list[Primitive] = []
    others: list[tuple[str, str, float]] = []
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
            prims.append(_in_base(thing.body, to_base))
            others.append((thing.name, thing.cls, scene.clearance[thing.cls]))
        for zone in scene.zones:
            if zone.kind == "keep_out":
                prims.append(_in_base(zone.body, to_base))
                others.append((zone.name, "zone", zone.clearance))
    checked = {(c.body, c.other) for c in model.checks}
    applies = np.array(
        [[(b, o[0]) in checked for o in others] for b in bodies], dtype=np.bool_
    ).reshape(len(bodies), len(others))
    return prims, others, applies


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


def _in_base(body: Primitive, to_base: np.ndarray) -> Primitive:
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
