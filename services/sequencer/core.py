"""The sequencer's deterministic core: one task at a time, from its submission to its end.

Inputs are method calls carrying messages and the time they arrived (``now_ns``); outputs
are :data:`~services.sequencer.actions.Action` values (:mod:`services.sequencer.actions`):
``Query`` (a request the shell sends with ``Node.query``; it feeds the answer back through
:meth:`SequencerCore.on_reply` with the query's ``token``), ``Publish`` (a message to
publish: the task events, and while a task runs one deadman
:class:`~schemas.control.Heartbeat` per joint state) and ``Reply`` (the answer to a
submitted task, for its submitter). No Zenoh, no threads, no clock: the same inputs give
the same outputs.

**Submission** (:meth:`SequencerCore.submit`): a task is refused at once (a task running
or paused, another being validated, required services missing, the bridge stopped), held
while the bridge is still starting (at most ``bridge_wait_s``, :mod:`bridge_wait`), or
validated whole (state ``validating``, :mod:`validate`): every
move is planned by the planner (``planner/plan`` queries, from where the previous steps
leave the arm) before anything moves. The ``Reply`` ends it: every problem found, or
accepted, and then the task starts at once (after checking again what may have changed
meanwhile).

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

from dataclasses import dataclass

from manus.scene import start_scene_state
from schemas import endpoints as ep
from schemas.base import Message
from schemas.collision import SceneState
from schemas.commands import EStop
from schemas.control import ControllerFeedback, GoalResult, Heartbeat
from schemas.guardian import GuardianReport
from schemas.jog import USER_TOOK_OVER, JogState
from schemas.planning import PlanReply
from schemas.sequencing import (
    SubmitReply,
    Task,
    TaskAction,
    TaskControl,
    TaskEventKind,
    TaskState,
    TaskStatus,
)
from schemas.state import BridgePhase, BridgeState, JointState
from services.sequencer.actions import HEARTBEAT_SUFFIX, Action, Publish, Reply
from services.sequencer.bridge_wait import BridgeWait, bridge_on_its_way
from services.sequencer.config import SequencerConfig
from services.sequencer.link import LinkWatch
from services.sequencer.step import Phase
from services.sequencer.task_run import TaskRun
from services.sequencer.validate import Validator, fold_checker, scene_fold_checker


def refusal(why: str) -> SubmitReply:
    """A refused submission."""
    return SubmitReply(accepted=False, task_id="", errors=[why])


def answer(task_id: str, reply: SubmitReply) -> Reply:
    """The answer to submission ``task_id``."""
    return Reply(ep.SUBMIT, reply, submission=task_id)


@dataclass
class Submission:
    """A submitted task being validated."""

    task_id: str
    task: Task
    validator: Validator
    token: int | None = None  # of the plan query waiting for its answer


class SequencerCore(TaskRun):
    """Runs one task at a time (see the module docstring).

    Args:
        config: timeouts, required services, arm geometry.
    """

    def __init__(self, config: SequencerConfig | None = None) -> None:
        super().__init__(config)
        self.bridge_phase = ""
        self.alive: set[str] = set()
        self._submission: Submission | None = None
        self.bridge_wait = BridgeWait(self.config.bridge_wait_s)
        self._heartbeats = 0
        self._bridge_state: BridgeState | None = None  # the newest, in the bridge's order
        self.link_watch = LinkWatch()
        """What the joint states and the guardian's reports say of the link to the arm."""
        self.fold_check = fold_checker(self.config.scene, self.config.arm)
        """Checks folds against the scene during validation (None: no scene)."""
        self.scene_seen = start_scene_state(self.config.scene)
        """The scene folds are checked against, as the planner announces it
        (``config.scene``'s until the planner's differs; None: no scene)."""

    # -- queries about the task ----------------------------------------------------------------

    @property
    def validating(self) -> str:
        """Id of the submitted task being validated or held ('' when none)."""
        held = self.bridge_wait.held
        if held is not None:
            return held.task_id
        return self._submission.task_id if self._submission is not None else ""

    def missing_services(self) -> list[str]:
        """Required services whose liveliness tokens are not up (sorted)."""
        return sorted(set(self.config.required_services) - self.alive)

    def status(self, ok: bool = True, message: str = "") -> TaskStatus:
        """Where the current (or last) task stands; a task being validated first."""
        sub = self._submission
        if self.bridge_wait.held is not None:
            return self.bridge_wait.status(self.bridge_phase)
        if sub is not None:
            return TaskStatus(ok=ok, task_id=sub.task_id, state=TaskState.VALIDATING, step=-1,
                              total=len(sub.task.steps), progress=0.0,
                              message=message or "planning its moves")  # fmt: skip
        total = len(self.task.steps) if self.task is not None else 0
        if self.state == TaskState.SUCCEEDED:
            progress = 1.0
        elif total and self.step >= 0:
            progress = min(1.0, (self.step + self.step_progress) / total)
        else:
            progress = 0.0
        detail = message or self.reason or self.phase
        return TaskStatus(
            ok=ok,
            task_id=self.task_id,
            state=self.state,
            step=self.step,
            total=total,
            progress=progress,
            message=detail,
        )

    # -- submission and control ----------------------------------------------------------------

    def refuse(self, task: Task) -> SubmitReply | None:
        """Why ``task`` cannot start now (busy, services missing, no arm), or None."""
        if self.busy:
            return refusal(f"busy: task {self.task_id} is {self.state}; cancel it first")
        held = self.bridge_wait.busy()
        if self._submission is not None or held:
            return refusal(
                held
                or f"busy: task {self.validating} is being validated; submit again once it "
                "is accepted or refused"
            )
        missing = self.missing_services()
        if missing:
            return refusal(f"required service(s) not running: {', '.join(missing)}")
        if self.start_configuration() is None and self.bridge_phase == BridgePhase.RUNNING:
            return refusal("no valid joint state from the arm yet; try again in a moment")
        if self.bridge_phase != BridgePhase.RUNNING:
            seen = self.bridge_phase or "no state/bridge received yet"
            detail = self._bridge_state.detail if self._bridge_state is not None else ""
            seen += f": {detail}" if detail and self.bridge_phase else ""
            return refusal(
                f"the bridge is not running ({seen}); a task starts only in phase running"
            )
        return None

    def submit(self, task: Task, now_ns: int, task_id: str) -> list[Action]:
        """A task submitted (``sequencer/submit``): refused at once, or validated (queries
        to the planner) and then started; a :class:`Reply` for ``task_id`` ends it.

        Args:
            task: the task.
            now_ns: time of the submission [ns].
            task_id: the id it gets if accepted (the caller makes it unique).
        """
        self.now = now_ns
        refused = self.refuse(task)
        held = refused is not None and self._bridge_starting()
        if held and self.bridge_wait.hold(task_id, task, now_ns):
            return []  # answered when the bridge runs, or at the end of the wait
        if refused is not None:
            return [answer(task_id, refused)]
        return self._begin(task_id, task)

    def _bridge_starting(self) -> bool:
        """Only the bridge, on its way to running, keeps a task from starting now."""
        if self.busy or self._submission is not None or self.missing_services():
            return False
        return bridge_on_its_way(self.bridge_phase, self.start_configuration() is not None)

    def _recheck_held(self) -> list[Action]:
        """The held submission: begun once the bridge is ready, refused when it stopped
        starting or the wait is over, else held on."""
        held = self.bridge_wait.held
        if held is None or (self._bridge_starting() and self.now < held.until_ns):
            return []
        self.bridge_wait.held = None
        refused = self.refuse(held.task)
        if refused is None:
            return self._begin(held.task_id, held.task)
        if self._bridge_starting():  # the wait is over
            detail = self._bridge_state.detail if self._bridge_state is not None else ""
            refused = self.bridge_wait.late(held, self.bridge_phase, detail, self.now)
        return [answer(held.task_id, refused)]

    def _begin(self, task_id: str, task: Task) -> list[Action]:
        """Validate ``task`` (plan queries), then start it."""
        validator = Validator(task, self.start_configuration(), self.config.arm, self.fold_check)
        self._submission = Submission(task_id, task, validator)
        return self._validate()

    def withdraw(self, task_id: str, now_ns: int, reason: str) -> list[Action]:
        """Give up validating submission ``task_id`` (its submitter stopped waiting): its
        :class:`Reply` refuses it with ``reason``; late plan answers are ignored."""
        self.now = now_ns
        held = self.bridge_wait.held
        if held is not None and held.task_id == task_id:
            self.bridge_wait.held = None
            return [answer(task_id, refusal(reason))]
        sub = self._submission
        if sub is None or sub.task_id != task_id:
            return []
        self._submission = None
        return [answer(task_id, refusal(reason))]

    def _validate(self) -> list[Action]:
        """Ask for the next plan of the submission, or answer it (and start the task)."""
        sub = self._submission
        assert sub is not None
        request = sub.validator.next_request()
        if request is not None:
            query = self.query(ep.PLAN, request, PlanReply)
            sub.token = query.token
            return [query]
        self._submission = None
        errors = sub.validator.errors
        if errors:
            return [answer(sub.task_id, SubmitReply(accepted=False, task_id="", errors=errors))]
        refused = self.refuse(sub.task)  # things may have changed while planning
        if refused is not None:
            return [answer(sub.task_id, refused)]
        accepted = SubmitReply(accepted=True, task_id=sub.task_id)
        return [*self.start(sub.task_id, sub.task, self.now), answer(sub.task_id, accepted)]

    def on_scene(self, scene: SceneState) -> list[Action]:
        """The planner's scene (replaced at run time, or its periodic announcement): later
        validations check folds against it (one that does not build leaves the check as it
        was). The same scene again changes nothing."""
        if scene.same_scene(self.scene_seen):
            return []
        self.scene_seen = scene
        check = scene_fold_checker(scene, self.config.arm)
        if check is not None and self.fold_check is not None:
            self.fold_check = check
        return []

    def control(self, req: TaskControl, now_ns: int) -> tuple[TaskStatus, list[Action]]:
        """Cancel, pause, resume or status (``sequencer/control``)."""
        self.now = now_ns
        if req.action == TaskAction.STATUS:
            return self.status(), []
        refused = self._why_not(req)
        if refused:
            return self.status(False, refused), []
        if req.action == TaskAction.CANCEL:
            out = self._cancel()
            return self.status(True, "cancelling" if self.busy else ""), out
        if req.action == TaskAction.PAUSE:
            out = self._pause()
            note = "pausing after the fold" if self.phase == Phase.FOLDING else ""
            return self.status(True, note), out
        if self.state != TaskState.PAUSED:  # resume before the pause took effect
            self.pause_requested = False
            return self.status(True, "pause withdrawn"), []
        self.state = TaskState.RUNNING
        out = [self._event(TaskEventKind.RESUMED, step=self.step, progress=self._task_progress())]
        if self._current is None:  # paused before the step began
            out += self._start_step()
        else:
            out += self._current.resume()
        return self.status(), out

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
            return []
        self.alive.discard(service)
        if self.busy and service in self.config.required_services:
            return self.fail(f"{service} is gone (its liveliness token vanished)")
        return []

    def on_tick(self, now_ns: int) -> list[Action]:
        """Time passes (call at least every 100 ms): waits and timeouts."""
        self.now = now_ns
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
