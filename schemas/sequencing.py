"""The supervisor's interface: tasks, their control and their events (their keys:
``SUBMIT``, ``TASK_CONTROL``, ``TASK_STATUS`` and ``EVENTS`` of :mod:`schemas.endpoints`).

A task is validated whole before anything moves (every file parses, every path plans
from where the previous step leaves the arm, every opening is in range); a refused task
gets every problem at once, each with its location.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.base import Message, field
from schemas.planning import Path

STEP_KINDS = ("move", "gripper", "fold_in", "fold_out", "wait", "pose")
TASK_ACTIONS = ("cancel", "pause", "resume", "status")
TASK_STATES = ("none", "validating", "running", "paused", "succeeded", "failed", "cancelled")
EVENTS = (
    "accepted",
    "step_started",
    "step_progress",
    "step_finished",
    "step_failed",
    "paused",
    "resumed",
    "cancelled",
    "succeeded",
    "failed",
)


@dataclass(frozen=True)
class TaskStep(Message):
    """One step of a task."""

    TYPE_NAME = "manus/TaskStep/1"

    kind: str = field("what the step does", choices=STEP_KINDS)
    path: Path | None = field("for move: the path", default=None)
    opening: float = field("for gripper: target opening", unit="m", default=0.0)
    duration: float = field(
        "for wait: how long; for pose: the shortest time of the move (the planner may stretch it)",
        unit="s",
        default=0.0,
    )
    pose: str = field("for pose: a named pose (home, folded, unfolded)", default="")
    where: str = field("where the step was written (file:line), for errors", default="")
    interpolation: str = field(
        "for move and pose: cubic spline or quintic segments",
        default="cubic",
        choices=("cubic", "quintic"),
    )
    speed_scaling: bool = field(
        "for move: stretch time to respect joint limits instead of refusing (pose: always)",
        default=False,
    )


@dataclass(frozen=True)
class Task(Message):
    """A task: steps run in order."""

    TYPE_NAME = "manus/Task/1"

    steps: list[TaskStep] = field("the steps, in execution order")
    name: str = field("a name for logs and events", default="")
    mode: str = field(
        "controller mode for move steps", default="default", choices=("default", "thesis")
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

    action: str = field("what to do", choices=TASK_ACTIONS)
    task_id: str = field("task concerned; empty: the current one", default="")


@dataclass(frozen=True)
class TaskStatus(Message):
    """Where a task stands."""

    TYPE_NAME = "manus/TaskStatus/1"

    ok: bool = field("the request was carried out")
    task_id: str = field("the task ('' when none)")
    state: str = field("task state", choices=TASK_STATES)
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
    event: str = field("what happened", choices=EVENTS)
    step: int = field("0-based step index (-1: the task as a whole)")
    total: int = field("number of steps")
    kind: str = field("kind of the step ('' for task events)", default="")
    progress: float = field("fraction of the step (step events) or task done", default=0.0)
    reason: str = field("why (failures, cancel), from the service that failed", default="")
