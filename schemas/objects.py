"""Objects the arm can fetch: what perception observes, what the world model keeps, and
what the simulator knows to be true (docs/objects.md).

Poses are in the **chair frame** (the scene's frame, docs/scene.md: x forward, y to the
user's left, z up, origin on the floor under the seat's centre): ``xyz`` is the object's
centre [m], ``ypr`` the (yaw, pitch, roll) of its own frame [rad] with R = Rz(yaw)
Ry(pitch) Rx(roll), as in via points. Shapes and sizes are the scene's primitives in SI
units: a box (x, y, z edge lengths), a sphere (radius), a cylinder or capsule (radius,
length along the object's own z; a capsule's length is its straight part).

- :class:`Perception` (``perception/objects``): one camera frame's detections, stamped
  with the capture time; objects not in it are not removed (they may be hidden), only
  those named in ``removed``.
- :class:`WorldUpdate` (``planner/objects``): the world model's objects as versioned
  diffs, and now and then whole (``base_version`` -1), as MoveIt's planning scene does.
- :class:`AttachRequest` -> :class:`AttachReply` (``planner/attach``): a grasped object
  becomes part of the arm (``WorldObject.link``), a released one goes back into the
  world where it is.
- :class:`ObjectTruth`, :class:`ObjectContact`: the simulator's truth
  (:class:`schemas.state.SimTruth`), which the stack never reads.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field


class ObjectShape(StrEnum):
    """The primitive an object is modelled as (``size`` per shape in the module docstring)."""

    BOX = "box"
    SPHERE = "sphere"
    CYLINDER = "cylinder"
    CAPSULE = "capsule"


SIZE_COUNTS = {
    ObjectShape.BOX: 3,
    ObjectShape.SPHERE: 1,
    ObjectShape.CYLINDER: 2,
    ObjectShape.CAPSULE: 2,
}
"""How many ``size`` values each shape takes."""

SIZE_DOC = (
    "box: x y z edges; sphere: radius; cylinder, capsule: radius, length along the object's z"
)


class ContactClass(StrEnum):
    """What an arm body or a held object touched (``ObjectContact.cls``)."""

    PERSON = "person"
    CHAIR = "chair"
    ENVIRONMENT = "environment"
    OBJECT = "object"
    """another object (held or free), or an arm body touching a free object"""


@dataclass(frozen=True)
class ObservedObject(Message):
    """One object as a perception source saw it in one frame."""

    TYPE_NAME = "manus/ObservedObject/1"

    id: str = field("identity the source keeps across frames (letters, digits, _ and -)")
    cls: str = field("class: cup, bottle, phone, ... (letters, digits, _ and -)")
    shape: str = field("the primitive it is modelled as", choices=ObjectShape)
    size: list[float] = field(SIZE_DOC, unit="m", minimum=0.0)
    xyz: list[float] = field("centre in the chair frame", unit="m", length=3)
    ypr: list[float] = field("(yaw, pitch, roll) in the chair frame", unit="rad", length=3)
    confidence: float = field("how sure the source is", minimum=0.0, maximum=1.0)


@dataclass(frozen=True)
class Perception(Message):
    """One frame of a perception source: the objects it saw (added or moved) and the ones
    it knows to be gone (removed). An object it did not see is not gone: it may be hidden."""

    TYPE_NAME = "manus/Perception/1"

    stamp_ns: int = field("capture time of the image the detections come from", unit="ns")
    seq: int = field("frame number of this source", minimum=0)
    source: str = field("the perception source (a camera's name)")
    objects: list[ObservedObject] = field("objects seen in this frame", default_factory=list)
    removed: list[str] = field("ids the source knows to be gone", default_factory=list)


@dataclass(frozen=True)
class WorldObject(Message):
    """One object of the world model: its last observation, and whether it is stale; or,
    attached to a link of the arm (``link``), where it is held (MoveIt's attached
    object: the same object, in another place)."""

    TYPE_NAME = "manus/WorldObject/1"

    id: str = field("its identity (the perception source's)")
    cls: str = field("class: cup, bottle, phone, ...")
    shape: str = field("the primitive it is modelled as", choices=ObjectShape)
    size: list[float] = field(SIZE_DOC, unit="m", minimum=0.0)
    xyz: list[float] = field(
        "centre in the chair frame (attached: in the frame of `link`)", unit="m", length=3
    )
    ypr: list[float] = field(
        "(yaw, pitch, roll) in the chair frame (attached: in the frame of `link`)",
        unit="rad",
        length=3,
    )
    confidence: float = field("the source's confidence", minimum=0.0, maximum=1.0)
    stamp_ns: int = field(
        "capture time of its last observation (attached or detached: the time of the arm's "
        "configuration it was attached or detached at)",
        unit="ns",
    )
    source: str = field("who observed it last (`arm`: attached or detached since)")
    stale: bool = field(
        "not observed for longer than stale_after_s at the update's stamp_ns (its age then: "
        "the update's stamp_ns minus this stamp_ns; a plan to it is refused); never while "
        "attached",
        default=False,
    )
    link: str = field(
        "the arm's link it is attached to (gripper_frame: held in the gripper; '': in the world)",
        default="",
    )
    touch_links: list[str] = field(
        "while attached: the arm's bodies that may touch it (no self clearance to them)",
        default_factory=list,
    )
    touch_objects: list[str] = field(
        "while attached: the scene objects it may touch (no clearance to them: the surface "
        "it is lifted from or put down on)",
        default_factory=list,
    )


@dataclass(frozen=True)
class ObjectJump(Message):
    """An observation that moved an object further than it could have moved."""

    TYPE_NAME = "manus/ObjectJump/1"

    id: str = field("the object")
    distance: float = field("how far it moved between the two observations", unit="m")
    allowed: float = field(
        "the most it could have moved: max_speed times the interval, plus jump_tolerance",
        unit="m",
    )
    interval: float = field("time between the two observations", unit="s")
    source: str = field("the source of the new observation")


@dataclass(frozen=True)
class WorldUpdate(Message):
    """The world model's objects, as a diff from ``base_version`` (-1: the whole set, which
    replaces whatever the follower held)."""

    TYPE_NAME = "manus/WorldUpdate/1"

    stamp_ns: int = field(
        "the world model's time: the capture time of the newest perception frame", unit="ns"
    )
    version: int = field("the version after this update", minimum=0)
    base_version: int = field(
        "the version this diff applies to (-1: the whole set); a follower that holds another "
        "version waits for the next whole set",
        minimum=-1,
    )
    objects: list[WorldObject] = field(
        "objects added or changed (the whole set: every object)", default_factory=list
    )
    removed: list[str] = field("ids removed", default_factory=list)
    jumps: list[ObjectJump] = field(
        "observations that jumped, in this update", default_factory=list
    )
    refused: int = field("perception messages refused since start", default=0, minimum=0)
    error: str = field("why the last refused one was refused ('': none)", default="")
    stale_after_s: float = field(
        "an object not observed for longer than this is stale (for a follower judging ages "
        "on its own clock)",
        unit="s",
        default=0.0,
        minimum=0.0,
    )


@dataclass(frozen=True)
class AttachRequest(Message):
    """Attach a world object to the arm (the gripper closed on it) or detach it (the
    gripper let it go), asked of the world model's owner (``planner/attach``); every
    follower learns it from the diff it makes (``planner/objects``)."""

    TYPE_NAME = "manus/AttachRequest/1"

    object_id: str = field("the object")
    link: str = field("attach it to this link (gripper_frame); '': detach it where it is")
    position: list[float] = field(
        "the arm's DH joint angles when it was grasped or released", unit="rad", length=6
    )
    stamp_ns: int = field(
        "when the arm was there (that joint state's stamp): perception frames captured "
        "before it do not move the object",
        unit="ns",
    )
    touch_links: list[str] = field(
        "attach: the arm's bodies that may touch it", default_factory=lambda: ["gripper"]
    )
    touch_objects: list[str] = field(
        "attach: the scene objects it may touch (the surface it is lifted from)",
        default_factory=list,
    )
    xyz: list[float] | None = field(
        "attach: its centre in the link's frame (null: where perception saw it, centred "
        "between the jaws; or, attached already, where it is held)",
        unit="m",
        length=3,
        default=None,
    )
    ypr: list[float] | None = field(
        "attach: its (yaw, pitch, roll) in the link's frame (null: as perception saw it; "
        "or, attached already, as it is held)",
        unit="rad",
        length=3,
        default=None,
    )


@dataclass(frozen=True)
class AttachReply(Message):
    """The world model owner's answer to an :class:`AttachRequest`."""

    TYPE_NAME = "manus/AttachReply/1"

    accepted: bool = field("the object is attached (detached) from `version` on")
    version: int = field("the world model's version now", minimum=0)
    error: str = field("why it was refused: the object and the reason ('': accepted)", default="")
    object: WorldObject | None = field("the object as it is now (null: refused)", default=None)


