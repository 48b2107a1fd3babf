"""Command sources: what drives the arm, one at a time, through one pipeline.

As in MoveIt Servo, a new kind of command adds an input, not a pipeline. Each source
turns its own requests (trajectory and gripper goals, the jog stream; next a tracked
target, then streamed via points) into one cycle's command; the controller core
(:class:`~services.controller.core.ControllerCore`) does the rest, the same for all:

    joint state -> the source holding the arm: its command (motor speed steps) ->
    the collision guard -> ``cmd/joint_velocity`` -> the sources' reports and outcomes

A source implements :class:`CommandSource`:

- **admit**: its requests ask :meth:`Host.admission` (a typed :class:`Refused`: nothing
  may move, or a source above it holds the arm) before they take anything;
- **command**: :meth:`CommandSource.command`, this cycle's command from the joint state
  and the drives' estimates (:class:`Cycle`), or None when it does not hold the arm;
- **preempt or stop**: :meth:`CommandSource.stop` with an :class:`End` (a source above it
  took the arm, or a fault stops everything: arm error, bridge phase, lost joint states);
- **a typed outcome**: every run it ends, it ends with an :class:`End` (status and
  :class:`~schemas.control.EndCause` on the wire: ``GoalResult``, ``JogState``).

Sources are ranked (:attr:`CommandSource.PRIORITY`): the one with the highest rank that
holds the arm commands it; when one takes the arm, every engaged source below it is
stopped with the taker's :meth:`CommandSource.preemption`; a request to a source while one
above it holds the arm is refused (:data:`~schemas.control.Refusal.BUSY`). The registry is
:data:`services.controller.sources.SOURCES`; a new source is one module implementing this
class, one line there, and its messages (docs/architecture.md, Command sources).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, ClassVar, NamedTuple, Protocol

import numpy as np

from manus.scene import Scene
from schemas.base import Message
from schemas.collision import ClearanceReport
from schemas.commands import JointVelocityCommand
from schemas.control import CommandSourceKind, EndCause, Refusal, ResultStatus
from schemas.endpoints import Queryable, Topic
from schemas.state import JointState
from services.controller.backlash import PlayModel
from services.controller.config import ControllerConfig
from services.controller.estimator import DriveEstimator
from services.controller.guard import Verdict
from services.controller.outbox import GoalOutcome, Output


class Cycle(NamedTuple):
    """One joint state as the sources see it (usable, no arm error).

    Attributes:
        js: the joint state.
        snap_ns: its snapshot time [ns] (stamp minus the snapshot age).
        q: measured DH joint angles [rad], shape (6,).
        position: the same angles as plain floats, 6 values.
        gap: states were missing before it (answer with zeros, start references afresh).
        joints: the motors' estimate [rad, rad/s], updated with this state.
        grip: the gripper's estimate [m, m/s], updated with this state.
        play: the belts' play model.
        last_counts: motor speed steps of the previous command, shape (6,).
    """

    js: JointState
    snap_ns: int
    q: np.ndarray
    position: list[float]
    gap: bool
    joints: DriveEstimator
    grip: DriveEstimator
    play: PlayModel
    last_counts: np.ndarray


class Command(NamedTuple):
    """A source's command for one cycle, before the collision guard.

    Attributes:
        counts: motor speed steps (:mod:`manus.quantize`), shape (6,) int64.
        grip: gripper speed steps.
        goal_id: the goal whose smallest clearance the guard keeps ('' : none).
    """

    counts: np.ndarray
    grip: int
    goal_id: str = ""


class Sent(NamedTuple):
    """The command that left for one cycle, as the sources' reports see it.

    Attributes:
        js: the joint state it answers.
        command: the message published.
        guard: what the collision guard did to it, in words ('' : nothing or not guarded).
    """

    js: JointState
    command: JointVelocityCommand
    guard: str


class End(NamedTuple):
    """How and why a source's run ended (its typed outcome).

    Attributes:
        status: how (succeeded, aborted, cancelled, preempted).
        cause: why.
        reason: why, in words (names the value and the limit).
    """

    status: ResultStatus
    cause: EndCause
    reason: str


class Refused(NamedTuple):
    """Why a request is refused.

    Attributes:
        refusal: the kind.
        reason: in words.
        held_by: the source that holds the arm (refusal ``busy``), else ''.
        transient: nothing may move only while the bridge resyncs (it runs again by
            itself within ``max_outage_ms``, or every source stops): a stream may wait.
    """

    refusal: Refusal
    reason: str
    held_by: str = ""
    transient: bool = False


class Host(Protocol):
    """What a source may ask of the core that holds it."""

    @property
    def config(self) -> ControllerConfig:
        """The controller's settings."""
        ...

    @property
    def last_js(self) -> JointState | None:
        """The newest joint state (None: none yet)."""
        ...

    def admission(self, source: CommandSource) -> Refused | None:
        """Why a request of ``source`` must be refused now (None: it may take the arm)."""
        ...

    def finish(self, outcome: GoalOutcome) -> None:
        """A goal ended: its result leaves with the next publication."""
        ...

    def clearance(self, goal_id: str) -> ClearanceReport | None:
        """The smallest clearance the guard computed for ``goal_id`` (forgotten once read)."""
        ...

    @property
    def scene(self) -> Scene | None:
        """The scene the collision guard keeps clear of (None: none); a new object when
        the planner's scene replaces it."""
        ...

    def move_object(self, name: str, pose: np.ndarray) -> None:
        """Place the scene object ``name`` at ``pose`` (4x4, chair frame) in the collision
        guard, now and in every scene that replaces this one (a person a tracker follows).

        Raises:
            SceneError: no such object.
        """
        ...


