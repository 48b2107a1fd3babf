"""The stages of the pick, place and give steps (docs/pick.md): what the arm does, in
order, as motions for the reach planner (goals and straight lines), gripper openings
and attach requests. Pure functions of what the sequencer knows (:class:`ObjectView`):
the validation plans these stages before anything moves, the running step
(:mod:`services.sequencer.object_step`) runs them, both from the same code.

Every problem is a sentence naming the object and the reason (:class:`ObjectProblem`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from manus.config import ArmConfig
from manus.grasp_poses import Grasp, blocked_by, extent_along, grasps_of, object_pose
from manus.grasps import GraspClass, GraspError, grasp_class
from manus.kinematics import fk
from manus.orientation import matrix_to_ypr, rot_z
from manus.scene import Scene
from schemas.goals import LineFrame, LineMotion, PoseGoal
from schemas.motion import Motion
from schemas.objects import WorldObject
from services.sequencer.pick_config import PickConfig

MAX_OPENING_M = 0.090
"""The gripper's widest opening [m]."""

SURFACE_GAP_M = 0.015
"""An object rests on a surface whose top is within this of its bottom [m] (perception's
noise puts it a little above or below)."""


class ObjectProblem(Exception):  # noqa: N818 (a reason, not a fault: it is reported)
    """Why an object task cannot be done: the object and the reason, in words."""


@dataclass(frozen=True)
class ObjectView:
    """What the sequencer knows when it plans an object task.

    Attributes:
        objects: the world model's objects, by id (as the planner publishes them).
        scene: the scene in use (None: none; the base frame is then the chair frame).
        arm: the arm's geometry.
        grasps: how each class is grasped.
        config: the pick settings.
        now_ns: the sequencer's time [ns].
        stale_after_s: the world model's staleness limit [s].
        world_ns: the world model's newest update's stamp (its newest camera frame) [ns].
        origins: where this task's picks took each object from, by id: its centre and yaw
            as the pick saw it, (x, y, z [m], yaw, 0, 0 [rad]); a pick records it here.
    """

    objects: dict[str, WorldObject]
    scene: Scene | None
    arm: ArmConfig
    grasps: dict[str, GraspClass]
    config: PickConfig
    now_ns: int
    stale_after_s: float
    world_ns: int
    origins: dict[str, list[float]] = field(default_factory=dict)

    @property
    def mount(self) -> np.ndarray:
        """The arm's base frame in the chair frame, (4, 4)."""
        return self.scene.mount if self.scene is not None else np.eye(4)

    def gripper(self, q: np.ndarray) -> np.ndarray:
        """The gripper pose at ``q`` [rad] in the chair frame, (4, 4)."""
        return np.asarray(self.mount @ fk(q, self.arm))

    def in_base(self, T: np.ndarray) -> np.ndarray:
        """A chair-frame pose in the base frame."""
        return np.asarray(np.linalg.solve(self.mount, T))

    def lost_limit_s(self) -> float:
        """How long the world model may go without an update before perception counts
        as lost [s]."""
        return self.config.lost_s or self.stale_after_s or 2.0

    def find(self, object_id: str) -> WorldObject:
        """The object ``object_id``.

        Raises:
            ObjectProblem: unknown (the known ones listed).
        """
        obj = self.objects.get(object_id)
        if obj is None:
            known = ", ".join(sorted(self.objects)) or "none: nothing has been perceived"
            raise ObjectProblem(f"unknown object {object_id!r} (the world model holds: {known})")
        return obj

    def how(self, obj: WorldObject) -> GraspClass:
        """How ``obj`` is grasped.

        Raises:
            ObjectProblem: its class has no grasps.
        """
        try:
            return grasp_class(self.grasps, obj.cls, obj.id)
        except GraspError as exc:
            raise ObjectProblem(str(exc)) from exc

    def age_s(self, obj: WorldObject) -> float:
        """Time since ``obj`` was last observed [s]."""
        return max(0.0, (self.now_ns - obj.stamp_ns) / 1e9)

    def check_fresh(self, obj: WorldObject, when: str) -> None:
        """Raises:
        ObjectProblem: perception lost (no update of the world model for longer than
            :meth:`lost_limit_s`), or ``obj`` not observed for longer than
            ``pick.hidden_s``."""
        quiet, lost = max(0.0, (self.now_ns - self.world_ns) / 1e9), self.lost_limit_s()
        if quiet > lost:
            raise ObjectProblem(
                f"object {obj.id!r} ({obj.cls}) {when}: perception lost: no update of the "
                f"world model for {quiet:.1f} s (limit {lost:g} s)"
            )
        age, hidden = self.age_s(obj), self.config.hidden_s
        if not obj.link and age > hidden:
            raise ObjectProblem(
                f"object {obj.id!r} ({obj.cls}) {when}: not seen for {age:.1f} s (last by "
                f"{obj.source}; limit {hidden:g} s): it is hidden, or gone"
            )


