"""The simulator's objects over time: resting, held by the gripper, falling, touching.

Each tick (after the arm's step, :meth:`ObjectWorld.tick`), on the true arm:

1. a held object follows the gripper (its pose in the gripper frame is kept); when the
   jaws open wider than its width plus ``RELEASE_MARGIN`` it is released where it is;
2. a released object falls straight down (``G``) onto the highest surface under its
   centre (:mod:`.supports`) and comes to rest there upright, its yaw kept;
3. a closing finger that reaches a standing object first pushes it along its surface;
   jaws that close past the width of an object between them (:mod:`.grasp`) hold it when
   the grasp is within ``grasp_tolerance_mm``, from then on the jaws stay at its width
   (:attr:`ObjectWorld.gripper_floor_mm`, which the arm's gripper obeys), or it slips;
4. contacts are recorded (:mod:`.object_contacts`); nothing is computed on a tick on
   which nothing moved.

Poses between ticks (:meth:`ObjectWorld.pose_at`) follow from the state: a held object
from the gripper's pose, a falling one from its release time. No randomness.
"""

from __future__ import annotations

import numpy as np

from manus.errors import ConfigError
from manus.orientation import matrix_to_ypr
from manus.scene import Scene
from schemas.objects import ObjectTruth
from services.simulator.arm_bodies import ArmBodies, Body
from services.simulator.config import SimConfig
from services.simulator.contact import Distance
from services.simulator.grasp import between_jaws, holds, pushed
from services.simulator.object_contacts import ObjectContacts
from services.simulator.objects import FALLING, HELD, RESTING, SimObject, load_objects, upright
from services.simulator.supports import Supports

G = 9.81
"""Gravity [m/s^2]."""
RELEASE_MARGIN = 0.002
"""Jaws opened this much wider than a held object's width let it go [m]."""


