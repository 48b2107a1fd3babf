"""Goals as a command source: trajectory and gripper goals, their deadman, their results.

A supervisor submits goals by query (``controller/goal``, ``controller/gripper``),
cancels them (``controller/cancel``) and scales a trajectory's speed
(``controller/speed_scale``); each is answered at once with a ``GoalAck``. An accepted
trajectory goal starts at the next joint state (preempting the running one, or, with
``replace``, spliced into it: :mod:`.reference`); a gripper goal runs beside it. Each
accepted goal ends with exactly one ``GoalResult`` (:class:`~.command_source.End`: status
and cause). While a goal runs, each cycle publishes a ``ControllerFeedback``.

Deadman: a goal with ``heartbeat_timeout`` > 0 runs only while the supervisor's
``Heartbeat`` echoes a joint state no older than that (:class:`.supervision.Supervision`,
from the goal's first joint state until an echo newer than it); the token of the
heartbeats' sender going stops it at once (:meth:`GoalSource.token_gone`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from manus.deadman import token_gone
from manus.kinematics import Vec3, gripper_position
from manus.trajectory import TrajectoryError
from schemas import endpoints as ep
from schemas.control import (
    CancelGoal,
    CommandSourceKind,
    EndCause,
    GoalAck,
    GoalKind,
    GripperGoal,
    Heartbeat,
    Refusal,
    ResultStatus,
    SpeedScale,
    TrajectoryGoal,
)
from schemas.state import JointState
from services.controller.command_source import (
    Command,
    CommandSource,
    Cycle,
    End,
    Host,
    Refused,
    Sent,
    SourceAnswer,
    SourceInput,
)
from services.controller.feedback import goal_feedback
from services.controller.goals import (
    GoalRefusedError,
    check_goal,
    check_start,
    tolerances,
    trajectory_error,
)
from services.controller.gripper import GripperRun, gripper_command
from services.controller.guard import Verdict
from services.controller.modes import LAWS
from services.controller.outbox import GoalOutcome, Output
from services.controller.reference import Reference
from services.controller.supervision import Supervision
from services.controller.tracking import Step, TrajectoryRun

_ZERO = np.zeros(6, dtype=np.int64)


def _ack(goal_id: str, refused: Refused | None = None) -> GoalAck:
    if refused is None:
        return GoalAck(accepted=True, goal_id=goal_id)
    reason, refusal, held_by = refused.reason, refused.refusal, refused.held_by
    return GoalAck(accepted=False, goal_id=goal_id, reason=reason, refusal=refusal, held_by=held_by)


class GoalSource(CommandSource):
    """Trajectory and gripper goals (see the module docstring).

    Attributes:
        pending: the trajectory goal that starts at the next joint state.
        run: the trajectory goal running.
        gripper: the gripper goal running.
    """

    KIND = CommandSourceKind.GOAL
    PRIORITY = 0

    def __init__(self, host: Host) -> None:
        super().__init__(host)
        self.config = host.config
        """The controller's settings (immutable)."""
        self.pending: TrajectoryGoal | None = None
        self.run: TrajectoryRun | None = None
        self.gripper: GripperRun | None = None
        self.heartbeat_since_ns = 0
        """Stamp [ns] of the joint state at which the running trajectory started (the
        deadman's reference until a heartbeat newer than it arrives)."""
        self.supervision = Supervision(self.config.cycle_ns)
        """The supervisor's deadman: the newest echo, its sender, when states are judged."""
        self._ran: tuple[Vec3, tuple[Step, TrajectoryRun] | None] | None = None
        """This cycle's gripper position [m] and trajectory step, for the feedback."""
        self._fb_seq = 0

    @property
    def engaged(self) -> bool:
        return self.pending is not None or self.run is not None or self.gripper is not None

    # -- requests ----------------------------------------------------------------------------

    def submit(self, goal: TrajectoryGoal) -> GoalAck:
        """Accept (start at the next joint state) or refuse a trajectory goal."""
        arm = self.config.arm
        try:
            check_goal(goal)  # then what it starts with, built again when it starts:
            tolerances(goal, "path_tolerance")
            tolerances(goal, "goal_tolerance")
            Reference(goal.trajectory, arm=arm)
        except TrajectoryError as exc:
            bad = Refused(Refusal.INVALID, str(trajectory_error(goal, exc)))
            return _ack(goal.goal_id, bad)
        except GoalRefusedError as exc:
            return _ack(goal.goal_id, Refused(Refusal.INVALID, str(exc)))
        refused = self.host.admission(self)
        if refused is not None:
            return _ack(goal.goal_id, refused)
        js = self.host.last_js
        if js is None or not js.valid:
            reason = "no valid joint state yet (is the bridge running?)"
            return _ack(goal.goal_id, Refused(Refusal.NOT_READY, reason))
        try:
            check_start(goal, np.asarray(js.position, dtype=float))
        except GoalRefusedError as exc:
            return _ack(goal.goal_id, Refused(Refusal.START_MISMATCH, str(exc)))
        new = End(ResultStatus.PREEMPTED, EndCause.NEW_GOAL, "")
        if self.pending is not None:
            self._finish(self.pending.goal_id, new._replace(reason=f"replaced by {goal.goal_id!r}"))
        if self.run is not None and not goal.replace:
            self._end_run(self.run, new._replace(reason=f"preempted by {goal.goal_id!r}"))
        self.pending = goal
        return _ack(goal.goal_id)

    def submit_gripper(self, goal: GripperGoal) -> GoalAck:
        """Accept or refuse a gripper goal (it runs beside any trajectory goal)."""
        if not goal.goal_id:
            return _ack("", Refused(Refusal.INVALID, "`goal_id` is empty"))
        refused = self.host.admission(self)
        if refused is not None:
            return _ack(goal.goal_id, refused)
        if not (math.isfinite(goal.tolerance) and goal.tolerance > 0 and goal.timeout > 0):
            reason = f"tolerance {goal.tolerance!r} m and timeout {goal.timeout!r} s must be > 0"
            return _ack(goal.goal_id, Refused(Refusal.INVALID, reason))
        if self.gripper is not None:
            why = f"preempted by {goal.goal_id!r}"
            end = End(ResultStatus.PREEMPTED, EndCause.NEW_GOAL, why)
            self._finish(self.gripper.goal.goal_id, end, GoalKind.GRIPPER)
        self.gripper = GripperRun(goal)
        return _ack(goal.goal_id)

    def cancel(self, req: CancelGoal) -> GoalAck:
        """Cancel one goal (or every goal with an empty id): decelerate, then report."""
        found = False
        every = not req.goal_id
        if self.pending is not None and (every or self.pending.goal_id == req.goal_id):
            end = End(
                ResultStatus.CANCELLED, EndCause.CANCEL_REQUEST, "cancelled before it started"
            )
            self._finish(self.pending.goal_id, end)
            self.pending, found = None, True
        if self.run is not None and (every or self.run.goal.goal_id == req.goal_id):
            self.run.cancelling, found = True, True
        if self.gripper is not None and (every or self.gripper.goal.goal_id == req.goal_id):
            self.gripper.cancelled, found = True, True
        if not found and not every:
            reason = f"no active goal {req.goal_id!r}"
            return _ack(req.goal_id, Refused(Refusal.UNKNOWN_GOAL, reason))
        return _ack(req.goal_id)

    def set_speed_scale(self, req: SpeedScale) -> GoalAck:
        """Scale the running trajectory's time from the next cycle (ramped)."""
        if not 0.05 <= req.scale <= 1.0:
            return _ack("", Refused(Refusal.INVALID, f"scale {req.scale!r} outside [0.05, 1]"))
        if self.run is not None:
            self.run.scale_target = req.scale
            return _ack(self.run.goal.goal_id)
        if self.pending is not None:
            self.pending = dataclasses.replace(self.pending, speed_scale=req.scale)
            return _ack(self.pending.goal_id)
        return _ack("", Refused(Refusal.NO_GOAL, "no trajectory goal is running"))

    def on_heartbeat(self, hb: Heartbeat) -> Output:
        """The supervisor's deadman heartbeat: remembered, judged at the next joint state."""
        self.supervision.on_heartbeat(hb)
        return []

    INPUTS = (SourceInput(ep.HEARTBEAT, on_heartbeat),)
    ANSWERS = (
        SourceAnswer(ep.GOAL, submit),
        SourceAnswer(ep.GRIPPER_GOAL, submit_gripper),
        SourceAnswer(ep.CANCEL, cancel),
        SourceAnswer(ep.SPEED_SCALE, set_speed_scale),
    )

    # -- the cycle ---------------------------------------------------------------------------

    def observe(self, js: JointState, last: JointState | None) -> None:
        self.supervision.on_joint_state(js.stamp_ns, None if last is None else last.stamp_ns)

    def command(self, cycle: Cycle) -> Command | None:
        """Start a pending goal, judge the deadman, step the trajectory and the gripper."""
        self._ran = None
        if self.pending is None and self.run is None and self.gripper is None:
            return None
        js, snap = cycle.js, cycle.snap_ns
        before = self.run
        self._start_pending(snap, cycle.q)
        if self.run is not None and self.run is not before:
            self.heartbeat_since_ns = js.stamp_ns
        lost = self._heartbeat_lost(js)
        if lost is not None:
            self.stop(End(ResultStatus.ABORTED, EndCause.HEARTBEAT_LOST, lost))
        run = self.run
        step: Step | None = None
        # The gripper position of the measured angles: one forward kinematics per cycle,
        # shared by the via points, the verdicts and the feedback.
        if run is not None or self.gripper is not None:
            xyz = gripper_position(cycle.position, self.config.arm)
            if run is not None:
                if cycle.gap:
                    run.pause(snap)  # the reference waits for the arm over the gap
                step = run.step(snap, cycle.q, xyz, cycle.joints, cycle.last_counts, cycle.play)
                if step.ended is not None:
                    self._end_run(run, step.ended)
            self._ran = (xyz, (step, run) if step is not None and run is not None else None)
        grip = self._gripper_cycle(js, snap, cycle)
        counts = step.counts if step is not None else _ZERO
        if cycle.gap:  # stop for this cycle: nothing is known of the cycle(s) missed
            counts, grip = _ZERO, 0
        return Command(counts, grip, run.goal.goal_id if run is not None else "")

    def guarded(self, command: Command, verdict: Verdict) -> None:
        """The guard stopped the trajectory's command: the goal aborts, its
        ``final_error`` how far the gripper stopped from the path's end."""
        ran = self._ran[1] if self._ran is not None else None
        if verdict.scale == 0.0 and ran is not None and self.run is ran[1] and self._ran:
            run = ran[1]
            run.final_error = math.dist(self._ran[0], run.ref.via_xyz[-1])
            why = f"collision guard {verdict.reason}"
            self._end_run(run, End(ResultStatus.ABORTED, EndCause.COLLISION, why))

    def reports(self, sent: Sent) -> Output:
        """The feedback of a cycle in which a goal ran."""
        if self._ran is None:
            return []
        xyz, ran = self._ran
        self._ran = None
        cmd = sent.command
        arm = self.config.arm
        fb = goal_feedback(sent.js, self._fb_seq, xyz, ran, self.gripper, cmd.velocity, arm)
        self._fb_seq += 1
        if sent.guard:
            fb = dataclasses.replace(fb, guard=sent.guard)
        return [(ep.FEEDBACK, fb)]

    def stop(self, end: End) -> None:
        """End every goal (pending, trajectory, gripper) with ``end``."""
        if self.pending is not None:
            self._finish(self.pending.goal_id, end)
            self.pending = None
        if self.run is not None:
            self._end_run(self.run, end)
        if self.gripper is not None:
            self._finish(self.gripper.goal.goal_id, end, GoalKind.GRIPPER)
            self.gripper = None

    def token_gone(self, service: str) -> str:
        """A running goal whose heartbeats came from ``service`` stops at once."""
        since: list[int | None] = []
        if self.run is not None and self.run.goal.heartbeat_timeout > 0.0:
            since.append(self.heartbeat_since_ns)
        if self.gripper is not None and self.gripper.goal.heartbeat_timeout > 0.0:
            since.append(self.gripper.heartbeat_since_ns)
        if not self.supervision.tied_to(service, since):
            return ""
        reason = f"{token_gone(service)} (stopped; nothing resumes by itself)"
        self.stop(End(ResultStatus.ABORTED, EndCause.TOKEN_GONE, reason))
        return reason

    # -- internals ---------------------------------------------------------------------------

    def _heartbeat_lost(self, js: JointState) -> str | None:
        """Why the running goals must stop for want of heartbeats (None: they need not).

        Each goal with a deadman (trajectory or gripper) is judged from its first joint
        state until a heartbeat newer than that arrives."""
        deadmen: list[tuple[float, int]] = []
        run, grip = self.run, self.gripper
        if run is not None and run.goal.heartbeat_timeout > 0.0:
            deadmen.append((run.goal.heartbeat_timeout, self.heartbeat_since_ns))
        if grip is not None and grip.goal.heartbeat_timeout > 0.0:
            if grip.heartbeat_since_ns is None:
                grip.heartbeat_since_ns = js.stamp_ns
            deadmen.append((grip.goal.heartbeat_timeout, grip.heartbeat_since_ns))
        return self.supervision.lost(js.seq, deadmen)

    def _start_pending(self, snap: int, q: np.ndarray) -> None:
        goal, self.pending = self.pending, None
        if goal is None:
            return
        cfg = self.config
        tols = (tolerances(goal, "path_tolerance"), tolerances(goal, "goal_tolerance"))
        old = self.run
        new = End(ResultStatus.PREEMPTED, EndCause.NEW_GOAL, "")
        shift = 0.0  # the new trajectory's time when the splice's first command acts [s]
        if goal.replace and old is not None and not old.cancelling:
            ref_old, tau = old.reference_at(snap)
            if goal.splice_at >= 0.0:  # its time 0 is the old one's splice_at: same clock
                shift = tau - goal.splice_at
            new_duration = Reference(goal.trajectory, arm=cfg.arm).duration
            blend = max(cfg.cycle_s, min(cfg.splice_blend_s, new_duration or cfg.splice_blend_s))
            ref = ref_old.spliced(goal.trajectory, tau, blend, shift)
            self._end_run(old, new._replace(reason=f"replaced by {goal.goal_id!r} (spliced)"))
            scale = old.scale
        else:
            if old is not None:
                self._end_run(old, new._replace(reason=f"preempted by {goal.goal_id!r}"))
            ref = Reference(goal.trajectory, arm=cfg.arm)
            scale = goal.speed_scale
        self.run = TrajectoryRun.start(goal, ref, cfg, tols, snap, scale, LAWS[goal.mode])
        self.run.tau += shift

    def _gripper_cycle(self, js: JointState, snap: int, cycle: Cycle) -> int:
        run = self.gripper
        if run is None:
            return 0
        if run.start_ns is None:
            run.start_ns = snap
        goal = run.goal
        error = goal.opening - js.gripper
        counts = gripper_command(self.config, cycle.grip, goal.opening, run.cancelled)
        end: End | None = None
        if run.cancelled:
            end = End(ResultStatus.CANCELLED, EndCause.CANCEL_REQUEST, "cancelled")
        elif abs(error) <= goal.tolerance and counts == 0:
            reached = f"opening {js.gripper * 1000:.1f} mm reached"
            end = End(ResultStatus.SUCCEEDED, EndCause.REACHED, reached)
        elif (snap - run.start_ns) / 1e9 > goal.timeout:
            end = End(
                ResultStatus.ABORTED,
                EndCause.TIMEOUT,
                f"gripper at {js.gripper * 1000:.1f} mm, target {goal.opening * 1000:.1f} mm "
                f"not reached within the timeout {goal.timeout:g} s",
            )
        if end is not None:
            self._finish(goal.goal_id, end, GoalKind.GRIPPER, final_error=abs(error))
            self.gripper = None
            return 0
        return counts

    def _end_run(self, run: TrajectoryRun, end: End) -> None:
        js = self.host.last_js
        stop_ns = js.stamp_ns - self.config.snapshot_age_ns if js is not None else 0
        self.host.finish(
            GoalOutcome(
                run.goal.goal_id,
                GoalKind.TRAJECTORY,
                *end,
                via_errors=tuple(run.via_errors),
                via_stamps=tuple(run.via_stamps),
                final_error=run.final_error,
                duration=max(0.0, (stop_ns - run.start_ns) / 1e9),
                clearance=self.host.clearance(run.goal.goal_id),
            )
        )
        if self.run is run:
            self.run = None

    def _finish(
        self,
        goal_id: str,
        end: End,
        kind: GoalKind = GoalKind.TRAJECTORY,
        *,
        final_error: float = 0.0,
    ) -> None:
        self.host.finish(GoalOutcome(goal_id, kind, *end, final_error=final_error))
