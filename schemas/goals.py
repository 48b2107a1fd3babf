"""Goals a planner reaches by itself: where the arm should end up, not how it gets there.

A :class:`Goal` is one of five kinds (``kind``), each using only its own fields:

- ``joints``: a joint configuration (``joints``, DH angles);
- ``pose``: a gripper pose in the arm's base frame (``xyz``, ``ypr``), with tolerances
  (``position_tolerance``, ``angle_tolerance``, ``free_axis``: any rotation about the
  gripper's approach axis is fine);
- ``named``: a named pose (``name``: ``home``, ``drink``, ``folded``, ``unfolded`` or one
  of the user's poses file, docs/reach.md);
- ``object``: a gripper pose given in a scene object's frame (``name`` the object,
  ``xyz``/``ypr`` the offset from its frame), with the same tolerances as ``pose``;
- ``line``: a straight Cartesian line from where the gripper is (MoveIt's Pilz LIN):
  ``frame`` ``base``: to the pose ``xyz``/``ypr`` (``ypr`` None: keep the orientation);
  ``frame`` ``tool``: by the displacement ``xyz`` in the gripper's frame (z along its
  axis: ``[0, 0, 0.05]`` approaches 50 mm, ``[0, 0, -0.05]`` retreats).

Orientations are (yaw, pitch, roll) with R = Rz(yaw) Ry(pitch) Rx(roll) (the CLI's
order, docs/protocol.md, Orientation convention).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field


class GoalKind(StrEnum):
    """What a :class:`Goal` names."""

    JOINTS = "joints"
    """a joint configuration"""
    POSE = "pose"
    """a gripper pose in the base frame, with tolerances"""
    NAMED = "named"
    """a named pose"""
    OBJECT = "object"
    """a gripper pose in a scene object's frame, with tolerances"""
    LINE = "line"
    """a straight Cartesian line"""


class LineFrame(StrEnum):
    """How a ``line`` goal's ``xyz`` / ``ypr`` are meant."""

    BASE = "base"
    """the end pose, in the base frame"""
    TOOL = "tool"
    """a displacement in the gripper's frame at the start (z: along the gripper's axis)"""


GOAL_KINDS = tuple(GoalKind)
LINE_FRAMES = tuple(LineFrame)


@dataclass(frozen=True)
class Goal(Message):
    """Where the arm should end up (see the module docstring for each kind's fields)."""

    TYPE_NAME = "manus/Goal/1"

    kind: str = field("what the goal names", choices=GoalKind)
    joints: list[float] | None = field(
        "joints: the configuration (DH joint angles)", unit="rad", default=None, length=6
    )
    xyz: list[float] | None = field(
        "pose: gripper position (base frame); object: offset from the object's frame; "
        "line: end position (frame base) or displacement (frame tool)",
        unit="m",
        default=None,
        length=3,
    )
    ypr: list[float] | None = field(
        "orientation (yaw, pitch, roll) in the same frame as xyz (line: None keeps it)",
        unit="rad",
        default=None,
        length=3,
    )
    name: str = field("named: the pose's name; object: the scene object's name", default="")
    frame: str = field("line: how xyz / ypr are meant", default=LineFrame.BASE, choices=LineFrame)
    position_tolerance: float = field(
        "pose, object: how far the gripper may end from xyz",
        unit="m",
        default=0.0,
        minimum=0.0,
        maximum=0.1,
    )
    angle_tolerance: float = field(
        "pose, object: how far its orientation may be turned from ypr (any axis)",
        unit="rad",
        default=0.0,
        minimum=0.0,
        maximum=0.5,
    )
    free_axis: bool = field(
        "pose, object: any rotation about the gripper's approach axis (its z) is fine",
        default=False,
    )


@dataclass(frozen=True)
class ReachRequest(Message):
    """Ask the planner for a trajectory to a goal (it finds the way around the scene)."""

    TYPE_NAME = "manus/ReachRequest/1"

    goal: Goal = field("where to go")
    start: list[float] | None = field(
        "start configuration (DH joint angles); None: the newest joint state",
        unit="rad",
        default=None,
        length=6,
    )
    seed: int = field(
        "seed of the search (the same request and seed give the same trajectory)",
        default=1,
        minimum=1,
        maximum=2**31 - 1,
    )
    budget: int = field(
        "most configurations the search may sample before it gives up",
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
        choices=("cubic", "quintic"),
    )
    preview_dt: float = field(
        "sampling step of the Cartesian preview in the reply (0: no preview)",
        unit="s",
        default=0.06,
        minimum=0.0,
        maximum=10.0,
    )
