"""The sequencer's deterministic core: one task at a time, a step state machine.

Inputs are method calls carrying messages and the time they arrived (``now_ns``); outputs
are :data:`Action` values: :class:`Query` (a request the shell sends with
``Node.query``; it feeds the answer back through :meth:`SequencerCore.on_reply` with the
query's ``token``) and :class:`Publish` (a message to publish: the task events, and while
a task runs one deadman :class:`~schemas.control.Heartbeat` per joint state). No Zenoh,
no threads, no clock: the same inputs give the same outputs.

Steps (SPEC 7, thesis 4.2.2):

- **move / pose**: plan from the newest joint state (``planner/plan`` with an explicit
  ``start``), send the trajectory (``controller/goal``), wait for its ``GoalResult``.
- **gripper**: ``controller/gripper``, wait for the result.
- **fold_in / fold_out**: ``bridge/command``; wait for ``state/bridge`` to show the fold
  (``folding_*``) and then leave it: ``running`` is success, ``arm_error`` / ``estopped``
  failure.
- **wait**: time from the inputs.

The task stops at the first failure, with the reason from the service that failed
(planner refusal, controller refusal or result, bridge phase, e-stop, a service whose
liveliness token vanished, no joint states for ``link_timeout_s`` while a goal is active,
or a timeout).

**Pause** stops the arm and keeps the task: a running trajectory or gripper goal is
cancelled (the controller decelerates within the arm's limits) and, on **resume**, the
rest of the step is planned again from where the arm stopped (the via points not yet
reached, at their planned pace; :func:`services.sequencer.poses.remainder_path`), or the
gripper goal is sent again. A wait keeps its remaining time. A fold cannot be interrupted
safely half-way: a pause asked during a fold (or while a plan or goal request is in
flight) takes effect as soon as that finishes. **Cancel** ends the task and stops the
arm: a running goal is cancelled (bounded deceleration), a fold is stopped by the bridge
(``stop``, then ``clear`` so the arm is ready for the next task). A controller that does
not confirm a cancel or pause within ``cancel_timeout_s`` gets the bridge's ``stop``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from schemas import endpoints as ep
from schemas.base import Message
from schemas.commands import ArmCommand, ArmCommandReply, EStop
from schemas.control import (
    CancelGoal,
    ControllerFeedback,
    GoalAck,
    GoalResult,
    GripperGoal,
    Heartbeat,
    TrajectoryGoal,
)
from schemas.planning import Path, PlanReply, Trajectory
from schemas.sequencing import SubmitReply, Task, TaskControl, TaskEvent, TaskStatus, TaskStep
from schemas.state import BridgeState, JointState
from services.sequencer.config import SequencerConfig
from services.sequencer.poses import remainder_path
from services.sequencer.validate import plan_request, step_label

NS = 1_000_000_000
EVENTS_SUFFIX = ep.EVENTS
HEARTBEAT_SUFFIX = ep.HEARTBEAT
"""Key suffix of the deadman heartbeat (``schemas.control.Heartbeat``)."""
ACTIVE_STATES = ("running", "paused")


@dataclass(frozen=True)
class Query:
    """Send ``request`` to the queryable ``<prefix>/<suffix>``; answer with ``token``."""

    token: int
    suffix: str
    request: Message
    reply_type: type[Message]


@dataclass(frozen=True)
class Publish:
    """Publish ``message`` on ``<prefix>/<suffix>``."""

    suffix: str
    message: Message


Action = Query | Publish


class SequencerCore:
    """Runs one task at a time (see the module docstring).

    Args:
        config: timeouts, required services, arm geometry.
    """

    def __init__(self, config: SequencerConfig | None = None) -> None:
        self.config = config or SequencerConfig()
        self.latest: JointState | None = None
        self.bridge_phase = ""
        self.alive: set[str] = set()
        self.task: Task | None = None
        self.task_id = ""
        self.state = "none"
        self.step = -1
        self.reason = ""
        self._seq = 0
        self._token = 0
        self._goals = 0
        self._now = 0
        self._heartbeats = 0
        self._js_rx: int | None = None  # receive time of the newest joint state [ns]
        self._reset_step()

    def _reset_step(self) -> None:
        self._phase = (
            ""  # planning, acking, active, folding, waiting, pausing, cancelling, stopping
        )
        self._await: int | None = None
        self._goal_id = ""
        self._traj: Trajectory | None = None
        self._t = 0.0  # trajectory time of the newest feedback of the running goal [s]
        self._started = False
        self._resume: tuple[Trajectory, float] | None = None
        self._base = 0.0  # step progress reached before a resume
        self._progress = 0.0
        self._reported = -1.0
        self._deadline: int | None = None
        self._wait_left = 0.0
        self._seen_fold = False
        self._grip0: float | None = None
        self._pause_requested = False
        self._cancel_requested = False

    # -- queries about the task ------------------------------------------------------------

    @property
    def busy(self) -> bool:
        """A task is running or paused."""
        return self.state in ACTIVE_STATES

    def missing_services(self) -> list[str]:
        """Required services whose liveliness tokens are not up (sorted)."""
        return sorted(set(self.config.required_services) - self.alive)

    def start_configuration(self) -> list[float] | None:
        """The arm's configuration now (newest valid joint state), for validation."""
        if self.latest is None or not self.latest.valid:
            return None
        return list(self.latest.position)

    def status(self, ok: bool = True, message: str = "") -> TaskStatus:
        """Where the current (or last) task stands."""
        total = len(self.task.steps) if self.task is not None else 0
        if self.state == "succeeded":
            progress = 1.0
        elif total and self.step >= 0:
            progress = min(1.0, (self.step + self._progress) / total)
        else:
            progress = 0.0
        detail = message or self.reason or self._phase
        return TaskStatus(
            ok=ok,
            task_id=self.task_id,
            state=self.state,
            step=self.step,
            total=total,
            progress=progress,
            message=detail,
        )

    # -- task life ---------------------------------------------------------------------------

    def refuse(self, task: Task) -> SubmitReply | None:
        """Why ``task`` cannot start now (busy, services missing), or None."""
        if self.busy:
            return SubmitReply(
                accepted=False,
                task_id="",
                errors=[f"busy: task {self.task_id} is {self.state}; cancel it first"],
            )
        missing = self.missing_services()
        if missing:
            return SubmitReply(
                accepted=False,
                task_id="",
                errors=[f"required service(s) not running: {', '.join(missing)}"],
            )
        if self.start_configuration() is None and self.bridge_phase == "running":
            return SubmitReply(
                accepted=False,
                task_id="",
                errors=["no valid joint state from the arm yet; try again in a moment"],
            )
        if self.bridge_phase != "running":
            seen = self.bridge_phase or "no state/bridge received yet"
            return SubmitReply(
                accepted=False,
                task_id="",
                errors=[f"the bridge is not running ({seen}); a task starts only in phase running"],
            )
        return None

    def start(self, task_id: str, task: Task, now_ns: int) -> list[Action]:
        """Start a validated task (the caller checked :meth:`refuse` and validated it)."""
        self._now = now_ns
        self.task, self.task_id, self.state, self.reason = task, task_id, "running", ""
        self.step = 0
        self._goals = 0
        self._reset_step()
        out = [self._event("accepted", step=-1, progress=0.0)]
        return out + self._start_step()

    def control(self, req: TaskControl, now_ns: int) -> tuple[TaskStatus, list[Action]]:
        """Cancel, pause, resume or status (``sequencer/control``)."""
        self._now = now_ns
        if req.action == "status":
            return self.status(), []
        if req.task_id and req.task_id != self.task_id:
            return self.status(False, f"no task {req.task_id!r} (current: {self.task_id!r})"), []
        if not self.busy:
            return self.status(False, f"no task to {req.action} (state {self.state})"), []
        if req.action == "cancel":
            out = self._cancel()
            return self.status(True, "cancelling" if self.busy else ""), out
        if req.action == "pause":
            if self.state == "paused" or self._pause_requested or self._phase == "pausing":
                return self.status(False, "already paused or pausing"), []
            if self._cancel_requested or self._phase in ("cancelling", "stopping"):
                return self.status(False, "the task is being cancelled"), []
            out = self._pause()
            note = "pausing after the fold" if self._phase == "folding" else ""
            return self.status(True, note), out
        # resume
        if self.state != "paused":
            if self._pause_requested:
                self._pause_requested = False
                return self.status(True, "pause withdrawn"), []
            return self.status(False, "the task is not paused"), []
        self.state = "running"
        out = [self._event("resumed", step=self.step, progress=self._task_progress())]
        out += self._continue()
        return self.status(), out

    # -- inputs ------------------------------------------------------------------------------

    def on_joint_state(self, js: JointState, now_ns: int) -> list[Action]:
        """Newest joint state: the start of the next plan; while a task runs, answered
        with a :class:`Heartbeat` echoing it (the controller's deadman)."""
        self._now = now_ns
        self._js_rx = now_ns
        if js.valid:
            self.latest = js
        out: list[Action] = []
        if self.busy:
            self._heartbeats += 1
            beat = Heartbeat(
                stamp_ns=now_ns,
                seq=self._heartbeats,
                source="sequencer",
                ref_seq=js.seq,
                ref_stamp_ns=js.stamp_ns,
                task_id=self.task_id,
            )
            out.append(Publish(HEARTBEAT_SUFFIX, beat))
        return out + self._check_deadline()

    def on_bridge_state(self, bs: BridgeState, now_ns: int) -> list[Action]:
        """Bridge phase: fold progress, arm errors, e-stop."""
        self._now = now_ns
        self.bridge_phase = bs.phase
        if not self.busy:
            return []
        if self._phase == "folding":
            kind = self._kind()
            if bs.phase == f"folding_{kind.removeprefix('fold_')}":
                self._seen_fold = True
            elif self._seen_fold and bs.phase == "running":
                return self._step_done()
        if bs.phase in ("arm_error", "estopped") and self._phase not in ("stopping",):
            return self._fail(f"can_bridge: phase {bs.phase}: {bs.detail}")
        return []

    def on_feedback(self, fb: ControllerFeedback, now_ns: int) -> list[Action]:
        """Controller feedback: progress of the running goal, the pause point."""
        self._now = now_ns
        if not self.busy or not self._goal_id:
            return []
        kind = self._kind()
        if kind in ("move", "pose") and fb.goal_id == self._goal_id and self._traj is not None:
            self._t = fb.t
            frac = min(1.0, max(0.0, fb.t / max(self._traj.times[-1], 1e-9)))
            return self._report(self._base + (1.0 - self._base) * frac)
        if kind == "gripper" and fb.gripper_goal_id == self._goal_id:
            if self._grip0 is None:
                self._grip0 = fb.gripper
            span = abs(fb.gripper_target - self._grip0)
            done = 1.0 if span < 1e-6 else 1.0 - abs(fb.gripper_target - fb.gripper) / span
            return self._report(min(1.0, max(0.0, done)))
        return []

    def on_result(self, res: GoalResult, now_ns: int) -> list[Action]:
        """The one result of a goal."""
        self._now = now_ns
        if not self.busy or not self._goal_id or res.goal_id != self._goal_id:
            return []
        self._goal_id = ""
        phase = self._phase
        if phase == "cancelling":
            return self._cancelled("cancelled by request")
        if res.status == "succeeded":
            return self._step_done()
        if res.status == "cancelled" and phase == "pausing":
            if self._kind() in ("move", "pose") and self._traj is not None:
                self._resume = (self._traj, self._t)
                self._base = self._progress
            return self._paused()
        return self._fail(f"controller: goal {res.status}: {res.reason}")

    def on_estop(self, msg: EStop, now_ns: int) -> list[Action]:
        """An e-stop on the bus (the bridge latches it itself): the task fails at once."""
        self._now = now_ns
        if msg.engaged and self.busy:
            why = f": {msg.reason}" if msg.reason else ""
            return self._fail(f"e-stop engaged by {msg.source or 'someone'}{why}")
        return []

    def on_liveliness(self, service: str, alive: bool, now_ns: int) -> list[Action]:
        """A service's liveliness token appeared or vanished."""
        self._now = now_ns
        if alive:
            self.alive.add(service)
            return []
        self.alive.discard(service)
        if self.busy and service in self.config.required_services:
            return self._fail(f"{service} is gone (its liveliness token vanished)")
        return []

    def on_tick(self, now_ns: int) -> list[Action]:
        """Time passes (call at least every 100 ms): waits and timeouts."""
        self._now = now_ns
        if self.state == "running" and self._phase == "waiting" and self._deadline is not None:
            step = self._step()
            left = (self._deadline - now_ns) / NS
            if left <= 0.0:
                self._deadline = None
                return self._step_done()
            return self._report(1.0 - left / step.duration if step.duration > 0 else 1.0)
        return self._check_link() + self._check_deadline()

    def _check_link(self) -> list[Action]:
        """Fail the task when joint states stop while a controller goal is active."""
        if self.state != "running" or self._phase not in ("acking", "active", "pausing"):
            return []
        if self._js_rx is None:
            return []
        silent = self._now - self._js_rx
        if silent <= self.config.link_timeout_s * NS:
            return []
        return self._fail(
            f"no joint states from the arm for {silent / 1e6:.0f} ms (more than link_timeout_s "
            f"{self.config.link_timeout_s:g} s): the link to the arm computer is down; the "
            "controller stops the arm itself when it loses the supervisor's heartbeat"
        )

    def on_reply(self, token: int, reply: Message | None, error: str, now_ns: int) -> list[Action]:
        """The answer to the :class:`Query` with ``token`` (None and ``error``: no answer)."""
        self._now = now_ns
        if token != self._await or not self.busy:
            return []
        self._await = None
        phase = self._phase
        if phase == "planning":
            return self._on_plan(reply, error)
        if phase == "acking":
            return self._on_ack(reply, error)
        if phase == "folding":
            if not isinstance(reply, ArmCommandReply):
                return self._fail(f"can_bridge: {error or 'no answer to the fold'}")
            if not reply.ok:
                return self._fail(f"can_bridge refused {self._kind()}: {reply.message}")
            # Done only after a state/bridge in folding_* and then running: a state
            # published before the bridge took the command may still be on its way.
            return []
        if phase == "stopping":
            # stop answered: clear, so the arm is back in joint mode and ready.
            if isinstance(reply, ArmCommandReply) and reply.ok and reply.phase == "stopped":
                return [
                    self._query(
                        ep.BRIDGE_COMMAND,
                        ArmCommand(action="clear", source="sequencer"),
                        ArmCommandReply,
                        wait=True,
                        phase="clearing",
                    )
                ]
            return self._cancelled("cancelled by request; fold stopped")
        if phase == "clearing":
            return self._cancelled("cancelled by request; fold stopped")
        return []

    # -- steps -------------------------------------------------------------------------------

    def _kind(self) -> str:
        return self._step().kind

    def _step(self) -> TaskStep:
        assert self.task is not None
        return self.task.steps[self.step]

    def _start_step(self) -> list[Action]:
        assert self.task is not None
        if self.step >= len(self.task.steps):
            self.state = "succeeded"
            self.step = len(self.task.steps) - 1
            self._progress = 1.0
            return [self._event("succeeded", step=-1, progress=1.0)]
        if self._pause_requested:
            return self._paused()
        self._started = True
        out: list[Action] = [self._event("step_started", progress=0.0)]
        return out + self._begin()

    def _begin(self, path: Path | None = None) -> list[Action]:
        """Do the current step (again, after a pause: the rest ``path`` of a move)."""
        step = self._step()
        if step.kind in ("move", "pose"):
            start = self.start_configuration()
            if start is None:
                return self._fail("no valid joint state from the arm (is the bridge running?)")
            request = plan_request(step, start, path)
            if path is not None:  # the rest of a paused path starts from rest: let it stretch
                request = dataclasses.replace(request, speed_scaling=True)
            return [self._query(ep.PLAN, request, PlanReply, wait=True, phase="planning")]
        if step.kind == "gripper":
            self._goals += 1
            self._goal_id = f"{self.task_id}.{self.step + 1}.{self._goals}"
            self._grip0 = None
            goal = GripperGoal(
                goal_id=self._goal_id, opening=step.opening, timeout=self.config.gripper_timeout_s
            )
            self._deadline = self._now + int((self.config.gripper_timeout_s + 5.0) * NS)
            return [self._query(ep.GRIPPER_GOAL, goal, GoalAck, wait=True, phase="acking")]
        if step.kind == "wait":
            left = self._wait_left if self._wait_left > 0.0 else step.duration
            self._wait_left = 0.0
            self._deadline = self._now + int(left * NS)
            self._phase = "waiting"
            return []
        # fold_in / fold_out
        self._seen_fold = False
        self._deadline = self._now + int(self.config.fold_timeout_s * NS)
        cmd = ArmCommand(action=step.kind, source="sequencer")
        return [self._query(ep.BRIDGE_COMMAND, cmd, ArmCommandReply, wait=True, phase="folding")]

    def _on_plan(self, reply: Message | None, error: str) -> list[Action]:
        if not isinstance(reply, PlanReply):
            return self._fail(f"planner: {error or 'bad reply'}")
        if not reply.ok or reply.trajectory is None:
            why = reply.error.message if reply.error is not None else "no trajectory"
            return self._fail(f"planner refused: {why}")
        if self._cancel_requested:
            return self._cancelled("cancelled by request")
        self._traj = reply.trajectory
        self._resume = None
        if self._pause_requested:
            return self._paused()
        self._goals += 1
        self._goal_id = f"{self.task_id}.{self.step + 1}.{self._goals}"
        self._t = 0.0
        assert self.task is not None
        goal = TrajectoryGoal(
            goal_id=self._goal_id,
            trajectory=reply.trajectory,
            mode=self.task.mode,
            heartbeat_timeout=self.config.heartbeat_timeout_s,
        )
        span = reply.trajectory.times[-1] + goal.goal_time_tolerance + self.config.result_margin_s
        self._deadline = self._now + int(span * NS)
        return [self._query(ep.GOAL, goal, GoalAck, wait=True, phase="acking")]

    def _on_ack(self, reply: Message | None, error: str) -> list[Action]:
        if not isinstance(reply, GoalAck):
            self._goal_id = ""
            return self._fail(f"controller: {error or 'bad reply'}")
        if not reply.accepted:
            self._goal_id = ""
            return self._fail(f"controller refused the goal: {reply.reason}")
        self._phase = "active"
        if self._cancel_requested:
            return self._cancel()
        if self._pause_requested:
            self._pause_requested = False
            return self._pause()
        return []

    def _step_done(self) -> list[Action]:
        self._progress = 1.0
        out: list[Action] = [self._event("step_finished", progress=1.0)]
        pause = self._pause_requested
        cancel = self._cancel_requested
        self.step += 1
        self._reset_step()
        if cancel:
            return out + self._cancelled("cancelled by request")
        self._pause_requested = pause
        return out + self._start_step()

    def _continue(self) -> list[Action]:
        """Resume the current step where the pause left it."""
        if not self._started:
            return self._start_step()
        step = self._step()
        if step.kind in ("move", "pose") and self._resume is not None:
            traj, t = self._resume  # cleared once the rest is planned
            rest = remainder_path(traj, t, source=step.where or step.kind, cfg=self.config.arm)
            if rest is None:
                return self._step_done()
            return self._begin(rest)
        return self._begin()

    # -- pause / cancel / failure --------------------------------------------------------------

    def _pause(self) -> list[Action]:
        if self._phase == "active" and self._goal_id:
            self._phase = "pausing"
            self._deadline = self._now + int(self.config.cancel_timeout_s * NS)
            return [self._query(ep.CANCEL, CancelGoal(goal_id=self._goal_id), GoalAck)]
        if self._phase == "waiting" and self._deadline is not None:
            self._wait_left = max(0.0, (self._deadline - self._now) / NS)
            self._deadline = None
            return self._paused()
        self._pause_requested = True  # planning, acking, folding: at their end
        return []

    def _paused(self) -> list[Action]:
        self._pause_requested = False
        self.state = "paused"
        self._phase = "paused"
        self._deadline = None
        return [self._event("paused", progress=self._task_progress(), step=self.step)]

    def _cancel(self) -> list[Action]:
        self._cancel_requested = True
        if self.state == "paused":
            return self._cancelled("cancelled by request")
        if self._phase == "active" and self._goal_id:
            self._phase = "cancelling"
            self._deadline = self._now + int(self.config.cancel_timeout_s * NS)
            return [self._query(ep.CANCEL, CancelGoal(goal_id=self._goal_id), GoalAck)]
        if self._phase == "pausing":
            self._phase = "cancelling"
            return []
        if self._phase == "folding":
            stop = ArmCommand(action="stop", source="sequencer")
            return [
                self._query(ep.BRIDGE_COMMAND, stop, ArmCommandReply, wait=True, phase="stopping")
            ]
        if self._phase in ("planning", "acking"):
            return []  # at the reply (an accepted goal is then cancelled)
        return self._cancelled("cancelled by request")

    def _cancelled(self, reason: str) -> list[Action]:
        self.state = "cancelled"
        self.reason = reason
        self._phase = ""
        self._await = None
        self._deadline = None
        return [
            self._event("cancelled", step=self.step, progress=self._task_progress(), reason=reason)
        ]

    def _fail(self, reason: str) -> list[Action]:
        out: list[Action] = []
        if self._goal_id and self._phase in ("acking", "active", "pausing", "cancelling"):
            out.append(self._query(ep.CANCEL, CancelGoal(goal_id=self._goal_id), GoalAck))
        if self._phase == "folding":
            out.append(
                self._query(
                    ep.BRIDGE_COMMAND,
                    ArmCommand(action="stop", source="sequencer"),
                    ArmCommandReply,
                )
            )
        label = step_label(self._step(), self.step)
        full = f"{label}: {reason}"
        out.append(self._event("step_failed", reason=full))
        self.state = "failed"
        self.reason = full
        self._phase = ""
        self._goal_id = ""
        self._await = None
        self._deadline = None
        out.append(
            self._event("failed", step=self.step, progress=self._task_progress(), reason=full)
        )
        return out

    def _check_deadline(self) -> list[Action]:
        if not self.busy or self._deadline is None or self._now < self._deadline:
            return []
        self._deadline = None
        phase = self._phase
        if phase in ("pausing", "cancelling"):
            goal_id, self._goal_id = self._goal_id, ""
            stop = self._query(
                ep.BRIDGE_COMMAND, ArmCommand(action="stop", source="sequencer"), ArmCommandReply
            )
            what = "pause" if phase == "pausing" else "cancel"
            msg = (
                f"controller did not confirm the {what} of goal {goal_id} within "
                f"{self.config.cancel_timeout_s:g} s; arm stopped by the bridge"
            )
            if phase == "cancelling":
                return [stop, *self._cancelled(msg)]
            return [stop, *self._fail(msg)]
        if phase == "folding":
            return self._fail(f"the fold did not complete within {self.config.fold_timeout_s:g} s")
        if phase in ("acking", "active"):
            return self._fail("no result from the controller in time (goal deadline passed)")
        return []

    # -- outputs -------------------------------------------------------------------------------

    def _query(
        self,
        suffix: str,
        request: Message,
        reply_type: type[Message],
        *,
        wait: bool = False,
        phase: str = "",
    ) -> Query:
        self._token += 1
        if wait:
            self._await = self._token
            self._phase = phase
        return Query(self._token, suffix, request, reply_type)

    def _task_progress(self) -> float:
        total = len(self.task.steps) if self.task is not None else 0
        if not total:
            return 0.0
        return min(1.0, max(0.0, (max(self.step, 0) + self._progress) / total))

    def _report(self, progress: float) -> list[Action]:
        self._progress = progress
        if abs(progress - self._reported) < self.config.progress_step and progress < 1.0:
            return []
        self._reported = progress
        return [self._event("step_progress", progress=progress)]

    def _event(
        self, event: str, *, step: int | None = None, progress: float = 0.0, reason: str = ""
    ) -> Publish:
        total = len(self.task.steps) if self.task is not None else 0
        index = self.step if step is None else step
        kind = self.task.steps[index].kind if self.task is not None and 0 <= index < total else ""
        self._seq += 1
        msg = TaskEvent(
            stamp_ns=self._now,
            seq=self._seq,
            task_id=self.task_id,
            event=event,
            step=index,
            total=total,
            kind=kind,
            progress=progress,
            reason=reason,
        )
        return Publish(EVENTS_SUFFIX, msg)