MotionOf = Callable[[np.ndarray], Motion]
"""A stage's motion from the arm's configuration at its start [rad]."""


@dataclass(frozen=True)
class Stage:
    """One thing the arm does in an object task.

    Attributes:
        label: its name in messages (``approach``).
        motion: a motion of the reach planner, built from where the stage starts.
        opening: a gripper opening [m] (with ``motion`` None and ``attach`` None).
        tolerance: the gripper's tolerance [m].
        holds: close on an object this wide [m]: the jaws stop at its width, short of
            ``opening``, which they must not reach (they would have closed past it: the
            grasp slipped); 0: an opening to reach.
        attach: ``gripper_frame``: attach the object; ``""``: detach it; None: no attach.
        touch_objects: scene objects the attached object may touch.
        upright: attach the object upright (its axis along the chair's z at the grasp).
        carrying: the object is held: the motion's tilt is checked.
        watch: the object is watched (moved, perception lost) while this stage runs.
        retry: a refused or too tight plan of this stage moves on to the next candidate
            (grasp, or yaw at a place).
        search: the motion is a search to a pose (the pre-grasp): the object must stay in
            perception's sight all along (a straight approach hides it behind the gripper:
            it must be seen only when the approach begins).
        aim: the straight approach: when it runs, it is aimed at the object's position
            averaged over perception's recent sightings (a line from where the pre-grasp
            left the gripper to the grasp there).
        reach_tolerance: a motion that ends (aborted by the controller) at most this far
            from its end counts as done [m] (0: the trajectory goal's own 2 mm).
        onto: the surface the held object is lowered onto: its clearance to it is not
            judged for spare (it is meant to come close).
        raised: the motion the validation plans instead when the object is held already
            (the planner knows the surface as a touch object only once the stage before
            attached it): the same, stopping just outside the surface's clearance.
    """

    label: str
    motion: MotionOf | None = None
    opening: float = 0.0
    tolerance: float = 0.001
    holds: float = 0.0
    attach: str | None = None
    touch_objects: tuple[str, ...] = ()
    upright: bool = False
    carrying: bool = False
    watch: bool = False
    retry: bool = False
    search: bool = False
    aim: bool = False
    reach_tolerance: float = 0.0
    onto: str = ""
    raised: MotionOf | None = None


def pose_goal(view: ObjectView, T: np.ndarray) -> MotionOf:
    """A search to the chair-frame gripper pose ``T``, exactly."""
    Tb = view.in_base(T)
    xyz, ypr = [float(v) for v in Tb[:3, 3]], [float(v) for v in matrix_to_ypr(Tb[:3, :3])]
    return lambda q: PoseGoal(xyz=xyz, ypr=ypr)


