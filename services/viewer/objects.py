"""The world model's objects as the viewer draws them (``planner/objects``, ``viz/objects``).

A free object is drawn where perception last saw it, in ``base_link`` (``mount⁻¹ ·
pose``, as the scene: :mod:`services.viewer.surroundings`); an object the arm holds
(attached to ``gripper_frame``) in the gripper frame at its pose there, frame-locked, so
it moves with the gripper as the guard and the planner count it. Colours: a free object
sand, a stale one grey (its last known pose), a held one green.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from manus.orientation import pose_matrix
from manus.scene import Primitive
from schemas.objects import WorldObject
from services.viewer.model import ROOT_FRAME
from services.viewer.surroundings import Drawn, primitive_solids

OBJECT_RGBA = {
    "free": (0.95, 0.78, 0.35, 0.9),
    "stale": (0.55, 0.55, 0.55, 0.5),
    "held": (0.30, 0.85, 0.45, 0.9),
}
"""Colour (r, g, b, a) of an object by its state."""


def drawn_objects(objects: Iterable[WorldObject], mount: np.ndarray) -> list[tuple[str, Drawn]]:
    """Each object (by id) as (frame it is drawn in, what is drawn); ``mount`` the arm's
    base in the chair frame, (4, 4)."""
    to_base = np.linalg.inv(mount)
    out = []
    for obj in sorted(objects, key=lambda o: o.id):
        state = "held" if obj.link else "stale" if obj.stale else "free"
        body = Primitive(
            obj.shape, tuple(obj.size), pose_matrix(obj.xyz, (obj.ypr[0], obj.ypr[1], obj.ypr[2]))
        )
        frame = obj.link or ROOT_FRAME
        solids = primitive_solids(body, np.eye(4) if obj.link else to_base, OBJECT_RGBA[state])
        meta = {
            "id": obj.id,
            "class": obj.cls,
            "shape": obj.shape,
            "state": state,
            "source": obj.source,
            "confidence": f"{obj.confidence:.2f}",
            "link": obj.link,
            "touch_links": ",".join(obj.touch_links),
            "touch_objects": ",".join(obj.touch_objects),
        }
        out.append((frame, Drawn(f"world/{obj.id}", solids, meta)))
    return out
