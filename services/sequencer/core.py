"""The sequencer's deterministic core: one task at a time, from its submission to its end.

Inputs are method calls carrying messages and the time they arrived (``now_ns``); outputs
are :data:`~services.sequencer.actions.Action` values (:mod:`services.sequencer.actions`):
``Query`` (a request the shell sends with ``Node.query``; it feeds the answer back through
:meth:`SequencerCore.on_reply` with the query's ``token``), ``Publish`` (a message to
publish: the task events, and while a task runs one deadman
:class:`~schemas.control.Heartbeat` per joint state) and ``Reply`` (the answer to a
submitted task, for its submitter). No Zenoh, no threads, no clock: the same inputs give
the same outputs.

The submission (refused at once, held while the bridge starts, or validated whole, then
started): :class:`~services.sequencer.submission.TaskSubmission`.

The task stops at the first failure, with the reason from the service that failed
(planner refusal, controller refusal or result, bridge phase, e-stop, a service whose
liveliness token vanished, no joint states for ``link_timeout_s`` while a goal or a fold
is active, or a timeout). The reason of the last one names what can be known: when the
guardian's reports (``guardian/report``) still come from the arm computer, the link is
up and the bridge is the one that fell silent.

Inherited from :class:`~services.sequencer.task_run.TaskRun`: the running task, its
steps (:mod:`services.sequencer.steps`), pause, resume and cancel, the user taking over,
the events and the history. The link to the arm: :mod:`services.sequencer.link`.
"""

from __future__ import annotations

from schemas.base import Message
from schemas.commands import EStop
from schemas.control import ControllerFeedback, GoalResult, Heartbeat
from schemas.follow import FollowState
from schemas.guardian import GuardianReport
from schemas.jog import USER_TOOK_OVER, JogState
from schemas.planning import PlanReply
from schemas.sequencing import (
    TaskAction,
    TaskControl,
    TaskEventKind,
    TaskState,
    TaskStatus,
)
from schemas.state import BridgePhase, BridgeState, JointState
from services.sequencer.actions import HEARTBEAT_SUFFIX, Action, Publish
from services.sequencer.config import SequencerConfig
from services.sequencer.link import LinkWatch
from services.sequencer.step import Phase
from services.sequencer.submission import TaskSubmission


