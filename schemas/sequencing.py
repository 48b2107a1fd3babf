"""The supervisor's interface: tasks, their control and their events (their keys:
``SUBMIT``, ``TASK_CONTROL``, ``TASK_STATUS`` and ``EVENTS`` of :mod:`schemas.endpoints`).

A task is validated whole before anything moves (every file parses, every path plans
from where the previous step leaves the arm, every opening is in range); a refused task
gets every problem at once, each with its location.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field
from schemas.control import ControlMode
from schemas.follow import FollowGoal
from schemas.motion import MOTIONS, Motion
from schemas.planning import Interpolation, Path


class StepKind(StrEnum):
    """What a task step does."""

    MOVE = "move"
    GRIPPER = "gripper"
    FOLD_IN = "fold_in"
    FOLD_OUT = "fold_out"
    WAIT = "wait"
    POSE = "pose"
    FOLLOW = "follow"
    REACH = "reach"
    PICK = "pick"
    PLACE = "place"
    GIVE = "give"


class TaskAction(StrEnum):
    """What a :class:`TaskControl` asks for."""

    CANCEL = "cancel"
    PAUSE = "pause"
    RESUME = "resume"
    STATUS = "status"
    DONE = "done"
    """end the running follow step: the arm stops following, the task goes on"""


class TaskState(StrEnum):
    """Where a task stands (``validating``: submitted, its moves being planned)."""

    NONE = "none"
    VALIDATING = "validating"
    RUNNING = "running"
    PAUSED = "paused"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    CANCELLED = "cancelled"


class TaskEventKind(StrEnum):
    """What happened to a task (:attr:`TaskEvent.event`)."""

    ACCEPTED = "accepted"
    STEP_STARTED = "step_started"
    STEP_PROGRESS = "step_progress"
    STEP_FINISHED = "step_finished"
    STEP_FAILED = "step_failed"
    PAUSED = "paused"
    RESUMED = "resumed"
    CANCELLED = "cancelled"
    SUCCEEDED = "succeeded"
    FAILED = "failed"


DEFAULT_POSE_DURATION_S = 4.0
"""Shortest time of a move to a named pose unless the step says otherwise [s]."""
STEP_KINDS = tuple(StepKind)
TASK_ACTIONS = tuple(TaskAction)
TASK_STATES = tuple(TaskState)
EVENTS = tuple(TaskEventKind)
FINAL_EVENTS = (TaskEventKind.SUCCEEDED, TaskEventKind.FAILED, TaskEventKind.CANCELLED)
"""Events that end a task."""


@dataclass(frozen=True)
class TaskStep(Message):
    """One step of a task."""

    TYPE_NAME = "manus/TaskStep/1"

    kind: str = field("what the step does", choices=StepKind)
    path: Path | None = field("for move: the path", default=None)
    opening: float = field("for gripper: target opening", unit="m", default=0.0)
    duration: float = field(
        "for wait: how long; for pose: the shortest time of the move (the planner may "
        f"stretch it; 0: {DEFAULT_POSE_DURATION_S:g} s); for follow: how long to hold at "
        "the standoff point once there (0: until the supervisor's `done`)",
        unit="s",
        default=0.0,
    )
    pose: str = field("for pose: a named pose (home, folded, unfolded)", default="")
    goal: Motion | None = field(
        "for reach: the goal, one of the goal motions (joints, pose, named, object, line; "
        "docs/reach.md), planned around the scene by the planner",
        default=None,
        union=MOTIONS,
    )
    where: str = field("where the step was written (file:line), for errors", default="")
    interpolation: str = field(
        "for move and pose: cubic spline or quintic segments",
        default=Interpolation.CUBIC,
        choices=Interpolation,
    )
    speed_scaling: bool = field(
        "for move: stretch time to respect joint limits instead of refusing (pose: always)",
        default=False,
    )
    follow: FollowGoal | None = field(
        "for follow: the tracker, standoff, approach and tracked point (its goal_id is the "
        "sequencer's)",
        default=None,
    )
    object: str = field(
        "for pick, place and give: the world model's object (its id, docs/pick.md)", default=""
    )
    at: list[float] | None = field(
        "for place: where the object's centre goes, chair frame: x, y, z [m] and yaw, pitch, "
        "roll [rad] (None: on `surface` or `back`); for give: where it is handed over, its "
        "centre and the gripper's yaw (pitch and roll 0; None: the sequencer's hand-over pose)",
        default=None,
        length=6,
    )
    surface: str = field(
        "for place: the scene object it is put on (its top, above where the object is held)",
        default="",
    )
    back: bool = field(
        "for place: back where this task's pick took it from (its centre and yaw as the pick "
        "saw it)",
        default=False,
    )


@dataclass(frozen=True)
class Task(Message):
    """A task: steps run in order."""

    TYPE_NAME = "manus/Task/1"

    steps: list[TaskStep] = field("the steps, in execution order")
    name: str = field("a name for logs and events", default="")
    mode: str = field(
        "controller mode for move steps", default=ControlMode.DEFAULT, choices=ControlMode
    )


@dataclass(frozen=True)
class SubmitReply(Message):
    """Answer to a submitted task: its id, or every validation error."""

    TYPE_NAME = "manus/SubmitReply/1"

    accepted: bool = field("the task passed validation and was queued")
    task_id: str = field("id of the task ('' when refused)")
    errors: list[str] = field(
        "every problem found, each naming its step and location", default_factory=list
    )


@dataclass(frozen=True)
class TaskControl(Message):
    """Cancel, pause, resume or ask for the status of a task."""

    TYPE_NAME = "manus/TaskControl/1"

    action: str = field("what to do", choices=TaskAction)
    task_id: str = field("task concerned; empty: the current one", default="")


@dataclass(frozen=True)
class TaskStatus(Message):
    """Where a task stands."""

    TYPE_NAME = "manus/TaskStatus/1"

    ok: bool = field("the request was carried out")
    task_id: str = field("the task ('' when none)")
    state: str = field("task state", choices=TaskState)
    step: int = field("0-based index of the current step (-1: none)")
    total: int = field("number of steps")
    progress: float = field("fraction of the task done, 0..1", minimum=0.0, maximum=1.0)
    message: str = field("details or why the request was refused", default="")


@dataclass(frozen=True)
class TaskEvent(Message):
    """Something happened to a task."""

    TYPE_NAME = "manus/TaskEvent/1"

    stamp_ns: int = field("time of the event", unit="ns")
    seq: int = field("sequence number", minimum=0)
    task_id: str = field("the task")
    event: str = field("what happened", choices=TaskEventKind)
    step: int = field("0-based step index (-1: the task as a whole)")
    total: int = field("number of steps")
    kind: str = field("kind of the step ('' for task events)", default="")
    progress: float = field("fraction of the step (step events) or task done", default=0.0)
    reason: str = field("why (failures, cancel), from the service that failed", default="")


@dataclass(frozen=True)
class TaskRecord(Message):
    """One task as the sequencer remembers it: how it ended (or that it still runs)."""

    TYPE_NAME = "manus/TaskRecord/1"

    task_id: str = field("the task")
    name: str = field("its name")
    state: str = field("its state now (running, paused, or how it ended)", choices=TaskState)
    steps: int = field("number of steps", minimum=0)
    step: int = field("0-based step it is at or ended at (-1: none)")
    reason: str = field("why it failed or was cancelled ('' otherwise)")
    started_ns: int = field("sequencer clock when it started", unit="ns")
    ended_ns: int = field("sequencer clock when it ended (0: not yet)", unit="ns")
    final: TaskEvent | None = field(
        "its final event (succeeded, failed, cancelled) exactly as published on "
        "sequencer/events; null while it runs. A client that missed it on the bus (a link "
        "cut, a sequencer whose session was down) reads it here",
        default=None,
    )


@dataclass(frozen=True)
class HistoryRequest(Message):
    """Ask for the most recent tasks (``sequencer/history``)."""

    TYPE_NAME = "manus/HistoryRequest/1"

    limit: int = field("at most this many, newest first", default=10, minimum=1, maximum=100)


@dataclass(frozen=True)
class TaskHistory(Message):
    """The most recent tasks, newest first: the current one (if any), then those that
    ended, as far back as the sequencer keeps (``SequencerConfig.history``)."""

    TYPE_NAME = "manus/TaskHistory/1"

    tasks: list[TaskRecord] = field("newest first", default_factory=list)