@dataclass(frozen=True)
class ObjectTruth(Message):
    """Where an object of the simulator truly is."""

    TYPE_NAME = "manus/ObjectTruth/1"

    id: str = field("its identity")
    cls: str = field("class: cup, bottle, phone, ...")
    shape: str = field("its primitive", choices=ObjectShape)
    size: list[float] = field(SIZE_DOC, unit="m", minimum=0.0)
    xyz: list[float] = field("centre in the chair frame", unit="m", length=3)
    ypr: list[float] = field("(yaw, pitch, roll) in the chair frame", unit="rad", length=3)
    held: bool = field("between the gripper's closed jaws, moving with the gripper")
    resting_on: str = field("the scene object it stands on ('floor'; '': held or falling)")
    slips: int = field("grasps on it that slipped (off by more than the tolerance)", minimum=0)


@dataclass(frozen=True)
class ObjectContact(Message):
    """A contact the simulator saw between an arm body or a held object and the scene or
    another object (one per pair, since power-up)."""

    TYPE_NAME = "manus/ObjectContact/1"

    first: str = field("the arm body (touching a free object) or the held object's id")
    second: str = field("the scene object or the other object's id")
    cls: str = field("what `second` is", choices=ContactClass)
    since_ns: int = field("simulated time of the first tick in contact", unit="ns")
    ticks: int = field("ticks in contact so far", minimum=0)
    depth: float = field("deepest penetration seen", unit="m", minimum=0.0)
