"""The controller's deterministic core: joint states and goals in, velocity commands out.

Contract (docs/architecture.md, Time; Freshness and safety rules):

- Every valid joint state is answered with exactly one ``cmd/joint_velocity`` command
  (``ref_seq`` = the state's ``seq``, ``counts`` already quantized): the active goal's
  command, zeros when idle. While a goal runs, one ``controller/feedback`` per cycle.
- A trajectory goal starts at the next joint state; each accepted goal (trajectory or
  gripper) ends with exactly one ``controller/result``.
- Stops: an error reported by the arm aborts every goal with the arm's message, and so
  does the bridge leaving ``running`` (stop, e-stop, arm error, fold), an invalid state
  or a mode other than joint mode. A gap in the joint states (a ``seq`` jump or a stamp
  gap over ``max_stamp_gap_ms``) is answered with zeros (nothing is extrapolated) and
  the running trajectory's time waits over it; a gap longer than ``max_outage_ms``
  aborts every goal. A cancel decelerates at ``cancel_decel`` to rest, then reports.
- Deadman: a trajectory or gripper goal with ``heartbeat_timeout`` > 0 runs only while the
  supervisor's :class:`~schemas.control.Heartbeat` keeps coming. Each heartbeat echoes the
  newest joint state its sender received; at every joint state the age of the newest echo
  (or of the goal's first joint state, before any) is judged on the bridge's stamps, and
  beyond the timeout every goal aborts ("lost the supervisor's heartbeat ...") with
  zeros. Nothing restarts by itself when heartbeats return. The echo of a state cannot
  come before the state, so a late state (a gap: answered with zeros) is judged as if it
  had come one cycle after the one before it: the deadman judges the link, the gap rules
  the arm's side. The deadman's sender dying or its link cut is seen at once: when the
  token ``alive/<source>`` of the service whose heartbeats a running goal got vanishes
  (the shell's liveliness watch, :meth:`ControllerCore.on_token_gone`), every goal aborts
  and the command already sent for this cycle is replaced by zeros; a hang keeps the
  token and is left to the echo's age.
- Live control (jog, :mod:`.jog`): the newest ``JogCommand`` drives the arm while no
  trajectory runs; a moving one preempts every goal (reason starting
  :data:`~schemas.jog.USER_TOOK_OVER`), goals are refused while it moves, and the same
  stops (arm error, bridge phases, long gaps) stop it.
- Time comes only from the messages' stamps; no clock, no randomness: replaying the same
  messages gives the same commands, bit for bit.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from manus.deadman import token_gone
from manus.joint_map import dh_to_encoder_list
from manus.kinematics import Vec3, gripper_position
from manus.quantize import COUNT_RAD_S, GRIPPER_COUNT_M_S
from manus.scene import start_scene_state
from manus.trajectory import TrajectoryError
from manus.world_follower import WorldFollower
from schemas import endpoints as ep
from schemas.collision import ClearanceReport, SceneState
from schemas.control import (
    CancelGoal,
    GoalAck,
    GoalResult,
    GripperGoal,
    Heartbeat,
    ResultStatus,
    SpeedScale,
    TrajectoryGoal,
)
from schemas.jog import JOGGING, USER_TOOK_OVER, JogCommand, JogLevel, JogTaken
from schemas.liveliness import TokenGone
from schemas.objects import WorldUpdate
from schemas.state import ArmStatus, BridgeState, JointState
from services.controller.backlash import PlayModel
from services.controller.config import MS, ControllerConfig
from services.controller.estimator import DriveEstimator
from services.controller.goals import (
    GoalRefusedError,
    check_goal,
    check_start,
    tolerances,
    trajectory_error,
)
from services.controller.gripper import GripperRun, gripper_command
from services.controller.guard import run_guard, scene_guard
from services.controller.jog import Jog
from services.controller.outbox import Outbox, Output
from services.controller.reference import Reference
from services.controller.supervision import Supervision
from services.controller.tracking import Step, TrajectoryRun

__all__ = ["STOPPING_PHASES", "ControllerCore", "Output"]

STOPPING_PHASES = ("stopped", "estopped", "arm_error", "folding_in", "folding_out", "shutdown")
"""Bridge phases in which no goal can run: entering one aborts every goal."""

_NO_COUNTS = (0.0,) * 8
"""``JointState.applied`` when the command in flight is not a joint move."""

GRIPPER_UNIT_M = 1e-4
"""Resolution of the gripper reading [m] (0.1 mm)."""


class ControllerCore:
    """Tracking loop, gripper loop and goal handling (see the module docstring).

    Args:
        config: controller settings.
    """

    def __init__(self, config: ControllerConfig | None = None) -> None:
        self.config = config or ControllerConfig()
        cfg = self.config
        tau = cfg.drive_tau_ms / 1000.0
        half = math.radians(cfg.encoder_unit_deg) / 2.0 if cfg.observer else 0.0
        self.joints = DriveEstimator(tau, half, 6)
        """Estimated motor angles [rad] and speeds."""
        self.play = PlayModel(
            np.radians(cfg.backlash_deg),
            math.radians(cfg.backlash_dead_zone_deg),
        )
        """Estimated belt outputs (default mode, when ``backlash_deg`` is set)."""
        self.grip = DriveEstimator(tau, GRIPPER_UNIT_M / 2.0, 1)
        """Estimated gripper opening [m] and speed."""
        self.last_js: JointState | None = None
        self.arm_error: str | None = None
        """The arm's error message while it reports one."""
        self.bridge_phase: str | None = None
        """The bridge's phase (None: no BridgeState seen, not checked)."""
        self.run: TrajectoryRun | None = None
        self.pending: TrajectoryGoal | None = None
        self.gripper: GripperRun | None = None
        self.last_counts = np.zeros(6, dtype=np.int64)
        """Motor increments of the last command sent, shape (6,)."""
        self.outbox = Outbox(cfg.arm)
        """Message numbering and the results waiting for their stamp."""
        self.guard = run_guard(cfg.scene, cfg.arm)
        """The collision guard every command passes (None: no scene)."""
        self.scene_seen = start_scene_state(cfg.scene)
        """The scene the guard keeps clear of, as the planner announces it (``cfg.scene``'s
        until the planner's differs; None: no scene)."""
        self.world = WorldFollower()
        """The world model as the planner publishes it: the objects the arm holds, which
        the guard keeps clear like the arm's own bodies."""
        self.heartbeat_since_ns = 0
        """Stamp [ns] of the joint state at which the running goal started (the deadman's
        reference until a heartbeat newer than it arrives)."""
        self.supervision = Supervision(cfg.cycle_ns)
        """The supervisor's deadman: the newest echo, its sender, when states are judged."""
        self.jog = Jog(cfg)
        """Live control: the jog stream, its level and its reference."""

    # -- requests --------------------------------------------------------------------------

    def submit(self, goal: TrajectoryGoal) -> GoalAck:
        """Accept (start at the next joint state) or refuse a trajectory goal."""
        try:
            check_goal(goal)
            tols = (tolerances(goal, "path_tolerance"), tolerances(goal, "goal_tolerance"))
            ref = Reference(goal.trajectory, arm=self.config.arm)
            self._check_ready()
            js = self.last_js
            if js is None or not js.valid:
                raise GoalRefusedError("no valid joint state yet (is the bridge running?)")
            check_start(goal, np.asarray(js.position, dtype=float))
        except TrajectoryError as exc:
            reason = str(trajectory_error(goal, exc))
            return GoalAck(accepted=False, goal_id=goal.goal_id, reason=reason)
        except GoalRefusedError as exc:
            return GoalAck(accepted=False, goal_id=goal.goal_id, reason=str(exc))
        del tols, ref  # built again when the goal starts; here only to validate
        if self.pending is not None:
            self._queue(self.pending.goal_id, "preempted", f"replaced by {goal.goal_id!r}")
        if self.run is not None and not goal.replace:
            self._end_run(self.run, "preempted", f"preempted by {goal.goal_id!r}")
        self.pending = goal
        return GoalAck(accepted=True, goal_id=goal.goal_id)

    def submit_gripper(self, goal: GripperGoal) -> GoalAck:
        """Accept or refuse a gripper goal (it runs beside any trajectory goal)."""
        if not goal.goal_id:
            return GoalAck(accepted=False, goal_id="", reason="`goal_id` is empty")
        try:
            self._check_ready()
        except GoalRefusedError as exc:
            return GoalAck(accepted=False, goal_id=goal.goal_id, reason=str(exc))
        if not (math.isfinite(goal.tolerance) and goal.tolerance > 0 and goal.timeout > 0):
            reason = f"tolerance {goal.tolerance!r} m and timeout {goal.timeout!r} s must be > 0"
            return GoalAck(accepted=False, goal_id=goal.goal_id, reason=reason)
        if self.gripper is not None:
            old = self.gripper.goal.goal_id
            self._queue(old, "preempted", f"preempted by {goal.goal_id!r}", kind="gripper")
        self.gripper = GripperRun(goal)
        return GoalAck(accepted=True, goal_id=goal.goal_id)

    def _check_ready(self) -> None:
        if self.jog.engaged:
            raise GoalRefusedError(
                f"{JOGGING} (controller/jog_state): goals wait until the jog stops"
            )
        reason = self._not_ready()
        if reason is not None:
            raise GoalRefusedError(reason)

    def _not_ready(self) -> str | None:
        """Why nothing may move now (None: it may)."""
        if self.arm_error is not None:
            return f"the arm reports an error: {self.arm_error}"
        if self.bridge_phase is not None and self.bridge_phase != "running":
            return (
                f"the bridge is in phase {self.bridge_phase!r}, not 'running' "
                "(clear it or wait for it first)"
            )
        return None

    def cancel(self, req: CancelGoal) -> GoalAck:
        """Cancel one goal (or every goal with an empty id): decelerate, then report."""
        found = False
        every = not req.goal_id
        if self.pending is not None and (every or self.pending.goal_id == req.goal_id):
            self._queue(self.pending.goal_id, "cancelled", "cancelled before it started")
            self.pending, found = None, True
        if self.run is not None and (every or self.run.goal.goal_id == req.goal_id):
            self.run.cancelling, found = True, True
        if self.gripper is not None and (every or self.gripper.goal.goal_id == req.goal_id):
            self.gripper.cancelled, found = True, True
        if not found and not every:
            reason = f"no active goal {req.goal_id!r}"
            return GoalAck(accepted=False, goal_id=req.goal_id, reason=reason)
        return GoalAck(accepted=True, goal_id=req.goal_id)

    def set_speed_scale(self, req: SpeedScale) -> GoalAck:
        """Scale the running trajectory's time from the next cycle (ramped)."""
        if not 0.05 <= req.scale <= 1.0:
            reason = f"scale {req.scale!r} outside [0.05, 1]"
            return GoalAck(accepted=False, goal_id="", reason=reason)
        if self.run is not None:
            self.run.scale_target = req.scale
            return GoalAck(accepted=True, goal_id=self.run.goal.goal_id)
        if self.pending is not None:
            self.pending = _with_scale(self.pending, req.scale)
            return GoalAck(accepted=True, goal_id=self.pending.goal_id)
        return GoalAck(accepted=False, goal_id="", reason="no trajectory goal is running")

    # -- the arm ---------------------------------------------------------------------------

    def on_status(self, st: ArmStatus) -> Output:
        """An error from the arm aborts every goal (the commands drop to zero)."""
        if st.msg_class != "error":
            self.arm_error = None
            return []
        first = self.arm_error is None
        self.arm_error = st.text or f"arm error code {st.msg_code}"
        if first:
            self._abort_all(f"arm error: {self.arm_error}")
        return self._flush(st.stamp_ns)

    def on_bridge_state(self, bs: BridgeState) -> Output:
        """Follow the bridge's phase: goals run only while it is ``running``.

        Leaving ``running`` for a stop, an e-stop, an arm error, a fold or a shutdown
        aborts every goal (``resync`` does not: it shows as a gap in the joint states).
        """
        self.bridge_phase = bs.phase
        if bs.phase in STOPPING_PHASES and self._active():
            self._abort_all(f"bridge phase {bs.phase}: {bs.detail}")
            return self._flush(bs.stamp_ns)
        return []

    def on_scene(self, scene: SceneState) -> Output:
        """The planner's scene (replaced at run time, or its periodic announcement): the
        guard follows it (one that does not build keeps the guard as it was; the planner
        validated it already). The same scene again changes nothing."""
        if scene.same_scene(self.scene_seen):
            return []
        self.scene_seen = scene
        guard = scene_guard(scene, self.config.arm, self.world.held)
        if guard is not None and self.guard is not None:
            self.guard = guard
        return []

    def on_objects(self, update: WorldUpdate) -> Output:
        """The world model's updates (``planner/objects``): the guard keeps an object the
        arm holds (attached to the gripper) clear like a link of the arm, from the next
        command on. Never publishes."""
        if self.world.on_update(update) and self.guard is not None:
            self.guard.hold(self.world.held)
        return []

    def on_heartbeat(self, hb: Heartbeat) -> Output:
        """The supervisor's deadman heartbeat: remember the newest joint state it echoes.

        Judged at the next joint state (:meth:`on_joint_state`); never publishes.
        """
        self.supervision.on_heartbeat(hb)
        return []

    def on_token_gone(self, service: str) -> Output:
        """The token ``alive/<service>`` vanished (its process died or its link was cut).

        If a running goal's heartbeats came from that service (:func:`manus.deadman.tied_to`),
        every goal aborts at once and a zero command replaces the one already sent for this
        cycle. Always published as a :class:`~schemas.liveliness.TokenGone` (after which
        joint state it came: the regression check feeds it there).
        """
        js = self.last_js
        tied = self._tied_to(service)
        reason = f"{token_gone(service)} (stopped; nothing resumes by itself)" if tied else ""
        if tied:
            self._abort_all(reason)
        record = TokenGone(service=service, after_seq=-1 if js is None else js.seq, stopped=reason)
        out: Output = [(ep.TOKEN_GONE, record)]
        if js is None:
            return out
        if tied:  # the stop replaces this cycle's command at the next sync
            self.last_counts = np.zeros(6, dtype=np.int64)
            out.append((ep.JOINT_VELOCITY, self.outbox.command(js, self.last_counts, 0)))
        return out + self._flush(js.stamp_ns)

    def _tied_to(self, service: str) -> bool:
        """A running goal with a deadman got its heartbeats from ``service``."""
        since: list[int | None] = []
        if self.run is not None and self.run.goal.heartbeat_timeout > 0.0:
            since.append(self.heartbeat_since_ns)
        if self.gripper is not None and self.gripper.goal.heartbeat_timeout > 0.0:
            since.append(self.gripper.heartbeat_since_ns)
        return self.supervision.tied_to(service, since)

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

    def _active(self) -> bool:
        goals = self.pending is not None or self.run is not None or self.gripper is not None
        return goals or self.jog.engaged

    # -- live control ------------------------------------------------------------------------

    def on_jog(self, cmd: JogCommand) -> Output:
        """A command of the jog stream: taken (it acts from the next joint state), or
        refused and counted (the arm stops). A moving one preempts every goal; one that
        stops a moving jog also replaces the command already sent for this cycle."""
        js = self.last_js
        stamp = js.stamp_ns if js is not None and js.valid else None
        moving = self.jog.engaged
        self.jog.receive(cmd, stamp, self._not_ready())
        if self.jog.engaged and self._active_goals():
            reason = f"{USER_TOOK_OVER}: jog command from {cmd.source!r}"
            self._abort_all(reason, ResultStatus.PREEMPTED)
        return [self._taken(cmd), *self._jog_stopped(moving)]

    def on_bad_jog(self, error: str) -> Output:
        """A jog payload that does not decode (the shell's node refused it): counted,
        and the arm stops."""
        moving = self.jog.engaged
        self.jog.refuse(f"bad jog payload: {error}")
        return [self._taken(None, error), *self._jog_stopped(moving)]

    def set_jog_level(self, req: JogLevel) -> GoalAck:
        """Set the jog speed level (shown in the next JogState)."""
        reason = self.jog.set_level(req.level)
        return GoalAck(accepted=reason is None, goal_id="", reason=reason or "")

    def _taken(self, cmd: JogCommand | None, error: str = "") -> tuple[str, JogTaken]:
        after = self.last_js.seq if self.last_js is not None else -1
        return ep.JOG_TAKEN, JogTaken(after_seq=after, command=cmd, error=error)

    def _active_goals(self) -> bool:
        return self.pending is not None or self.run is not None or self.gripper is not None

    def _jog_stopped(self, moving: bool) -> Output:
        js = self.last_js
        out = self._flush(js.stamp_ns) if js is not None else []
        if not moving or self.jog.engaged or js is None:
            return out
        zero = np.zeros(6, dtype=np.int64)
        self.last_counts = zero  # the stop replaces this cycle's command at the next sync
        return [(ep.JOINT_VELOCITY, self.outbox.command(js, zero, 0)), *out]

    def on_joint_state(self, js: JointState) -> Output:
        """One cycle: the command for this joint state, feedback and any results."""
        last = self.last_js
        if last is not None and js.seq <= last.seq and js.stamp_ns <= last.stamp_ns:
            return []  # a duplicate or an old state: already answered
        # A lower seq with a newer stamp is a restarted bridge (its seq starts again at 0):
        # a gap, answered.
        cfg = self.config
        gap = last is not None and (
            js.seq != last.seq + 1 or js.stamp_ns - last.stamp_ns > cfg.max_stamp_gap_ns
        )
        self.last_js = js
        self.supervision.on_joint_state(js.stamp_ns, None if last is None else last.stamp_ns)
        usable = js.valid and js.mode == "joint"
        if gap or not usable:
            self._interrupted(js, last, gap, usable)
        if not usable:
            return self._answer(js, np.zeros(6, dtype=np.int64), 0, None, None, None)
        position = [float(v) for v in js.position]
        self._estimate(js, position, 0.0 if last is None or gap else js.stamp_ns - last.stamp_ns)
        if self.arm_error is not None:
            return self._answer(js, np.zeros(6, dtype=np.int64), 0, None, None, None)
        jogged = self._jog_cycle(js, gap)
        if jogged is not None:
            return jogged
        return self._goal_cycle(js, position, gap)

    def _interrupted(
        self, js: JointState, last: JointState | None, gap: bool, usable: bool
    ) -> None:
        """A gap in the joint states or an unusable one: the estimates start afresh; a long
        outage or an unusable state aborts every goal."""
        cfg = self.config
        self.joints.reset()
        self.grip.reset()
        self.play.reset()
        if gap and last is not None and self._outage(js, last) > cfg.max_outage_ms * MS:
            self._abort_all(
                f"joint states interrupted: seq {js.seq} after {last.seq}, "
                f"{(js.stamp_ns - last.stamp_ns) / 1e6:.0f} ms apart, more than "
                f"max_outage_ms {cfg.max_outage_ms:g} ms (stopped)"
            )
        if not usable:
            self._abort_all(f"joint state not usable (valid={js.valid}, mode {js.mode})")

    def _estimate(self, js: JointState, position: list[float], dt_ns: int | float) -> None:
        """Update the motor, belt and gripper estimates with this snapshot and the
        increments in flight (``dt_ns``: time since the last state, 0 after a gap)."""
        dt = dt_ns / 1e9
        applied = js.applied if js.applied_kind == "joint" else _NO_COUNTS
        motors = self.joints.update(
            dh_to_encoder_list(position), [c * COUNT_RAD_S for c in applied[1:7]], dt
        )
        if self.play.active:
            self.play.update(np.array(motors))
        self.grip.update([js.gripper], [applied[7] * GRIPPER_COUNT_M_S], dt)

    def _goal_cycle(self, js: JointState, position: list[float], gap: bool) -> Output:
        """The goals' cycle: start a pending goal, the deadman, the trajectory's and the
        gripper's commands."""
        cfg = self.config
        snap = js.stamp_ns - cfg.snapshot_age_ns
        q = np.array(position)
        before = self.run
        self._start_pending(snap, q)
        if self.run is not None and self.run is not before:
            self.heartbeat_since_ns = js.stamp_ns
        lost = self._heartbeat_lost(js)
        if lost is not None:
            self._abort_all(lost)
        step: Step | None = None
        run = self.run
        had_gripper = self.gripper is not None
        # The gripper position of the measured angles: one forward kinematics per cycle,
        # shared by the via points, the verdicts and the feedback.
        xyz = gripper_position(position, cfg.arm) if run is not None or had_gripper else None
        if run is not None and xyz is not None:
            if gap:
                run.pause(snap)  # the reference waits for the arm over the gap
            step = run.step(snap, q, xyz, self.joints, self.last_counts, self.play)
            if step.ended is not None:
                self._end_run(run, *step.ended)
        grip = self._gripper_cycle(js, snap)
        counts = step.counts if step is not None else np.zeros(6, dtype=np.int64)
        if gap:  # stop for this cycle: nothing is known of the cycle(s) missed
            counts, grip = np.zeros(6, dtype=np.int64), 0
        return self._answer(js, counts, grip, step, run, xyz)

    def _jog_cycle(self, js: JointState, gap: bool) -> Output | None:
        """This cycle's answer while a jog drives the arm (None: no jog does)."""
        self.jog.deadman(js)
        if not self.jog.engaged or self.run is not None or self.pending is not None:
            return None
        counts, grip = self.jog.cycle(self.joints)
        if gap:  # nothing is known of the cycle(s) missed: stop, start the reference afresh
            counts, grip, self.jog.run = np.zeros(6, dtype=np.int64), 0, None
        return self._answer(js, counts, grip, None, None, None)

    def _outage(self, js: JointState, last: JointState) -> int:
        """How long the joint states were missing [ns] (0: none)."""
        cycle = self.config.cycle_ns
        by_stamp = js.stamp_ns - last.stamp_ns - cycle
        by_seq = (js.seq - last.seq - 1) * cycle
        return max(0, by_stamp, by_seq)

    # -- internals -------------------------------------------------------------------------

    def _start_pending(self, snap: int, q: np.ndarray) -> None:
        goal, self.pending = self.pending, None
        if goal is None:
            return
        cfg = self.config
        tols = (tolerances(goal, "path_tolerance"), tolerances(goal, "goal_tolerance"))
        old = self.run
        if goal.replace and old is not None and not old.cancelling:
            ref_old, tau = old.reference_at(snap)
            new_duration = Reference(goal.trajectory, arm=cfg.arm).duration
            blend = max(cfg.cycle_s, min(cfg.splice_blend_s, new_duration or cfg.splice_blend_s))
            ref = ref_old.spliced(goal.trajectory, tau, blend)
            self._end_run(old, "preempted", f"replaced by {goal.goal_id!r} (spliced)")
            scale = old.scale
        else:
            if old is not None:
                self._end_run(old, "preempted", f"preempted by {goal.goal_id!r}")
            ref = Reference(goal.trajectory, arm=cfg.arm)
            scale = goal.speed_scale
        self.run = TrajectoryRun.start(goal, ref, cfg, tols, snap, scale)

    def _gripper_cycle(self, js: JointState, snap: int) -> int:
        run = self.gripper
        if run is None:
            return 0
        if run.start_ns is None:
            run.start_ns = snap
        goal = run.goal
        error = goal.opening - js.gripper
        counts = gripper_command(self.config, self.grip, goal.opening, run.cancelled)
        result: tuple[str, str] | None = None
        if run.cancelled:
            result = ("cancelled", "cancelled")
        elif abs(error) <= goal.tolerance and counts == 0:
            result = ("succeeded", f"opening {js.gripper * 1000:.1f} mm reached")
        elif (snap - run.start_ns) / 1e9 > goal.timeout:
            result = (
                "aborted",
                f"gripper at {js.gripper * 1000:.1f} mm, target {goal.opening * 1000:.1f} mm "
                f"not reached within the timeout {goal.timeout:g} s",
            )
        if result is not None:
            self._queue(goal.goal_id, *result, kind="gripper", final_error=abs(error))
            self.gripper = None
            return 0
        return counts

    def _abort_all(self, reason: str, status: str = ResultStatus.ABORTED) -> None:
        if self.pending is not None:
            self._queue(self.pending.goal_id, status, reason)
            self.pending = None
        if self.run is not None:
            self._end_run(self.run, status, reason)
        if self.gripper is not None:
            self._queue(self.gripper.goal.goal_id, status, reason, kind="gripper")
            self.gripper = None
        if status == ResultStatus.ABORTED and self.jog.engaged:
            self.jog.stop(reason)

    def _end_run(self, run: TrajectoryRun, status: str, reason: str) -> None:
        end = self.last_js.stamp_ns - self.config.snapshot_age_ns if self.last_js else 0
        self._queue(
            run.goal.goal_id,
            status,
            reason,
            via_errors=list(run.via_errors),
            via_stamps=list(run.via_stamps),
            final_error=run.final_error,
            duration=max(0.0, (end - run.start_ns) / 1e9),
            clearance=self.guard.result(run.goal.goal_id) if self.guard is not None else None,
        )
        if self.run is run:
            self.run = None

    def _queue(
        self,
        goal_id: str,
        status: str,
        reason: str,
        *,
        kind: str = "trajectory",
        via_errors: list[float] | None = None,
        via_stamps: list[int] | None = None,
        final_error: float = 0.0,
        duration: float = 0.0,
        clearance: ClearanceReport | None = None,
    ) -> None:
        self.outbox.queue(
            GoalResult(
                stamp_ns=0,
                seq=0,
                goal_id=goal_id,
                kind=kind,
                status=status,
                reason=reason,
                via_errors=via_errors or [],
                via_stamps=via_stamps or [],
                final_error=final_error,
                duration=duration,
                clearance=clearance,
            )
        )

    def _flush(self, stamp_ns: int) -> Output:
        return self.outbox.flush(stamp_ns)

    def _answer(
        self,
        js: JointState,
        counts: np.ndarray,
        grip: int,
        step: Step | None,
        run: TrajectoryRun | None,
        xyz: Vec3 | None,
    ) -> Output:
        """The command, the feedback (while a goal ran this cycle: ``xyz`` is the gripper
        position of the measured angles [m], None when none ran) and queued results."""
        counts = np.asarray(counts, dtype=np.int64)
        guarded = "" if self.guard is None else None
        if self.guard is not None and js.valid:
            verdict = self.guard.command(js, counts, run.goal.goal_id if run else "")
            counts, guarded = verdict.counts, verdict.reason
            if verdict.scale == 0.0 and run is not None and self.run is run:
                self._end_run(run, "aborted", f"collision guard {verdict.reason}")
        self.last_counts = counts
        cmd = self.outbox.command(js, counts, grip)
        out: Output = [(ep.JOINT_VELOCITY, cmd)]
        if xyz is not None:
            fb = self.outbox.feedback(js, xyz, step, run, self.gripper, cmd.velocity)
            out.append((ep.FEEDBACK, dataclasses.replace(fb, guard=guarded) if guarded else fb))
        jog = self.jog.state(js)
        if jog is not None:
            if guarded and jog.active:  # the collision guard slowed or stopped the jog
                jog = dataclasses.replace(jog, reason=f"collision guard {guarded}")
            out.append((ep.JOG_STATE, jog))
        return out + self._flush(js.stamp_ns)


def _with_scale(goal: TrajectoryGoal, scale: float) -> TrajectoryGoal:
    return dataclasses.replace(goal, speed_scale=scale)
