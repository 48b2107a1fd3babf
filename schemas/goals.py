"""Goals a planner reaches by itself: where the arm should end up, not how it gets there.

Five kinds of motion (members of :data:`schemas.motion.MOTIONS`, each named by its
``kind``), planned by the goal planners (:mod:`services.planner.goal_planner`,
docs/reach.md):

- ``joints`` (:class:`JointGoal`): a joint configuration;
- ``pose`` (:class:`PoseGoal`): a gripper pose in the arm's base frame, with tolerances
  (:class:`Tolerance`: a position ball, an angle, free rotation about the gripper's
  approach axis);
- ``named`` (:class:`NamedGoal`): a named pose (``home``, ``drink``, ``folded``,
  ``unfolded`` or one of the user's poses file);
- ``object`` (:class:`ObjectGoal`): a gripper pose given in a scene object's frame (an
  offset from it), with tolerances;
- ``line`` (:class:`LineMotion`): a straight Cartesian line from where the gripper is
  (MoveIt's Pilz LIN): ``frame`` ``base``: to the pose ``xyz``/``ypr`` (``ypr`` None:
  keep the orientation); ``frame`` ``tool``: by the displacement ``xyz`` in the gripper's
  frame (z along its axis: ``[0, 0, 0.05]`` approaches 50 mm, ``[0, 0, -0.05]``
  retreats).

The first four find their way around the scene (a seeded search, :class:`Search`).
Orientations are (yaw, pitch, roll) with R = Rz(yaw) Ry(pitch) Rx(roll) (the CLI's
order, docs/protocol.md, Orientation convention).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field
from schemas.motion import MOTIONS, Motion
from schemas.tagged import tag

INTERPOLATIONS = ("cubic", "quintic")
"""The interpolations (those of :class:`schemas.planning.Interpolation`; a test keeps them
equal)."""


class LineFrame(StrEnum):
    """How a ``line`` motion's ``xyz`` / ``ypr`` are meant."""

    BASE = "base"
    """the end pose, in the base frame"""
    TOOL = "tool"
    """a displacement in the gripper's frame at the start (z: along the gripper's axis)"""


LINE_FRAMES = tuple(LineFrame)


@dataclass(frozen=True)
class Search(Message):
    """How a goal's path is searched for and timed."""

    TYPE_NAME = "manus/Search/1"

    seed: int = field(
        "seed of the search (the same request, start, scene and seed give the same plan)",
        default=1,
        minimum=1,
        maximum=2**31 - 1,
    )
    budget: int = field(
        "most iterations of the search before it gives up",
        default=3000,
        minimum=1,
        maximum=1_000_000,
    )
    speed: float = field(
        "fraction of each joint's speed and acceleration limit the motion may use",
        default=0.5,
        minimum=0.05,
        maximum=1.0,
    )
    interpolation: str = field(
        "cubic spline through the waypoints, or quintic segments",
        default="cubic",
        choices=INTERPOLATIONS,
    )


@dataclass(frozen=True)
class Tolerance(Message):
    """How far from a pose goal the gripper may end."""

    TYPE_NAME = "manus/Tolerance/1"

    position: float = field(
        "largest distance from the goal position", unit="m", default=0.0, minimum=0.0, maximum=0.1
    )
    angle: float = field(
        "largest turn from the goal orientation (any axis)",
        unit="rad",
        default=0.0,
        minimum=0.0,
        maximum=0.5,
    )
    free_axis: bool = field(
        "any rotation about the gripper's approach axis (its z) is fine", default=False
    )


@MOTIONS.member
@dataclass(frozen=True)
class JointGoal(Motion):
    """A joint configuration to reach."""

    TYPE_NAME = "manus/JointGoal/1"

    kind: str = tag("joints", "a joint configuration")
    joints: list[float] = field("the configuration (DH joint angles)", unit="rad", length=6)
    search: Search = field("search and timing", default_factory=Search)


@MOTIONS.member
@dataclass(frozen=True)
class PoseGoal(Motion):
    """A gripper pose to reach, in the base frame; every IK branch is a goal."""

    TYPE_NAME = "manus/PoseGoal/1"

    kind: str = tag("pose", "a gripper pose in the base frame")
    xyz: list[float] = field("gripper position, base frame", unit="m", length=3)
    ypr: list[float] = field("gripper orientation (yaw, pitch, roll)", unit="rad", length=3)
    tolerance: Tolerance = field("how far from it the gripper may end", default_factory=Tolerance)
    search: Search = field("search and timing", default_factory=Search)


@MOTIONS.member
@dataclass(frozen=True)
class NamedGoal(Motion):
    """A named pose to reach (docs/reach.md, Named poses)."""

    TYPE_NAME = "manus/NamedGoal/1"

    kind: str = tag("named", "a named pose")
    name: str = field("the pose's name: home, drink, folded, unfolded or the user's")
    search: Search = field("search and timing", default_factory=Search)


@MOTIONS.member
@dataclass(frozen=True)
class ObjectGoal(Motion):
    """A gripper pose given in a scene object's frame (an offset from it)."""

    TYPE_NAME = "manus/ObjectGoal/1"

    kind: str = tag("object", "a gripper pose in a scene object's frame")
    name: str = field("the scene object")
    xyz: list[float] = field("gripper position in the object's frame", unit="m", length=3)
    ypr: list[float] = field(
        "gripper orientation (yaw, pitch, roll) in the object's frame", unit="rad", length=3
    )
    tolerance: Tolerance = field("how far from it the gripper may end", default_factory=Tolerance)
    search: Search = field("search and timing", default_factory=Search)


@MOTIONS.member
@dataclass(frozen=True)
class LineMotion(Motion):
    """A straight Cartesian line from where the gripper is (see the module docstring)."""

    TYPE_NAME = "manus/LineMotion/1"

    kind: str = tag("line", "a straight Cartesian line")
    xyz: list[float] = field(
        "frame base: the end position; frame tool: the displacement in the gripper's frame",
        unit="m",
        length=3,
    )
    ypr: list[float] | None = field(
        "frame base: the end orientation (None: keep it); frame tool: a turn in the "
        "gripper's frame (None: none)",
        unit="rad",
        default=None,
        length=3,
    )
    frame: str = field("how xyz / ypr are meant", default=LineFrame.BASE, choices=LineFrame)
    speed: float = field(
        "fraction of the line's top speed (200 mm/s) and acceleration (400 mm/s^2)",
        default=0.5,
        minimum=0.05,
        maximum=1.0,
    )


GOAL_MOTIONS = (JointGoal, PoseGoal, NamedGoal, ObjectGoal, LineMotion)
"""Every goal kind (each a member of :data:`schemas.motion.MOTIONS`)."""

TargetGoal = JointGoal | PoseGoal | NamedGoal | ObjectGoal
"""The goals a search reaches (all but the line)."""
