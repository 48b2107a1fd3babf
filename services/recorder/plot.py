"""``manus plot``: what a run did, from its recording.

Like the thesis's figures of its test paths (docs/protocol.md, Thesis test paths).

Four panels:

- the gripper path in the yz plane [mm]: planned (the trajectory preview of each
  controller goal or planner reply, else the FK of the controller's reference) vs
  executed (the controller's measured ``actual_xyz``, else the FK of ``state/joints``),
  plus the simulator's true path when the recording has ``sim/truth``, and the via
  points;
- joint references vs actuals over time [deg] (controller feedback; actuals only from
  ``state/joints`` when there is no controller);
- commanded joint speeds [deg/s], as the arm executed them
  (``JointState.applied_velocity``);
- the via-point error table of every ``controller/result`` [mm] (mean, max);
- when the simulator's truth carries clearances, the run's clearances over time [mm]
  (a fifth panel, :mod:`services.recorder.plot_clearance`): the true distance to the
  nearest thing, and the tightest check by the scene's rules with the clearance it
  needs, its pair named, the arm's folds shaded.

:func:`load_plot_data` extracts the series (testable without drawing); :func:`plot_recording`
draws them with matplotlib's Agg backend and is what ``manus demo`` calls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from manus.clearance import Clearance
from manus.config import ArmConfig
from manus.kinematics import fk_batch
from schemas import endpoints as ep
from schemas.base import Message
from schemas.control import ControllerFeedback, GoalResult, TrajectoryGoal
from schemas.planning import PlanReply, Trajectory
from schemas.state import JointState, SimTruth
from services.recorder.errors import RecordingError
from services.recorder.plot_clearance import ClearanceCollector, ClearanceSeries, clearance_panel
from services.recorder.reading import Recording

if TYPE_CHECKING:
    from matplotlib.axes import Axes

_SUFFIXES = (
    ep.JOINTS,
    ep.FEEDBACK,
    ep.RESULT,
    ep.SIM_TRUTH,
    ep.SCENE_STATE,
    ep.BRIDGE_STATE,
    ep.GOAL.trace("request"),
    ep.PLAN.trace("reply"),
)


@dataclass
class PlotData:
    """The series of one recording (times in s since the first message; SI units).

    Attributes:
        planned: planned paths, each (n, 3) [m].
        planned_source: where ``planned`` came from (``goal``, ``plan``, ``reference``).
        via_xyz: via points of the planned paths, (k, 3) [m].
        executed: measured gripper path (m, 3) [m].
        executed_source: ``feedback`` or ``joint_states``.
        truth: the simulator's true path (t, 3) [m] (empty without ``sim/truth``).
        t_fb: feedback times (f,) [s]; ``reference``/``actual``: (f, 6) [rad].
        t_js: joint-state times (j,) [s]; ``q_js``: (j, 6) [rad]; ``applied``: (j, 6) [rad/s].
        results: every goal result.
        clearances: the run's clearances on the simulator's truth (empty without it).
    """

    planned: list[np.ndarray] = field(default_factory=list)
    planned_source: str = ""
    via_xyz: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    executed: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    executed_source: str = ""
    truth: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    t_fb: np.ndarray = field(default_factory=lambda: np.zeros(0))
    reference: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    actual: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    t_js: np.ndarray = field(default_factory=lambda: np.zeros(0))
    q_js: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    applied: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    results: list[GoalResult] = field(default_factory=list)
    clearances: ClearanceSeries = field(default_factory=ClearanceSeries)


def _preview(traj: Trajectory) -> np.ndarray:
    if traj.preview_xyz:
        return np.asarray(traj.preview_xyz, dtype=float)
    return np.asarray(traj.via_xyz, dtype=float).reshape(-1, 3)


@dataclass
class _Series:
    """The recording's messages sorted into the plotted series, in log order."""

    clearances: ClearanceCollector
    goals: list[Trajectory] = field(default_factory=list)
    plans: list[Trajectory] = field(default_factory=list)
    fb_t: list[float] = field(default_factory=list)
    fb_ref: list[list[float]] = field(default_factory=list)
    fb_act: list[list[float]] = field(default_factory=list)
    fb_xyz: list[list[float]] = field(default_factory=list)
    js_t: list[float] = field(default_factory=list)
    js_q: list[list[float]] = field(default_factory=list)
    js_applied: list[list[float]] = field(default_factory=list)
    truth: list[list[float]] = field(default_factory=list)
    results: list[GoalResult] = field(default_factory=list)

    def add(self, t: float, msg: Message) -> None:
        """One message logged at ``t`` [s since the recording's start]."""
        self.clearances.add(t, msg)
        if isinstance(msg, JointState):
            if msg.valid:
                self.js_t.append(t)
                self.js_q.append(msg.position)
                self.js_applied.append(msg.applied_velocity)
        elif isinstance(msg, ControllerFeedback):
            if msg.goal_id:
                self.fb_t.append(t)
                self.fb_ref.append(msg.reference)
                self.fb_act.append(msg.actual)
                self.fb_xyz.append(msg.actual_xyz)
        elif isinstance(msg, GoalResult):
            self.results.append(msg)
        elif isinstance(msg, SimTruth):
            self.truth.append(msg.xyz)
        elif isinstance(msg, TrajectoryGoal):
            self.goals.append(msg.trajectory)
        elif isinstance(msg, PlanReply) and msg.ok and msg.trajectory is not None:
            self.plans.append(msg.trajectory)


