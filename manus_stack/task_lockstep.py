"""Tasks in lock-step: the sequencer core driving the real planner, controller, bridge and
simulator cores on one simulated clock (no Zenoh, no threads; :mod:`manus_stack.lockstep`).

The sequencer's queries are answered in-process, at the simulated instant they are sent,
by the core that owns each key (``planner/plan``, ``controller/*``, ``bridge/command``);
its task events are published on ``sequencer/events`` like every other message, so
:attr:`LockStep.messages` holds the whole run. Used by the sequencer's scenario tests and
by ``manus bench sequencer``.
"""

from __future__ import annotations

from manus_stack.lockstep import LockStep
from schemas.base import Message
from schemas.commands import ArmCommand
from schemas.control import CancelGoal, GoalResult, GripperGoal, TrajectoryGoal
from schemas.planning import PlanRequest
from schemas.sequencing import SubmitReply, Task, TaskControl, TaskEvent, TaskStatus
from schemas.state import JointState
from services.controller.core import ControllerCore
from services.planner.core import PlannerCore
from services.sequencer.core import Action, Publish, SequencerCore
from services.sequencer.validate import Validator
from services.simulator.config import SimConfig

NS = 1_000_000_000


class TaskLockStep:
    """Simulator + bridge (:class:`LockStep`) + controller + planner + sequencer cores.

    Args:
        sim: simulator settings.
    """

    def __init__(self, sim: SimConfig | None = None) -> None:
        self.ls = LockStep(sim)
        self.controller = ControllerCore()
        self.planner = PlannerCore()
        self.seq = SequencerCore()
        self.events: list[TaskEvent] = []
        self.requests: list[Message] = []
        ls = self.ls
        ls.subscribe("state/joints", self._on_joints)
        ls.subscribe("state/status", lambda m, t: self.controller.on_status(m))  # type: ignore[arg-type]
        ls.subscribe("heartbeat", lambda m, t: self.controller.on_heartbeat(m))  # type: ignore[arg-type]
        ls.subscribe("jog", lambda m, t: self.controller.on_jog(m))  # type: ignore[arg-type]
        ls.subscribe("state/bridge", lambda m, t: self.do(self.seq.on_bridge_state(m, t), t))  # type: ignore[arg-type]
        ls.subscribe("controller/feedback", lambda m, t: self.do(self.seq.on_feedback(m, t), t))  # type: ignore[arg-type]
        ls.subscribe("controller/result", lambda m, t: self.do(self.seq.on_result(m, t), t))  # type: ignore[arg-type]
        ls.subscribe("controller/jog_state", lambda m, t: self.do(self.seq.on_jog_state(m, t), t))  # type: ignore[arg-type]
        for name in self.seq.config.required_services:
            self.seq.on_liveliness(name, True, 0)

    def _on_joints(self, msg: Message, t: int) -> list[tuple[str, Message]]:
        assert isinstance(msg, JointState)
        out = self.controller.on_joint_state(msg)
        return out + self.do(self.seq.on_joint_state(msg, t) + self.seq.on_tick(t), t)

    def start_arm(self, timeout_s: float = 20.0) -> None:
        """Power up: run until the bridge is running and the sequencer has heard it."""
        self.ls.run_until_phase("running", timeout_s)
        self.ls.run_for(0.5)

    def answer(self, request: Message) -> Message:
        """The owning core's answer to one of the sequencer's queries."""
        self.requests.append(request)
        if isinstance(request, PlanRequest):
            return self.planner.plan(request)
        if isinstance(request, TrajectoryGoal):
            return self.controller.submit(request)
        if isinstance(request, GripperGoal):
            return self.controller.submit_gripper(request)
        if isinstance(request, CancelGoal):
            return self.controller.cancel(request)
        if isinstance(request, ArmCommand):
            return self.ls.arm_command(request)
        raise TypeError(f"no core answers {type(request).__name__}")

    def do(self, actions: list[Action], t: int) -> list[tuple[str, Message]]:
        """Carry out the sequencer's actions; the messages to publish."""
        out: list[tuple[str, Message]] = []
        for action in actions:
            if isinstance(action, Publish):
                if isinstance(action.message, TaskEvent):
                    self.events.append(action.message)
                out.append((action.suffix, action.message))
                continue
            reply = self.answer(action.request)
            out += self.do(self.seq.on_reply(action.token, reply, "", t), t)
        return out

    def submit(self, task: Task, task_id: str = "t") -> SubmitReply:
        """Validate ``task`` whole (as the shell does) and start it when it passes."""
        refused = self.seq.refuse(task)
        if refused is not None:
            return refused
        v = Validator(task, self.seq.start_configuration())
        while (request := v.next_request()) is not None:
            v.on_reply(self.planner.plan(request))
        if v.errors:
            return SubmitReply(accepted=False, task_id="", errors=v.errors)
        for suffix, msg in self.do(self.seq.start(task_id, task, self.ls.t_ns), self.ls.t_ns):
            self.ls.publish(suffix, msg)
        return SubmitReply(accepted=True, task_id=task_id)

    def control(self, action: str) -> TaskStatus:
        """Cancel, pause, resume or status, now."""
        status, actions = self.seq.control(TaskControl(action=action), self.ls.t_ns)
        for suffix, msg in self.do(actions, self.ls.t_ns):
            self.ls.publish(suffix, msg)
        return status

    def run_while_busy(self, limit_s: float = 300.0) -> None:
        """Run until the task ends (or ``limit_s`` of simulated time)."""
        end = self.ls.t_ns + round(limit_s * NS)
        while self.seq.busy and self.ls.t_ns < end:
            self.ls.run_for(0.1)

    def run_until_event(self, name: str, limit_s: float = 60.0) -> None:
        """Run until the sequencer has published event ``name``.

        Raises:
            TimeoutError: not within ``limit_s`` of simulated time.
        """
        end = self.ls.t_ns + round(limit_s * NS)
        while not any(e.event == name for e in self.events):
            if self.ls.t_ns >= end:
                raise TimeoutError(f"no {name!r} event within {limit_s:g} s of simulated time")
            self.ls.run_for(0.06)

    def names(self) -> list[str]:
        """The task events so far, progress left out."""
        return [e.event for e in self.events if e.event != "step_progress"]

    def joint_states(self, since_ns: int = 0) -> list[tuple[int, JointState]]:
        """Published joint states with their times, from ``since_ns``."""
        return [
            (t, m)
            for t, s, m in self.ls.messages
            if s == "state/joints" and t >= since_ns and isinstance(m, JointState)
        ]

    def results(self) -> list[GoalResult]:
        """Every GoalResult published."""
        return [m for m in self.ls.published("controller/result") if isinstance(m, GoalResult)]