class SequencerCore(TaskSubmission):
    """Runs one task at a time (see the module docstring).

    Args:
        config: timeouts, required services, arm geometry.
    """

    def __init__(self, config: SequencerConfig | None = None) -> None:
        super().__init__(config)
        self._heartbeats = 0
        self.link_watch = LinkWatch()
        """What the joint states and the guardian's reports say of the link to the arm."""

    # -- control -------------------------------------------------------------------------------

    def control(self, req: TaskControl, now_ns: int) -> tuple[TaskStatus, list[Action]]:
        """Cancel, pause, resume, done or status (``sequencer/control``)."""
        self.now = now_ns
        if req.action == TaskAction.STATUS:
            return self.status(), []
        refused = self._why_not(req)
        if refused:
            return self.status(False, refused), []
        if req.action == TaskAction.CANCEL:
            out = self._cancel()
            return self.status(True, "cancelling" if self.busy else ""), out
        if req.action == TaskAction.DONE:
            return self._done()
        if req.action == TaskAction.PAUSE:
            out = self._pause()
            note = "pausing after the fold" if self.phase == Phase.FOLDING else ""
            return self.status(True, note), out
        return self._resume()

    def _resume(self) -> tuple[TaskStatus, list[Action]]:
        if self.state != TaskState.PAUSED:  # resume before the pause took effect
            self.pause_requested = False
            return self.status(True, "pause withdrawn"), []
        self.state = TaskState.RUNNING
        out: list[Action] = [
            self._event(TaskEventKind.RESUMED, step=self.step, progress=self._task_progress())
        ]
        if self._current is None:  # paused before the step began
            out += self._start_step()
        else:
            out += self._current.resume()
        return self.status(), out

    def _done(self) -> tuple[TaskStatus, list[Action]]:
        """The supervisor's ``done``: the running follow step ends (None: not one)."""
        done = self._current.done() if self._current is not None else None
        if done is None:
            return self.status(False, "the running step is not a follow step"), []
        return self.status(True, "done"), done

    def _why_not(self, req: TaskControl) -> str:
        """Why the cancel, pause or resume ``req`` cannot be done now ('' if it can)."""
        action = req.action
        pausing = (
            self.state == TaskState.PAUSED or self.pause_requested or self.phase == Phase.PAUSING
        )
        cancelling = self.cancel_requested or self.phase in (Phase.CANCELLING, Phase.STOPPING)
        not_paused = self.state != TaskState.PAUSED and not self.pause_requested
        checks = (
            (self._submission is not None, f"nothing to {action} before the task starts"),
            (
                bool(req.task_id) and req.task_id != self.task_id,
                f"no task {req.task_id!r} (current: {self.task_id!r})",
            ),
            (not self.busy, f"no task to {action} (state {self.state})"),
            (action == TaskAction.PAUSE and pausing, "already paused or pausing"),
            (action == TaskAction.PAUSE and cancelling, "the task is being cancelled"),
            (action == TaskAction.RESUME and not_paused, "the task is not paused"),
            (action == TaskAction.DONE and pausing, "the task is paused or pausing"),
        )
        return next((why for failed, why in checks if failed), "")

    # -- inputs --------------------------------------------------------------------------------

    def on_joint_state(self, js: JointState, now_ns: int) -> list[Action]:
        """Newest joint state: the start of the next plan; while a task runs, answered
        with a :class:`Heartbeat` echoing it (the controller's deadman)."""
        self.now = now_ns
        self.link_watch.on_joint_state(now_ns)
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
        return out + self._check_deadline() + self._recheck_held()

    def on_bridge_state(self, bs: BridgeState, now_ns: int) -> list[Action]:
        """Bridge phase: fold progress, arm errors, e-stop."""
        self.now = now_ns
        last = self._bridge_state
        if last is not None and bs.seq <= last.seq and bs.stamp_ns <= last.stamp_ns:
            return []  # published late: the bridge has said something newer already
        # (a lower seq with a newer stamp is a restarted bridge: its seq starts at 0)
        self._bridge_state = bs
        self.bridge_phase = bs.phase
        if not self.busy:
            return self._recheck_held()
        if self.state == TaskState.RUNNING and self._current is not None:
            out = self._current.on_bridge_state(bs)
            if out is not None:
                return out
        if (
            bs.phase in (BridgePhase.ARM_ERROR, BridgePhase.ESTOPPED)
            and self.phase != Phase.STOPPING
        ):
            return self.fail(f"can_bridge: phase {bs.phase}: {bs.detail}")
        return []

    def on_feedback(self, fb: ControllerFeedback, now_ns: int) -> list[Action]:
        """Controller feedback: progress of the running goal, the pause point."""
        self.now = now_ns
        if not self.busy or self._current is None:
            return []
        return self._current.on_feedback(fb)

    def on_result(self, res: GoalResult, now_ns: int) -> list[Action]:
        """The one result of a goal."""
        self.now = now_ns
        if not self.busy or self._current is None:
            return []
        return self._current.on_result(res)

    def on_follow_state(self, state: FollowState, now_ns: int) -> list[Action]:
        """The controller's follow state: a follow step holds, or not yet."""
        self.now = now_ns
        if not self.busy or self._current is None:
            return []
        return self._current.on_follow_state(state)

    def on_jog_state(self, msg: JogState, now_ns: int) -> list[Action]:
        """The controller's jog: the user took over. A running goal is ended by the
        controller itself (see the module docstring); a wait pauses now; a plan or a goal
        request at its answer."""
        self.now = now_ns
        if not (msg.active and self.state == TaskState.RUNNING and self._current is not None):
            return []
        self.pause_reason = USER_TOOK_OVER
        return self._pause()

    def on_estop(self, msg: EStop, now_ns: int) -> list[Action]:
        """An e-stop on the bus (the bridge latches it itself): the task fails at once."""
        self.now = now_ns
        if msg.engaged and self.busy:
            why = f": {msg.reason}" if msg.reason else ""
            return self.fail(f"e-stop engaged by {msg.source or 'someone'}{why}")
        return []

    def on_guardian_report(self, report: GuardianReport, now_ns: int) -> list[Action]:
        """The CAN guardian's report: proof that the arm computer is heard, and whether
        the bridge leaves the arm's syncs unanswered (named when joint states stop)."""
        self.now = now_ns
        self.link_watch.on_guardian_report(report, now_ns)
        return []

    def on_liveliness(self, service: str, alive: bool, now_ns: int) -> list[Action]:
        """A service's liveliness token appeared or vanished."""
        self.now = now_ns
        if alive:
            self.alive.add(service)
            self.seen.add(service)
            return self._recheck_held()  # a submission may wait for it
        self.alive.discard(service)
        if self.busy and service in self.config.required_services:
            return self.fail(f"{service} is gone (its liveliness token vanished)")
        return []

    def on_tick(self, now_ns: int) -> list[Action]:
        """Time passes (call at least every 100 ms): waits and timeouts."""
        self.now = now_ns
        self.link_watch.on_tick(now_ns, self.config.link_timeout_s)
        if self.state == TaskState.RUNNING and self._current is not None:
            out = self._current.on_tick()
            if out is not None:
                return out
        return self._check_link() + self._check_deadline() + self._recheck_held()

    def on_reply(self, token: int, reply: Message | None, error: str, now_ns: int) -> list[Action]:
        """The answer to the :class:`Query` with ``token`` (None and ``error``: no answer)."""
        self.now = now_ns
        sub = self._submission
        if sub is not None and token == sub.token:
            sub.token = None
            if isinstance(reply, PlanReply):
                sub.validator.on_reply(reply)
            else:
                sub.validator.on_reply(None, error or f"bad reply {type(reply).__name__}")
            return self._validate()
        if token != self._await or not self.busy or self._current is None:
            return []
        self._await = None
        return self._current.on_reply(reply, error)

    def _check_link(self) -> list[Action]:
        """Fail the task when joint states stop while a controller goal is active."""
        if self.state != TaskState.RUNNING or self._current is None:
            return []
        if not self._current.needs_joint_states:
            return []
        silence = self.link_watch.silence(self.now, self.config.link_timeout_s)
        return self.fail(silence) if silence else []
