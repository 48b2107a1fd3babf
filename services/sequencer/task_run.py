"""A task's run: its state, its steps one after the other, its events and its end.

:class:`TaskRun` is the base of :class:`~services.sequencer.core.SequencerCore` (which
adds the submission, the controls and the inputs): it holds the running task (the task,
the step index, the task state, the pause and cancel requests, the query the step waits
for, the step's deadline, progress, events, the history of ended tasks) and is the
:class:`~services.sequencer.step.StepContext` of the running step.

Steps (docs/protocol.md, Thesis task form), one class per kind in
:mod:`services.sequencer.steps`:

- **move / pose**: plan from the newest joint state (``planner/plan`` with an explicit
  ``start``), send the trajectory (``controller/goal``), wait for its ``GoalResult``.
- **gripper**: ``controller/gripper``, wait for the result.
- **fold_in / fold_out**: ``bridge/command`` with the deadman of moves; wait for
  ``state/bridge`` to show the fold (``folding_*``) and then leave it: ``running`` is
  success, ``stopped`` (the fold's deadman) / ``arm_error`` / ``estopped`` failure. Bridge
  states are taken in the bridge's order: one with a lower ``seq`` and no newer stamp
  than the newest (published late by another of the bridge's threads) is ignored, or
  it could end a fold that has only just begun.
- **wait**: time from the inputs.

**Pause** stops the arm and keeps the task: a running trajectory or gripper goal is
cancelled (the controller decelerates within the arm's limits) and, on **resume**, the
rest of the step is planned again from where the arm stopped, by the planner that made
the plan (the same motion, with the paused trajectory and how far it got:
:class:`~schemas.planning.PlanResume`; for a path, the via points not yet reached, at
their planned pace), or the gripper goal is sent again. A wait keeps its remaining time.
A fold cannot be interrupted safely half-way: a pause asked during a fold (or while a
plan or goal request is in flight) takes effect as soon as that finishes. **Cancel** ends
the task and stops the arm: a running goal is cancelled (bounded deceleration), a fold is
stopped by the bridge (``stop``, then ``clear`` so the arm is ready for the next task). A
controller that does not confirm a cancel or pause within ``cancel_timeout_s`` gets the
bridge's ``stop``.

**The user takes over** (live control, ``schemas/jog.py``): when the controller ends the
running goal because a jog command arrived (result ``preempted``, cause
``user_took_over``) or refuses a goal because the user jogs (refusal ``busy``, held by
the ``jog``), the task
pauses (event ``paused``, reason "user took over") instead of failing, and so it does when
``controller/jog_state`` shows a jog while it waits, plans or sends a goal (a fold cannot
be jogged: the bridge holds the arm). It resumes only when asked, from wherever the user
left the arm.
"""

from __future__ import annotations

from manus.grasps import load_grasps
from manus.scene import Scene, scene_from_setting
from manus.world_follower import WorldFollower
from schemas.base import Message
from schemas.sequencing import (
    Task,
    TaskEvent,
    TaskEventKind,
    TaskHistory,
    TaskRecord,
    TaskState,
)
from schemas.state import JointState
from services.sequencer.actions import EVENTS_SUFFIX, Action, Publish, Query
from services.sequencer.config import SequencerConfig
from services.sequencer.object_stages import ObjectView
from services.sequencer.step import BY_REQUEST, NS, Phase, Step
from services.sequencer.steps import STEP_TYPES
from services.sequencer.validate import step_label

ACTIVE_STATES = (TaskState.RUNNING, TaskState.PAUSED)


