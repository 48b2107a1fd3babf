"""Where a follow goal's tracked point may go: the scene's persons, zones and frames, as
the follow source sees them (plain floats: this runs every cycle).

- **Frames**: a target given in the chair frame is brought into the arm's base frame
  through the scene's mount (no scene: only base-frame targets can be followed).
- **Persons**: the tracked point's distance to the nearest person object (the body the
  target moves with where the tracker last put it), for the speed profile and for the
  clearance the standoff point keeps. Boxes are measured by their largest axis excess, an
  underestimate outside a corner: the profile slows a little early there, never late.
- **Zones**: a standoff point inside a keep-out zone, or outside the keep-in workspace,
  by less than the zone's clearance, is refused (``keep_out``).
- **Reach**: the standoff point's wrist centre must lie within the stretched arm's
  reach, short of ``reach_margin_deg`` of a straight elbow (``out_of_reach``).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.config import ArmConfig
from manus.kinematics import Rot, Vec3
from manus.scene import Scene

_IDENTITY = np.eye(4)


class Solid(NamedTuple):
    """A primitive in the base frame, as plain floats.

    Attributes:
        name: the scene object or zone.
        shape: box, sphere, cylinder, capsule (a plane: a half-space, its normal in
            ``size``).
        size: as :class:`manus.scene.Primitive` [m].
        origin: its centre [m].
        axes: its rotation, row by row.
        margin: a zone's clearance [m] (0 for objects).
    """

    name: str
    shape: str
    size: tuple[float, ...]
    origin: Vec3
    axes: Rot
    margin: float = 0.0


def _solid(
    name: str, shape: str, size: tuple[float, ...], pose: np.ndarray, margin: float
) -> Solid:
    r = [float(v) for v in pose[:3, :3].ravel()]
    rows = (r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8])
    o = pose[:3, 3]
    return Solid(name, shape, size, (float(o[0]), float(o[1]), float(o[2])), rows, margin)


def inside(solid: Solid, p: Vec3) -> float:
    """How deep ``p`` is inside ``solid`` [m]: its distance to the boundary inside,
    negative outside (a box's largest axis excess; exact for the others)."""
    dx, dy, dz = p[0] - solid.origin[0], p[1] - solid.origin[1], p[2] - solid.origin[2]
    a = solid.axes
    x = a[0] * dx + a[3] * dy + a[6] * dz
    y = a[1] * dx + a[4] * dy + a[7] * dz
    z = a[2] * dx + a[5] * dy + a[8] * dz
    s = solid.size
    if solid.shape == "box":
        return min(s[0] / 2.0 - abs(x), s[1] / 2.0 - abs(y), s[2] / 2.0 - abs(z))
    if solid.shape == "sphere":
        return s[0] - math.sqrt(x * x + y * y + z * z)
    if solid.shape == "cylinder":
        return min(s[0] - math.hypot(x, y), s[1] / 2.0 - abs(z))
    if solid.shape == "capsule":
        along = z - max(-s[1] / 2.0, min(s[1] / 2.0, z))
        return s[0] - math.sqrt(x * x + y * y + along * along)
    # a half-space: normal in size, through the origin (the solid side below it)
    return -(s[0] * dx + s[1] * dy + s[2] * dz)


class FollowSpace:
    """The scene as the follow source sees it (see the module docstring).

    Args:
        scene: the scene the collision guard uses (None: none).
        arm: the arm's geometry.
    """

    def __init__(self, scene: Scene | None, arm: ArmConfig) -> None:
        self.arm = arm
        self.to_base = _IDENTITY if scene is None else np.linalg.inv(scene.mount)
        self.has_scene = scene is not None
        self.person_clearance = scene.clearance["person"] if scene is not None else 0.0
        self.persons: dict[str, Solid] = {}
        self.zones: list[tuple[str, Solid]] = []
        if scene is None:
            return
        for obj in scene.objects:
            if obj.cls == "person":
                body = obj.body
                pose = self.to_base @ body.pose
                self.persons[obj.name] = _solid(obj.name, body.shape, body.size, pose, 0.0)
        for zone in scene.zones:
            pose = self.to_base @ zone.body.pose
            solid = _solid(zone.name, zone.body.shape, zone.body.size, pose, zone.clearance)
            self.zones.append((zone.kind, solid))

    def point_to_base(self, xyz: list[float] | Vec3, frame: str) -> Vec3:
        """A point of ``frame`` (``chair`` or ``base``) in the base frame [m]."""
        if frame == "base":
            return float(xyz[0]), float(xyz[1]), float(xyz[2])
        T = self.to_base
        x, y, z = xyz
        return (
            float(T[0, 0] * x + T[0, 1] * y + T[0, 2] * z + T[0, 3]),
            float(T[1, 0] * x + T[1, 1] * y + T[1, 2] * z + T[1, 3]),
            float(T[2, 0] * x + T[2, 1] * y + T[2, 2] * z + T[2, 3]),
        )

    def rotation_to_base(self, R: np.ndarray, frame: str) -> np.ndarray:
        """A rotation of ``frame`` in the base frame, (3, 3)."""
        return R if frame == "base" else np.asarray(self.to_base[:3, :3] @ R)

    def pose_to_chair(self, pose_base: np.ndarray) -> np.ndarray:
        """A base-frame pose in the chair frame (what the collision model is given)."""
        return np.asarray(np.linalg.solve(self.to_base, pose_base))

    def move_person(self, name: str, pose_base: np.ndarray) -> None:
        """The person object ``name`` is now at ``pose_base`` (4x4)."""
        old = self.persons[name]
        self.persons[name] = _solid(name, old.shape, old.size, pose_base, 0.0)

    def person_distance(self, p: Vec3) -> tuple[float, str]:
        """The distance of ``p`` to the nearest person object [m] and its name (inf, ''
        without persons)."""
        best, name = math.inf, ""
        for solid in self.persons.values():
            d = -inside(solid, p)
            if d < best:
                best, name = d, solid.name
        return best, name

    def zone_breach(self, p: Vec3) -> str | None:
        """Why ``p`` may not be a standoff point (a keep-out zone, outside the workspace),
        None: it may."""
        for kind, solid in self.zones:
            depth = inside(solid, p)
            if kind == "keep_out" and depth > -solid.margin:
                return f"in the keep-out zone {solid.name!r} ({depth * 1e3:.0f} mm inside)"
            if kind == "keep_in" and depth < solid.margin:
                return f"outside the workspace {solid.name!r} ({-depth * 1e3:.0f} mm out)"
        return None

    def reach_breach(self, wrist: Vec3, margin_deg: float) -> str | None:
        """Why the wrist centre ``wrist`` [m] is out of reach (None: it is within)."""
        cfg = self.arm
        rho2 = wrist[0] * wrist[0] + wrist[1] * wrist[1]
        if rho2 < cfg.l1 * cfg.l1:
            return "the wrist centre would be inside the shoulder's offset from the base axis"
        reach2 = rho2 - cfg.l1 * cfg.l1 + wrist[2] * wrist[2]
        most = (
            cfg.l2 * cfg.l2
            + cfg.l3 * cfg.l3
            + 2.0 * cfg.l2 * cfg.l3 * math.cos(math.radians(margin_deg))
        )
        if reach2 <= most:
            return None
        return (
            f"the wrist centre {math.sqrt(reach2) * 1e3:.0f} mm from the shoulder, beyond "
            f"{math.sqrt(most) * 1e3:.0f} mm (the elbow {margin_deg:g} deg short of straight)"
        )
