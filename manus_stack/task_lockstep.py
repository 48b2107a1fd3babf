"""Tasks in lock-step: the sequencer core driving the real planner, controller, bridge and
simulator cores on one simulated clock (no Zenoh, no threads; :mod:`manus_stack.lockstep`).

Every core is fed through its service's wiring map, as its live shell is: the controller
and the planner are attached to the :class:`~manus_stack.lockstep.LockStep`, the
sequencer gets its inputs (and, with each joint state, its clock tick); a task is
submitted through :meth:`SequencerCore.submit`, as live. The sequencer's queries (the
plan requests that validate a submitted task included) are answered in-process, at the
simulated instant they are sent, by the core whose wiring answers that key
(``planner/plan``, ``controller/*``; ``bridge/command`` by the bridge core of the
lock-step); its task events are published like every other message, so
:attr:`LockStep.messages` holds the whole run. Used by the sequencer's scenario tests and
by ``manus bench sequencer``.
"""

from __future__ import annotations

from typing import Any

from manus.wiring import Input, Wiring
from manus_stack.lockstep import Handler, LockStep
from schemas import endpoints as ep
from schemas.base import Message
from schemas.control import GoalResult
from schemas.sequencing import SubmitReply, Task, TaskControl, TaskEvent, TaskStatus
from schemas.state import BridgePhase, JointState
from services.controller.core import ControllerCore
from services.controller.wiring import WIRING as CONTROLLER
from services.planner.core import PlannerCore
from services.planner.wiring import WIRING as PLANNER
from services.sequencer.actions import Action, Publish, Reply
from services.sequencer.config import SequencerConfig
from services.sequencer.core import SequencerCore
from services.sequencer.wiring import WIRING as SEQUENCER
from services.simulator.config import SimConfig

NS = 1_000_000_000


class TaskLockStep:
    """Simulator + bridge (:class:`LockStep`) + controller + planner + sequencer cores.

    Args:
        sim: simulator settings.
        controller: the controller core (default: a new one; tests pass one they can
            kill).
        sequencer: the sequencer's settings (default: its defaults).
    """

    def __init__(
        self,
        sim: SimConfig | None = None,
        controller: ControllerCore | None = None,
        sequencer: SequencerConfig | None = None,
    ) -> None:
        self.ls = LockStep(sim)
        self.controller = controller or ControllerCore()
        self.planner = PlannerCore()
        self.seq = SequencerCore(sequencer)
        self.events: list[TaskEvent] = []
        self.requests: list[Message] = []
        self.replies: dict[str, SubmitReply] = {}  # answers to submissions, by task id
        ls = self.ls
        ls.attach(CONTROLLER, self.controller)
        ls.attach(PLANNER, self.planner)
        for inp in SEQUENCER.inputs:
            ls.subscribe(inp.endpoint, self._sequencer_input(inp))
        ls.subscribe(ep.JOINTS, lambda m, t: self.do(self.seq.on_tick(t), t))
        ctrl = self.controller
        ls.watch_tokens(lambda service, t: CONTROLLER.published(ctrl.on_token_gone(service)))
        ls.watch_tokens(lambda service, t: self.do(self.seq.on_liveliness(service, False, t), t))
        self._answerers: dict[str, tuple[Wiring[Any, Any], Any]] = {
            a.endpoint: (wiring, core)
            for wiring, core in ((CONTROLLER, self.controller), (PLANNER, self.planner))
            for a in wiring.answers
        }
        for name in self.seq.config.required_services:
            self.seq.on_liveliness(name, True, 0)

    def _sequencer_input(self, inp: Input[SequencerCore, Any, list[Action]]) -> Handler:
        def handle(msg: Message, t: int) -> list[tuple[str, Message]]:
            return self.do(inp.handle(self.seq, msg, t), t)

        return handle

    def start_arm(self, timeout_s: float = 20.0) -> None:
        """Power up: run until the bridge is running and the sequencer has heard it."""
        self.ls.run_until_phase(BridgePhase.RUNNING, timeout_s)
        self.ls.run_for(0.5)

    def answer(self, request: Message, suffix: str | None = None) -> Message:
        """The answer of the core that owns queryable ``suffix`` (None: the queryable whose
        request type is ``request``'s) to one of the sequencer's queries, now; what that
        core publishes meanwhile is published."""
        self.requests.append(request)
        if suffix is None:
            suffix = next(
                e for e in ep.TABLE.of_kind(ep.Kind.QUERYABLE) if e.msg_type is type(request)
            )
        if suffix == ep.BRIDGE_COMMAND:
            return self.ls.arm_command(request)  # type: ignore[arg-type]
        found = self._answerers.get(suffix)
        if found is None:
            raise TypeError(f"no core answers {suffix!r} ({type(request).__name__})")
        wiring, core = found
        reply: Message
        reply, out = wiring.answer(suffix).handle(core, request, self.ls.t_ns)
        for key, msg in wiring.published(out):
            self.ls.publish(key, msg)
        return reply

    def do(self, actions: list[Action], t: int) -> list[tuple[str, Message]]:
        """Carry out the sequencer's actions; the messages to publish."""
        out: list[tuple[str, Message]] = []
        for action in actions:
            if isinstance(action, Reply):
                self.replies[action.submission] = action.reply
                continue
            if isinstance(action, Publish):
                if isinstance(action.message, TaskEvent):
                    self.events.append(action.message)
                out.append((action.suffix, action.message))
                continue
            reply = self.answer(action.request, action.suffix)
            out += self.do(self.seq.on_reply(action.token, reply, "", t), t)
        return out

    def submit(self, task: Task, task_id: str = "t") -> SubmitReply:
        """Submit ``task`` as the live shell does (:meth:`SequencerCore.submit`: refused,
        or validated whole and started); its answer."""
        t = self.ls.t_ns
        for suffix, msg in self.do(self.seq.submit(task, t, task_id), t):
            self.ls.publish(suffix, msg)
        reply = self.replies.pop(task_id, None)
        if reply is None:  # the cores answer every query at once: never
            raise RuntimeError(f"submission {task_id!r} got no answer")
        return reply

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
            if s == ep.JOINTS and t >= since_ns and isinstance(m, JointState)
        ]

    def results(self) -> list[GoalResult]:
        """Every GoalResult published."""
        return [m for m in self.ls.published(ep.RESULT) if isinstance(m, GoalResult)]
