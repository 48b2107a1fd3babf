"""The demo's parts: its task, what it collects from the bus, its table and its plot.

The task: fold out, the thesis path (square or circle) in real time, close
and open the gripper, fold in. While it runs the demo follows ``controller/feedback``,
``controller/result`` and the controller's goal requests (their trace mirror), and then
reports the via-point errors (the controller's ``GoalResult.via_errors``: gripper position
error at each via point's time, FK of the encoders) next to the thesis's figures, and
plots planned vs executed path in the yz plane and the error over time (like the
thesis's figures: docs/protocol.md, Thesis test paths).
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field
from pathlib import Path

from manus.node import Node
from manus.viapoints import load_path
from schemas import endpoints as ep
from schemas.control import ControllerFeedback, GoalResult, TrajectoryGoal
from schemas.sequencing import Task, TaskStep

PATHS_DIR = Path(__file__).resolve().parent.parent / "paths"
"""The thesis's paths (``paths/thesis_square.txt``, ``paths/thesis_circle.txt``)."""

THESIS_MEAN_MM = 5.0
"""Mean via-point error the thesis reports for its controller [mm] (docs/protocol.md, Thesis
test paths)."""

THESIS_MAX_MM = 10.0
"""Largest via-point error the thesis reports, about [mm]."""

CLOSED_M, OPEN_M = 0.0, 0.060
"""Gripper openings of the demo [m]."""


def demo_path_file(shape: str) -> Path:
    """The via-point file of ``shape`` (square or circle)."""
    return PATHS_DIR / f"thesis_{shape}.txt"


def demo_task(shape: str) -> Task:
    """Fold out, the thesis path, close and open the gripper, fold in."""
    file = demo_path_file(shape)
    path = load_path(file)
    return Task(
        name=f"demo {shape}",
        steps=[
            TaskStep(kind="fold_out", where="demo"),
            TaskStep(kind="move", path=path, where=str(file)),
            TaskStep(kind="gripper", opening=CLOSED_M, where="demo: close the gripper"),
            TaskStep(kind="gripper", opening=OPEN_M, where="demo: open the gripper"),
            TaskStep(kind="fold_in", where="demo"),
        ],
    )


@dataclass
class Collected:
    """What the demo heard on the bus."""

    feedback: list[ControllerFeedback] = field(default_factory=list)
    results: list[GoalResult] = field(default_factory=list)
    goals: dict[str, TrajectoryGoal] = field(default_factory=dict)
    lock: threading.Lock = field(default_factory=threading.Lock)

    def listen(self, node: Node) -> None:
        """Subscribe ``node`` to feedback, results and trajectory goal requests."""
        keys = node.keys
        node.subscribe(keys(ep.FEEDBACK), ControllerFeedback, self._on_feedback, locked=False)
        node.subscribe(keys(ep.RESULT), GoalResult, self._on_result, locked=False)
        node.subscribe(keys(ep.GOAL.trace("request")), TrajectoryGoal, self._on_goal, locked=False)

    def _on_feedback(self, fb: ControllerFeedback, rx_ns: int) -> None:
        if fb.goal_id:
            with self.lock:
                self.feedback.append(fb)

    def _on_result(self, res: GoalResult, rx_ns: int) -> None:
        with self.lock:
            self.results.append(res)

    def _on_goal(self, goal: TrajectoryGoal, rx_ns: int) -> None:
        with self.lock:
            self.goals[goal.goal_id] = goal

    def path_result(self, task_id: str) -> GoalResult | None:
        """The result of the task's (last) trajectory goal."""
        with self.lock:
            mine = [
                r for r in self.results if r.kind == "trajectory" and r.goal_id.startswith(task_id)
            ]
        return mine[-1] if mine else None

    def feedback_of(self, goal_id: str) -> list[ControllerFeedback]:
        """Feedback of one goal, in order."""
        with self.lock:
            return [f for f in self.feedback if f.goal_id == goal_id]


@dataclass(frozen=True)
class ErrorTable:
    """Via-point errors [mm] of one path."""

    errors_mm: list[float]
    lines: list[int]

    @property
    def scored_mm(self) -> list[float]:
        """The errors that count [mm]: all but via point 0, the start pose (see
        ``GoalResult.path_via_errors``)."""
        return self.errors_mm[1:]

    @property
    def mean_mm(self) -> float:
        return sum(self.scored_mm) / len(self.scored_mm) if self.scored_mm else math.nan

    @property
    def max_mm(self) -> float:
        return max(self.scored_mm) if self.scored_mm else math.nan

    def render(self, title: str) -> str:
        """The table as text, with the thesis's figures alongside."""
        out = [title, f"  {'via':>4} {'line':>5} {'error [mm]':>11}"]
        for i, err in enumerate(self.errors_mm):
            line = self.lines[i] if i < len(self.lines) else 0
            note = "   (the start pose: not counted)" if i == 0 else ""
            out.append(f"  {i:>4} {line or '':>5} {err:>11.2f}{note}")
        out.append(f"  {'mean':>10} {self.mean_mm:>11.2f}   (thesis: {THESIS_MEAN_MM:g} mm)")
        out.append(f"  {'max':>10} {self.max_mm:>11.2f}   (thesis: ~{THESIS_MAX_MM:g} mm)")
        return "\n".join(out)


def error_table(result: GoalResult, goal: TrajectoryGoal | None) -> ErrorTable:
    """The table of a trajectory goal's result (source lines from the goal, if heard)."""
    lines = goal.trajectory.via_lines if goal is not None else []
    return ErrorTable([e * 1e3 for e in result.via_errors], list(lines))


def plot_run(
    feedback: list[ControllerFeedback], goal: TrajectoryGoal | None, out: Path, title: str
) -> Path:
    """Planned vs executed path in the yz plane, and the error over time, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_yz, ax_err) = plt.subplots(1, 2, figsize=(12, 5.2))
    ref = [(f.reference_xyz[1] * 1e3, f.reference_xyz[2] * 1e3) for f in feedback]
    act = [(f.actual_xyz[1] * 1e3, f.actual_xyz[2] * 1e3) for f in feedback]
    if ref:
        ax_yz.plot(*zip(*ref, strict=True), "--", color="tab:blue", label="planned")
        ax_yz.plot(*zip(*act, strict=True), "-", color="tab:red", label="executed")
    if goal is not None and goal.trajectory.via_xyz:
        vy = [p[1] * 1e3 for p in goal.trajectory.via_xyz]
        vz = [p[2] * 1e3 for p in goal.trajectory.via_xyz]
        ax_yz.plot(vy, vz, "o", color="black", markersize=4, label="via points")
    ax_yz.set_xlabel("y [mm]")
    ax_yz.set_ylabel("z [mm]")
    ax_yz.set_aspect("equal", adjustable="datalim")
    ax_yz.grid(True, alpha=0.3)
    ax_yz.legend(loc="best")
    ax_yz.set_title("gripper path, yz plane")
    ax_err.plot(
        [f.t for f in feedback], [f.position_error * 1e3 for f in feedback], color="tab:red"
    )
    if goal is not None:
        for t in goal.trajectory.times:
            ax_err.axvline(t, color="grey", alpha=0.3, linewidth=0.8)
    ax_err.set_xlabel("trajectory time [s]")
    ax_err.set_ylabel("|planned - executed| [mm]")
    ax_err.grid(True, alpha=0.3)
    ax_err.set_title("position error (grey: via point times)")
    fig.suptitle(title)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
