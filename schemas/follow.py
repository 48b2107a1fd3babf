"""Following a moving target: the goal and the state of the controller's follow source
(docs/follow.md).

A :class:`FollowGoal` on ``controller/follow`` (answered with a ``GoalAck``) makes the
arm's tracked point (the gripper, or a held object's point: ``offset`` in the gripper
frame) follow the target of one tracker (:class:`schemas.target.TargetPose` on
``target/pose``, its ``source``) to a standoff along an approach axis, and hold it there,
until it is stopped (the same query with ``stop``), preempted (a jog) or a fault ends it.
Every cycle while it runs, and once when it ends, the controller publishes a
:class:`FollowState` (``controller/follow_state``); the goal ends with one ``GoalResult``
(kind ``follow``) on ``controller/result``. Nothing resumes by itself: after an end, only
a new goal moves the arm again.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field
from schemas.jog import JogLimit

CLOSE_SPEED_CAP = 0.025
"""The closer approach's speed cap inside :data:`CLOSE_ZONE` of the target [m/s]."""
CLOSE_ZONE = 0.100
"""Where the closer approach's speed cap applies: this close to the target [m]."""


class FollowPhase(StrEnum):
    """What the follow source does (``FollowState.state``)."""

    APPROACHING = "approaching"
    """moving the tracked point toward the standoff point"""
    HOLDING = "holding"
    """at the standoff point (within ``hold_tolerance``), following the target"""
    ENDED = "ended"
    """the goal ended (``cause``, ``reason``): nothing moves until a new goal"""


@dataclass(frozen=True)
class FollowGoal(Message):
    """Follow a tracker's target to a standoff, or stop following (key ``controller/follow``)."""

    TYPE_NAME = "manus/FollowGoal/1"

    goal_id: str = field("caller-chosen unique id (a stop names the goal to stop)")
    source: str = field("the tracker to follow: `TargetPose.source` on target/pose", default="")
    stop: bool = field(
        "stop the goal `goal_id` (it decelerates; result `cancelled`) instead of starting one",
        default=False,
    )
    standoff: float = field(
        "where the tracked point stops: this far from the target along `approach` (0: the "
        "controller's default, 60 mm: just outside the person's 50 mm clearance)",
        unit="m",
        default=0.0,
        minimum=0.0,
        maximum=0.5,
    )
    approach: list[float] = field(
        "direction from the target to the standoff point, in the target's own frame (a "
        "mouth's x points out of the face); normalised",
        default_factory=lambda: [1.0, 0.0, 0.0],
        length=3,
    )
    offset: list[float] = field(
        "the tracked point in the gripper frame: the gripper origin (0, 0, 0), or a held "
        "object's point, e.g. a cup's rim",
        unit="m",
        default_factory=lambda: [0.0, 0.0, 0.0],
        length=3,
        minimum=-0.3,
        maximum=0.3,
    )
    max_speed: float = field(
        "speed cap of the tracked point (0: the controller's, which is also the most)",
        unit="m/s",
        default=0.0,
        minimum=0.0,
    )
    close: bool = field(
        "the closer approach, for a user who cannot lean forward (never the default): the "
        "tracked point (the held object's rim) may come to `close_clearance` of the person, "
        "at most 25 mm/s toward or along the target inside 100 mm of it; the arm's own "
        "bodies keep the person's clearance",
        default=False,
    )
    close_clearance: float = field(
        "with `close`: the smallest distance of the tracked point to the person",
        unit="m",
        default=0.02,
        minimum=0.005,
        maximum=0.5,
    )
    lost_after: float = field(
        "the target is lost when no newer frame came for this long beyond its latency (0: "
        "two frame periods of the stream)",
        unit="s",
        default=0.0,
        minimum=0.0,
        maximum=5.0,
    )
    max_target_speed: float = field(
        "a target moving faster than this between two frames jumped (0: the controller's "
        "default, faster than a person moves)",
        unit="m/s",
        default=0.0,
        minimum=0.0,
        maximum=10.0,
    )


@dataclass(frozen=True)
class FollowState(Message):
    """The follow source as it runs (key ``controller/follow_state``): every cycle while a
    goal runs, once when it ends. Positions in the arm's base frame."""

    TYPE_NAME = "manus/FollowState/1"

    stamp_ns: int = field("stamp of the joint state this answers", unit="ns")
    seq: int = field("sequence number", minimum=0)
    goal_id: str = field("the goal")
    source: str = field("the tracker followed")
    state: str = field("what it does", choices=FollowPhase)
    cause: str = field(
        "when ended: why (schemas.control.EndCause: target_lost, target_jump, out_of_reach, "
        "keep_out, singularity, cancel_request, user_took_over, ...); '' while it runs",
        default="",
    )
    reason: str = field("what it does or why it ended, in words", default="")
    target_xyz: list[float] = field(
        "the newest target point received (empty: none yet)", unit="m", default_factory=list
    )
    target_stamp_ns: int = field("its capture stamp (0: none yet)", unit="ns", default=0)
    predicted_xyz: list[float] = field(
        "the target point predicted to the end of this cycle's command (empty: none)",
        unit="m",
        default_factory=list,
    )
    aim_xyz: list[float] = field(
        "the standoff point the tracked point goes to (empty: none)",
        unit="m",
        default_factory=list,
    )
    point_xyz: list[float] = field(
        "the tracked point where the joint state puts it", unit="m", default_factory=list
    )
    distance: float = field("from the tracked point to the standoff point", unit="m", default=0.0)
    speed_cap: float = field("the speed cap in force this cycle", unit="m/s", default=0.0)
    latency: float = field(
        "age of the newest target frame at this joint state (stamp minus capture)",
        unit="s",
        default=0.0,
    )
    body: str = field("the person's body the guard moves with the target ('' : none)", default="")
    body_xyz: list[float] = field(
        "where the guard has that body (empty: none)", unit="m", default_factory=list
    )
    limits: list[JogLimit] = field(
        "what holds the motion back this cycle (speed caps, zones, the collision guard)",
        default_factory=list,
    )
    frames: int = field("target frames taken for this goal", default=0, minimum=0)
    refused: int = field(
        "target frames of this source refused (not decodable, wrong frame)", default=0, minimum=0
    )
