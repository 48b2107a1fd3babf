"""The fast check's kernel arrays (:mod:`manus.validity`): from a collision model's
bodies, as shaped now, and what they are checked against, the arrays its kernels take.

Built when a checker is made, and again for each gripper opening (the gripper box's
size is in its pieces and cover points): :class:`manus.validity.ValidityChecker` keeps
what it builds per opening, and can build an opening's ahead of a control cycle
(:meth:`~manus.validity.ValidityChecker.prepare`).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from manus.clearance import Check
from manus.collision import CollisionModel
from manus.collision_pairs import STATIC_BODIES
from manus.validity_parts import (
    Piece,
    body_pieces,
    cover_points,
    lever_table,
    primitive_arrays,
    primitive_box,
)
from manus.validity_scene import Obstacles, static_shapes

SLACK_M = 1e-5
"""Taken off every bound [m]: Coal's distances carry a tolerance of their own."""

Shaped = tuple[str, tuple[float, ...], np.ndarray]
"""A body as the pieces take it: kind, size [m], placement in its joint's frame (4x4)."""


class KernelArrays(NamedTuple):
    """What the kernels take for one shape of the bodies.

    Attributes:
        arm: the arm's arrays (joint placements, pieces, bodies, cover points).
        scene: the obstacles' and keep-in zones' arrays.
        zone_checks: each keep-in zone's check.
        levers: per joint and body, the farthest any point of the body can be from the
            joint's origin [m], shape (6, B).
    """

    arm: tuple[Any, ...]
    scene: tuple[Any, ...]
    zone_checks: list[Check]
    levers: np.ndarray


def kernel_arrays(
    model: CollisionModel,
    placements: np.ndarray,
    shaped: list[Shaped],
    joint_of: list[int],
    bodies: list[str],
    found: Obstacles,
) -> KernelArrays:
    """The kernels' arrays for the bodies ``bodies`` of ``model`` shaped as ``shaped``
    (on joints ``joint_of``; ``placements``: the joints' placements, (7, 4, 4)) and the
    obstacles ``found``."""
    pieces: list[Piece] = []
    p_joint, p_body, b_start, b_center, b_radius = [], [], [0], [], []
    for b, ((kind, size, placement), joint) in enumerate(zip(shaped, joint_of, strict=True)):
        mine = body_pieces(kind, size, placement)
        pieces += mine
        p_joint += [joint] * len(mine)
        p_body += [b] * len(mine)
        b_start.append(len(pieces))
        centre = np.mean([p.center for p in mine], axis=0)
        b_center.append(centre)
        b_radius.append(max(float(np.linalg.norm(p.center - centre)) + p.rb for p in mine))
    statics = static_shapes(model)
    cover_local, cover_r, cover_joint, cover_body = cover_points(statics, shaped, joint_of)
    cover_names = [STATIC_BODIES[-1 - b] if b < 0 else bodies[b] for b in cover_body]
    arm = (
        placements,
        np.array(p_joint, dtype=np.int64),
        np.array(p_body, dtype=np.int64),
        np.array([p.center for p in pieces]),
        np.array([p.axes for p in pieces]),
        np.array([p.half for p in pieces]),
        np.array([p.rc for p in pieces]),
        np.array([p.rs for p in pieces]),
        np.array([p.rb for p in pieces]),
        np.array(b_start, dtype=np.int64),
        np.array(joint_of, dtype=np.int64),
        np.array(b_center),
        np.array(b_radius),
        cover_joint,
        cover_body,
        cover_local,
        cover_r,
    )
    o_kind, o_R, o_t, o_s = primitive_arrays(found.prims)
    req = np.array([r for _, _, r in found.others]) + SLACK_M
    zones = model.keep_in_bodies
    zk, zR, zt, zs = primitive_arrays([z for _, z, _ in zones])
    holds = np.zeros((len(zones), len(cover_body)), dtype=np.bool_)
    for z, (_, _, members) in enumerate(zones):
        names = {model.shapes[i].name for i in members}
        holds[z] = [name in names for name in cover_names]
    z_req = np.array([c.required for c, _, _ in zones]) + SLACK_M
    moving = found.partner >= 0
    boxes = np.array([primitive_box(p) for p in found.prims]).reshape(-1, 2, 3)
    boxes[moving] = [np.full(3, -math.inf), np.full(3, math.inf)]  # placed per configuration
    local = np.array([np.eye(4) if m else np.zeros((4, 4)) for m in moving]).reshape(-1, 4, 4)
    for o in np.flatnonzero(moving):
        local[o] = found.prims[o].pose
    scene = (o_kind, o_R, o_t, o_s, req, found.applies, zk, zR, zt, zs, z_req, holds,
        boxes, found.partner, found.rigid, found.joint.astype(np.int64), local)  # fmt: skip
    return KernelArrays(arm, scene, [c for c, _, _ in zones], lever_table(model, arm, joint_of))
