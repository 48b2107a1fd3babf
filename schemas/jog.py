"""Live control (jog): the user drives the arm with a stream of speed commands.

A supervisor, a keypad or a joystick publishes :class:`JogCommand` on ``jog`` at its own
rate (10-50 Hz); the controller turns the newest one into joint speeds every cycle
(``services/controller/jog.py``). No new command for the controller's ``jog_timeout``
(the deadman, 150 ms), a zero command or a bad one stops the arm. The speed level (1..5
by default, like the arm's own controller) is set with :class:`JogLevel` on the queryable
``controller/jog_level`` and shown in :class:`JogState` (``controller/jog_state``), which
says in typed fields whether the jog runs, what holds it back (:class:`JogLimit`) and
why it stopped.

Values are SI (m/s, rad/s) with ``units = "si"``, or unitless deflections in -1..1 (a
joystick's) with ``units = "unitless"``, scaled by the speed level's share of the caps.
Which fields each kind uses is :data:`KIND_FIELDS` (in the JSON Schema as ``allOf``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

from schemas.base import Message, field
from schemas.control import EndCause


class JogKind(StrEnum):
    """What a jog command's values mean."""

    TWIST = "twist"
    """gripper linear + angular velocity"""
    JOINTS = "joints"
    """DH joint velocities"""
    STOP = "stop"
    """stop at once"""


class JogFrame(StrEnum):
    """The axes a twist is expressed in."""

    BASE = "base"
    """the arm's base frame (frame 0 at the shoulder: docs/protocol.md, Kinematics)"""
    GRIPPER = "gripper"
    """the gripper frame's axes, moving with it"""


class JogUnits(StrEnum):
    """How a jog command's speeds are given."""

    SI = "si"
    """m/s, rad/s"""
    UNITLESS = "unitless"
    """-1..1, a joystick's deflection, scaled by the speed level"""


class JogRunState(StrEnum):
    """What the jog does (``JogState.state``)."""

    IDLE = "idle"
    """no jog runs; a moving command would be taken"""
    RUNNING = "running"
    """a jog command is executed (``limits`` says what holds it back, if anything)"""
    STOPPED = "stopped"
    """stopped (``cause``): nothing moves until the controls are released (a zero command)"""


class LimitKind(StrEnum):
    """What holds a jog back (``JogLimit.kind``)."""

    SPEED_CAP = "speed_cap"
    """a speed cap: the level's (object ``linear``, ``angular``, ``joints``) or the
    motors' top speed (object ``motors``)"""
    JOINT_LIMIT = "joint_limit"
    """a joint nears its limit (object ``joint 1`` .. ``joint 6``; ``angle``)"""
    SINGULARITY = "singularity"
    """the wrist (q5 near 0 or 180 deg) or the elbow (q3 near 90 deg) nears a singularity
    (object ``wrist`` or ``elbow``; ``angle``)"""
    COLLISION = "collision"
    """the collision guard: an arm body (``body``) nears an object of the scene or the
    arm itself (``object``; ``distance``)"""
    ZONE = "zone"
    """the collision guard: an arm body nears a protection zone's boundary (``object``:
    the zone; ``distance``)"""


KIND_FIELDS: dict[str, tuple[str, ...]] = {
    JogKind.TWIST: ("frame", "linear", "angular", "gripper", "drink", "pour"),
    JogKind.JOINTS: ("joints", "gripper"),
    JogKind.STOP: (),
}
"""The fields each kind uses; the other speeds of a ``twist`` or ``joints`` command must
be 0 (``drink`` false). A ``stop`` ignores them all."""
SPEED_FIELDS = ("linear", "angular", "joints", "gripper", "pour")
"""The fields that carry a speed (SI or -1..1 by ``units``)."""
MAX_LINEAR = 0.150
"""Default cap of the gripper's linear speed at the top level [m/s] (150 mm/s)."""
MAX_ANGULAR = math.radians(30.0)
"""Default cap of the angular speed (and drink mode's pour) at the top level [rad/s]."""
MAX_JOINT = math.radians(50.0)
"""Default cap of each joint's speed at the top level [rad/s] (the arm's top speed)."""
MAX_GRIPPER = 0.030
"""Default cap of the gripper's opening speed at the top level [m/s]."""
USER_TOOK_OVER = "user took over"
"""The words of a goal ended or a task paused because a jog took the arm (typed: cause
``user_took_over``)."""
JOGGING = "the user is jogging"
"""The words of a goal refused while a jog moves the arm (typed: refusal ``busy``,
``held_by`` ``jog``)."""


