"""A task's submission: refused at once, held while the bridge starts, or validated whole.

:class:`TaskSubmission` is the layer of :class:`~services.sequencer.core.SequencerCore`
between the running task (:class:`~services.sequencer.task_run.TaskRun`) and the inputs:
what a submitted task is judged on (the services alive, the bridge's phase, the scene
folds are checked against) and the submission's life until its ``Reply``.

**Submission** (:meth:`TaskSubmission.submit`): a task is refused at once (a task running
or paused, another being validated, required services missing, the bridge stopped), held
while the bridge is still starting (at most ``bridge_wait_s``, :mod:`bridge_wait`), or
validated whole (state ``validating``, :mod:`validate`): every
move is planned by the planner (``planner/plan`` queries, from where the previous steps
leave the arm) before anything moves. The ``Reply`` ends it: every problem found, or
accepted, and then the task starts at once (after checking again what may have changed
meanwhile).
"""

from __future__ import annotations

from dataclasses import dataclass

from manus.scene import start_scene_state
from schemas import endpoints as ep
from schemas.collision import SceneState
from schemas.objects import WorldUpdate
from schemas.planning import PlanReply
from schemas.sequencing import SubmitReply, Task, TaskState, TaskStatus
from schemas.state import BridgePhase, BridgeState
from services.sequencer.actions import Action, Reply
from services.sequencer.bridge_wait import BridgeWait, bridge_on_its_way
from services.sequencer.config import SequencerConfig
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


class TaskSubmission(TaskRun):
    """Takes submitted tasks (see the module docstring).

    Args:
        config: timeouts, required services, arm geometry, the bridge wait.
    """

    def __init__(self, config: SequencerConfig | None = None) -> None:
        super().__init__(config)
        self.alive: set[str] = set()
        self.seen: set[str] = set()
        """Services whose tokens this sequencer has seen up (a required one missing and
        never seen is still starting: a submission waits for it like for the bridge)."""
        self._submission: Submission | None = None
        self.bridge_wait = BridgeWait(self.config.bridge_wait_s)
        self._bridge_state: BridgeState | None = None  # the newest, in the bridge's order
        self.fold_check = fold_checker(self.config.scene, self.config.arm)
        """Checks folds against the scene and what the arm holds during validation (None:
        no scene)."""
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
            return self.bridge_wait.status(self.bridge_phase, self.missing_services())
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

    # -- submission ----------------------------------------------------------------------------

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
        held = refused is not None and self._getting_ready()
        if held and self.bridge_wait.hold(task_id, task, now_ns):
            return []  # answered when the bridge runs, or at the end of the wait
        if refused is not None:
            return [answer(task_id, refused)]
        return self._begin(task_id, task)

    def _getting_ready(self) -> bool:
        """Only what gets ready by itself keeps a task from starting now: the bridge on its
        way to running (every required service up), or, with the bridge running, required
        services not seen up yet since this sequencer started (``manus up`` starts them
        together; one seen up and then gone is not on its way)."""
        if self.busy or self._submission is not None:
            return False
        valid = self.start_configuration() is not None
        missing = set(self.missing_services())
        if not missing:
            return bridge_on_its_way(self.bridge_phase, valid)
        running = self.bridge_phase == BridgePhase.RUNNING and valid
        return running and not missing & self.seen

    def _recheck_held(self) -> list[Action]:
        """The held submission: begun once the bridge is ready, refused when it stopped
        starting or the wait is over, else held on."""
        held = self.bridge_wait.held
        if held is None or (self._getting_ready() and self.now < held.until_ns):
            return []
        self.bridge_wait.held = None
        refused = self.refuse(held.task)
        if refused is None:
            return self._begin(held.task_id, held.task)
        if self._getting_ready():  # the wait is over
            detail = self._bridge_state.detail if self._bridge_state is not None else ""
            missing = self.missing_services()
            refused = self.bridge_wait.late(held, self.bridge_phase, detail, self.now, missing)
        return [answer(held.task_id, refused)]

    def _begin(self, task_id: str, task: Task) -> list[Action]:
        """Validate ``task`` (plan queries), then start it."""
        validator = Validator(
            task, self.start_configuration(), self.config.arm, self.fold_check, self.object_view
        )
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
        check = scene_fold_checker(scene, self.config.arm, self.world.held)
        if check is not None:
            self.scene = check.model.scene
            if self.fold_check is not None:
                self.fold_check = check
        return []

    def on_objects(self, update: WorldUpdate, now_ns: int | None = None) -> list[Action]:
        """The world model's updates (``planner/objects``): later validations check folds
        with the objects the arm holds (attached to the gripper) as part of it; a running
        object step watches the object it approaches."""
        if now_ns is not None:
            self.now = now_ns
        if self.world.on_update(update) and self.fold_check is not None:
            self.fold_check = self.fold_check.holding(self.world.held)
        if update.stale_after_s > 0.0:
            self.stale_after_s = update.stale_after_s
        self.world_ns = max(self.world_ns, update.stamp_ns)
        if self.state == TaskState.RUNNING and self._current is not None:
            return self._current.on_objects()
        return []