def line_to(view: ObjectView, T: np.ndarray, speed: float = 0.5) -> MotionOf:
    """A straight line to the chair-frame gripper pose ``T``."""
    Tb = view.in_base(T)
    xyz, ypr = [float(v) for v in Tb[:3, 3]], [float(v) for v in matrix_to_ypr(Tb[:3, :3])]
    return lambda q: LineMotion(xyz=xyz, ypr=ypr, frame=LineFrame.BASE, speed=speed)


APPROACH_TOLERANCE_M = 0.005
"""The approach may end this far short of the grasp [m] (the controller slowing close to
the table): the jaws hold an object whose centre is within 15 mm of the grasp point."""

NEAR_SPEED = 0.2
"""The speed of lines near a surface (fraction of the line's top speed, 200 mm/s): the
guard judges the clearance ahead at the commanded speed, and the approach runs close."""


def line_tool(dz: float, speed: float = NEAR_SPEED) -> MotionOf:
    """A straight line along the gripper's own axis by ``dz`` [m] (negative: back)."""
    return lambda q: LineMotion(xyz=[0.0, 0.0, dz], frame=LineFrame.TOOL, speed=speed)


def line_up(view: ObjectView, dz: float) -> MotionOf:
    """A straight line up (chair z) by ``dz`` [m], the orientation kept."""

    def motion(q: np.ndarray) -> Motion:
        T = view.gripper(q)
        T[2, 3] += dz
        Tb = view.in_base(T)
        return LineMotion(xyz=[float(v) for v in Tb[:3, 3]], frame=LineFrame.BASE, speed=NEAR_SPEED)

    return motion


def line_toward(view: ObjectView, point: np.ndarray, length: float) -> MotionOf:
    """A straight horizontal line by ``length`` [m] toward the chair-frame ``point``
    (the shoulder: a retreat that stays within reach), the orientation kept."""

    def motion(q: np.ndarray) -> Motion:
        T = view.gripper(q)
        d = point[:2] - T[:2, 3]
        T[:2, 3] += length * d / max(float(np.linalg.norm(d)), 1e-9)
        Tb = view.in_base(T)
        return LineMotion(xyz=[float(v) for v in Tb[:3, 3]], frame=LineFrame.BASE, speed=NEAR_SPEED)

    return motion


def surface_under(scene: Scene | None, obj: WorldObject, bottom: float) -> str:
    """The scene object whose top ``obj`` (bottom at ``bottom`` [m]) rests on ('' none)."""
    if scene is None:
        return ""
    x, y = obj.xyz[0], obj.xyz[1]
    best, best_top = "", -math.inf
    for s in scene.objects:
        top = surface_top(s.body.shape, s.body.size, s.body.pose, x, y)
        if top is not None and abs(top - bottom) <= SURFACE_GAP_M and top > best_top:
            best, best_top = s.name, top
    return best


def surface_top(
    shape: str, size: tuple[float, ...], pose: np.ndarray, x: float, y: float
) -> float | None:
    """The top of an upright box or cylinder at (x, y), chair frame [m] (None: not there)."""
    if abs(pose[2, 2]) < 0.999:
        return None  # not upright
    local = np.linalg.solve(pose, np.array([x, y, pose[2, 3], 1.0]))
    if shape == "box":
        if abs(local[0]) <= size[0] / 2 and abs(local[1]) <= size[1] / 2:
            return float(pose[2, 3] + size[2] / 2)
    elif shape == "cylinder" and math.hypot(local[0], local[1]) <= size[0]:
        return float(pose[2, 3] + size[1] / 2)
    return None


def half_height(obj: WorldObject) -> float:
    """Half the object's height standing upright [m] (perception's noisy lean left out)."""
    upright = replace(obj, ypr=[obj.ypr[0], 0.0, 0.0])
    return 0.5 * extent_along(upright, np.array([0.0, 0.0, 1.0]))