def _kind_rules() -> list[dict[str, Any]]:
    """``allOf`` rules of :class:`JogCommand`: per kind, the speeds that must be 0; per
    units, the range; drink mode's constraints."""
    zero_list = {"items": {"const": 0}}
    rules: list[dict[str, Any]] = []
    for kind, uses in KIND_FIELDS.items():
        if kind == JogKind.STOP:
            rules.append(
                {
                    "description": "stop: stops at once; every other value is ignored",
                    "if": {"properties": {"kind": {"const": kind}}},
                    "then": {},
                }
            )
            continue
        unused = [f for f in (*SPEED_FIELDS, "drink") if f not in uses]
        then: dict[str, Any] = {}
        for name in unused:
            if name == "drink":
                then[name] = {"const": False}
            elif name in ("linear", "angular", "joints"):
                then[name] = zero_list
            else:
                then[name] = {"const": 0}
        rules.append(
            {
                "description": f"{kind}: uses {', '.join(uses)}; every other speed is 0",
                "if": {"properties": {"kind": {"const": kind}}},
                "then": {"properties": then},
            }
        )
    unit = {"items": {"minimum": -1, "maximum": 1}}
    rules.append(
        {
            "description": "unitless: every speed is a deflection in -1..1, scaled to the "
            "level's caps (JogState.caps: the top level's caps times level / levels)",
            "if": {"properties": {"units": {"const": JogUnits.UNITLESS}}},
            "then": {
                "properties": {
                    "linear": unit,
                    "angular": unit,
                    "joints": unit,
                    "gripper": {"minimum": -1, "maximum": 1},
                    "pour": {"minimum": -1, "maximum": 1},
                }
            },
        }
    )
    rules.append(
        {
            "description": "si: m/s and rad/s; refused above the top level's caps (the "
            f"controller's defaults: |linear| {MAX_LINEAR * 1e3:g} mm/s, |angular| + |pour| "
            f"{math.degrees(MAX_ANGULAR):g} deg/s, each joint {math.degrees(MAX_JOINT):g} "
            f"deg/s, |gripper| {MAX_GRIPPER * 1e3:g} mm/s); level L of N caps at L / N of "
            "them (JogState.caps: the caps in force). Above the level's caps every speed is "
            "scaled down by one factor (the direction kept) and JogState reports it: state "
            "running, a limit of kind speed_cap naming the speed, its scale",
            "if": {"properties": {"units": {"const": JogUnits.SI}}},
            "then": {},
        }
    )
    rules.append(
        {
            "description": "pour needs drink mode; drink mode turns only about the base z "
            "axis (angular[0] and angular[1] are 0)",
            "if": {"properties": {"drink": {"const": True}}, "required": ["drink"]},
            "then": {"properties": {"angular": {"prefixItems": [{"const": 0}, {"const": 0}]}}},
            "else": {"properties": {"pour": {"const": 0}}},
        }
    )
    return rules


@dataclass(frozen=True)
class JogCommand(Message):
    """One speed command of the live control stream (key ``jog``).

    A ``twist`` moves the gripper frame's origin at ``linear`` and turns it at
    ``angular`` (both in ``frame``'s axes); ``joints`` moves each DH joint at its speed;
    ``gripper`` opens (+) or closes (-) the gripper with either kind. ``drink`` holds the
    cup level (the gripper's pitch and roll relative to gravity are kept, only yaw turns);
    ``pour`` then tilts the cup about its rim (the controller's ``rim_offset`` in the
    gripper frame) instead of about the wrist. All zeros, or ``kind = "stop"``, stops at
    once.
    """

    TYPE_NAME = "manus/JogCommand/1"

    stamp_ns: int = field(
        "the sender's own clock when sent: informative only (the controller judges a "
        "command's age on the joint states' stamps)",
        unit="ns",
    )
    seq: int = field("sequence number of the sender", minimum=0)
    source: str = field("who sends it (e.g. 'teleop', 'joystick')")
    kind: str = field("what the values mean (the fields each kind uses: allOf)", choices=JogKind)
    units: str = field("SI speeds or unitless deflections in -1..1", choices=JogUnits)
    frame: str = field("twist: axes of linear and angular", default=JogFrame.BASE, choices=JogFrame)
    linear: list[float] = field(
        "twist: gripper origin velocity x, y, z",
        unit="m/s or -1..1",
        default_factory=lambda: [0.0] * 3,
        length=3,
    )
    angular: list[float] = field(
        "twist: angular velocity about x, y, z",
        unit="rad/s or -1..1",
        default_factory=lambda: [0.0] * 3,
        length=3,
    )
    joints: list[float] = field(
        "joints: DH joint velocities q1..q6",
        unit="rad/s or -1..1",
        default_factory=lambda: [0.0] * 6,
        length=6,
    )
    gripper: float = field(
        "twist or joints: gripper opening velocity (positive opens)",
        unit="m/s or -1..1",
        default=0.0,
    )
    drink: bool = field("twist: drink mode, keep the cup level", default=False)
    pour: float = field(
        "twist in drink mode: tilt about the cup's rim (positive pours forward, about the "
        "gripper's y axis)",
        unit="rad/s or -1..1",
        default=0.0,
    )

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        """Per kind and units, what the fields must hold (from :data:`KIND_FIELDS`)."""
        return _kind_rules()


@dataclass(frozen=True)
class JogLevel(Message):
    """Set the jog speed level (queryable ``controller/jog_level``, answered by a GoalAck)."""

    TYPE_NAME = "manus/JogLevel/1"

    level: int = field("speed level: 1 (slowest) .. the controller's number of levels", minimum=1)


