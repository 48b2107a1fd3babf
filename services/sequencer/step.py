"""The base of the kinds of task step: :class:`Step`, its :class:`Phase` and what it may
see and do of its task (:class:`StepContext`).

The core (:class:`services.sequencer.core.SequencerCore`) keeps what belongs to the task:
the task, the step index, the task state, the pause and cancel requests, the query it
waits for, the step's deadline, progress and events. The object of the running step
keeps what belongs to the step (its :class:`Phase`, its goal, its trajectory, where it
paused) and is dropped when the step ends. It reaches the core only through
:class:`StepContext`. Each kind is one class in its own module, listed in
:data:`services.sequencer.steps.STEP_TYPES`; its checks before the task starts are
:meth:`Step.problems`, :meth:`Step.plan` and :meth:`Step.leaves_arm_at` (used by
:class:`services.sequencer.validate.Validator`).

Hooks the core calls while the step runs (each returns the actions to take; ``None``
from :meth:`Step.pause`, :meth:`Step.on_bridge_state` and :meth:`Step.on_tick` means
"not mine": the core does its default):

- :meth:`Step.begin` starts the step, :meth:`Step.resume` goes on after a pause;
- :meth:`Step.on_reply` takes the answer to the query the step waits for;
- :meth:`Step.on_feedback`, :meth:`Step.on_result`, :meth:`Step.on_follow_state`: the
  controller's feedback, results and follow states;
- :meth:`Step.done`: the supervisor's ``done`` (a step that holds until told);
- :meth:`Step.on_bridge_state`, :meth:`Step.on_tick`: bridge phases, time passing;
- :meth:`Step.pause` (``None``: not now, at the end of what is in flight),
  :meth:`Step.cancel`;
- :meth:`Step.on_deadline`: the deadline the step set passed;
- :meth:`Step.cleanup`: the task fails: stop what the step started.
"""

from __future__ import annotations

from enum import StrEnum
from typing import TYPE_CHECKING, ClassVar, Protocol

from manus.config import ArmConfig
from schemas.base import Message
from schemas.commands import ArmAction, ArmCommand
from schemas.control import ControllerFeedback, GoalResult
from schemas.follow import FollowState
from schemas.planning import PlanRequest
from schemas.sequencing import Task, TaskStep
from schemas.state import BridgeState, JointState
from services.sequencer.actions import Action, Query
from services.sequencer.config import SequencerConfig

if TYPE_CHECKING:
    from services.sequencer.object_stages import ObjectView

MAX_WAIT_S = 3600.0
"""Longest wait [s]."""

NS = 1_000_000_000
BY_REQUEST = "cancelled by request"


class Phase(StrEnum):
    """What the running step is doing (``TaskStatus.message`` while nothing else is said)."""

    IDLE = ""
    PLANNING = "planning"
    ACKING = "acking"
    ACTIVE = "active"
    FOLDING = "folding"
    WAITING = "waiting"
    WAITING_BRIDGE = "waiting_bridge"
    PAUSING = "pausing"
    PAUSED = "paused"
    CANCELLING = "cancelling"
    STOPPING = "stopping"
    CLEARING = "clearing"


class StepContext(Protocol):
    """What a step may see and do of its task (the core implements it)."""

    pause_requested: bool

    @property
    def bridge_phase(self) -> str: ...  # the bridge's newest phase ("" before its first)
    @property
    def config(self) -> SequencerConfig: ...
    @property
    def now(self) -> int: ...  # time of the input being handled [ns]
    @property
    def task(self) -> Task | None: ...
    @property
    def step_progress(self) -> float: ...  # fraction of the running step done, 0..1
    @property
    def cancel_requested(self) -> bool: ...
    @property
    def latest(self) -> JointState | None: ...  # the newest valid joint state

    def start_configuration(self) -> list[float] | None: ...
    def object_view(self) -> ObjectView: ...
    def new_goal_id(self) -> str: ...
    def query(
        self, suffix: str, request: Message, reply_type: type[Message], *, wait: bool = False
    ) -> Query: ...
    def set_deadline(self, after_s: float) -> None: ...
    def report(self, progress: float) -> list[Action]: ...
    def step_done(self) -> list[Action]: ...
    def paused(self, reason: str = "") -> list[Action]: ...
    def cancelled(self, reason: str) -> list[Action]: ...
    def fail(self, reason: str) -> list[Action]: ...


def stop_command() -> ArmCommand:
    """The bridge's ``stop``, sent by the sequencer."""
    return ArmCommand(action=ArmAction.STOP, source="sequencer")


class Step:
    """Base of the step kinds (see the module docstring).

    Args:
        spec: the step as the task gives it.
        ctx: its task (the core).
    """

    planned: ClassVar[bool] = False
    """Validation plans the step (from where the previous steps leave the arm)."""

    def __init__(self, spec: TaskStep, ctx: StepContext) -> None:
        self.spec = spec
        self.ctx = ctx
        self.phase = Phase.IDLE

    # -- before the task starts --------------------------------------------------------------

    @classmethod
    def problems(cls, spec: TaskStep) -> list[str]:
        """What is wrong with ``spec`` by itself (no planning)."""
        return []

    @classmethod
    def plan(cls, spec: TaskStep, start: list[float] | None, arm: ArmConfig) -> PlanRequest:
        """The request that plans ``spec`` from ``start`` for the arm ``arm`` (only for
        kinds with :attr:`planned`)."""
        raise TypeError(f"a {spec.kind} step is not planned")

    @classmethod
    def leaves_arm_at(cls, spec: TaskStep) -> list[float] | None:
        """Where the step leaves the arm whatever its start (DH [rad]), or None."""
        return None

    # -- while it runs -----------------------------------------------------------------------

    def begin(self) -> list[Action]:
        """Start the step (its first query, or its timer)."""
        raise NotImplementedError

    def resume(self) -> list[Action]:
        """Go on after a pause (by default: begin again)."""
        return self.begin()

    def on_reply(self, reply: Message | None, error: str) -> list[Action]:
        """The answer to the query the step waits for (None and ``error``: none came)."""
        return []

    def on_feedback(self, fb: ControllerFeedback) -> list[Action]:
        """The controller's feedback (any goal's)."""
        return []

    def on_result(self, res: GoalResult) -> list[Action]:
        """A goal's result (any goal's)."""
        return []

    def on_follow_state(self, state: FollowState) -> list[Action]:
        """The controller's follow state (any goal's)."""
        return []

    def done(self) -> list[Action] | None:
        """The supervisor's ``done`` (None: this step cannot be told it is done)."""
        return None

    def on_bridge_state(self, bs: BridgeState) -> list[Action] | None:
        """The bridge's state (None: the core checks for arm errors and e-stops)."""
        return None

    def on_tick(self) -> list[Action] | None:
        """Time passed (None: the core checks the link and the deadline)."""
        return None

    def pause(self) -> list[Action] | None:
        """Stop for a pause now (None: not now; the core keeps the request for later)."""
        return None

    def cancel(self) -> list[Action]:
        """Stop for good (by default at once: the task is cancelled)."""
        return self.ctx.cancelled(BY_REQUEST)

    def on_objects(self) -> list[Action]:
        """The world model changed (the sequencer's follower holds the new objects)."""
        return []

    def on_deadline(self) -> list[Action]:
        """The deadline the step set (:meth:`StepContext.set_deadline`) passed."""
        return []

    def cleanup(self) -> list[Action]:
        """The task fails: the queries that stop what the step started."""
        return []

    @property
    def needs_joint_states(self) -> bool:
        """Joint states must keep coming (a controller goal is on its way or running)."""
        return False
