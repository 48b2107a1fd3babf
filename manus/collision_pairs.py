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

An object the arm holds (:class:`manus.held.HeldBody`, on joint 6) is a body of the arm
like the others, with its own rules: it keeps every scene object's class clearance but
its touch objects', every zone's (a gripper zone too: the gripper holds it), and the
``self`` clearance from every arm body but its touch links and :data:`HELD_UNJUDGED`.
Its pairs with arm bodies that move (the forearm, the wrist, the gripper's) are
*mutual* (:data:`Pairs.mutual`): both bodies move, so each may close only half of the
pair's margin (the per-body margins that bound travel count half of it for each); with
a body on its own joint (the gripper's) the distance never changes, so that pair bounds
no travel at all (it still counts in every configuration's margin).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

import coal
import numpy as np
import pinocchio as pin

from manus.clearance import Check
from manus.held import HeldBody
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

HELD_UNJUDGED = ("shoulder_offset", "upper_arm")
"""Arm bodies a held object is not checked against: like the gripper that holds it, it
folds beside them on the arm, in one plane with them in the DH model."""


class Pairs(NamedTuple):
    """The checks of a geometry model (:func:`build_pairs`).

    Attributes:
        pairs: (body, partner) geometry indices, one per check, the moving body first.
        checks: the checks, in the order of ``pairs``.
        static: (static body, scene object, check): checked once, at build time.
        keep_in: per keep-in zone: its check (no body named), the zone placed in the
            base frame, and the geometry indices of the bodies it must hold.
        mutual: the pairs (as in ``pairs``) of a held body with an arm body that moves,
            each with that arm body's index and whether it is on the held body's own
            joint (rigid: their distance never changes).
    """

    pairs: list[tuple[int, int]]
    checks: list[Check]
    static: list[tuple[int, int, Check]]
    keep_in: list[tuple[Check, Primitive, list[int]]]
    mutual: dict[tuple[int, int], tuple[int, bool]]


def build_pairs(
    gm: Any, shapes: list[Shape], scene: Scene | None, held: Sequence[HeldBody] = ()
) -> Pairs:
    """Add to ``gm`` (the bodies, named and ordered as ``shapes``: the arm's, then the
    held ones, ``held``) what the bodies are checked against, and return the checks.

    The scene's objects and keep-out zones become fixed bodies (placed through the
    mount, their clearance as swept-sphere radius); the self pairs' partners get
    inflated copies (the originals face the scene).
    """
    index = {s.name: i for i, s in enumerate(shapes)}
    out = Pairs([], [], [], [], {})
    required = scene.clearance["self"] if scene is not None else 0.01
    self_pairs = list(SELF_PAIRS)
    arm = [s.name for s in shapes[: len(shapes) - len(held)]]
    for body in held:
        unjudged = {*body.touch_links, *HELD_UNJUDGED}
        self_pairs += [(body.name, name) for name in arm if name not in unjudged]
    _self_pairs(gm, index, required, self_pairs, out)
    if scene is not None:
        _scene_pairs(gm, shapes, scene, {h.name: h for h in held}, out)
        _keep_in_zones(shapes, scene, {h.name for h in held}, out)
    return out


def _self_pairs(
    gm: Any, index: dict[str, int], required: float, pairs: list[tuple[str, str]], out: Pairs
) -> None:
    """``pairs`` (body, arm body), each against an inflated copy of its partner."""
    copies: dict[str, int] = {}
    for a, b in pairs:
        original = gm.geometryObjects[index[b]]
        if b not in copies:
            geometry = original.geometry.clone()
            geometry.setSweptSphereRadius(required)
            copies[b] = gm.addGeometryObject(
                pin.GeometryObject(f"{b}+self", original.parentJoint, original.placement, geometry)
            )
        out.pairs.append((index[a], copies[b]))
        out.checks.append(Check(a, b, "self", required))
        if b not in STATIC_BODIES:  # a held body and an arm body: both move
            rigid = gm.geometryObjects[index[a]].parentJoint == original.parentJoint
            out.mutual[out.pairs[-1]] = (index[b], rigid)


def _scene_pairs(
    gm: Any, shapes: list[Shape], scene: Scene, held: dict[str, HeldBody], out: Pairs
) -> None:
    """The scene's objects and keep-out zones as fixed bodies and their pairs with the
    arm's moving bodies and the held ones (but the objects they may touch); the static
    bodies' pairs go to ``out.static``."""
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
            holding = held.get(shape.name)
            if holding is not None and name in holding.touch_objects:
                continue
            if links == "gripper" and shape.name not in GRIPPER_BODIES and holding is None:
                continue
            check = Check(shape.name, name, cls, required)
            if shape.name in STATIC_BODIES:
                out.static.append((i, partner, check))
            else:
                out.pairs.append((i, partner))
                out.checks.append(check)


def _keep_in_zones(shapes: list[Shape], scene: Scene, held: set[str], out: Pairs) -> None:
    """Each keep-in zone and the bodies it must hold (a held one in every zone)."""
    to_base = np.linalg.inv(scene.mount)
    for zone in scene.zones:
        if zone.kind == "keep_in":
            bodies = [
                i
                for i, body in enumerate(shapes)
                if zone.links == "all" or body.name in GRIPPER_BODIES or body.name in held
            ]
            check = Check("", f"keep_in {zone.name}", "zone", zone.clearance)
            body = Primitive(zone.body.shape, zone.body.size, to_base @ zone.body.pose)
            out.keep_in.append((check, body, bodies))


def base_overlaps(gm: Any, static: list[tuple[int, int, Check]], scene: Scene | None) -> list[str]:
    """The scene objects of ``static`` (:attr:`Pairs.static`, in the geometry model
    ``gm``) that touch the arm's fixed base (column, shoulder), one line each."""
    out = []
    for i, j, check in static:
        body, other = gm.geometryObjects[i], gm.geometryObjects[j]
        distance = coal.distance(
            body.geometry,
            coal.Transform3s(body.placement.rotation, body.placement.translation),
            other.geometry,
            coal.Transform3s(other.placement.rotation, other.placement.translation),
            coal.DistanceRequest(),
            coal.DistanceResult(),
        )
        distance += check.required  # the object carries its clearance
        if distance <= 0.0:
            line = next((o.line for o in scene.objects if o.name == check.other), 0) if scene else 0
            where = scene.where(line) if scene is not None else ""
            out.append(
                f"{where}: objects.{check.other}: overlaps the arm's {check.body} (its "
                f"base, at the mount) by {-distance * 1e3:.1f} mm: move the object or the mount"
            )
    return out