class TaskRun:
    """One task at a time, run step by step (see the module docstring).

    Args:
        config: timeouts, arm geometry.
    """

    def __init__(self, config: SequencerConfig | None = None) -> None:
        self.config = config or SequencerConfig()
        self.latest: JointState | None = None
        self.task: Task | None = None
        self.task_id = ""
        self.state = TaskState.NONE
        self.step = -1
        self.reason = ""
        self.now = 0
        self.bridge_phase = ""  # the bridge's newest phase ("" before its first state)
        self._seq = 0
        self._token = 0
        self._goals = 0
        self._started_ns = 0
        self._history: list[TaskRecord] = []  # ended tasks, oldest first
        self._reset_step()
        self.world = WorldFollower()
        """The world model as the planner publishes it (the objects, what the arm holds)."""
        self.stale_after_s = 0.0  # the world model's, from its newest update [s]
        self.world_ns = 0  # the world model's newest update's stamp [ns]
        self.origins: dict[str, list[float]] = {}
        """Where the running task's picks took each object from (``ObjectView.origins``)."""
        self.grasps = load_grasps(self.config.pick.grasps)
        self.scene: Scene | None = scene_from_setting(self.config.scene)
        """The scene in use (the planner's, once it announced it)."""

    def _reset_step(self) -> None:
        self._current: Step | None = None  # the running step (None: not begun)
        self._await: int | None = None  # token of the query the step waits for
        self._deadline: int | None = None  # the step fails (or stops) if nothing by then [ns]
        self.step_progress = 0.0
        self._reported = -1.0
        self.pause_requested = False
        self.pause_reason = ""  # why the next pause happens ('' : asked for)
        self.cancel_requested = False

    # -- the task ------------------------------------------------------------------------------

    @property
    def busy(self) -> bool:
        """A task is running or paused."""
        return self.state in ACTIVE_STATES

    @property
    def _phase(self) -> Phase:  # the name the live tests poll
        return self.phase

    @property
    def phase(self) -> Phase:
        """What the current step is doing (:class:`~services.sequencer.step.Phase`)."""
        if self.state == TaskState.PAUSED:
            return Phase.PAUSED
        if self.state != TaskState.RUNNING or self._current is None:
            return Phase.IDLE
        return self._current.phase

    def start_configuration(self) -> list[float] | None:
        """The arm's configuration now (newest valid joint state), for validation."""
        if self.latest is None or not self.latest.valid:
            return None
        return list(self.latest.position)

    def object_view(self) -> ObjectView:
        """What an object step knows of the world now."""
        return ObjectView(
            self.world.objects,
            self.scene,
            self.config.arm,
            self.grasps,
            self.config.pick,
            self.now,
            self.stale_after_s,
            self.world_ns,
            self.origins,
        )

    def history(self, limit: int) -> TaskHistory:
        """The ``limit`` most recent tasks, newest first (``sequencer/history``)."""
        records = list(reversed(self._history))
        if self.busy:
            records.insert(0, self._record(0))
        return TaskHistory(tasks=records[:limit])

    def _record(self, ended_ns: int, final: TaskEvent | None = None) -> TaskRecord:
        assert self.task is not None
        return TaskRecord(
            task_id=self.task_id,
            name=self.task.name,
            state=self.state,
            steps=len(self.task.steps),
            step=self.step,
            reason=self.reason,
            started_ns=self._started_ns,
            ended_ns=ended_ns,
            final=final,
        )

    def _end(self, final: Publish) -> list[Action]:
        """The task has just ended with ``final``: remember it, with its final event
        (at most ``config.history``); the event to publish."""
        assert isinstance(final.message, TaskEvent)
        self._history.append(self._record(self.now, final.message))
        del self._history[: -self.config.history]
        return [final]

    def start(self, task_id: str, task: Task, now_ns: int) -> list[Action]:
        """Start a validated task (:meth:`submit` does it; a caller of its own checked
        :meth:`refuse` and validated the task)."""
        self.now = now_ns
        self._started_ns = now_ns
        self.task, self.task_id, self.state, self.reason = task, task_id, TaskState.RUNNING, ""
        self.step = 0
        self._goals = 0
        self.origins = {}
        self._reset_step()
        out = [self._event(TaskEventKind.ACCEPTED, step=-1, progress=0.0)]
        return out + self._start_step()

    # -- steps ---------------------------------------------------------------------------------

    def _start_step(self) -> list[Action]:
        assert self.task is not None
        if self.step >= len(self.task.steps):
            self.state = TaskState.SUCCEEDED
            self.step = len(self.task.steps) - 1
            self.step_progress = 1.0
            return self._end(self._event(TaskEventKind.SUCCEEDED, step=-1, progress=1.0))
        if self.pause_requested:
            return self.paused()
        spec = self.task.steps[self.step]
        self._current = STEP_TYPES[spec.kind](spec, self)
        out: list[Action] = [self._event(TaskEventKind.STEP_STARTED, progress=0.0)]
        return out + self._current.begin()

    def _pause(self) -> list[Action]:
        out = self._current.pause() if self._current is not None else None
        if out is None:  # planning, acking, folding: at their end
            self.pause_requested = True
            return []
        return out

    def _cancel(self) -> list[Action]:
        self.cancel_requested = True
        if self.state == TaskState.PAUSED or self._current is None:
            return self.cancelled(BY_REQUEST)
        return self._current.cancel()

    def _check_deadline(self) -> list[Action]:
        if not self.busy or self._deadline is None or self.now < self._deadline:
            return []
        self._deadline = None
        return self._current.on_deadline() if self._current is not None else []

    # -- the running step's calls (services.sequencer.step.StepContext) ------------------------

    def new_goal_id(self) -> str:
        """A controller goal id for the current step: ``<task>.<step, 1-based>.<n>``."""
        self._goals += 1
        return f"{self.task_id}.{self.step + 1}.{self._goals}"

    def query(
        self, suffix: str, request: Message, reply_type: type[Message], *, wait: bool = False
    ) -> Query:
        """A query; with ``wait`` its answer goes to the running step."""
        self._token += 1
        if wait:
            self._await = self._token
        return Query(self._token, suffix, request, reply_type)

    def set_deadline(self, after_s: float) -> None:
        """The step's deadline: ``after_s`` [s] from now (its ``on_deadline`` then)."""
        self._deadline = self.now + int(after_s * NS)

    def report(self, progress: float) -> list[Action]:
        """The step's progress (an event when it moved by ``progress_step``)."""
        self.step_progress = progress
        if abs(progress - self._reported) < self.config.progress_step and progress < 1.0:
            return []
        self._reported = progress
        return [self._event(TaskEventKind.STEP_PROGRESS, progress=progress)]

    def step_done(self) -> list[Action]:
        """The step succeeded: the next one (or a pause or cancel asked meanwhile)."""
        self.step_progress = 1.0
        out: list[Action] = [self._event(TaskEventKind.STEP_FINISHED, progress=1.0)]
        pause = self.pause_requested
        cancel = self.cancel_requested
        self.step += 1
        self._reset_step()
        if cancel:
            return out + self.cancelled(BY_REQUEST)
        self.pause_requested = pause
        return out + self._start_step()

    def paused(self, reason: str = "") -> list[Action]:
        """The arm stopped for a pause (``reason``: why, when it was not asked for)."""
        reason, self.pause_reason = reason or self.pause_reason, ""
        self.pause_requested = False
        self.state = TaskState.PAUSED
        self._deadline = None
        progress = self._task_progress()
        return [self._event(TaskEventKind.PAUSED, progress=progress, step=self.step,
                            reason=reason)]  # fmt: skip

    def cancelled(self, reason: str) -> list[Action]:
        """The task ends cancelled."""
        self.state = TaskState.CANCELLED
        self.reason = reason
        self._await = None
        self._deadline = None
        progress = self._task_progress()
        return self._end(self._event(TaskEventKind.CANCELLED, step=self.step,
                                     progress=progress, reason=reason))  # fmt: skip

    def fail(self, reason: str) -> list[Action]:
        """The task fails (what the running step started is stopped)."""
        out: list[Action] = []
        if self.state == TaskState.RUNNING and self._current is not None:
            out += self._current.cleanup()
        assert self.task is not None
        full = f"{step_label(self.task.steps[self.step], self.step)}: {reason}"
        out.append(self._event(TaskEventKind.STEP_FAILED, reason=full))
        self.state = TaskState.FAILED
        self.reason = full
        self._await = None
        self._deadline = None
        progress = self._task_progress()
        return out + self._end(self._event(TaskEventKind.FAILED, step=self.step,
                                           progress=progress, reason=full))  # fmt: skip

    # -- outputs -------------------------------------------------------------------------------

    def _task_progress(self) -> float:
        total = len(self.task.steps) if self.task is not None else 0
        if not total:
            return 0.0
        return min(1.0, max(0.0, (max(self.step, 0) + self.step_progress) / total))

    def _event(
        self,
        event: TaskEventKind,
        *,
        step: int | None = None,
        progress: float = 0.0,
        reason: str = "",
    ) -> Publish:
        total = len(self.task.steps) if self.task is not None else 0
        index = self.step if step is None else step
        kind = self.task.steps[index].kind if self.task is not None and 0 <= index < total else ""
        self._seq += 1
        msg = TaskEvent(
            stamp_ns=self.now,
            seq=self._seq,
            task_id=self.task_id,
            event=event,
            step=index,
            total=total,
            kind=kind,
            progress=progress,
            reason=reason,
        )
        return Publish(EVENTS_SUFFIX, msg)
