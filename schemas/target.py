"""A moving target the arm follows: the tracker's stream and the simulator's truth of it
(docs/follow.md).

A tracker (a face tracker finding the user's mouth, the simulator's moving target)
publishes one :class:`TargetPose` per frame on ``target/pose``, 5-30 Hz, stamped with
the capture time on the stack's clock (the clock of the joint states' stamps). Poses are
in the **chair frame** (the scene's frame, docs/scene.md: x forward, y to the user's
left, z up) or in the arm's **base frame**; ``xyz`` is the target point [m], ``ypr`` the
(yaw, pitch, roll) of the target's own frame [rad] with R = Rz(yaw) Ry(pitch) Rx(roll),
as for objects (:mod:`schemas.objects`). The target's frame is what a follow goal's
approach axis is expressed in: for a mouth, x points out of the face.

A target on a person carries the pose of the scene object it moves with (``body``: the
person's ``head``), so that the collision model of the person follows what the tracker
sees (the controller's guard moves that object, within a bound: docs/follow.md, The
person moves).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field


class TargetFrame(StrEnum):
    """The frame a target's pose is given in."""

    CHAIR = "chair"
    """the scene's frame (the arm's mount places the base in it)"""
    BASE = "base"
    """the arm's base frame (DH frame 0)"""


@dataclass(frozen=True)
class TargetPose(Message):
    """One frame of a tracker: where the target is (key ``target/pose``)."""

    TYPE_NAME = "manus/TargetPose/1"

    stamp_ns: int = field(
        "capture time of the frame the pose comes from, on the stack's clock (the joint "
        "states' stamps)",
        unit="ns",
    )
    seq: int = field("frame number of this source", minimum=0)
    source: str = field("the tracker, the name a follow goal asks for (e.g. 'mouth')")
    xyz: list[float] = field("the target point", unit="m", length=3)
    ypr: list[float] = field(
        "(yaw, pitch, roll) of the target's frame (a mouth's: x out of the face)",
        unit="rad",
        length=3,
    )
    frame: str = field("frame of the poses", choices=TargetFrame, default=TargetFrame.CHAIR)
    tracked: bool = field(
        "the tracker sees the target (false: it lost it; the pose fields are not used and "
        "a follow goal on it stops at once)",
        default=True,
    )
    confidence: float = field("how sure the tracker is", minimum=0.0, maximum=1.0, default=1.0)
    body: str = field(
        "the scene object (class person) the target moves with, e.g. 'head' ('' : none)",
        default="",
    )
    body_xyz: list[float] = field(
        "centre of `body` in the pose's frame (empty: not given)", unit="m", default_factory=list
    )
    body_ypr: list[float] = field(
        "(yaw, pitch, roll) of `body` in the pose's frame (empty: not given)",
        unit="rad",
        default_factory=list,
    )


@dataclass(frozen=True)
class TargetTaken(Message):
    """A target pose as the controller took it (key ``controller/target_taken``), published
    at once: after which joint state it came. Like :class:`schemas.jog.JogTaken`: the
    tracker and the bridge are two publishers, and the regression check
    (``manus replay --check controller``) feeds each pose where the controller saw it."""

    TYPE_NAME = "manus/TargetTaken/1"

    after_seq: int = field("seq of the newest joint state when it came (-1: none yet)")
    target: TargetPose | None = field("the pose (None: a payload that did not decode)")
    error: str = field("why the payload did not decode ('' when it did)", default="")


@dataclass(frozen=True)
class TargetTruth(Message):
    """Where the simulator's moving target and the body it moves with truly are (in
    :class:`schemas.state.SimTruth`, which the stack never reads)."""

    TYPE_NAME = "manus/TargetTruth/1"

    source: str = field("the tracker's name it is published under")
    xyz: list[float] = field("the target point in the chair frame", unit="m", length=3)
    ypr: list[float] = field("(yaw, pitch, roll) of its frame, chair frame", unit="rad", length=3)
    visible: bool = field("the tracker sees it now (false: in a window where it is lost)")
    body: str = field("the scene object that moves with it ('' : none)")
    body_xyz: list[float] = field(
        "centre of `body` in the chair frame (empty: none)", unit="m", default_factory=list
    )
    body_ypr: list[float] = field(
        "(yaw, pitch, roll) of `body`, chair frame (empty: none)", unit="rad", default_factory=list
    )
