"""The sequencer's deterministic core: one task at a time, from its submission to its end.

Inputs are method calls carrying messages and the time they arrived (``now_ns``); outputs
are :data:`~services.sequencer.actions.Action` values: :class:`Query` (a request the
shell sends with ``Node.query``; it feeds the answer back through
:meth:`SequencerCore.on_reply` with the query's ``token``), :class:`Publish` (a message to
publish: the task events, and while a task runs one deadman
:class:`~schemas.control.Heartbeat` per joint state) and :class:`Reply` (the answer to a
submitted task, for its submitter). No Zenoh, no threads, no clock: the same inputs give
the same outputs.

**Submission** (:meth:`SequencerCore.submit`): a task is refused at once (a task running
or paused, another being validated, required services missing, the bridge stopped), held
while the bridge is still starting (at most ``bridge_wait_s``, :mod:`bridge_wait`), or
validated whole (state ``validating``, :mod:`validate`): every
move is planned by the planner (``planner/plan`` queries, from where the previous steps
leave the arm) before anything moves. The :class:`Reply` ends it: every problem found, or
accepted, and then the task starts at once (after checking again what may have changed
meanwhile).

Steps (docs/protocol.md, Thesis task form), one class per kind in :mod:`services.sequencer.steps`:

- **move / pose**: plan from the newest joint state (``planner/plan`` with an explicit
  ``start``), send the trajectory (``controller/goal``), wait for its ``GoalResult``.
- **gripper**: ``controller/gripper``, wait for the result.
- **fold_in / fold_out**: ``bridge/command`` with the deadman of moves; wait for
  ``state/bridge`` to show the fold (``folding_*``) and then leave it: ``running`` is
  success, ``stopped`` (the fold's deadman) / ``arm_error`` / ``estopped`` failure. Bridge
  states are taken in the bridge's order: one with a lower ``seq`` and no newer stamp
  than the newest (published late by another of the bridge's threads) is ignored, or
  it could end a fold that has only just begun.
- **wait**: time from the inputs.

The task stops at the first failure, with the reason from the service that failed
(planner refusal, controller refusal or result, bridge phase, e-stop, a service whose
liveliness token vanished, no joint states for ``link_timeout_s`` while a goal or a fold
is active, or a timeout). The reason of the last one names what can be known: when the
guardian's reports (``guardian/report``) still come from the arm computer, the link is
up and the bridge is the one that fell silent.

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

**The user takes over** (live control, ``schemas/jog.py``): when the controller ends the
running goal because a jog command arrived (result ``preempted``, cause
``user_took_over``) or refuses a goal because the user jogs (refusal ``busy``, held by
the ``jog``), the task
pauses (event ``paused``, reason "user took over") instead of failing, and so it does when
``controller/jog_state`` shows a jog while it waits, plans or sends a goal (a fold cannot
be jogged: the bridge holds the arm). It resumes only when asked, from wherever the user
left the arm.
"""

from __future__ import annotations

from dataclasses import dataclass

from manus.scene import start_scene_state
from schemas import endpoints as ep
from schemas.base import Message
from schemas.collision import SceneState
from schemas.commands import EStop
from schemas.control import ControllerFeedback, GoalResult, Heartbeat
from schemas.follow import FollowState
from schemas.guardian import GuardianReport
from schemas.jog import USER_TOOK_OVER, JogState
from schemas.planning import PlanReply
from schemas.sequencing import (
    SubmitReply,
    Task,
    TaskAction,
    TaskControl,
    TaskEvent,
    TaskEventKind,
    TaskHistory,
    TaskRecord,
    TaskState,
    TaskStatus,
)
from schemas.state import BridgePhase, BridgeState, JointState
from services.sequencer.actions import (
    EVENTS_SUFFIX,
    HEARTBEAT_SUFFIX,
    Action,
    Publish,
    Query,
    Reply,
)
from services.sequencer.bridge_wait import BridgeWait, bridge_on_its_way
from services.sequencer.config import SequencerConfig
from services.sequencer.steps import BY_REQUEST, NS, STEP_TYPES, Phase, Step
from services.sequencer.validate import Validator, fold_checker, scene_fold_checker, step_label

