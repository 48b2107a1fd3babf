"""The clearance panel of ``manus plot``: the run's clearances on the simulator's truth.

Two curves over time: the true distance to the nearest thing (``SimTruth.clearance``,
physical, any pair, no rules: 0 is a contact), and the scene's rules judged on the true
joint angles and gripper opening (:class:`manus.clearance_judge.ClearanceJudge`): the
distance of the tightest check and the clearance that check needs, so the panel's title
can name the tightest pair and its rule (``gripper_motor 12.3 mm from shoulder (self:
needs 10 mm)``) and say whether it was kept. The arm's own folds (bridge phases
``folding_out`` / ``folding_in``) are shaded: the arm's firmware moves it there, and the
sequencer checks those motions before a task starts (docs/scene.md, Where it is checked).

The scene is the recording's (``planner/scene_state``, as each arrives); before the
first one, the ``scene`` setting given (as every service's: ``""`` = ``$MANUS_SCENE`` or
the shipped one).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from manus.clearance import Clearance
from manus.clearance_judge import ClearanceJudge
from manus.config import ArmConfig
from manus.scene import SceneError, parse_scene, scene_from_setting
from schemas.base import Message
from schemas.collision import SceneState
from schemas.state import BridgePhase, BridgeState, SimTruth

if TYPE_CHECKING:
    from matplotlib.axes import Axes

FOLD_PHASES: dict[str, str] = {
    BridgePhase.FOLDING_OUT: "fold out",
    BridgePhase.FOLDING_IN: "fold in",
}
"""Bridge phases of the arm's own folds, and their names in the panel."""


@dataclass
class ClearanceSeries:
    """The run's clearances (times in s since the recording's start; SI units).

    Attributes:
        t: truth sample times (n,) [s].
        nearest: true distance to the nearest thing, any pair, no rules (n,) [m].
        distance: distance of the tightest check by the scene's rules (n,) [m].
        required: the clearance that check needs (n,) [m].
        tightest: the tightest check of the run (its ``time`` in s), None: no truth.
        broken: samples whose tightest check was below its clearance.
        contacts: ticks on which the simulator stopped a body at a contact.
        folds: the arm's own folds, (start [s], end [s], ``fold out`` or ``fold in``).
    """

    t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nearest: np.ndarray = field(default_factory=lambda: np.zeros(0))
    distance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    required: np.ndarray = field(default_factory=lambda: np.zeros(0))
    tightest: Clearance | None = None
    broken: int = 0
    contacts: int = 0
    folds: list[tuple[float, float, str]] = field(default_factory=list)

    def verdict(self) -> str:
        """The tightest check in words and whether every clearance was kept."""
        if self.tightest is None:
            return "no truth recorded"
        worst = self.tightest
        head = f"tightest {worst.describe()} at t = {worst.time:.1f} s"
        if self.broken:
            return f"{head}: BROKEN ({self.broken} samples below their clearance)"
        return f"{head}: every clearance kept"


class ClearanceCollector:
    """Collects the truth, the scene states and the bridge phases of a recording in log
    order and judges them (:meth:`series`).

    Args:
        arm: the recorded arm's geometry.
        scene: the ``scene`` setting used before the recording's first scene state.
    """

    def __init__(self, arm: ArmConfig, scene: str = "") -> None:
        self._judge: ClearanceJudge | None = None
        self._arm = arm
        self._setting = scene
        self._scene_seen: SceneState | None = None
        self._out = ClearanceSeries()
        self._t: list[float] = []
        self._nearest: list[float] = []
        self._distance: list[float] = []
        self._required: list[float] = []
        self._fold: tuple[float, str] | None = None

    def add(self, t: float, msg: Message) -> None:
        """One message logged at ``t`` [s]; other types are ignored."""
        if isinstance(msg, SceneState):
            self._scene(msg)
        elif isinstance(msg, BridgeState):
            self._phase(t, msg.phase)
        elif isinstance(msg, SimTruth) and msg.clearance is not None:
            judge = self._judge or self._start(None)
            found = judge.add(t, msg.q_true, msg.gripper)
            self._t.append(t)
            self._nearest.append(msg.clearance)
            self._distance.append(found.distance)
            self._required.append(found.check.required)
            self._out.broken += found.margin < 0.0
            self._out.contacts = msg.contacts

    def series(self) -> ClearanceSeries:
        """What was collected, judged."""
        out = self._out
        if self._fold is not None and self._t:
            out.folds.append((self._fold[0], self._t[-1], self._fold[1]))
            self._fold = None
        out.t = np.asarray(self._t)
        out.nearest = np.asarray(self._nearest, dtype=float)
        out.distance = np.asarray(self._distance, dtype=float)
        out.required = np.asarray(self._required, dtype=float)
        out.tightest = self._judge.tightest if self._judge is not None else None
        return out

    def _start(self, state: SceneState | None) -> ClearanceJudge:
        if state is None:
            scene = scene_from_setting(self._setting)
        else:
            parsed = parse_scene(state.text, state.source or "<scene update>")
            scene = dataclasses.replace(parsed, version=state.version)
        if self._judge is None:
            self._judge = ClearanceJudge(self._arm, scene)
        else:
            self._judge.set_scene(scene)
        return self._judge

    def _scene(self, state: SceneState) -> None:
        if state.same_scene(self._scene_seen):
            return  # the planner's announcement of the scene in use (every second)
        self._scene_seen = state
        try:
            self._start(state)
        except SceneError:  # the planner validated it: garbage or another stack's
            return

    def _phase(self, t: float, phase: str) -> None:
        name = FOLD_PHASES.get(phase)
        if self._fold is not None and name != self._fold[1]:
            self._out.folds.append((self._fold[0], t, self._fold[1]))
            self._fold = None
        if name is not None and self._fold is None:
            self._fold = (t, name)


def clearance_panel(a: Axes, s: ClearanceSeries) -> None:
    """Draw the clearances of ``s`` on ``a`` [mm over s]."""
    for start, end, name in s.folds:
        a.axvspan(start, end, color="0.88" if name == "fold out" else "0.80", lw=0)
        a.text((start + end) / 2, 0.02, f"{name} (the arm's own motion)", ha="center",
               va="bottom", transform=a.get_xaxis_transform(), fontsize=8)  # fmt: skip
    a.plot(s.t, s.nearest * 1e3, color="tab:green", lw=1.0,
           label="true distance to the nearest thing (simulator, no rules)")  # fmt: skip
    a.plot(s.t, s.distance * 1e3, color="tab:blue", lw=1.0,
           label="tightest check by the scene's rules (true joints)")  # fmt: skip
    a.step(s.t, s.required * 1e3, where="post", color="black", ls="--", lw=0.9,
           label="the clearance that check needs")  # fmt: skip
    a.axhline(0.0, color="tab:red", lw=0.8, label="contact")
    if s.tightest is not None:
        worst = s.tightest
        a.plot([worst.time], [worst.distance * 1e3], "o", color="tab:blue", ms=5)
        a.annotate(f"{worst.check.body} / {worst.check.other}", (worst.time, worst.distance * 1e3),
                   textcoords="offset points", xytext=(6, 6), fontsize=8)  # fmt: skip
    a.set_xlabel("time [s]")
    a.set_ylabel("clearance [mm]")
    a.set_title(f"clearances on the simulator's truth: {s.verdict()}; {s.contacts} contact "
                "ticks", fontsize=9)  # fmt: skip
    a.grid(True, alpha=0.3)
    a.legend(loc="upper right", fontsize=8)