# -- pick ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PickPlan:
    """A pick of one object: its candidate grasps and what they are set aside for.

    Attributes:
        obj: the object (as perception last saw it).
        how: its class's grasps.
        grasps: the candidates, preferred first.
        surface: the scene object it stands on ('': none found).
    """

    obj: WorldObject
    how: GraspClass
    grasps: tuple[Grasp, ...]
    surface: str


def pick_plan(view: ObjectView, object_id: str) -> PickPlan:
    """The candidate grasps of ``object_id`` as it is now.

    Raises:
        ObjectProblem: unknown, held already, perception lost, no grasps for its class,
            wider than the gripper.
    """
    obj = view.find(object_id)
    if obj.link:
        raise ObjectProblem(f"object {object_id!r} is held already (attached to {obj.link})")
    view.check_fresh(obj, "cannot be picked")
    how = view.how(obj)
    candidates = grasps_of(obj, how, view.mount[:3, 3])
    narrow = [g for g in candidates if g.width + 0.002 <= MAX_OPENING_M]
    if not narrow:
        width = min(g.width for g in candidates) * 1e3
        raise ObjectProblem(
            f"object {object_id!r} ({obj.cls}) is {width:.0f} mm wide where it would be "
            f"grasped: wider than the gripper opens ({MAX_OPENING_M * 1e3:.0f} mm)"
        )
    _check_reach(view, obj, narrow)
    others = [o for o in view.objects.values() if o.id != obj.id and not o.link]
    blocked = {g.label: blocked_by(g, others) for g in narrow}
    clear = [g for g in narrow if not blocked[g.label]]
    if not clear:
        tried = "; ".join(f"{label}: object {b!r} in the way" for label, b in blocked.items())
        raise ObjectProblem(
            f"every grasp pose of object {object_id!r} ({obj.cls}) collides ({tried})"
        )
    surface = surface_under(view.scene, obj, obj.xyz[2] - half_height(obj))
    return PickPlan(obj, how, tuple(clear), surface)


def _check_reach(view: ObjectView, obj: WorldObject, grasps: list[Grasp]) -> None:
    """Raises:
    ObjectProblem: no grasp brings the wrist centre within the arm's reach."""
    arm = view.arm
    nearest = math.inf
    for g in grasps:
        T = view.in_base(g.grasp)
        p = T[:3, 3] - arm.l4 * T[:3, 2]
        horizontal = math.hypot(p[0], p[1])
        nearest = min(nearest, math.sqrt(max(0.0, horizontal**2 - arm.l1**2) + p[2] ** 2))
    if nearest > arm.l2 + arm.l3:
        raise ObjectProblem(
            f"object {obj.id!r} ({obj.cls}) is out of reach: its nearest grasp needs the wrist "
            f"centre {nearest * 1e3:.0f} mm from the shoulder (the arm reaches "
            f"{(arm.l2 + arm.l3) * 1e3:.0f} mm)"
        )


def held_upright(view: ObjectView, obj: WorldObject, q: np.ndarray) -> np.ndarray:
    """Where ``obj`` (in the world) is held with the gripper at ``q`` [rad], (4, 4) in the
    gripper frame: centred between the jaws (as closing jaws centre it, and as the attach
    does), standing upright with its observed yaw (a level object rests upright)."""
    G = view.gripper(q)
    T = np.linalg.solve(G, object_pose(obj))
    T[0, 3] = 0.0
    T[:3, :3] = G[:3, :3].T @ rot_z(obj.ypr[0])
    return np.asarray(T)


def predicted_hold(grasp: Grasp, obj: WorldObject) -> np.ndarray:
    """Where ``obj`` will be held in the gripper frame after ``grasp``, (4, 4): centred
    between the jaws, upright, as the attach makes it."""
    T = np.linalg.solve(grasp.grasp, object_pose(obj))
    T[0, 3] = 0.0
    R = grasp.grasp[:3, :3].T @ rot_z(obj.ypr[0])
    T[:3, :3] = R
    return np.asarray(T)
