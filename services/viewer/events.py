"""What the viewer's log (``P/viz/log``) says about the bus: arm warnings and errors,
bridge phases, goals and results, task events, e-stops, a scene replaced at run time,
services appearing and vanishing.

:class:`EventLog` turns each decoded message into :class:`LogLine` s (none when nothing
changed worth a line); the viewer's core encodes them. Deterministic, no clock.
"""

from __future__ import annotations

from typing import NamedTuple

from manus.scene import Scene
from schemas.collision import SceneState
from schemas.commands import EStop
from schemas.control import GoalResult, TrajectoryGoal
from schemas.liveliness import LivelinessChange
from schemas.planning import PlanReply
from schemas.sequencing import TaskEvent
from schemas.state import ArmStatus, BridgeState

BAD_PHASES = ("resync", "stopped", "estopped", "arm_error", "shutdown")
"""Bridge phases logged as warnings."""


class LogLine(NamedTuple):
    """One line of the viewer's log.

    Attributes:
        level: ``info``, ``warning`` or ``error``.
        name: who it is about (``arm``, ``can_bridge``, ``controller``, a service, ...).
        text: the line.
    """

    level: str
    name: str
    text: str


class EventLog:
    """Log lines of the bus's messages; arm messages and bridge phases only when they
    change."""

    def __init__(self) -> None:
        self._status: tuple[str, int] = ("none", 0)
        self._phase = ""

    def arm_status(self, msg: ArmStatus) -> list[LogLine]:
        """A new arm warning or error, or its clearing (general messages are not logged)."""
        now = (msg.msg_class, msg.msg_code)
        if now == self._status or msg.msg_class == "general":
            return []
        self._status = now
        if msg.msg_class == "none":
            return [LogLine("info", "arm", "message cleared")]
        level = "error" if msg.msg_class == "error" else "warning"
        return [LogLine(level, "arm", f"{msg.msg_class} {msg.msg_code}: {msg.text}")]

    def bridge(self, msg: BridgeState) -> list[LogLine]:
        """A new bridge phase."""
        if msg.phase == self._phase:
            return []
        self._phase = msg.phase
        level = "warning" if msg.phase in BAD_PHASES else "info"
        detail = f" ({msg.detail})" if msg.detail else ""
        return [LogLine(level, "can_bridge", f"phase {msg.phase}{detail}")]

    @staticmethod
    def goal(msg: TrajectoryGoal) -> list[LogLine]:
        """A trajectory goal sent to the controller."""
        traj = msg.trajectory
        text = (
            f"goal {msg.goal_id}: {len(traj.times)} knots, {traj.times[-1]:.2f} s, mode {msg.mode}"
        )
        return [LogLine("info", "controller", text)]

    @staticmethod
    def plan_refused(msg: PlanReply) -> list[LogLine]:
        """A plan the planner refused."""
        reason = msg.error.message if msg.error is not None else "no trajectory"
        return [LogLine("warning", "planner", f"plan refused: {reason}")]

    @staticmethod
    def result(msg: GoalResult) -> list[LogLine]:
        """A goal's end, with its via-point errors."""
        level = {"succeeded": "info", "aborted": "error"}.get(msg.status, "warning")
        errs = msg.path_via_errors
        err = (
            f", via error mean {1000 * sum(errs) / len(errs):.2f} max {1000 * max(errs):.2f} mm"
            if errs
            else ""
        )
        text = f"{msg.kind} goal {msg.goal_id} {msg.status}: {msg.reason}{err}"
        return [LogLine(level, "controller", text)]

    @staticmethod
    def task_event(msg: TaskEvent) -> list[LogLine]:
        """A task's event (progress is not logged)."""
        if msg.event == "step_progress":
            return []
        level = {"failed": "error", "step_failed": "error", "cancelled": "warning"}.get(
            msg.event, "info"
        )
        step = f" step {msg.step + 1}/{msg.total} {msg.kind}" if msg.step >= 0 else ""
        reason = f": {msg.reason}" if msg.reason else ""
        return [LogLine(level, "sequencer", f"task {msg.task_id}{step} {msg.event}{reason}")]

    @staticmethod
    def estop(msg: EStop) -> list[LogLine]:
        """An e-stop engaged or released."""
        what = "engaged" if msg.engaged else "released"
        reason = f": {msg.reason}" if msg.reason else ""
        level = "error" if msg.engaged else "info"
        return [LogLine(level, msg.source or "estop", f"e-stop {what}{reason}")]

    @staticmethod
    def scene(msg: SceneState, parsed: Scene | None, problem: str = "") -> list[LogLine]:
        """A scene the planner published: drawn (``parsed``), or not (``problem``)."""
        if parsed is None:
            return [
                LogLine("warning", "planner", f"scene version {msg.version} not drawn: {problem}")
            ]
        text = (
            f"scene version {msg.version} ({parsed.source}): {len(parsed.objects)} objects, "
            f"{len(parsed.zones)} zones"
        )
        return [LogLine("info", "planner", text)]

    @staticmethod
    def liveliness(msg: LivelinessChange) -> list[LogLine]:
        """A service's ``alive`` token appearing or vanishing."""
        if msg.kind != "alive":
            return []
        what = "up" if msg.alive else "gone"
        level = "info" if msg.alive else "warning"
        return [LogLine(level, msg.service or "liveliness", f"{msg.service} {what}")]