__all__ = [  # the actions are defined in services.sequencer.actions
    "EVENTS_SUFFIX",
    "HEARTBEAT_SUFFIX",
    "Action",
    "Publish",
    "Query",
    "Reply",
    "SequencerCore",
]

ACTIVE_STATES = (TaskState.RUNNING, TaskState.PAUSED)
HEARD_AFTER_NS = 120_000_000
"""A guardian report received this long after the newest joint state was sent after the
joint states stopped, not before a cut link (two cycles: both stream at most one per
cycle) [ns]."""


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
        self.state = TaskState.NONE
        self.step = -1
        self.reason = ""
        self.now = 0
        self._submission: Submission | None = None
        self.bridge_wait = BridgeWait(self.config.bridge_wait_s)
        self._seq = 0
        self._token = 0
        self._goals = 0
        self._heartbeats = 0
        self._js_rx: int | None = None  # receive time of the newest joint state [ns]
        self._bridge_state: BridgeState | None = None  # the newest, in the bridge's order
        self._guardian_rx: int | None = None  # receive time of its newest report [ns]
        self._guardian_engaged_rx: int | None = None  # ... of its newest 'engaged' one
        self._started_ns = 0
        self._history: list[TaskRecord] = []  # ended tasks, oldest first
        self.fold_check = fold_checker(self.config.scene, self.config.arm)
        """Checks folds against the scene during validation (None: no scene)."""
        self.scene_seen = start_scene_state(self.config.scene)
        """The scene folds are checked against, as the planner announces it
        (``config.scene``'s until the planner's differs; None: no scene)."""
        self._reset_step()

    def _reset_step(self) -> None:
        self._current: Step | None = None  # the running step (None: not begun)
        self._await: int | None = None  # token of the query the step waits for
        self._deadline: int | None = None  # the step fails (or stops) if nothing by then [ns]
        self.step_progress = 0.0
        self._reported = -1.0
        self.pause_requested = False
        self.pause_reason = ""  # why the next pause happens ('' : asked for)
        self.cancel_requested = False

    # -- queries about the task ------------------------------------------------------------

    @property
    def busy(self) -> bool:
        """A task is running or paused."""
        return self.state in ACTIVE_STATES

    @property
    def validating(self) -> str:
        """Id of the submitted task being validated or held ('' when none)."""
        held = self.bridge_wait.held
        if held is not None:
            return held.task_id
        return self._submission.task_id if self._submission is not None else ""

    @property
    def _phase(self) -> Phase:  # the name the live tests poll
        return self.phase

    @property
    def phase(self) -> Phase:
        """What the current step is doing (:class:`~services.sequencer.steps.Phase`)."""
        if self.state == TaskState.PAUSED:
            return Phase.PAUSED
        if self.state != TaskState.RUNNING or self._current is None:
            return Phase.IDLE
        return self._current.phase

    def missing_services(self) -> list[str]:
        """Required services whose liveliness tokens are not up (sorted)."""
        return sorted(set(self.config.required_services) - self.alive)

    def start_configuration(self) -> list[float] | None:
        """The arm's configuration now (newest valid joint state), for validation."""
        if self.latest is None or not self.latest.valid:
            return None
        return list(self.latest.position)

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

    # -- task life ---------------------------------------------------------------------------

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

    def history(self, limit: int) -> TaskHistory:
        """The ``limit`` most recent tasks, newest first (``sequencer/history``)."""
        records = list(reversed(self._history))
        if self.busy:
            records.insert(0, self._record(0))
        return TaskHistory(tasks=records[:limit])

    def _record(self, ended_ns: int, final: TaskEvent | None = None) -> TaskRecord:
        assert self.task is not None
        return TaskRecord(
            task_id=self.task_id,
            name=self.task.name,
            state=self.state,
            steps=len(self.task.steps),
            step=self.step,
            reason=self.reason,
            started_ns=self._started_ns,
            ended_ns=ended_ns,
            final=final,
        )

    def _end(self, final: Publish) -> list[Action]:
        """The task has just ended with ``final``: remember it, with its final event
        (at most ``config.history``); the event to publish."""
        assert isinstance(final.message, TaskEvent)
        self._history.append(self._record(self.now, final.message))
        del self._history[: -self.config.history]
        return [final]

    def start(self, task_id: str, task: Task, now_ns: int) -> list[Action]:
        """Start a validated task (:meth:`submit` does it; a caller of its own checked
        :meth:`refuse` and validated the task)."""
        self.now = now_ns
        self._started_ns = now_ns
        self.task, self.task_id, self.state, self.reason = task, task_id, TaskState.RUNNING, ""
        self.step = 0
        self._goals = 0
        self._reset_step()
        out = [self._event(TaskEventKind.ACCEPTED, step=-1, progress=0.0)]
        return out + self._start_step()

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

    # -- inputs ------------------------------------------------------------------------------

    def on_joint_state(self, js: JointState, now_ns: int) -> list[Action]:
        """Newest joint state: the start of the next plan; while a task runs, answered
        with a :class:`Heartbeat` echoing it (the controller's deadman)."""
        self.now = now_ns
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
        self._guardian_rx = now_ns
        if report.engaged:
            self._guardian_engaged_rx = now_ns
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
        if not self._current.needs_joint_states or self._js_rx is None:
            return []
        silent = self.now - self._js_rx
        if silent <= self.config.link_timeout_s * NS:
            return []
        return self.fail(
            f"no joint states from the arm for {silent / 1e6:.0f} ms (more than link_timeout_s "
            f"{self.config.link_timeout_s:g} s): {self._silence_cause(self._js_rx)}"
        )

    def _silence_cause(self, js_rx: int) -> str:
        """What stopped the joint states (received last at ``js_rx``), as far as the arm
        computer's other messages tell."""
        after = js_rx + HEARD_AFTER_NS
        engaged = self._guardian_engaged_rx
        if engaged is not None and engaged > after:
            return (
                "can_bridge stopped answering the arm (the guardian sends the stops in its "
                "place and reports it, so the link to the arm computer is up): can_bridge "
                "hangs or died"
            )
        heard = self._guardian_rx
        if heard is not None and heard > after:
            return (
                "can_bridge publishes none, though the arm computer is heard (the guardian "
                "reports): the bridge or its input from the arm is stuck"
            )
        return (
            "nothing is heard from the arm computer (nor from its guardian): the link to it "
            "is down; the controller stops the arm itself when it loses the supervisor's "
            "heartbeat"
        )

    def _check_deadline(self) -> list[Action]:
        if not self.busy or self._deadline is None or self.now < self._deadline:
            return []
        self._deadline = None
        return self._current.on_deadline() if self._current is not None else []

    # -- steps -------------------------------------------------------------------------------

    def _start_step(self) -> list[Action]:
        assert self.task is not None
        if self.step >= len(self.task.steps):
            self.state = TaskState.SUCCEEDED
            self.step = len(self.task.steps) - 1
            self.step_progress = 1.0
            return self._end(self._event(TaskEventKind.SUCCEEDED, step=-1, progress=1.0))
        if self.pause_requested:
            return self.paused()
        spec = self.task.steps[self.step]
        self._current = STEP_TYPES[spec.kind](spec, self)
        out: list[Action] = [self._event(TaskEventKind.STEP_STARTED, progress=0.0)]
        return out + self._current.begin()

    def _pause(self) -> list[Action]:
        out = self._current.pause() if self._current is not None else None
        if out is None:  # planning, acking, folding: at their end
            self.pause_requested = True
            return []
        return out

    def _cancel(self) -> list[Action]:
        self.cancel_requested = True
        if self.state == TaskState.PAUSED or self._current is None:
            return self.cancelled(BY_REQUEST)
        return self._current.cancel()

    # -- the running step's calls (services.sequencer.steps.StepContext) ----------------------

    def new_goal_id(self) -> str:
        """A controller goal id for the current step: ``<task>.<step, 1-based>.<n>``."""
        self._goals += 1
        return f"{self.task_id}.{self.step + 1}.{self._goals}"

    def query(
        self, suffix: str, request: Message, reply_type: type[Message], *, wait: bool = False
    ) -> Query:
        """A query; with ``wait`` its answer goes to the running step."""
        self._token += 1
        if wait:
            self._await = self._token
        return Query(self._token, suffix, request, reply_type)

    def set_deadline(self, after_s: float) -> None:
        """The step's deadline: ``after_s`` [s] from now (its ``on_deadline`` then)."""
        self._deadline = self.now + int(after_s * NS)

    def report(self, progress: float) -> list[Action]:
        """The step's progress (an event when it moved by ``progress_step``)."""
        self.step_progress = progress
        if abs(progress - self._reported) < self.config.progress_step and progress < 1.0:
            return []
        self._reported = progress
        return [self._event(TaskEventKind.STEP_PROGRESS, progress=progress)]

    def step_done(self) -> list[Action]:
        """The step succeeded: the next one (or a pause or cancel asked meanwhile)."""
        self.step_progress = 1.0
        out: list[Action] = [self._event(TaskEventKind.STEP_FINISHED, progress=1.0)]
        pause = self.pause_requested
        cancel = self.cancel_requested
        self.step += 1
        self._reset_step()
        if cancel:
            return out + self.cancelled(BY_REQUEST)
        self.pause_requested = pause
        return out + self._start_step()

    def paused(self, reason: str = "") -> list[Action]:
        """The arm stopped for a pause (``reason``: why, when it was not asked for)."""
        reason, self.pause_reason = reason or self.pause_reason, ""
        self.pause_requested = False
        self.state = TaskState.PAUSED
        self._deadline = None
        progress = self._task_progress()
        return [self._event(TaskEventKind.PAUSED, progress=progress, step=self.step,
                            reason=reason)]  # fmt: skip

    def cancelled(self, reason: str) -> list[Action]:
        """The task ends cancelled."""
        self.state = TaskState.CANCELLED
        self.reason = reason
        self._await = None
        self._deadline = None
        progress = self._task_progress()
        return self._end(self._event(TaskEventKind.CANCELLED, step=self.step,
                                     progress=progress, reason=reason))  # fmt: skip

    def fail(self, reason: str) -> list[Action]:
        """The task fails (what the running step started is stopped)."""
        out: list[Action] = []
        if self.state == TaskState.RUNNING and self._current is not None:
            out += self._current.cleanup()
        assert self.task is not None
        full = f"{step_label(self.task.steps[self.step], self.step)}: {reason}"
        out.append(self._event(TaskEventKind.STEP_FAILED, reason=full))
        self.state = TaskState.FAILED
        self.reason = full
        self._await = None
        self._deadline = None
        progress = self._task_progress()
        return out + self._end(self._event(TaskEventKind.FAILED, step=self.step,
                                           progress=progress, reason=full))  # fmt: skip

    # -- outputs -------------------------------------------------------------------------------

    def _task_progress(self) -> float:
        total = len(self.task.steps) if self.task is not None else 0
        if not total:
            return 0.0
        return min(1.0, max(0.0, (max(self.step, 0) + self.step_progress) / total))

    def _event(
        self,
        event: TaskEventKind,
        *,
        step: int | None = None,
        progress: float = 0.0,
        reason: str = "",
    ) -> Publish:
        total = len(self.task.steps) if self.task is not None else 0
        index = self.step if step is None else step
        kind = self.task.steps[index].kind if self.task is not None and 0 <= index < total else ""
        self._seq += 1
        msg = TaskEvent(
            stamp_ns=self.now,
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