class SourceInput(NamedTuple):
    """A publication a source takes (a row of the controller's wiring map).

    Attributes:
        endpoint: the key.
        handle: ``(source, message) -> outputs``.
        bad: ``(source, error) -> outputs`` for a payload that does not decode (None:
            only counted by the node).
    """

    endpoint: Topic[Any]
    handle: Callable[[Any, Any], Output]
    bad: Callable[[Any, str], Output] | None = None


class SourceAnswer(NamedTuple):
    """A queryable a source answers (a row of the controller's wiring map).

    Attributes:
        endpoint: the queryable.
        handle: ``(source, request) -> reply``.
    """

    endpoint: Queryable[Any, Any]
    handle: Callable[[Any, Any], Message]


class CommandSource(ABC):
    """One way of driving the arm (see the module docstring).

    Args:
        host: the core holding it.
    """

    KIND: ClassVar[CommandSourceKind]
    """Its name on the wire (``GoalAck.held_by``)."""
    PRIORITY: ClassVar[int]
    """Its rank: a source above another preempts it and refuses its requests."""
    STOPS_AT_ONCE: ClassVar[bool] = False
    """When it stops the arm by a request, a zero command replaces the one already sent
    for this cycle (the jog: a released stick); else the stop waits for the next cycle
    (a cancelled goal decelerates)."""
    BUSY: ClassVar[str] = ""
    """What a refused request of a source below it is told while it holds the arm."""
    INPUTS: ClassVar[tuple[SourceInput, ...]] = ()
    ANSWERS: ClassVar[tuple[SourceAnswer, ...]] = ()

    def __init__(self, host: Host) -> None:
        self.host = host

    @property
    @abstractmethod
    def engaged(self) -> bool:
        """It holds the arm (has something to run, or runs it)."""

    def observe(self, js: JointState, last: JointState | None) -> None:
        """Every new joint state, usable or not, before any command (its clocks)."""
        return None

    @abstractmethod
    def command(self, cycle: Cycle) -> Command | None:
        """This cycle's command (None: it does not hold the arm; the next source may)."""

    def guarded(self, command: Command, verdict: Verdict) -> None:
        """The collision guard scaled its command down (``verdict.scale``; 0: stopped)."""
        return None

    @abstractmethod
    def stop(self, end: End) -> None:
        """End whatever it holds with ``end`` (preempted by a source above it, or a fault)."""

    def preemption(self) -> End | None:
        """The end of the engaged sources below it now that it holds the arm (None: it
        takes nothing from them)."""
        return None

    def token_gone(self, service: str) -> str:
        """The liveliness token ``alive/<service>`` went: why it stopped ('' : it did not)."""
        return ""

    def reports(self, sent: Sent) -> Output:
        """What it publishes with the command of a cycle (every cycle answered)."""
        return []