def load_plot_data(path: str | Path, arm: ArmConfig, scene: str = "") -> PlotData:
    """Extract the plotted series from a recording (``arm``: the recorded arm's geometry,
    for the paths of recordings without controller feedback and the clearances; ``scene``:
    the scene setting before the recording's first ``planner/scene_state``, ``""`` =
    ``$MANUS_SCENE`` or the shipped one).

    Raises:
        RecordingError: the file cannot be read, or it holds neither joint states nor
            controller feedback (nothing to plot).
    """
    rec = Recording(path)
    t0 = rec.info.start_ns
    series = _Series(ClearanceCollector(arm, scene))
    for r, msg in rec.decoded(_SUFFIXES):
        series.add((r.log_ns - t0) / 1e9, msg)
    if not series.js_t and not series.fb_t:
        raise RecordingError(
            f"{path}: nothing to plot: no valid state/joints and no controller/feedback"
        )
    data = PlotData(
        results=series.results,
        t_fb=np.asarray(series.fb_t),
        reference=np.asarray(series.fb_ref, dtype=float).reshape(-1, 6),
        actual=np.asarray(series.fb_act, dtype=float).reshape(-1, 6),
        t_js=np.asarray(series.js_t),
        q_js=np.asarray(series.js_q, dtype=float).reshape(-1, 6),
        applied=np.asarray(series.js_applied, dtype=float).reshape(-1, 6),
        truth=np.asarray(series.truth, dtype=float).reshape(-1, 3),
        clearances=series.clearances.series(),
    )
    _paths(data, series, arm)
    return data


def _paths(data: PlotData, series: _Series, arm: ArmConfig) -> None:
    """The planned path (goal previews, else plan replies, else the FK of the reference)
    and the executed one (feedback, else the FK of the joint states)."""
    chosen = series.goals or series.plans
    if chosen:
        data.planned = [_preview(tr) for tr in chosen]
        data.planned_source = "goal" if series.goals else "plan"
        vias = [np.asarray(tr.via_xyz, dtype=float).reshape(-1, 3) for tr in chosen]
        data.via_xyz = np.vstack(vias)
    elif len(data.reference):
        data.planned = [fk_batch(data.reference, arm)[:, :3, 3]]
        data.planned_source = "reference"
    if series.fb_xyz:
        data.executed = np.asarray(series.fb_xyz, dtype=float)
        data.executed_source = "feedback"
    elif len(data.q_js):
        data.executed = fk_batch(data.q_js, arm)[:, :3, 3]
        data.executed_source = "joint_states"


@dataclass(frozen=True)
class PlotSummary:
    """What :func:`plot_recording` drew.

    Attributes:
        output: the PNG written.
        goals: trajectory results in the table.
        via_errors_mm: every via-point error of every trajectory result but the start
            knots' (``GoalResult.path_via_errors``) [mm].
        mean_mm: their mean [mm] (nan when none).
        max_mm: their largest [mm] (nan when none).
        clearance: the run's tightest clearance check on the simulator's truth (None: no
            truth with clearances).
        clearance_verdict: it in words, and whether every clearance was kept.
        clearance_broken: truth samples whose tightest check was below its clearance.
    """

    output: str
    goals: int
    via_errors_mm: list[float]
    mean_mm: float
    max_mm: float
    clearance: Clearance | None = None
    clearance_verdict: str = ""
    clearance_broken: int = 0


