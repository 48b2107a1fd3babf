"""FAKES FOR TESTS ONLY: a bridge and a controller that answer the sequencer's keys.

They speak the schema messages on the real keys, but simulate nothing faithfully: the
controller "moves" the arm by jumping the fake bridge's joint state along the trajectory
(time running ``speedup`` times faster than real time); the bridge holds folds for a
moment. Used until (and besides) the real bridge and controller shells, to test the
sequencer's supervisor API over Zenoh.
"""

from __future__ import annotations

import math
import threading
import time
from typing import Self

from manus.config import UNFOLDED_Q_DEG
from manus.node import Node
from manus.session import ZenohSettings
from manus.trajectory import JointTrajectory
from schemas import endpoints as ep
from schemas.commands import ArmCommand, ArmCommandReply
from schemas.control import (
    CancelGoal,
    ControllerFeedback,
    EndCause,
    GoalAck,
    GoalResult,
    GripperGoal,
    ResultStatus,
    TrajectoryGoal,
)
from schemas.state import BridgeState, JointState

UNFOLDED = [math.radians(v) for v in UNFOLDED_Q_DEG]
PERIOD_S = 0.06


CAUSES = {
    ResultStatus.SUCCEEDED: EndCause.REACHED,
    ResultStatus.CANCELLED: EndCause.CANCEL_REQUEST,
    ResultStatus.ABORTED: EndCause.TOLERANCE,
    ResultStatus.PREEMPTED: EndCause.NEW_GOAL,
}
"""The usual cause of each result status (tests that need another give it)."""


class FakeBridge:
    """Publishes state/joints and state/bridge every 60 ms; answers bridge/command."""

    def __init__(self, settings: ZenohSettings, *, fold_s: float = 0.3) -> None:
        self.node = Node("can_bridge", settings)
        self.q = list(UNFOLDED)
        self.gripper = 0.0
        self.phase = "running"
        self.detail = ""
        self.fold_s = fold_s
        self.commands: list[str] = []
        self._fold_until = 0.0
        self._seq = 0
        self._joints = self.node.publisher(self.node.keys(ep.JOINTS))
        self._state = self.node.publisher(self.node.keys(ep.BRIDGE_STATE))
        self.node.queryable(self.node.keys(ep.BRIDGE_COMMAND), ArmCommand, self._on_command)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _on_command(self, cmd: ArmCommand) -> ArmCommandReply:
        self.commands.append(cmd.action)
        if cmd.action in ("fold_in", "fold_out"):
            self.phase = "folding_" + cmd.action.removeprefix("fold_")
            self._fold_until = time.monotonic() + self.fold_s
        elif cmd.action == "stop":
            self.phase = "stopped"
        elif cmd.action == "clear":
            self.phase = "running"
        return ArmCommandReply(ok=True, phase=self.phase, message="")

    def _loop(self) -> None:
        while not self._stop.wait(PERIOD_S):
            with self.node.lock:
                if self.phase.startswith("folding") and time.monotonic() >= self._fold_until:
                    self.detail = f"fold_{self.phase.removeprefix('folding_')} complete"
                    self.phase = "running"
                self._seq += 1
                stamp = time.time_ns()
                self._joints.put(JointState(stamp_ns=stamp, seq=self._seq, position=list(self.q),
                                            gripper=self.gripper, valid=True, mode="joint",
                                            encoder=[0] * 7, applied_velocity=[0.0] * 6,
                                            applied_gripper_velocity=0.0,
                                            applied_kind="none", applied_seq=-1))  # fmt: skip
                self._state.put(BridgeState(stamp_ns=stamp, seq=self._seq, phase=self.phase,
                                            estop=False, cycles=self._seq, period_ms=60.0,
                                            jitter_ms=0.0, reply_latency_ms=0.1,
                                            reply_latency_max_ms=0.1, missed_windows=0,
                                            stale_commands=0, resyncs=0, dropped_frames=0,
                                            duplicate_frames=0, garbled_frames=0,
                                            buffered_syncs=0, bad_payloads=0,
                                            detail=self.detail))  # fmt: skip

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.node.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class FakeController:
    """Answers controller/goal, /gripper, /cancel; publishes feedback and results."""

    def __init__(self, settings: ZenohSettings, bridge: FakeBridge, *, speedup: float = 10.0):
        self.node = Node("controller", settings)
        self.bridge = bridge
        self.speedup = speedup
        self.goals: list[TrajectoryGoal | GripperGoal] = []
        self.cancels: list[str] = []
        self.refuse = ""
        self._active: tuple[str, JointTrajectory, float] | None = None
        self._cancelled = False
        self._seq = 0
        self._feedback = self.node.publisher(self.node.keys(ep.FEEDBACK))
        self._result = self.node.publisher(self.node.keys(ep.RESULT))
        keys = self.node.keys
        self.node.queryable(keys(ep.GOAL), TrajectoryGoal, self._on_goal)
        self.node.queryable(keys(ep.GRIPPER_GOAL), GripperGoal, self._on_gripper)
        self.node.queryable(keys(ep.CANCEL), CancelGoal, self._on_cancel)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _on_goal(self, goal: TrajectoryGoal) -> GoalAck:
        self.goals.append(goal)
        if self.refuse:
            return GoalAck(accepted=False, goal_id=goal.goal_id, reason=self.refuse)
        self._active = (goal.goal_id, JointTrajectory(goal.trajectory), time.monotonic())
        self._cancelled = False
        return GoalAck(accepted=True, goal_id=goal.goal_id)

    def _on_gripper(self, goal: GripperGoal) -> GoalAck:
        self.goals.append(goal)
        self.bridge.gripper = goal.opening
        self._publish_result(goal.goal_id, "gripper", "succeeded", "reached")
        return GoalAck(accepted=True, goal_id=goal.goal_id)

    def _on_cancel(self, req: CancelGoal) -> GoalAck:
        self.cancels.append(req.goal_id)
        self._cancelled = True
        return GoalAck(accepted=True, goal_id=req.goal_id)

    def _publish_result(self, goal_id: str, kind: str, status: str, reason: str) -> None:
        self._seq += 1
        self._result.put(GoalResult(stamp_ns=time.time_ns(), seq=self._seq, goal_id=goal_id,
                                    kind=kind, status=status, cause=CAUSES[ResultStatus(status)],
                                    reason=reason))  # fmt: skip

    def _loop(self) -> None:
        while not self._stop.wait(PERIOD_S / 2):
            with self.node.lock:
                if self._active is None:
                    continue
                goal_id, traj, t0 = self._active
                t = min(traj.duration, (time.monotonic() - t0) * self.speedup)
                q = [float(v) for v in traj.sample(t).q]
                self.bridge.q = q
                self._seq += 1
                z3 = [0.0, 0.0, 0.0]
                fb = ControllerFeedback(
                    stamp_ns=time.time_ns(), seq=self._seq, goal_id=goal_id, state="tracking",
                    segment=traj.segment(t), t=t, reference=q, actual=q, error=[0.0] * 6,
                    command=[0.0] * 6, reference_xyz=z3, actual_xyz=z3, position_error=0.0,
                )  # fmt: skip
                self._feedback.put(fb)
                if self._cancelled:
                    self._active = None
                    self._publish_result(goal_id, "trajectory", "cancelled", "cancelled: at rest")
                elif t >= traj.duration:
                    self._active = None
                    self._publish_result(goal_id, "trajectory", "succeeded", "reached the end")

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2.0)
        self.node.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
