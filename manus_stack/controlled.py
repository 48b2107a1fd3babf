"""A lock-step arm with the controller attached, wired as the live stack wires them.

:class:`ControlledArm` puts a :class:`ControllerCore` on a
:class:`~manus_stack.lockstep.LockStep` through the controller's wiring map
(:data:`services.controller.wiring.WIRING`): it gets the bridge's states and the
heartbeat, and its queryables are asked as the live ``Node`` mirrors them: the request is
published on ``trace/<queryable>/request``, the controller handles it when it is
delivered and publishes its answer on ``trace/<queryable>/reply``. So
:attr:`LockStep.messages` holds everything the controller saw, in the order it saw it,
and a fresh core fed those messages gives the same commands (the replay test).
"""

from __future__ import annotations

from pathlib import Path as FilePath

from manus.viapoints import load_path
from manus_stack.lockstep import LockStep
from schemas import endpoints as ep
from schemas.base import Message
from schemas.control import GoalAck, GoalResult, TrajectoryGoal
from schemas.planning import PlanRequest, Trajectory, ViaPointPath
from schemas.state import BridgePhase, JointState
from services.can_bridge.config import BridgeConfig
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore, Output
from services.controller.wiring import WIRING
from services.planner.core import PlannerCore
from services.simulator.config import SimConfig


def controller_input(core: ControllerCore, suffix: str, msg: Message, t_ns: int = 0) -> Output:
    """Hand one bus message to the controller as its shell would (its wiring map); returns
    what it publishes (a query's GoalAck on ``trace/<queryable>/reply``)."""
    return WIRING.feed(core, suffix, msg, t_ns)


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
        self.ls.attach(WIRING, self.core)
        self.ls.watch_tokens(lambda service, t: WIRING.feed_token_gone(self.core, service, t))

    def start(self, timeout_s: float = 10.0) -> JointState:
        """Run until the bridge is running and the controller has a valid joint state."""
        self.ls.run_until_phase(BridgePhase.RUNNING, timeout_s)
        for _ in range(round(timeout_s / 0.06)):
            js = self.core.last_js
            if js is not None and js.valid:
                return js
            self.ls.run_for(0.06)
        raise TimeoutError(f"no valid joint state within {timeout_s:g} s of simulated time")

    def query(self, name: str, request: Message) -> GoalAck:
        """Ask the controller's queryable ``name`` (e.g. :data:`schemas.endpoints.GOAL`)
        and wait for it."""
        queryable = WIRING.answer(name).endpoint
        before = len(self.ls.messages)
        self.ls.publish(queryable.trace("request"), request)
        self.ls.run_for(self.ls.bus_latency_ns / 1e9)
        for _, suffix, msg in self.ls.messages[before:]:
            if suffix == queryable.trace("reply") and isinstance(msg, GoalAck):
                return msg
        raise TimeoutError(f"{name}: no reply")

    def submit(self, goal: TrajectoryGoal) -> GoalAck:
        """A trajectory goal (:data:`schemas.endpoints.GOAL`)."""
        return self.query(ep.GOAL, goal)

    def results(self, goal_id: str | None = None) -> list[GoalResult]:
        """Results published so far (of one goal, or all)."""
        messages = self.ls.messages
        for _, suffix, msg in messages[self._scanned :]:
            if suffix == ep.RESULT and isinstance(msg, GoalResult):
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
        request = PlanRequest(ViaPointPath(path=load_path(path_file)), start=start, preview_dt=0.0)
        reply = PlannerCore().plan(request)
        if reply.trajectory is None:
            raise RuntimeError(f"planning {path_file} failed: {reply.error}")
        return reply.trajectory