def plot_recording(
    path: str | Path,
    output: str | Path | None = None,
    *,
    arm: ArmConfig,
    title: str | None = None,
    scene: str = "",
) -> PlotSummary:
    """Draw the four panels of ``path`` to a PNG (default: next to it, ``.png``); ``arm``
    is the recorded arm's geometry, ``scene`` the scene before the recording's first
    scene state (:func:`load_plot_data`).

    Raises:
        RecordingError: see :func:`load_plot_data`.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    data = load_plot_data(path, arm, scene)
    out = Path(output) if output is not None else Path(path).with_suffix(".png")
    rows = 3 if len(data.clearances.t) else 2
    fig, axes = plt.subplots(rows, 2, figsize=(14, 5 * rows))
    try:
        _path_panel(axes[0][0], data)
        _joint_panel(axes[0][1], data)
        _increment_panel(axes[1][0], data)
        errors = _table_panel(axes[1][1], data)
        if rows == 3:
            gs = axes[2][0].get_gridspec()
            axes[2][0].remove()
            axes[2][1].remove()
            clearance_panel(fig.add_subplot(gs[2, :]), data.clearances)
        fig.suptitle(title or Path(path).name)
        fig.tight_layout()
        fig.savefig(out, dpi=80)
    finally:
        plt.close(fig)
    goals = sum(1 for r in data.results if r.kind == "trajectory")
    mean = float(np.mean(errors)) if errors else math.nan
    peak = float(np.max(errors)) if errors else math.nan
    c = data.clearances
    return PlotSummary(str(out), goals, errors, mean, peak, c.tightest, c.verdict(), c.broken)


def _path_panel(a: Axes, data: PlotData) -> None:
    for i, p in enumerate(data.planned):
        label = f"planned ({data.planned_source})" if i == 0 else None
        a.plot(p[:, 1] * 1e3, p[:, 2] * 1e3, "--", color="tab:blue", lw=1.2, label=label)
    if len(data.executed):
        a.plot(
            data.executed[:, 1] * 1e3,
            data.executed[:, 2] * 1e3,
            color="tab:red",
            lw=1.0,
            label=f"executed ({data.executed_source})",
        )
    if len(data.truth):
        a.plot(
            data.truth[:, 1] * 1e3,
            data.truth[:, 2] * 1e3,
            color="tab:green",
            lw=0.8,
            alpha=0.7,
            label="true (simulator)",
        )
    if len(data.via_xyz):
        a.plot(data.via_xyz[:, 1] * 1e3, data.via_xyz[:, 2] * 1e3, "k+", ms=8, label="via points")
    a.set_xlabel("y [mm]")
    a.set_ylabel("z [mm]")
    a.set_title("gripper path, yz plane")
    a.set_aspect("equal", adjustable="datalim")
    a.grid(True, alpha=0.3)
    a.legend(loc="best", fontsize=8)


def _joint_panel(a: Axes, data: PlotData) -> None:
    colors = ["tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown"]
    if len(data.t_fb):
        for j in range(6):
            a.plot(data.t_fb, np.degrees(data.reference[:, j]), "--", color=colors[j], lw=1.0)
            a.plot(
                data.t_fb, np.degrees(data.actual[:, j]), color=colors[j], lw=1.0, label=f"q{j + 1}"
            )
        a.set_title("joint reference (dashed) vs actual")
    else:
        for j in range(6):
            a.plot(
                data.t_js, np.degrees(data.q_js[:, j]), color=colors[j], lw=1.0, label=f"q{j + 1}"
            )
        a.set_title("joint angles (no controller feedback recorded)")
    a.set_xlabel("time [s]")
    a.set_ylabel("angle [deg]")
    a.grid(True, alpha=0.3)
    a.legend(loc="best", fontsize=8, ncol=2)


def _increment_panel(a: Axes, data: PlotData) -> None:
    speeds = np.degrees(data.applied)
    for j in range(6):
        a.step(data.t_js, speeds[:, j] + 0.0, where="post", lw=0.9, label=f"q{j + 1}")
    a.set_xlabel("time [s]")
    a.set_ylabel("joint speed [deg/s]")
    a.set_title("commanded joint speeds, as executed")
    a.set_ylim(-105.0, 105.0)  # q3 runs at the sum of two motors' 50 deg/s
    a.grid(True, alpha=0.3)
    a.legend(loc="best", fontsize=8, ncol=3)


def _table_panel(a: Axes, data: PlotData) -> list[float]:
    a.axis("off")
    rows: list[list[str]] = []
    every: list[float] = []
    for r in data.results:
        if r.kind != "trajectory":
            continue
        errs = [e * 1e3 for e in r.path_via_errors]
        every.extend(errs)
        mean = f"{np.mean(errs):.2f}" if errs else "-"
        peak = f"{np.max(errs):.2f}" if errs else "-"
        rows.append(
            [r.goal_id[:24], r.status, str(len(errs)), mean, peak, f"{r.final_error * 1e3:.2f}"]
        )
    if every:
        rows.append(
            ["all", "", str(len(every)), f"{np.mean(every):.2f}", f"{np.max(every):.2f}", ""]
        )
    if not rows:
        a.text(0.5, 0.5, "no controller/result recorded", ha="center", va="center")
        return every
    table = a.table(
        cellText=rows[:30],
        colLabels=["goal", "status", "scored vias", "mean [mm]", "max [mm]", "final [mm]"],
        loc="upper center",
    )
    table.scale(1.0, 1.4)
    a.set_title("via-point errors (gripper position, FK of the encoders)")
    return every
