"""Which distances the arm's collision model watches: its bodies and what each must keep
clear of, as the pairs of one Pinocchio geometry model.

Every check is one :class:`manus.clearance.Check`: an arm body, what it is checked
against, the class (``person``, ``chair``, ``environment``, ``self`` or ``zone``) and
the clearance that class requires. Each class's clearance is baked into the partner as
Coal's swept-sphere radius, so a pair's distance is its margin (distance minus
clearance) and the smallest distance of a geometry model is its tightest check.

Self-collision pairs are declared once, in :data:`SELF_PAIRS`: the gripper, its motor,
the wrist and the forearm against the arm's base (column and shoulder). Adjacent bodies
are excluded, and so is everything between the upper arm and the forearm-wrist-gripper
chain: the DH model puts them in one plane (folded, on one line), while on the arm the
forearm and the gripper fold beside the upper arm, so their distance in this model says
nothing about the arm. The ``column`` and the ``shoulder`` do not move (the shoulder
turns about its own axis), so their distances to the scene are checked once, when the
model is built (:data:`Pairs.static`), not per configuration.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np
import pinocchio as pin

from manus.clearance import Check
from manus.scene import Primitive, Scene
from manus.shapes import coal_shape
from manus.urdf import Shape

SELF_PAIRS: tuple[tuple[str, str], ...] = (
    ("gripper", "column"),
    ("gripper", "shoulder"),
    ("gripper_motor", "column"),
    ("gripper_motor", "shoulder"),
    ("wrist", "column"),
    ("forearm", "column"),
)
"""Self-collision pairs (arm body, arm body), the only place they are declared."""

GRIPPER_BODIES = ("gripper", "gripper_motor")
"""The bodies a zone with ``links: gripper`` applies to."""

STATIC_BODIES = ("column", "shoulder")
"""Bodies whose distance to the scene does not depend on the joint angles."""


class Pairs(NamedTuple):
    """The checks of a geometry model (:func:`build_pairs`).

    Attributes:
        pairs: (body, partner) geometry indices, one per check, the moving body first.
        checks: the checks, in the order of ``pairs``.
        static: (static body, scene object, check): checked once, at build time.
        keep_in: per keep-in zone: its check (no body named), the zone placed in the
            base frame, and the geometry indices of the bodies it must hold.
    """

    pairs: list[tuple[int, int]]
    checks: list[Check]
    static: list[tuple[int, int, Check]]
    keep_in: list[tuple[Check, Primitive, list[int]]]


def build_pairs(gm: Any, shapes: list[Shape], scene: Scene | None) -> Pairs:
    """Add to ``gm`` (the arm's bodies, named and ordered as ``shapes``) what the bodies
    are checked against, and return the checks.

    The scene's objects and keep-out zones become fixed bodies (placed through the
    mount, their clearance as swept-sphere radius); the self pairs' partners get
    inflated copies (the originals face the scene).
    """
    index = {s.name: i for i, s in enumerate(shapes)}
    out = Pairs([], [], [], [])
    _self_pairs(gm, index, scene.clearance["self"] if scene is not None else 0.01, out)
    if scene is not None:
        _scene_pairs(gm, shapes, scene, out)
        _keep_in_zones(shapes, scene, out)
    return out


def _self_pairs(gm: Any, index: dict[str, int], required: float, out: Pairs) -> None:
    """The pairs of :data:`SELF_PAIRS`, each against an inflated copy of its partner."""
    copies: dict[str, int] = {}
    for a, b in SELF_PAIRS:
        if b not in copies:
            original = gm.geometryObjects[index[b]]
            geometry = original.geometry.clone()
            geometry.setSweptSphereRadius(required)
            copies[b] = gm.addGeometryObject(
                pin.GeometryObject(f"{b}+self", original.parentJoint, original.placement, geometry)
            )
        out.pairs.append((index[a], copies[b]))
        out.checks.append(Check(a, b, "self", required))


def _scene_pairs(gm: Any, shapes: list[Shape], scene: Scene, out: Pairs) -> None:
    """The scene's objects and keep-out zones as fixed bodies and their pairs with the
    arm's moving bodies; the static bodies' pairs go to ``out.static``."""
    to_base = np.linalg.inv(scene.mount)
    fixed = [(o.name, o.cls, o.body, scene.clearance[o.cls], "all") for o in scene.objects]
    fixed += [
        (z.name, "zone", z.body, z.clearance, z.links) for z in scene.zones if z.kind == "keep_out"
    ]
    for name, cls, body, required, links in fixed:
        geometry, pose = coal_shape(body)
        geometry.setSweptSphereRadius(required)
        placement = pin.SE3(to_base @ pose)
        partner = gm.addGeometryObject(pin.GeometryObject(name, 0, placement, geometry))
        for i, shape in enumerate(shapes):
            if links == "gripper" and shape.name not in GRIPPER_BODIES:
                continue
            check = Check(shape.name, name, cls, required)
            if shape.name in STATIC_BODIES:
                out.static.append((i, partner, check))
            else:
                out.pairs.append((i, partner))
                out.checks.append(check)


def _keep_in_zones(shapes: list[Shape], scene: Scene, out: Pairs) -> None:
    to_base = np.linalg.inv(scene.mount)
    for zone in scene.zones:
        if zone.kind == "keep_in":
            bodies = [
                i
                for i, arm_body in enumerate(shapes)
                if zone.links == "all" or arm_body.name in GRIPPER_BODIES
            ]
            check = Check("", f"keep_in {zone.name}", "zone", zone.clearance)
            body = Primitive(zone.body.shape, zone.body.size, to_base @ zone.body.pose)
            out.keep_in.append((check, body, bodies))