@dataclass(frozen=True)
class JogTaken(Message):
    """A jog command as the controller took it (key ``controller/jog_taken``), published
    at once: after which joint state it came. The command stream and the joint states come
    from two publishers, so a recorder may log a command and a joint state that arrived
    together in the other order than the controller saw them; this record says where the
    controller saw it, and the regression check (``manus replay --check controller``)
    feeds the command there."""

    TYPE_NAME = "manus/JogTaken/1"

    after_seq: int = field("seq of the newest joint state when it came (-1: none yet)")
    command: JogCommand | None = field("the command (None: a payload that did not decode)")
    error: str = field("why the payload did not decode ('' when it did)", default="")


@dataclass(frozen=True)
class JogLimit(Message):
    """One thing that holds the jog back this cycle (``JogState.limits``)."""

    TYPE_NAME = "manus/JogLimit/1"

    kind: str = field("what limits", choices=LimitKind)
    object: str = field(
        "what it is: the capped speed (linear, angular, joints, motors), the joint "
        "(joint 1..6), the singularity (wrist, elbow), the object or zone of the scene"
    )
    scale: float = field(
        "share of the asked speed it lets through (1: none held back, 0: stopped)",
        minimum=0.0,
        maximum=1.0,
    )
    body: str = field("collision, zone: the arm body nearest to it ('' otherwise)", default="")
    distance: float = field(
        "collision, zone: the body's distance to the object (to the zone's boundary) "
        "where the guard judged it (0 otherwise)",
        unit="m",
        default=0.0,
    )
    angle: float = field(
        "joint_limit, singularity: how far the joint is from the limit or the singular "
        "angle (0 otherwise)",
        unit="rad",
        default=0.0,
    )


@dataclass(frozen=True)
class JogCaps(Message):
    """The speed caps at the level in use (``JogState.caps``): a unitless deflection of 1
    asks for exactly these; an SI command above them is scaled down to them."""

    TYPE_NAME = "manus/JogCaps/1"

    linear: float = field("gripper origin speed |linear|", unit="m/s", minimum=0.0)
    angular: float = field("angular speed |angular| + |pour|", unit="rad/s", minimum=0.0)
    joints: float = field("each DH joint's speed", unit="rad/s", minimum=0.0)
    gripper: float = field("gripper opening speed", unit="m/s", minimum=0.0)


@dataclass(frozen=True)
class JogState(Message):
    """The jog as the controller runs it (key ``controller/jog_state``): every cycle while
    a jog runs or a moving command is held back while stopped, once when it stops, and at
    the cycle after a level change or a refusal. A client decides on the typed fields
    (``state``, ``cause``, ``limits``, ``scale``); ``reason`` says the same in words and
    stays the same while they do."""

    TYPE_NAME = "manus/JogState/2"

    stamp_ns: int = field(
        "the bridge's clock, not a wall clock: the stamp of the joint state this answers "
        "(JointState.stamp_ns, the CAN receive time of its 0x360)",
        unit="ns",
    )
    seq: int = field("sequence number", minimum=0)
    state: str = field("what the jog does", choices=JogRunState)
    active: bool = field("a jog command is being executed (state running)")
    cause: str = field(
        "why the jog last stopped ('' : it has not stopped yet): released, deadman, "
        "bad_command, not_ready, arm_error, bridge_phase, states_interrupted, state_unusable",
        choices=("", *EndCause),
    )
    kind: str = field("kind of the command executed ('' when none)", choices=("", *JogKind))
    frame: str = field("frame of the twist executed ('' when none)", choices=("", *JogFrame))
    drink: bool = field("drink mode")
    level: int = field("speed level in use", minimum=1)
    levels: int = field("number of speed levels", minimum=1)
    caps: JogCaps = field("the speed caps at the level in use")
    scale: float = field(
        "share of the asked speed commanded this cycle: the product of the limits' scales "
        "(1: nothing held back, 0: stopped at a limit)",
        minimum=0.0,
        maximum=1.0,
    )
    limits: list[JogLimit] = field(
        "what holds the jog back this cycle, each with its scale (empty: nothing)"
    )
    reason: str = field(
        "the state, the stop or the tightest limit in words ('' when none); the same "
        "text while they stay the same"
    )
    command_seq: int = field("seq of the newest command accepted (-1: none)")
    refused: int = field(
        "refusals so far: each bad command, and once per stop the moving commands held "
        "back until the controls are released (not allowed now, or after a stop)",
        minimum=0,
    )
    deadman_stops: int = field("stops for want of a new command within jog_timeout", minimum=0)
    folded: bool = field(
        "the arm stands in its folded pose (every joint within 5 deg of it): unfold it "
        "first (ArmCommand fold_out; a sequencer task's fold_out step)"
    )
    actual_xyz: list[float] = field(
        "gripper position of the joint state's angles, in the arm's base frame (frame 0 at "
        "the shoulder; docs/protocol.md, Kinematics)",
        unit="m",
        length=3,
    )
    actual_ypr: list[float] = field(
        "gripper orientation of the joint state's angles in the base frame: yaw, pitch, "
        "roll with R = Rz(yaw) Ry(pitch) Rx(roll)",
        unit="rad",
        length=3,
    )