class ObjectWorld:
    """The objects of one simulator (see the module docstring).

    Args:
        config: the simulator's configuration (``objects``, ``grasp_tolerance_mm``).
        scene: the scene it reads (surfaces, contacts; None: the floor alone).

    Raises:
        SceneError: the objects file is bad.
        ConfigError: two objects share an id.
    """

    def __init__(self, config: SimConfig, scene: Scene | None) -> None:
        self.mount = scene.mount if scene is not None else np.eye(4)
        self.supports = Supports(scene)
        self.bodies = ArmBodies(config.arm, self.mount)
        self.contacts = ObjectContacts(scene)
        self.tolerance = config.grasp_tolerance_mm * 1e-3
        self.objects: list[SimObject] = []
        self._held: SimObject | None = None
        self._width = 0.0
        self._opening: float | None = None
        self._key = b""
        for obj in load_objects(config.objects):
            self.add(obj)

    # -- run-time changes ----------------------------------------------------------------------

    def add(self, obj: SimObject) -> None:
        """Put ``obj`` in the world, at rest on the highest surface under its centre.

        Raises:
            ConfigError: its id is taken.
        """
        if any(o.id == obj.id for o in self.objects):
            raise ConfigError(f"object {obj.id!r}: an object with that id is already there")
        self._rest(obj, obj.pose)
        self.objects.append(obj)
        self._key = b""

    def remove(self, object_id: str) -> None:
        """Take object ``object_id`` out of the world (held: out of the jaws too).

        Raises:
            ConfigError: no such object.
        """
        obj = self.get(object_id)
        if obj is self._held:
            self._held, self._width = None, 0.0
        self.objects.remove(obj)
        self._key = b""

    def get(self, object_id: str) -> SimObject:
        """The object called ``object_id``.

        Raises:
            ConfigError: none is.
        """
        for obj in self.objects:
            if obj.id == object_id:
                return obj
        known = ", ".join(o.id for o in self.objects) or "none"
        raise ConfigError(f"no object {object_id!r} in the simulator (objects: {known})")

    # -- the timeline --------------------------------------------------------------------------

    @property
    def gripper_floor_mm(self) -> float:
        """The jaws cannot close below this: the held object's width [mm] (0: none held)."""
        return self._width * 1e3 if self._held is not None else 0.0

    def tick(self, t_ns: int, q_deg: np.ndarray, opening_mm: float) -> None:
        """One tick at ``t_ns`` with the true arm at DH angles ``q_deg`` [deg] and the jaws
        ``opening_mm`` [mm] apart (see the module docstring)."""
        if not self.objects:
            return
        opening = opening_mm * 1e-3
        before = opening if self._opening is None else self._opening
        self._opening = opening
        bodies, gripper = self.bodies.place(np.radians(q_deg), opening)
        held = self._held
        if held is not None and opening > self._width + RELEASE_MARGIN:
            self._release(held, gripper @ held.grip, t_ns)
        for obj in self.objects:
            if obj.state == FALLING and self.pose_at(obj, t_ns, gripper)[2, 3] <= self._rest_z(obj):
                self._rest(obj, obj.pose)
        if self._held is None and opening < before:
            self._close(t_ns, gripper, before, opening)
        key = np.radians(q_deg).tobytes() + np.float64(opening).tobytes()
        if key == self._key and not any(o.state == FALLING for o in self.objects):
            self.contacts.again()
            return
        self._key = key
        self._contacts(t_ns, bodies, gripper)

    def held_distance(self, q_deg: np.ndarray, opening_mm: float) -> Distance | None:
        """The held object's smallest true distance to the scene with the arm at
        ``q_deg`` [deg] and the jaws ``opening_mm`` [mm] apart (None: nothing held):
        :attr:`services.simulator.arm.ArmModel.held`, so that it meets the scene as the
        arm's bodies do."""
        held = self._held
        if held is None:
            return None
        _, gripper = self.bodies.place(np.radians(q_deg), opening_mm * 1e-3)
        return self.contacts.scene_distance(held, gripper @ held.grip)

    def blocked(self, t_ns: int, pair: str) -> None:
        """The arm stopped at ``t_ns`` on a contact ``pair`` (``body/object``): recorded
        among the objects' contacts when the held object made it."""
        if self._held is not None and pair.startswith(f"{self._held.id}/"):
            self.contacts.blocked(t_ns, pair)

    def pose_at(self, obj: SimObject, t_ns: int, gripper: np.ndarray) -> np.ndarray:
        """Where ``obj`` is at ``t_ns`` (at or after its last change) with the gripper at
        ``gripper`` (chair frame), (4, 4)."""
        if obj.state == HELD:
            return np.asarray(gripper @ obj.grip)
        if obj.state == RESTING:
            return obj.pose
        dt = max(0.0, (t_ns - obj.fall_ns) * 1e-9)
        pose = obj.pose.copy()
        pose[2, 3] = max(float(obj.pose[2, 3]) - 0.5 * G * dt * dt, self._rest_z(obj))
        return pose

    def truth(self, t_ns: int, q_deg: np.ndarray, opening_mm: float) -> list[ObjectTruth]:
        """Every object as it truly is at ``t_ns`` (the arm at ``q_deg`` [deg], the jaws
        ``opening_mm`` [mm] apart)."""
        if not self.objects:
            return []
        _, gripper = self.bodies.place(np.radians(q_deg), opening_mm * 1e-3)
        out = []
        for obj in self.objects:
            pose = self.pose_at(obj, t_ns, gripper)
            out.append(
                ObjectTruth(
                    id=obj.id,
                    cls=obj.cls,
                    shape=obj.shape,
                    size=list(obj.size),
                    xyz=[float(v) for v in pose[:3, 3]],
                    ypr=[float(v) for v in matrix_to_ypr(pose[:3, :3])],
                    held=obj.state == HELD,
                    resting_on=obj.support if obj.state == RESTING else "",
                    slips=obj.slips,
                )
            )
        return out

    def placed(
        self, t_ns: int, q_deg: np.ndarray, opening_mm: float
    ) -> tuple[list[Body], list[np.ndarray]]:
        """The arm's bodies and every object's pose at ``t_ns`` (chair frame)."""
        bodies, gripper = self.bodies.place(np.radians(q_deg), opening_mm * 1e-3)
        return bodies, [self.pose_at(o, t_ns, gripper) for o in self.objects]

    # -- state changes -------------------------------------------------------------------------

    def _rest_z(self, obj: SimObject) -> float:
        return self.supports.named(obj.support).top + obj.half_height

    def _rest(self, obj: SimObject, pose: np.ndarray) -> None:
        x, y, z = (float(v) for v in pose[:3, 3])
        surface = self.supports.below(x, y, z)
        obj.pose = upright(pose)
        obj.pose[2, 3] = surface.top + obj.half_height
        obj.state, obj.support = RESTING, surface.name

    def _release(self, obj: SimObject, pose: np.ndarray, t_ns: int) -> None:
        self._held, self._width = None, 0.0
        x, y, z = (float(v) for v in pose[:3, 3])
        obj.support = self.supports.below(x, y, z).name
        obj.pose, obj.state, obj.fall_ns = pose, FALLING, t_ns
        if z <= self._rest_z(obj):
            self._rest(obj, pose)

    def _close(self, t_ns: int, gripper: np.ndarray, before: float, opening: float) -> None:
        """Jaws closed from ``before`` to ``opening`` [m]: the first object whose width
        they passed is held, or slips."""
        for obj in self.objects:
            contact = between_jaws(obj, self.pose_at(obj, t_ns, gripper), gripper, before)
            if contact is not None and obj.state == RESTING:  # a finger may push it first
                moved = pushed(obj.pose, gripper, opening, contact.width)
                if moved is not None:
                    obj.pose = moved
                    contact = between_jaws(obj, moved, gripper, before)
            if contact is None or not opening <= contact.width < before:
                continue  # not between the jaws, or not reached in this tick
            if holds(contact, self.tolerance):
                obj.state, obj.grip, obj.support = HELD, contact.grip, ""
                self._held, self._width = obj, contact.width
            else:
                obj.slips += 1
            return

    def _contacts(self, t_ns: int, bodies: list[Body], gripper: np.ndarray) -> None:
        poses = [self.pose_at(o, t_ns, gripper) for o in self.objects]
        self.contacts.update(t_ns, bodies, self.objects, poses)
