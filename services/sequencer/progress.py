"""Terminal progress of a task: a bar for the task and one for the current step.

On a terminal the two bars are redrawn in place; otherwise (a pipe, a log file) each
event is one line, so logs stay readable.
"""

from __future__ import annotations

from typing import TextIO

from schemas.sequencing import StepKind, Task, TaskEvent
from schemas.sequencing import TaskEventKind as Ev

BAR_WIDTH = 24


def bar(fraction: float, width: int = BAR_WIDTH) -> str:
    """``[#####-----]  50%`` for ``fraction`` in 0..1."""
    f = min(1.0, max(0.0, fraction))
    filled = round(f * width)
    return f"[{'#' * filled}{'-' * (width - filled)}] {f * 100:3.0f}%"


def describe(task: Task, index: int) -> str:
    """A short label of step ``index`` (0-based): kind and what it does."""
    if not 0 <= index < len(task.steps):
        return ""
    step = task.steps[index]
    if step.kind == StepKind.MOVE:
        what = step.path.source if step.path is not None and step.path.source else step.where
    elif step.kind == StepKind.GRIPPER:
        what = f"{step.opening * 1e3:g} mm"
    elif step.kind == StepKind.WAIT:
        what = f"{step.duration:g} s"
    elif step.kind == StepKind.POSE:
        what = step.pose
    elif step.kind == StepKind.REACH and step.goal is not None:
        what = getattr(step.goal, "name", "") or str(getattr(step.goal, "kind", ""))
    else:
        what = ""
    return f"{step.kind} {what}".strip()


class ProgressView:
    """Shows :class:`TaskEvent` s of one task on ``stream``.

    Args:
        task: the task (for step labels).
        stream: where to write.
        live: redraw the two bars in place (a terminal); else one line per event.
    """

    def __init__(self, task: Task, stream: TextIO, *, live: bool) -> None:
        self.task = task
        self.stream = stream
        self.live = live
        self._drawn = False
        self._step = -1
        self._step_progress = 0.0
        self._task_progress = 0.0

    def show(self, event: TaskEvent) -> None:
        """Take one event of the task."""
        total = max(event.total, 1)
        if event.step >= 0:
            self._step = event.step
            self._step_progress = event.progress if event.event != Ev.STEP_STARTED else 0.0
            if event.event in (Ev.STEP_STARTED, Ev.STEP_PROGRESS, Ev.STEP_FINISHED):
                self._task_progress = (event.step + self._step_progress) / total
        elif event.event == Ev.SUCCEEDED:
            self._task_progress = 1.0
        if event.event in (Ev.PAUSED, Ev.CANCELLED, Ev.FAILED, Ev.RESUMED):
            self._task_progress = event.progress
        if self.live:
            self._redraw(event)
        elif event.event != Ev.STEP_PROGRESS:
            self._line(event)

    def _label(self, step: int, total: int) -> str:
        return f"step {step + 1}/{total} {describe(self.task, step)}"

    def _line(self, event: TaskEvent) -> None:
        head = self._label(event.step, event.total) if event.step >= 0 else "task"
        why = f": {event.reason}" if event.reason else ""
        self.stream.write(f"{head}: {event.event}{why}  task {bar(self._task_progress)}\n")
        self.stream.flush()

    def _redraw(self, event: TaskEvent) -> None:
        total = max(event.total, 1)
        if self._drawn:
            self.stream.write("\x1b[2A")  # back to the first bar; notable events scroll above
        if event.event not in (Ev.STEP_PROGRESS, Ev.STEP_STARTED, Ev.ACCEPTED):
            why = f": {event.reason}" if event.reason else ""
            head = self._label(event.step, total) if event.step >= 0 else "task"
            self.stream.write(f"\x1b[2K\r{head}: {event.event}{why}\n")
        step_text = self._label(self._step, total) if self._step >= 0 else ""
        self.stream.write(f"\x1b[2K\rtask  {bar(self._task_progress)}  {self.task.name}\n")
        self.stream.write(f"\x1b[2K\rstep  {bar(self._step_progress)}  {step_text}\n")
        self._drawn = True
        self.stream.flush()
