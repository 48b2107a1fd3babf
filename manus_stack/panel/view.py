"""What the panel shows, from what the stack says: a deterministic model of the page.

:class:`PanelView` takes the supervisor API's messages (task events, submission replies,
task status, the jog's state, e-stops, services appearing and vanishing) and keeps what
the person needs: the arm's state and the task's progress in plain words, the last
trouble in one sentence (:mod:`manus_stack.panel.words`) with the stack's own report as
its details, the speed level, whether STOP is on. :meth:`PanelView.snapshot` is what the
page renders (JSON). No clock, no bus: the same messages give the same page.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from manus_stack.panel.tasks import TaskButton
from manus_stack.panel.words import Trouble, jog_trouble, refusal_trouble, sentence, task_trouble
from schemas.commands import EStop
from schemas.jog import JogState
from schemas.sequencing import (
    FINAL_EVENTS,
    StepKind,
    SubmitReply,
    TaskEvent,
    TaskEventKind,
    TaskState,
)

NEEDED = ("sequencer", "controller", "can_bridge", "planner")
"""Services without which the panel can do nothing (their liveliness tokens)."""

STEP_WORDS: dict[str, str] = {
    StepKind.FOLD_OUT: "Unfolding",
    StepKind.FOLD_IN: "Folding",
    StepKind.MOVE: "Moving",
    StepKind.POSE: "Moving",
    StepKind.GRIPPER: "Moving the hand",
    StepKind.WAIT: "Waiting",
    StepKind.FOLLOW: "Holding it for you",
}
"""What a step does, in words (a kind not here: "Working")."""


@dataclass
class Running:
    """The task the panel follows."""

    task_id: str
    label: str
    button: TaskButton | None
    choice: str = ""
    state: str = TaskState.RUNNING
    step: int = -1
    total: int = 0
    kind: str = ""
    progress: float = 0.0


@dataclass
class Notice:
    """The last thing the user was told: a sentence, the stack's report, and whether it
    is a trouble (else good news)."""

    text: str
    details: str = ""
    trouble: bool = True
    jog: bool = False
    """about the hand control: it goes once the jog runs or is released"""


class PanelView:
    """The page's model.

    Args:
        buttons: the task buttons.
    """

    def __init__(self, buttons: list[TaskButton]) -> None:
        self.buttons = buttons
        self.alive: set[str] = set()
        self.estop = False
        self.level = 0  # unknown until the controller says
        self.levels = 5
        self.jogging = False
        self.refused = -1  # the jog's refusal count (-1: none seen)
        self.task: Running | None = None
        self.notice: Notice | None = None
        self._pending: dict[str, tuple[TaskButton, str]] = {}  # submitted, by task id
        self._submitting: tuple[TaskButton, str] | None = None  # sent, not answered yet
        self._ended: list[str] = []  # the last tasks that ended (their final event came)

    # -- inputs ------------------------------------------------------------------------------

    def on_alive(self, service: str, alive: bool) -> None:
        """A service's liveliness token appeared or vanished."""
        if alive:
            self.alive.add(service)
        else:
            self.alive.discard(service)

    def on_estop(self, msg: EStop) -> None:
        """An e-stop on the bus (from anyone): STOP is on or released."""
        self.estop = msg.engaged
        if msg.engaged:
            self.notice = Notice(sentence(Trouble.STOPPED), f"e-stop by {msg.source}")
        elif self.notice is not None and self.notice.text == sentence(Trouble.STOPPED):
            self.notice = None

    def on_submitting(self, button: TaskButton, choice: str) -> None:
        """This panel sends ``button``'s task: the sequencer validates it before it answers,
        and the task's first events may come before the answer (they are this task's: the
        sequencer validates one submission at a time)."""
        self._submitting = (button, choice)

    def on_submitted(self, button: TaskButton, choice: str, reply: SubmitReply) -> None:
        """The sequencer's answer to a task this panel submitted."""
        self._submitting = None
        if not reply.accepted:
            trouble = refusal_trouble(reply)
            self._learn(trouble)
            self.notice = Notice(button.sentence(trouble, choice), "\n".join(reply.errors))
            return
        if reply.task_id in self._ended:
            return  # it ran and ended before the answer came
        self._pending[reply.task_id] = (button, choice)
        task = self.task
        if task is None or task.task_id != reply.task_id:
            self.task = Running(reply.task_id, button.label, button, choice)
        else:
            task.label, task.button, task.choice = button.label, button, choice

    def on_not_sent(self, button: TaskButton, why: str) -> None:
        """A task could not be submitted (no sequencer answered; the button not set up)."""
        self._submitting = None
        if not button.ready:
            self.notice = Notice(sentence(Trouble.NOT_SET_UP, button.label), why)
        else:
            self.notice = Notice(button.sentence(Trouble.NO_CONNECTION), why)

    def on_event(self, event: TaskEvent) -> None:
        """A task event (of any task: the panel shows whatever task runs)."""
        task = self.task
        if task is None or task.task_id != event.task_id:
            if event.task_id in self._ended:
                return  # a late event of a task that ended
            mine = self._pending.get(event.task_id) or self._submitting
            button, choice = mine if mine is not None else (None, "")
            if mine is not None:
                self._pending[event.task_id] = mine
            label = button.label if button is not None else "A task"
            task = self.task = Running(event.task_id, label, button, choice)
        task.total = event.total or task.total
        if event.step >= 0:
            task.step = event.step
            task.kind = event.kind or task.kind
        if event.event in (TaskEventKind.STEP_STARTED, TaskEventKind.STEP_PROGRESS):
            done = task.step + (event.progress if event.event == TaskEventKind.STEP_PROGRESS else 0)
            task.progress = done / task.total if task.total else 0.0
        elif event.event == TaskEventKind.STEP_FINISHED and task.total:
            task.progress = (task.step + 1) / task.total
        self._on_state(task, event)

    def _on_state(self, task: Running, event: TaskEvent) -> None:
        kind = event.event
        if kind == TaskEventKind.PAUSED:
            task.state = TaskState.PAUSED
            trouble = task_trouble(event.reason) if event.reason else None
            words = sentence(trouble) if trouble is Trouble.TOOK_OVER else "The task is paused."
            self.notice = Notice(words, event.reason, trouble=False)
        elif kind in (TaskEventKind.RESUMED, TaskEventKind.ACCEPTED):
            task.state = TaskState.RUNNING
            self.notice = None
        elif kind in FINAL_EVENTS:
            self._pending.pop(task.task_id, None)
            self._ended = [*self._ended[-9:], task.task_id]
            self.task = None
            if kind == TaskEventKind.SUCCEEDED:
                self.notice = Notice(f"Done: {task.label}.", trouble=False)
            elif kind == TaskEventKind.CANCELLED:
                self.notice = Notice(sentence(Trouble.CANCELLED), event.reason, trouble=False)
            else:
                trouble = task_trouble(event.reason)
                self._learn(trouble)
                said = (
                    task.button.sentence(trouble, task.choice)
                    if task.button is not None
                    else sentence(trouble)
                )
                self.notice = Notice(said, event.reason)

    def on_status(self, task_id: str, state: str) -> None:
        """The sequencer's current task (``sequencer/status``): a task whose final event
        the panel missed (a link cut) is no longer shown as running. The sequencer runs one
        task at a time, so a shown task that is not its current one, or no longer runs,
        has ended."""
        task = self.task
        if task is None:
            return
        live = state in (TaskState.RUNNING, TaskState.PAUSED)
        if task.task_id == task_id and live:
            task.state = state
        elif task.task_id != task_id or state != TaskState.VALIDATING:
            self._pending.pop(task.task_id, None)
            self._ended = [*self._ended[-9:], task.task_id]
            self.task = None

    def on_jog_state(self, msg: JogState) -> None:
        """The controller's jog: the level, whether it moves, why it stopped."""
        self.level, self.levels = msg.level, msg.levels
        self.jogging = msg.active
        grew = self.refused >= 0 and msg.refused > self.refused
        self.refused = msg.refused
        trouble = jog_trouble(msg.reason, grew)
        if trouble is not None:
            self._learn(trouble)
            self.notice = Notice(sentence(trouble), msg.reason, jog=True)
        elif self.notice is not None and self.notice.jog:
            self.notice = None  # the jog runs again, or was released

    def on_notice(self, trouble: Trouble, details: str = "") -> None:
        """Something the panel itself ran into (the bus, a bad request)."""
        self.notice = Notice(sentence(trouble), details)

    def _learn(self, trouble: Trouble) -> None:
        """A report that says STOP is on tells the panel so (it may have started after)."""
        if trouble is Trouble.STOPPED:
            self.estop = True

    # -- output ------------------------------------------------------------------------------

    @property
    def connected(self) -> bool:
        """Every needed service is alive."""
        return all(s in self.alive for s in NEEDED)

    def arm_words(self) -> str:
        """The arm's state in plain words."""
        task = self.task
        if not self.connected:
            missing = [s for s in NEEDED if s not in self.alive]
            return f"Not connected to the arm ({', '.join(missing)} not running)"
        if self.estop:
            return "Stopped: STOP is on"
        if task is not None and task.state == TaskState.PAUSED:
            return f"Paused: {task.label}"
        if task is not None:
            return f"Busy: {task.label}"
        if self.jogging:
            return "Moving by hand"
        return "Ready"

    def can_finish(self) -> bool:
        """The person can say "done": the running task's step is a follow step (the drink's
        hold at the mouth; the sequencer's ``done`` ends it and the task goes on)."""
        task = self.task
        return task is not None and task.state == TaskState.RUNNING and task.kind == StepKind.FOLLOW

    def task_words(self) -> str:
        """The task's progress in plain words ('' when none runs)."""
        task = self.task
        if task is None:
            return ""
        doing = STEP_WORDS.get(task.kind, "Working") if task.step >= 0 else "Starting"
        if task.state == TaskState.PAUSED:
            doing = "Paused"
        of = f", step {task.step + 1} of {task.total}" if task.total > 1 and task.step >= 0 else ""
        done = f" ({round(100 * task.progress)} %)" if task.progress > 0 else ""
        return f"{task.label}: {doing}{of}{done}"

    def snapshot(self) -> dict[str, Any]:
        """What the page shows (JSON-able)."""
        task = self.task
        notice = self.notice
        return {
            "t": "view",
            "connected": self.connected,
            "arm": self.arm_words(),
            "task": None
            if task is None
            else {
                "label": task.label,
                "state": str(task.state),
                "words": self.task_words(),
                "progress": round(task.progress, 3),
                "can_finish": self.can_finish(),
            },
            "notice": None
            if notice is None
            else {"text": notice.text, "details": notice.details, "trouble": notice.trouble},
            "estop": self.estop,
            "level": self.level,
            "levels": self.levels,
            "jogging": self.jogging,
        }

    def buttons_json(self) -> list[dict[str, Any]]:
        """The task buttons (sent once per page)."""
        return [
            {"id": b.id, "label": b.label, "ready": b.ready, "objects": list(b.objects)}
            for b in self.buttons
        ]
