"""The guardian in lock-step: a bridge stopped or killed mid-path, judged on the truth.

:class:`GuardianNode` puts a :class:`~services.guardian.core.GuardianCore` on the
lock-step bus as another PC-side node (:meth:`manus_stack.lockstep.LockStep.attach_node`).
:func:`bridge_fault_trial` runs the thesis square on a :class:`ControlledArm`, stops
(SIGSTOP) or kills (SIGKILL) the bridge at a given instant, and measures from the
simulator's true motor speeds when the arm is at rest and how many syncs it took.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from manus.protocol import Frame
from manus.viapoints import parse_viapoints
from manus_stack.controlled import ControlledArm
from schemas.control import TrajectoryGoal
from schemas.planning import PlanRequest, Trajectory, ViaPointPath
from services.guardian.core import Action, GuardianCore
from services.planner.core import PlannerCore
from services.simulator.config import SimConfig

PATHS = Path(__file__).resolve().parents[1] / "paths"
REST_DEG_S = 0.05
"""The arm is at rest when every true motor speed is below this [deg/s]."""
MS = 1_000_000


class GuardianNode:
    """A :class:`GuardianCore` as a lock-step bus node; keeps every action."""

    def __init__(self, core: GuardianCore | None = None) -> None:
        self.core = core or GuardianCore()
        self.actions: list[Action] = []

    def receive(self, frame: Frame) -> None:
        """A frame of the arm or of the bridge, at its arrival time."""
        action = self.core.on_frame(frame)
        if action is not None:
            self.actions.append(action)

    def next_event_ns(self) -> int | None:
        """The waiting sync's deadline."""
        return self.core.next_deadline_ns()

    def advance(self, t_ns: int) -> list[Frame]:
        """The 0x370 if the deadline passed unanswered."""
        frame, action = self.core.due(t_ns)
        if action is not None:
            self.actions.append(action)
        return [frame] if frame is not None else []


@dataclass(frozen=True)
class Trial:
    """One bridge fault mid-path.

    Attributes:
        fault: ``stop`` (SIGSTOP) or ``kill`` (SIGKILL).
        offset_ms: fault instant after the first sync following 3 s of the path [ms].
        speed_before_deg_s: largest true motor speed at the fault [deg/s].
        rest_ms: fault -> every true motor speed below 0.05 deg/s for good [ms] (None:
            still moving at the end).
        syncs_to_stop: syncs from the fault to the first one whose 0x370 stopped the arm.
        stops_sent: 0x370 frames the guardian sent.
        resumed_moving: after SIGCONT (``stop``) or a new bridge (``kill``), the arm
            moved again before a new goal (must be False).
        new_goal: status of a short goal submitted after the recovery.
    """

    fault: str
    offset_ms: float
    speed_before_deg_s: float
    rest_ms: float | None
    syncs_to_stop: int | None
    stops_sent: int
    resumed_moving: bool
    new_goal: str


def _speed(arm: ControlledArm) -> float:
    return float(abs(arm.ls.sim.state.speed_deg_s).max())


def bridge_fault_trial(fault: str, offset_ms: float, *, guardian: bool = True) -> Trial:
    """Run the square, fault the bridge ``offset_ms`` after a sync 3 s in, watch 1 s,
    recover (SIGCONT, or a new bridge), then submit a short goal (see :class:`Trial`)."""
    if fault not in ("stop", "kill"):
        raise ValueError(f"fault must be 'stop' or 'kill', got {fault!r}")
    arm = ControlledArm(SimConfig(start_pose="unfolded"))
    node = GuardianNode()
    if guardian:
        arm.ls.attach_node(node)
    arm.start()
    traj = arm.plan(PATHS / "thesis_square.txt")
    arm.submit(TrajectoryGoal(goal_id="square", trajectory=traj))
    arm.ls.run_for(3.0)
    syncs = [f.t_ns for f in arm.ls.arm_frames if f.remote]
    t0 = syncs[-1] + round(offset_ms * MS)
    arm.ls.run_until(t0)
    before = _speed(arm)
    arm.ls.pause_bridge(kill=fault == "kill")
    samples: list[tuple[int, float]] = []
    end = t0 + 1000 * MS
    while arm.ls.t_ns < end:
        arm.ls.run_for(0.02)
        samples.append((arm.ls.t_ns, _speed(arm)))
    moving = [t for t, v in samples if v >= REST_DEG_S]
    rest_ms = (
        None
        if moving and moving[-1] >= samples[-1][0]
        else (((moving[-1] + 20 * MS) if moving else t0) - t0) / MS
    )
    stops = [a.sync_ns for a in node.actions if a.kind == "stop_sent" and a.sync_ns >= t0]
    after = syncs_after(arm, t0)
    syncs_to_stop = after.index(stops[0]) + 1 if stops and stops[0] in after else None
    if fault == "stop":
        arm.ls.resume_bridge()
    else:
        arm.ls.restart_bridge()
    recovered_from = arm.ls.t_ns
    arm.ls.run_for(0.5)
    resumed = False
    while arm.ls.bridge.phase != "running" and arm.ls.t_ns < recovered_from + 10_000 * MS:
        arm.ls.run_for(0.06)
        resumed = resumed or _speed(arm) > 1.0
    arm.ls.run_for(0.5)
    resumed = resumed or _speed(arm) > 1.0
    status = "bridge not running"
    if arm.ls.bridge.phase == "running":
        ack = arm.submit(TrajectoryGoal(goal_id="again", trajectory=_short_move(arm)))
        status = arm.run_until_result("again").status if ack.accepted else f"refused: {ack.reason}"
    return Trial(
        fault=fault,
        offset_ms=offset_ms,
        speed_before_deg_s=round(before, 3),
        rest_ms=None if rest_ms is None else round(rest_ms, 1),
        syncs_to_stop=syncs_to_stop,
        stops_sent=node.core.counts.stops_sent,
        resumed_moving=resumed,
        new_goal=status,
    )


SHORT_MOVE = """
0 0 0   0 0 0  0 0 0  0 0 0  0.0 2
0 20 0  0 0 0  0 0 0  0 0 0  1.0 2
"""
"""20 mm along y in 1 s from wherever the arm is (via points relative to the previous)."""


def _short_move(arm: ControlledArm) -> Trajectory:
    js = arm.core.last_js
    start = list(js.position) if js is not None else None
    motion = ViaPointPath(path=parse_viapoints(SHORT_MOVE))
    request = PlanRequest(motion, start=start, preview_dt=0.0)
    reply = PlannerCore().plan(request)
    if reply.trajectory is None:
        raise RuntimeError(f"planning the short move failed: {reply.error}")
    return reply.trajectory


def syncs_after(arm: ControlledArm, t0: int) -> list[int]:
    """Arrival times at the guardian of the syncs after ``t0`` [ns]."""
    return [f.t_ns for f in arm.ls.arm_frames if f.remote and f.t_ns >= t0]
