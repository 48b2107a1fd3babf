"""Paths of Cartesian via points, plan requests and the joint trajectories that answer them.

A via point travels in SI units (m, rad, s) with the thesis's meaning (docs/protocol.md,
Thesis via-point format): ``type`` 0 absolute (base frame), 1 relative to the first via
point, 2 relative to the previous one; the first via point is replaced by the gripper's pose
when the plan is made; only the first and last velocities are used; ``time`` is the arrival
time since the first via point. Orientation is (yaw, pitch, roll) with R = Rz(yaw) Ry(pitch)
Rx(roll).

A plan request asks for one kind of motion (:class:`~schemas.motion.Motion`, told apart
by its ``kind``; :data:`~schemas.motion.MOTIONS` holds the kinds the planner serves: the
via-point path, :class:`ViaPointPath`, the rest of a running one from its moving state,
:class:`ViaPointContinuation` (streamed via points), and the goals of :mod:`schemas.goals`,
:data:`~schemas.goals.GOAL_MOTIONS`). Each kind is served by its own planner and answered
with the same :class:`Trajectory`. A request that resumes a paused plan
(:class:`PlanResume`) carries that plan's trajectory and how far it got, and asks for the
same motion again: the planner of its kind plans what is left from where the arm is.

A trajectory is piecewise Hermite in joint space: positions and velocities at each knot
(cubic segments), plus accelerations when present (quintic segments). Its time starts at
0 at the first knot; the controller anchors it when the goal starts. Each knot says what
it is (:class:`KnotKind`): the start, a via point of the request's path (with its index
there), a waypoint the planner chose, or the goal.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field
from schemas.collision import ClearanceReport
from schemas.goals import GOAL_MOTIONS
from schemas.motion import MOTIONS, Motion
from schemas.tagged import tag


class Interpolation(StrEnum):
    """How the planner joins the knots."""

    CUBIC = "cubic"
    """one cubic spline through every knot (the thesis's choice)"""
    QUINTIC = "quintic"
    """rest-to-rest quintic segments"""


class PlanErrorReason(StrEnum):
    """Kind of a planning failure (``PlanError.reason``)."""

    PARSE = "parse"
    """the via-point text is malformed"""
    UNREACHABLE = "unreachable"
    """outside the workspace"""
    SINGULAR = "singular"
    """wrist singularity"""
    JOINT_LIMIT = "joint_limit"
    """a joint limit is broken"""
    BRANCH = "branch"
    """the path would need an IK branch flip"""
    SPEED_LIMIT = "speed_limit"
    """a joint speed or acceleration limit is broken (no speed scaling asked)"""
    NO_STATE = "no_state"
    """no start configuration given and no joint state known"""
    INVALID = "invalid"
    """the request itself is inconsistent"""
    COLLISION = "collision"
    """the arm would come too close to the scene, a protection zone or itself"""
    GOAL_COLLISION = "goal_collision"
    """every configuration that reaches the goal is too close to something (named)"""
    ZONE = "zone"
    """the goal lies inside a keep-out zone or outside the keep-in zone, or outside the
    arm's own work area"""
    NO_PATH = "no_path"
    """no collision-free path was found within the search budget"""


class KnotKind(StrEnum):
    """What a knot of a trajectory is (``Trajectory.knot_kinds``)."""

    START = "start"
    """where the arm is when the trajectory begins (a path's via point 0 is replaced by it;
    a resumed plan's start is no via point of the path)"""
    VIA_POINT = "via_point"
    """a via point of the request's path (``Trajectory.via_indices``: which one)"""
    WAYPOINT = "waypoint"
    """a configuration the planner chose on its way (no via point)"""
    GOAL = "goal"
    """the configuration reaching the goal a goal motion names (its last knot)"""


INTERPOLATIONS = tuple(Interpolation)
PLAN_ERROR_REASONS = tuple(PlanErrorReason)


@dataclass(frozen=True)
class ViaPoint(Message):
    """One via point (docs/protocol.md, Thesis via-point format) in SI units."""

    TYPE_NAME = "manus/ViaPoint/1"

    xyz: list[float] = field("gripper position", unit="m", length=3)
    velocity: list[float] = field("linear velocity (used at the ends only)", unit="m/s", length=3)
    ypr: list[float] = field("orientation (yaw, pitch, roll)", unit="rad", length=3)
    angular_velocity: list[float] = field(
        "(yaw, pitch, roll) rates (used at the ends only)", unit="rad/s", length=3
    )
    time: float = field("arrival time since the first via point", unit="s", minimum=0.0)
    type: int = field(
        "0 absolute, 1 relative to the first, 2 relative to the previous", minimum=0, maximum=2
    )
    line: int = field("line in the source file (0: not from a file)", default=0, minimum=0)


@dataclass(frozen=True)
class Path(Message):
    """A sequence of via points, in execution order."""

    TYPE_NAME = "manus/Path/1"

    via_points: list[ViaPoint] = field("the via points; the first is replaced by the current pose")
    source: str = field("where it came from (file name), for error messages", default="")


@MOTIONS.member
@dataclass(frozen=True)
class ViaPointPath(Motion):
    """A path of via points, each reached at its time (the thesis's via-point file).

    docs/protocol.md, Thesis via-point format; the first via point stands for the start.
    """

    TYPE_NAME = "manus/ViaPointPath/1"

    kind: str = tag("via_points", "a path of via points (the thesis's via-point file)")
    path: Path = field("the path")
    interpolation: str = field(
        "cubic spline through all via points, or quintic segments",
        default="cubic",
        choices=Interpolation,
    )
    speed_scaling: bool = field(
        "stretch time to respect joint speed/acceleration limits instead of refusing", default=False
    )


@MOTIONS.member
@dataclass(frozen=True)
class ViaPointContinuation(Motion):
    """The rest of a running path from a moving state: streamed via points appended to it,
    or replacing those not yet reached (docs/follow.md, Streamed via points).

    Via point 0 stands for the running reference's state at the splice (the request's
    ``start``: its joint angles; ``velocity``: its joint velocities); the others are
    absolute (type 0), their times counted from the splice. Never stretched in time: the
    continuation keeps the path's clock, so one the joint limits do not allow is refused.
    """

    TYPE_NAME = "manus/ViaPointContinuation/1"

    kind: str = tag("continuation", "the rest of a running path, from its moving state")
    path: Path = field("via point 0 the state at the splice, then the via points to pass")
    velocity: list[float] = field(
        "the joint velocities at the splice (the running reference's)", unit="rad/s", length=6
    )
    first_index: int = field(
        "index of via point 1 in the whole streamed path (its knots are labelled by it)",
        default=1,
        minimum=1,
    )
    interpolation: str = field(
        "cubic spline through all via points, or quintic segments",
        default="cubic",
        choices=Interpolation,
    )


SERVED_MOTIONS: tuple[type[Motion], ...] = (ViaPointPath, ViaPointContinuation, *GOAL_MOTIONS)
"""Every kind of motion a plan request may ask for (importing this module declares them
all in :data:`~schemas.motion.MOTIONS`)."""


@dataclass(frozen=True)
class Trajectory(Message):
    """A joint trajectory: piecewise cubic (or quintic) Hermite through its knots."""

    TYPE_NAME = "manus/Trajectory/1"

    times: list[float] = field("knot times, from 0, strictly increasing", unit="s")
    positions: list[list[float]] = field(
        "joint positions at the knots, one row of 6 per knot", unit="rad"
    )
    velocities: list[list[float]] = field("joint velocities at the knots", unit="rad/s")
    accelerations: list[list[float]] = field(
        "joint accelerations at the knots (empty: cubic segments)",
        unit="rad/s^2",
        default_factory=list,
    )
    via_xyz: list[list[float]] = field(
        "Cartesian gripper position of each knot",
        unit="m",
        default_factory=list,
    )
    via_lines: list[int] = field(
        "source line of each knot's via point (0: none)", default_factory=list
    )
    knot_kinds: list[str] = field(
        "what each knot is: start, via_point (a via point of the request's path) or waypoint "
        "(the planner's); empty: knot i is via point i (the start being via point 0)",
        default_factory=list,
        choices=KnotKind,
    )
    via_indices: list[int] = field(
        "for each knot, the 0-based index in the request's path of the via point it is (-1: "
        "none: a waypoint, or a resumed plan's start); empty: knot i is via point i",
        default_factory=list,
        minimum=-1,
    )
    preview_xyz: list[list[float]] = field(
        "gripper positions sampled every `preview_dt` along the trajectory, for display",
        unit="m",
        default_factory=list,
    )
    preview_dt: float = field("sampling step of the preview", unit="s", default=0.0)
    time_scale: float = field("how much the planner stretched time (1: not at all)", default=1.0)
    notes: list[str] = field("what the planner wants the user to know", default_factory=list)
    clearance: ClearanceReport | None = field(
        "the smallest clearance along the trajectory (None: not checked, no scene)",
        default=None,
    )
    scene_version: int = field(
        "version of the scene it was checked against (-1: not checked)", default=-1, minimum=-1
    )

    def knot_kind(self, i: int) -> KnotKind:
        """What knot ``i`` is (a trajectory without ``knot_kinds``: a via point, knot 0 the
        start)."""
        if self.knot_kinds:
            return KnotKind(self.knot_kinds[i])
        return KnotKind.START if i == 0 else KnotKind.VIA_POINT

    def via_index(self, i: int) -> int:
        """The index in the request's path of knot ``i``'s via point (-1: none)."""
        return self.via_indices[i] if self.via_indices else i


@dataclass(frozen=True)
class PlanResume(Message):
    """A paused plan going on: the plan as it was and how far it got.

    The request asks for the same motion again, from where the arm is now (its ``start``);
    the planner of that kind plans what is left (for a path: the via points not reached
    yet, at the plan's pace).
    """

    TYPE_NAME = "manus/PlanResume/1"

    trajectory: Trajectory = field(
        "the paused plan's trajectory, as the planner made it (after an earlier pause: the "
        "resumed one)"
    )
    reached: float = field(
        "trajectory time the arm had reached when it stopped", unit="s", minimum=0.0
    )


@dataclass(frozen=True)
class PlanRequest(Message):
    """Ask the planner for a joint trajectory: one kind of motion, from a start."""

    TYPE_NAME = "manus/PlanRequest/2"

    motion: Motion = field(
        "what to plan: one of the kinds the planner serves, named by its `kind`", union=MOTIONS
    )
    start: list[float] | None = field(
        "start configuration (DH joint angles); None: the newest joint state",
        unit="rad",
        default=None,
        length=6,
    )
    preview_dt: float = field(
        "sampling step of the Cartesian preview in the reply (0: no preview; the planner "
        "coarsens it for very long trajectories)",
        unit="s",
        default=0.06,
        minimum=0.0,
        maximum=10.0,
    )
    resume: PlanResume | None = field(
        "a paused plan of this motion to go on with (None: plan it whole)", default=None
    )


@dataclass(frozen=True)
class PlanError(Message):
    """Why a path cannot be planned, with where."""

    TYPE_NAME = "manus/PlanError/1"

    reason: str = field("kind of failure", choices=PlanErrorReason)
    message: str = field("one line for a human, naming file, line, via point, joint, value, limit")
    via_point: int = field("0-based via point index (-1: none)", default=-1)
    line: int = field("source line (0: none)", default=0)
    joint: int = field("1-based joint (0: none)", default=0)
    value: float | None = field("offending value (rad, rad/s, m)", default=None)
    limit: float | None = field("the limit it broke", default=None)


@dataclass(frozen=True)
class PlanReply(Message):
    """The planner's answer: a trajectory or an error."""

    TYPE_NAME = "manus/PlanReply/1"

    ok: bool = field("a trajectory was planned")
    trajectory: Trajectory | None = field("the trajectory (when ok)", default=None)
    error: PlanError | None = field("the error (when not ok)", default=None)
    start: list[float] | None = field(
        "the start configuration used", unit="rad", default=None, length=6
    )
    compute_ms: float = field("time spent planning", unit="ms", default=0.0)
