"""A lock-step arm with the controller attached, wired as the live stack wires them.

:class:`ControlledArm` puts a :class:`ControllerCore` on a
:class:`~manus_stack.lockstep.LockStep`: it subscribes ``state/joints``,
``state/status`` and ``state/bridge`` and answers the controller's queryables. A
query travels as the live ``Node`` mirrors it: the request is published on
``trace/<queryable>/request``, the controller handles it when it is delivered and
publishes its answer on ``trace/<queryable>/reply``. So :attr:`LockStep.messages` holds
everything the controller saw, in the order it saw it, and a fresh core fed those
messages gives the same commands (the replay test).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path as FilePath

from manus.viapoints import load_path
from manus_stack.lockstep import LockStep
from schemas.base import Message
from schemas.control import (
    CancelGoal,
    GoalAck,
    GoalResult,
    GripperGoal,
    Heartbeat,
    SpeedScale,
    TrajectoryGoal,
)
from schemas.jog import JogCommand, JogLevel
from schemas.planning import PlanRequest, Trajectory
from schemas.state import ArmStatus, BridgeState, JointState
from services.can_bridge.config import BridgeConfig
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore, Output
from services.planner.core import PlannerCore
from services.simulator.config import SimConfig

QUERYABLES = (
    "controller/goal",
    "controller/gripper",
    "controller/cancel",
    "controller/speed_scale",
    "controller/jog_level",
)
"""The controller's queryables (key suffixes)."""


def controller_input(core: ControllerCore, suffix: str, msg: Message) -> Output:
    """Hand one bus message to the controller as its shell would; returns what it publishes.

    ``state/joints``, ``state/status``, ``state/bridge`` and ``heartbeat`` go to their handlers; a
    ``trace/<queryable>/request`` goes to the queryable's method and its GoalAck comes back
    on ``trace/<queryable>/reply``. Anything else is ignored.
    """
    if suffix == "state/joints" and isinstance(msg, JointState):
        return core.on_joint_state(msg)
    if suffix == "state/status" and isinstance(msg, ArmStatus):
        return core.on_status(msg)
    if suffix == "state/bridge" and isinstance(msg, BridgeState):
        return core.on_bridge_state(msg)
    if suffix == "heartbeat" and isinstance(msg, Heartbeat):
        return core.on_heartbeat(msg)
    if suffix == "jog" and isinstance(msg, JogCommand):
        return core.on_jog(msg)
    if suffix.startswith("trace/") and suffix.endswith("/request"):
        name = suffix.removeprefix("trace/").removesuffix("/request")
        ack: GoalAck | None = None
        if isinstance(msg, TrajectoryGoal) and name == "controller/goal":
            ack = core.submit(msg)
        elif isinstance(msg, GripperGoal) and name == "controller/gripper":
            ack = core.submit_gripper(msg)
        elif isinstance(msg, CancelGoal) and name == "controller/cancel":
            ack = core.cancel(msg)
        elif isinstance(msg, SpeedScale) and name == "controller/speed_scale":
            ack = core.set_speed_scale(msg)
        elif isinstance(msg, JogLevel) and name == "controller/jog_level":
            ack = core.set_jog_level(msg)
        if ack is not None:
            return [(f"trace/{name}/reply", ack)]
    return []


class ControlledArm:
    """Simulator + bridge + controller in lock-step (see the module docstring).

    Args:
        sim: simulator settings.
        config: controller settings.
        bridge: bridge settings.
    """

    def __init__(
        self,
        sim: SimConfig | None = None,
        config: ControllerConfig | None = None,
        bridge: BridgeConfig | None = None,
    ) -> None:
        self.ls = LockStep(sim, bridge)
        self.core = ControllerCore(config)
        self._results: list[GoalResult] = []
        self._scanned = 0
        for suffix in ("state/joints", "state/status", "state/bridge", "heartbeat", "jog"):
            self.ls.subscribe(suffix, self._handler(suffix))
        for name in QUERYABLES:
            request = f"trace/{name}/request"
            self.ls.subscribe(request, self._handler(request))

    def _handler(self, suffix: str) -> Callable[[Message, int], Output]:
        def handle(msg: Message, t_ns: int) -> Output:
            return controller_input(self.core, suffix, msg)

        return handle

    def start(self, timeout_s: float = 10.0) -> JointState:
        """Run until the bridge is running and the controller has a valid joint state."""
        self.ls.run_until_phase("running", timeout_s)
        for _ in range(round(timeout_s / 0.06)):
            js = self.core.last_js
            if js is not None and js.valid:
                return js
            self.ls.run_for(0.06)
        raise TimeoutError(f"no valid joint state within {timeout_s:g} s of simulated time")

    def query(self, name: str, request: Message) -> GoalAck:
        """Ask the controller's queryable ``name`` (e.g. ``controller/goal``) and wait for it."""
        before = len(self.ls.messages)
        self.ls.publish(f"trace/{name}/request", request)
        self.ls.run_for(self.ls.bus_latency_ns / 1e9)
        for _, suffix, msg in self.ls.messages[before:]:
            if suffix == f"trace/{name}/reply" and isinstance(msg, GoalAck):
                return msg
        raise TimeoutError(f"{name}: no reply")

    def submit(self, goal: TrajectoryGoal) -> GoalAck:
        """``controller/goal``."""
        return self.query("controller/goal", goal)

    def results(self, goal_id: str | None = None) -> list[GoalResult]:
        """Results published so far (of one goal, or all)."""
        messages = self.ls.messages
        for _, suffix, msg in messages[self._scanned :]:
            if suffix == "controller/result" and isinstance(msg, GoalResult):
                self._results.append(msg)
        self._scanned = len(messages)
        return [r for r in self._results if goal_id is None or r.goal_id == goal_id]

    def run_until_result(self, goal_id: str, timeout_s: float = 60.0) -> GoalResult:
        """Run until ``goal_id`` has its result.

        Raises:
            TimeoutError: none within ``timeout_s`` of simulated time.
        """
        for _ in range(round(timeout_s / 0.06)):
            done = self.results(goal_id)
            if done:
                return done[0]
            self.ls.run_for(0.06)
        raise TimeoutError(f"goal {goal_id!r}: no result within {timeout_s:g} s")

    def plan(self, path_file: str | FilePath) -> Trajectory:
        """Plan a via-point file from the newest joint state (the planner core, in process).

        Raises:
            RuntimeError: the planner refused (its message).
        """
        js = self.core.last_js
        start = list(js.position) if js is not None else None
        request = PlanRequest(path=load_path(path_file), start=start, preview_dt=0.0)
        reply = PlannerCore().plan(request)
        if reply.trajectory is None:
            raise RuntimeError(f"planning {path_file} failed: {reply.error}")
        return reply.trajectory
